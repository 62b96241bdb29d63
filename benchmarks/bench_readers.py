"""Which compiled parser reads measurement files: numpy's text reader against pandas', by parse
time, import time and install size.

Run: python benchmarks/bench_readers.py [--poses 100000,1000000]

For each size, a 6-joint arm's tracker export (as ``bench_io.py`` writes it) is parsed in a fresh
process by each parser alone (the ten columns as floats, the pose labels as text) and read whole by
``robocal.read_measurements``; each figure is the process's CPU time (``process_time``) and its
peak (``VmHWM``). Then the time ``import pandas`` adds to a process that has numpy already
(best of five fresh processes), and the size on disk of each parser's distribution with what it
requires that robocal's core does not (from the installed distributions' file records). pandas must
be installed for its figures (``pip install pandas``); they are left out otherwise.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from importlib import metadata
from pathlib import Path

import robocal as rc

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_identify import arm6r  # noqa: E402
from bench_io import HWM, tracker_file  # noqa: E402

PARSE = {
    "numpy": "import io, numpy as np\n"
             "raw = open(DATA, 'rb').read(); t = time.process_time()\n"
             "x = np.loadtxt(io.BytesIO(raw), delimiter=',', skiprows=1, usecols=range(1, 10), comments=None,"
             " quotechar=None, encoding='utf-8', ndmin=2)\n"
             "p = np.loadtxt(io.BytesIO(raw), delimiter=',', skiprows=1, usecols=[0], dtype=object, comments=None,"
             " quotechar=None, encoding='utf-8')\n",
    "pandas": "import io, numpy as np, pandas as pd\n"
              "raw = open(DATA, 'rb').read(); t = time.process_time()\n"
              "x = pd.read_csv(io.BytesIO(raw), header=None, skiprows=1, engine='c', quoting=3,"
              " dtype={0: object, **{k: np.float64 for k in range(1, 10)}})\n",
    "robocal.read_measurements": "import robocal as rc\n"
                                 "model = rc.read_model(MODEL); t = time.process_time()\n"
                                 "data = rc.read_measurements(DATA, model)\n",
}
# what the core requires already: not counted in a parser's install size
CORE = {"numpy", "scipy", "pyyaml", "threadpoolctl"}


def installed(name: str) -> bool:
    try:
        metadata.distribution(name)
    except metadata.PackageNotFoundError:
        return False
    return True


def parse(name: str, folder: Path) -> tuple[float, float]:
    """(CPU seconds, peak MB) of one parser on the folder's data.csv, in a fresh process."""
    code = "import time\n" + PARSE[name].replace("DATA", repr(str(folder / "data.csv"))).replace(
        "MODEL", repr(str(folder / "model.yaml"))) + f"print(time.process_time() - t, {HWM})\n"
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    cpu, peak = p.stdout.split()[-2:]
    return float(cpu), float(peak)


def import_seconds(module: str) -> float:
    """The best of five fresh processes' wall time to import ``module`` after numpy."""
    code = f"import numpy, time\nt = time.perf_counter()\nimport {module}\nprint(time.perf_counter() - t)"
    return min(float(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                                    check=True).stdout) for _ in range(5))


def install_mb(name: str) -> float:
    """MB on disk of distribution ``name`` and what it requires beyond the core (installed ones)."""
    seen: set[str] = set()
    todo, total = [name], 0
    while todo:
        dist = metadata.distribution(todo.pop())
        key = dist.metadata["Name"].lower()
        if key in seen or key in CORE:
            continue
        seen.add(key)
        total += sum(f.size or 0 for f in dist.files or ())  # the sizes its record lists (not the bytecode)
        for req in dist.requires or ():
            if "extra ==" not in req:
                dep = req.split(";")[0].split("[")[0].split("(")[0]
                dep = dep.split(">")[0].split("<")[0].split("=")[0].split("!")[0].split("~")[0].strip()
                if installed(dep):
                    todo.append(dep)
    return total / 2 ** 20


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", default="100000,1000000")
    args = ap.parse_args(argv)
    print(f"# compiled parsers, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, load average "
          f"{os.getloadavg()[0]:.1f}")
    parsers = [p for p in PARSE if p != "pandas" or installed("pandas")]
    print(f"numpy {metadata.version('numpy')}: in the core, nothing more installed or imported", flush=True)
    if installed("pandas"):
        print(f"pandas {metadata.version('pandas')}: {install_mb('pandas'):.0f} MB more installed (without bytecode), "
              f"import after numpy {import_seconds('pandas'):.2f} s", flush=True)
    print(f"{'poses':>9} {'parser':>26} {'CPU s':>8} {'peak MB':>8}", flush=True)
    model = arm6r(False)
    for n in (int(v) for v in args.poses.split(",")):
        with tempfile.TemporaryDirectory(prefix="robocal-bench-readers-") as d:
            folder = Path(d)
            rc.write_model(model, folder / "model.yaml")
            tracker_file(model, n, folder)
            for name in parsers:
                cpu, peak = parse(name, folder)
                print(f"{n:>9,} {name:>26} {cpu:>8.2f} {peak:>8.0f}", flush=True)


if __name__ == "__main__":
    main()
