"""Every measurement slot given an endless or non-regular input, run from a shell as a user runs it:
wall-clock time and peak memory of each ``robocal`` process, start-up included.

    python benchmarks/bench_streams.py [--slots calibrate,verify] [--seconds 60]

The slots and their files are tests/test_input_streams.py's (which runs the same cases in forked
children of one process, under the bound of 5 s and 300 MB). Each case is one ``bash -c`` line
timed by GNU time (``/usr/bin/time -f '%e %M %U %S'``): the file itself, ``/dev/zero``, ``/dev/urandom``,
a FIFO that ``cat FILE > FIFO &`` feeds, a FIFO nothing feeds, and ``<(cat FILE)``. Prints a
Markdown table: wall seconds, CPU seconds (user and system: on a shared machine the wall clock is
not the program's), peak MB, exit code and the first line robocal printed on stderr.
"""

from __future__ import annotations

import argparse
import os
import shlex
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from test_input_streams import OUTPUT, SLOTS, stream_files  # noqa: E402

KINDS = ("file", "/dev/zero", "/dev/urandom", "fifo", "fifo, no writer", "<(cat FILE)")


def shell_line(kind: str, argv: list[str], content: str, folder: Path, timing: Path) -> str:
    """The bash line of one case: robocal under GNU time, its input ``kind`` in the slot."""
    robocal = [sys.executable, "-m", "robocal"]
    timed = f"/usr/bin/time -f '%e %M %U %S' -o {shlex.quote(str(timing))} " + " ".join(map(shlex.quote, robocal))

    def run(path: str) -> str:
        return timed + " " + " ".join(path if a == "INPUT" else shlex.quote(a) for a in argv)

    fifo = shlex.quote(str(folder / "input.fifo"))
    if kind == "file":
        return run(shlex.quote(content))
    if kind.startswith("/dev/"):
        return run(kind)
    if kind == "fifo":
        return f"mkfifo {fifo}; cat {shlex.quote(content)} > {fifo} & {run(fifo)}; kill %1 2>/dev/null; true"
    if kind == "fifo, no writer":
        return f"mkfifo {fifo}; {run(fifo)}"
    return run(f"<(cat {shlex.quote(content)})")


def measure(slot: str, kind: str, files: Path, seconds: float) -> dict:
    argv, content = SLOTS[slot]
    names = {"points": files / "points.csv", "fit": files / "fit.csv", "joints": files / "joints.csv",
             "store": files / "store.sqlite"}
    argv, content = [str(a).format(**names) for a in argv], str(content).format(**names)
    folder = Path(tempfile.mkdtemp(dir=files))
    output = OUTPUT.get(slot, OUTPUT.get(argv[0]))
    argv += ["--out", str(folder / output)] if output else []
    timing = folder / "time.txt"
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    try:
        p = subprocess.run(["bash", "-c", shell_line(kind, argv, content, folder, timing)], capture_output=True,
                           text=True, env=env, timeout=seconds)
        code, err = p.returncode, p.stderr
    except subprocess.TimeoutExpired:
        return {"wall": f"over {seconds:g}", "cpu": "", "peak": "", "code": "killed", "said": ""}
    fields = timing.read_text().split()[-4:] if timing.exists() else ["?", "0", "0", "0"]
    said = next((ln for ln in err.splitlines() if ln.startswith("robocal") and "Command exited" not in ln), "")
    return {"wall": fields[0], "cpu": f"{float(fields[2]) + float(fields[3]):.2f}",
            "peak": f"{int(fields[1]) / 1024:.0f}", "code": str(code), "said": said[:110]}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--slots", help="comma-separated (default every one of tests/test_input_streams.py)")
    p.add_argument("--seconds", type=float, default=60.0, help="kill a case after this long")
    args = p.parse_args(argv)
    slots = args.slots.split(",") if args.slots else list(SLOTS)
    with tempfile.TemporaryDirectory() as folder:
        files = stream_files(Path(folder))
        print("| slot | input | wall s | CPU s | peak MB | exit | robocal said |\n|---|---|---|---|---|---|---|")
        for slot in slots:
            for kind in KINDS:
                r = measure(slot, kind, files, args.seconds)
                print(f"| {slot} | `{kind}` | {r['wall']} | {r['cpu']} | {r['peak']} | {r['code']} | {r['said']} |",
                      flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
