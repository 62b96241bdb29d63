"""Time calibrate() of socket campaigns against the package at an earlier commit, in one run.

Run: python benchmarks/bench_contacts.py [--baseline REV] [--repeat 3] [--turns 2]

Two campaigns, each calibrated with default options (``rc.calibrate(model, contacts=c)``, geometric,
the diagnosis included):

* the Franka Panda's sphere-in-socket campaign as its authors publish it (tests/data/real/mukca,
  6 placements, 387 seatings);
* a simulated socket plate on the 7-joint arm of examples/arm7 (8 placements, 3 sockets, 83 seatings
  per socket: 1,992 seatings, ``robocal.sim.socket_campaign``, seed 0).

The package at ``--baseline`` (``git archive`` into a temporary folder, first on ``sys.path``) and
this one run in child processes of their own, taking ``--turns`` turns; a figure is the best CPU
time (``process_time``) of ``--repeat`` calls after one untimed, over the turns (on a shared virtual
machine a whole process can run a quarter slower than the next). The parent checks that both give the
same estimates (1e-9 of the largest).
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from bench_identify import options  # noqa: E402
from bench_kinematics import baseline_sources, child_figures, heading  # noqa: E402

import robocal as rc  # noqa: E402
from robocal.sim import socket_campaign  # noqa: E402

ROOT = Path(HERE).parent
MUKCA = ROOT / "tests" / "data" / "real" / "mukca"


def campaigns() -> dict:
    """name: (model, contacts)."""
    panda = rc.read_urdf(MUKCA / "panda.urdf", tip_link="ball_link", markers=[("ball", (0.0, 0.0, 0.0))])
    arm = rc.read_model(ROOT / "examples" / "arm7" / "model.yaml")
    rng = np.random.default_rng(0)
    names = [n for n in rc.candidate_parameters(arm, ("geometric",)) if not n.startswith("base.")][:20]
    true = rc.perturb_model(arm, names, rng=rng)
    plate = socket_campaign(true, placements=8, poses_per_socket=83, joint_noise=2e-5, rng=rng)
    return {"Panda, published (387 seatings)": (panda, rc.io.read_contacts(MUKCA / "panda_3", panda)),
            f"7-joint arm, simulated ({plate.n_rows:,} seatings)": (arm, plate)}


def child(repeat: int, folder: str) -> None:
    """This process' best CPU times as JSON on stdout, its estimates saved in ``folder``."""
    warnings.simplefilter("ignore")
    out, saved = {}, {}
    for k, (name, (model, contacts)) in enumerate(campaigns().items()):
        result = rc.calibrate(model, contacts=contacts)
        saved[f"c{k}"] = [e.estimate for e in result.parameters]
        times = []
        for _ in range(repeat):
            t = time.process_time()
            rc.calibrate(model, contacts=contacts)
            times.append(time.process_time() - t)
        out[name] = min(times)
    np.savez(os.path.join(folder, "out.npz"), **saved)
    print(json.dumps(out))


def main(argv=None):
    args = options(__doc__, argv, repeat=3, turns=2, baseline="a6c0df6", child=0, folder="")
    if args.child:
        return child(args.repeat, args.folder)
    print(heading("calibrate() of socket campaigns", args.baseline, args.repeat))
    found: dict = {args.baseline: {}, "now": {}}
    with tempfile.TemporaryDirectory() as tmp:
        sources = {args.baseline: baseline_sources(args.baseline, tmp), "now": None}
        saved = {label: tempfile.mkdtemp(dir=tmp) for label in found}
        for _ in range(args.turns):
            for label, figures in found.items():
                for key, t in child_figures(__file__, sources[label], "--repeat", args.repeat, "--folder",
                                            saved[label]).items():
                    figures[key] = min(figures.get(key, np.inf), t)
        with np.load(os.path.join(saved["now"], "out.npz")) as x, \
                np.load(os.path.join(saved[args.baseline], "out.npz")) as y:
            for k in y:
                assert np.abs(x[k] - y[k]).max() <= 1e-9 * np.abs(y[k]).max(), k
    print(f"| campaign | {args.baseline} CPU (s) | now CPU (s) | now / {args.baseline} |")
    print("|---|---|---|---|")
    for key, t0 in found[args.baseline].items():
        t = found["now"][key]
        print(f"| {key} | {t0:.3f} | {t:.3f} | {t / t0:.2f}x |")
    print(f"\nestimates agree (1e-9 of the largest); load average after: "
          f"{' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
