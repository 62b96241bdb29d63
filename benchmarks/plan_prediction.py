"""How well ``robocal plan`` predicts: parameter standard deviations and the held-out error of
calibrations on the planned poses with simulated noise, over seeds.

    python benchmarks/plan_prediction.py [--seeds 20]

For each seed: a true robot drawn near the nominal one, measured at the planned poses with the
instrument's noise, calibrated; the reported standard deviations are compared with the plan's
predicted ones (ratio per parameter) and the held-out RMS error (200 other poses of the same true
robot, same noise) with the predicted one. The test suite runs a few seeds of the same
(tests/test_cli_job.py); this runs the 20 of the issue.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

import robocal as rc

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from robots import arm6r  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=20)
    args = ap.parse_args()
    for label, model in (("6R arm", arm6r()), ("TH8-like", rc.read_model("examples/th8/model.yaml"))):
        noise = 2e-5
        sel = rc.select_poses(model, 50, n_candidates=10000, rng=0)
        pred = rc.predict_campaign(model, sel.q, noise=noise, rng=0)
        ratios, held = [], []
        for seed in range(args.seeds):
            true, data = rc.simulate(model, q=sel.q, noise=noise, seed=seed)
            q_val = rc.random_configurations(model, 200, 1000 + seed)
            validation = rc.measure(true, q_val, noise=noise, rng=seed)
            res = rc.calibrate(model, data, validation=validation, noise=rc.Noise.of(position=noise))
            got = {p.name: p.std for p in res.parameters}
            ratios.append(np.mean([got[n] / s for n, s in zip(pred.parameters, pred.std) if n in got]))
            held.append(res.stats.validation_after.rms)
        print(f"{label}: {len(pred.parameters)} parameters, {args.seeds} seeds, noise {noise * 1e3:.3f} mm")
        print(f"  reported std / predicted std, mean over parameters and seeds: {np.mean(ratios):.3f} "
              f"(seeds from {min(ratios):.3f} to {max(ratios):.3f})")
        print(f"  held-out RMS: measured {np.mean(held) * 1e3:.4f} mm, predicted {pred.held_out_rms * 1e3:.4f} mm, "
              f"ratio {np.mean(held) / pred.held_out_rms:.3f}")


if __name__ == "__main__":
    main()
