"""Whether ``compare``'s budget for its larger models changes what it chooses, and what it saves.

Run: python benchmarks/compare_budget.py [--simulated 30] [--th8 16] [--seed 5]

Each campaign is compared twice, with the budget (100 evaluations of the residuals for every model
beyond the geometric one) and without it (``max_nfev=10**9``, which ``compare`` then gives every
model); the model chosen, its error in use and its verdict must be the same, and the levels the
budget left out are counted. The campaigns are
small, where a larger model may crawl: ``--simulated`` robots beyond the model (the 6R arm and the
cylindrical one with masses, ``robocal.sim.PRESETS`` in turn, 20 to 120 poses) and ``--th8``
random subsets of 20 to 40 of the TH8 example's poses (every other one with the base registered),
after the 20 of them on which a comparison crawled (the fuzzer's seed 205; its transmission levels
ran 612 to 5,800 evaluations each without the budget).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "tests"))
from robots import beyond_model  # noqa: E402

import robocal as rc  # noqa: E402

UNBUDGETED = {"max_nfev": 10 ** 9}


def simulated(n: int, rng):
    for name, preset, k, nominal, data in beyond_model(n, rng, poses=(20, 120)):
        yield f"{name} {preset} #{k} ({data.n_poses} poses)", nominal, data, {}


def th8_subsets(n: int, rng):
    root = os.path.join(os.path.dirname(HERE), "examples", "th8")
    model = rc.read_model(os.path.join(root, "model.yaml"))
    data = rc.io.read_measurements(os.path.join(root, "measurements.csv"), model)
    crawled = (17, 28, 26, 4, 10, 5, 21, 8, 3, 24, 19, 25, 30, 18, 6, 13, 20, 29, 16, 9)
    yield ("TH8, the 20 poses that crawled (base registered)", model,
           data.subset(np.array([data.labels.index(f"P{p:02d}") for p in crawled])), {"initial_base": "register"})
    for k in range(n):
        size = int(rng.integers(20, 41))
        sub = data.subset(np.sort(rng.choice(data.n_poses, size, replace=False)))
        options = {"initial_base": "register"} if k % 2 else {}
        yield f"TH8 subset #{k} ({size} poses{', base registered' if options else ''})", model, sub, options


def outcome(model, data, options):
    start = time.process_time()
    cmp = rc.compare(model, data, **options)
    best = cmp.best
    rms = None if best.in_use is None else round(float(best.in_use.position_after.rms), 9)
    left = sum("had not converged" in s for s in cmp.skipped)
    return (best.families, rms, best.verdict), time.process_time() - start, left


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--simulated", type=int, default=30)
    parser.add_argument("--th8", type=int, default=16)
    parser.add_argument("--seed", type=int, default=5)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    differ, cpu, cpu_free, left_out = 0, 0.0, 0.0, 0
    warnings.simplefilter("ignore")
    campaigns = [*simulated(args.simulated, rng), *th8_subsets(args.th8, rng)]
    for what, model, data, options in campaigns:
        chosen, spent, left = outcome(model, data, options)
        free, spent_free, _ = outcome(model, data, {**options, **UNBUDGETED})
        cpu += spent
        cpu_free += spent_free
        left_out += left
        differ += chosen != free
        print(f"{what}: {'same' if chosen == free else 'DIFFERENT'}, {spent:.1f} s against {spent_free:.1f} s"
              + ("" if chosen == free else f"\n  with the budget: {chosen}\n  without: {free}"), flush=True)
    print(f"{len(campaigns)} campaigns: {differ} chose differently; levels left out by the budget {left_out}; "
          f"CPU {cpu:.0f} s with the budget, {cpu_free:.0f} s without")


if __name__ == "__main__":
    main()
