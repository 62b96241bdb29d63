"""Time the kinematic pass and the position Jacobian against the engine as found, in one run.

Run: python benchmarks/bench_kinematics.py [--repeat 50] [--baseline fa10f9e] [--fk-poses 100000]

The baseline is the engine's source (``src/robocal/_kinematics.py``) at commit ``--baseline`` (read with ``git show``),
loaded as a second module of the package, so both engines see the same model, data and helpers.
Both run with BLAS on one thread. Timed, at 1,000 and 10,000 poses of the 6-joint arm of
``bench_identify.py`` (``rc.simulate(m, n, seed=1)``):

* the pass: ``kinematic_pass`` (frames and marker positions);
* a solver step's kinematics: a pass, then the position Jacobian (3 rows) of the identifiable
  geometric columns on it (the step axes and points they need are built on the way); the
  Jacobian's own cost is the difference of the two best times;
* forward kinematics at ``--fk-poses`` poses (positions and orientations, ``rc.forward_kinematics``)
  against plain vectorised numpy (``mdh_numpy`` of ``bench_busy.py``).

Both engines' results are checked to agree to 1e-12 (relative to the largest entry).
"""

from __future__ import annotations

import importlib.util
import os
import platform
import subprocess
import sys
import time

import numpy as np
from threadpoolctl import threadpool_limits

import robocal as rc
from robocal.kinematics import evaluate, parameter_vector

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_busy import mdh_numpy  # noqa: E402
from bench_identify import arm6r, options  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
# the engine behind the public ``evaluate``: the pass and the columns it times are its private parts
new = sys.modules[evaluate.__module__]


def baseline_module(rev: str):
    """The engine's source file as it was at commit ``rev``, loaded as a second module of the package."""
    src = subprocess.run(["git", "show", f"{rev}:src/robocal/_kinematics.py"], cwd=HERE, check=True,
                         capture_output=True, text=True).stdout
    spec = importlib.util.spec_from_loader("kinematics_as_found", loader=None)
    mod = importlib.util.module_from_spec(spec)
    mod.__package__ = "robocal"
    sys.modules[spec.name] = mod
    exec(compile(src, f"{rev}:_kinematics.py", "exec"), mod.__dict__)
    return mod


def best(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def step_call(eng, model, lay, p, qf, cols):
    """A function running one solver step's kinematics: a pass, then the position columns ``cols``
    on it (the step axes and points they need are built on the way)."""
    def run():
        st = eng.evaluate_state(model, lay, p, qf, compliance=False, orientations=False)
        return st.ps.P, eng.jacobian_columns(model, lay, st, cols, 0, 3)
    return run


def agree(a, b) -> float:
    a, b = np.asarray(a), np.asarray(b)
    return float(np.abs(a - b).max() / max(np.abs(b).max(), 1e-300))


def figures(base, m, n: int, repeat: int) -> tuple:
    """Best times of both engines at ``n`` poses: each function timed in a block of ``repeat``
    calls after three untimed ones, as a solver's loop runs it (interleaving the engines call by
    call would time the allocator: memory freed by one engine's arrays is given back to the
    system and faulted in again by the other's), the two engines' blocks twice in turn."""
    _, data = rc.simulate(m, n, seed=1)
    q = np.asarray(data.q)
    p = parameter_vector(m)
    qf = q @ m.coupling_matrix.T
    names = list(rc.identifiability(m, data, parameters=("geometric",)).identified)
    calls, out = {}, {}
    for label, eng in (("as found", base), ("now", new)):
        lay = eng.layout(m)
        cols = np.array([lay.names.index(c) for c in names])
        calls[label] = (lambda eng=eng, lay=lay: eng.kinematic_pass(m, lay, p, qf),
                        step_call(eng, m, lay, p, qf, cols))
        out[label] = calls[label][1]()
    times = {label: [np.inf, np.inf] for label in calls}
    for _ in range(2):
        for label, fns in calls.items():
            for k, fn in enumerate(fns):
                best(fn, 3)
                times[label][k] = min(times[label][k], best(fn, repeat))
    dp, dj = agree(out["now"][0], out["as found"][0]), agree(out["now"][1], out["as found"][1])
    assert dp < 1e-12 and dj < 1e-12, (dp, dj)
    return [(label, *times[label]) for label in ("as found", "now")], len(names), max(dp, dj)


def main(argv=None):
    args = options(__doc__, argv, repeat=50, baseline="fa10f9e", fk_poses=100_000)
    base = baseline_module(args.baseline)
    m = arm6r(False)
    print(f"# kinematics engine against {args.baseline}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
          f"{platform.machine()}, {os.cpu_count()} cores, numpy {np.__version__}, one BLAS thread, best of "
          f"{args.repeat}; load average before {os.getloadavg()[0]:.1f}\n")
    print("| poses | engine | pass (ms) | pass + position Jacobian of the identifiable geometric columns (ms) "
          "| the Jacobian alone: difference (ms) |")
    print("|---|---|---|---|---|")
    with threadpool_limits(limits=1, user_api="blas"):
        for n in (1000, 10_000):
            rows, k, diff = figures(base, m, n, args.repeat if n <= 1000 else max(3, args.repeat // 5))
            for label, tp, tj in rows:
                print(f"| {n} | {label} | {tp * 1e3:.3f} | {tj * 1e3:.3f} ({k} columns) | {(tj - tp) * 1e3:.3f} |")
            (_, p0, j0), (_, p1, j1) = rows
            print(f"| {n} | now / as found | {p1 / p0:.2f}x | {j1 / j0:.2f}x | {(j1 - p1) / (j0 - p0):.2f}x |")
            print(f"| {n} | largest relative difference | {diff:.1e} | | |")
        q = rc.random_configurations(m, args.fk_poses, rng=0)
        rc.forward_kinematics(m, q)

        def fk():
            new._TURNS.clear()            # the readings' cosines are not remembered from the last call
            return rc.forward_kinematics(m, q)
        t_fk = best(fk, 5)
        t_np = best(lambda: mdh_numpy(m, q), 5)
        ev, (pos, rot) = rc.forward_kinematics(m, q), mdh_numpy(m, q)
        assert np.allclose(ev.positions[:, 0], pos, atol=1e-12) and np.allclose(ev.rotations[:, 0], rot, atol=1e-12)
    print(f"\nforward kinematics at {args.fk_poses} poses: {t_fk * 1e3:.1f} ms "
          f"({t_fk / args.fk_poses * 1e6:.2f} us/pose) against plain numpy's {t_np * 1e3:.1f} ms "
          f"({t_np / args.fk_poses * 1e6:.2f} us/pose)")


if __name__ == "__main__":
    main()
