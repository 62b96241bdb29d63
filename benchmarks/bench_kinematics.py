"""Time the kinematics of a solver step against the package as found, in one run.

Run: python benchmarks/bench_kinematics.py [--repeat 50] [--baseline fa10f9e] [--fk-poses 100000]

The baseline is the package at commit ``--baseline`` (``git archive`` into a temporary folder),
timed by this same script in a child process with those sources first on ``sys.path``; the two
take turns, twice. Everything is timed through public names, with BLAS on one thread, at 1,000
and 10,000 poses of the 6-joint arm of ``bench_identify.py`` (``rc.simulate(m, n, seed=1)``), on
the problem over its identifiable geometric parameters (``robocal.identification.Problem``):

* a pass: ``Problem.residuals`` at parameters not evaluated before (frames, marker positions,
  residuals);
* a solver step's kinematics: ``residuals`` then ``jacobian`` at new parameters; the Jacobian's
  own cost is the difference of the two best times;
* forward kinematics at ``--fk-poses`` poses (``rc.forward_kinematics``, positions and
  orientations; three sets of readings in turn, so nothing is remembered from the call before)
  against plain vectorised numpy (``mdh_numpy`` of ``bench_busy.py``).

Each is timed in a block of calls after three untimed ones, as a solver's loop runs it. Both
packages' residuals and Jacobians are checked to agree to 1e-12 (relative to the largest entry).
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import tempfile
import time

import numpy as np
from threadpoolctl import threadpool_limits

import robocal as rc
from robocal.identification import Problem
from robocal.kinematics import parameter_vector

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from bench_busy import mdh_numpy  # noqa: E402
from bench_identify import arm6r, options  # noqa: E402

POSES = (1000, 10_000)


def best(fn, repeat: int) -> float:
    fn(), fn(), fn()
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def step_times(m, n: int, repeat: int, out: str) -> dict:
    """Best times of a pass and of a step at ``n`` poses; the residuals and Jacobian at the first
    parameters are saved to ``out`` (an .npz) for the comparison."""
    _, data = rc.simulate(m, n, seed=1)
    names = rc.identifiability(m, data, parameters=("geometric",)).identified
    prob = Problem(m, free=names, data=data, compliance=False)   # keywords: the order changed after fa10f9e
    p0 = parameter_vector(m)
    rng = np.random.default_rng(0)
    moves = iter([prob.full(p0[prob.free_idx] + 1e-6 * rng.standard_normal(len(names)), p0)
                  for _ in range(8 * repeat + 40)])
    np.savez(out, r=prob.residuals(p0), J=prob.jacobian(p0))

    def step():
        p = next(moves)
        return prob.residuals(p), prob.jacobian(p)
    return {"pass": best(lambda: prob.residuals(next(moves)), repeat), "step": best(step, repeat)}


def child(repeat: int, folder: str) -> None:
    """This process' figures as JSON on stdout (the package first on ``sys.path`` is timed)."""
    m = arm6r(False)
    with threadpool_limits(limits=1, user_api="blas"):
        out = {str(n): step_times(m, n, repeat if n <= 1000 else max(3, repeat // 5), os.path.join(folder, f"{n}.npz"))
               for n in POSES}
    print(json.dumps(out))


def child_figures(script: str, src: str | None, *argv) -> dict:
    """The figures (JSON on stdout) of ``script`` run with ``--child 1`` and ``argv`` on the package in
    ``src`` (None: this one, as the caller's environment finds it), in a process of its own."""
    env = dict(os.environ)
    if src is not None:
        env["PYTHONPATH"] = os.pathsep.join([src, env.get("PYTHONPATH", "")])
    cmd = [sys.executable, os.path.abspath(script), "--child", "1", *map(str, argv)]
    return json.loads(subprocess.run(cmd, env=env, check=True, capture_output=True, text=True).stdout)


def heading(what: str, baseline: str, repeat: int) -> str:
    """The first line of a run against ``baseline``: what is timed, when, on what, and the load before."""
    return (f"# {what} against {baseline}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
            f"{platform.machine()}, {os.cpu_count()} cores, numpy {np.__version__}, best of {repeat}; load average "
            f"before {' '.join(f'{v:.2f}' for v in os.getloadavg())}\n")


def baseline_sources(rev: str, folder: str) -> str:
    """The package's sources at commit ``rev``, unpacked under ``folder``; the path to put first."""
    archive = subprocess.run(["git", "archive", rev, "src/robocal"], cwd=os.path.dirname(HERE), check=True,
                             capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", folder], input=archive, check=True)
    return os.path.join(folder, "src")


def agree(a: str, b: str) -> float:
    with np.load(a) as x, np.load(b) as y:
        return max(float(np.abs(x[k] - y[k]).max() / max(np.abs(y[k]).max(), 1e-300)) for k in ("r", "J"))


def forward_kinematics_times(m, fk_poses: int) -> tuple[float, float]:
    """Best times of ``rc.forward_kinematics`` and plain numpy at ``fk_poses`` poses, checked equal."""
    qs = [rc.random_configurations(m, fk_poses, rng=k) for k in range(3)]
    turn = iter(range(10 ** 6))
    with threadpool_limits(limits=1, user_api="blas"):
        t_fk = best(lambda: rc.forward_kinematics(m, qs[next(turn) % 3]), 5)
        t_np = best(lambda: mdh_numpy(m, qs[next(turn) % 3]), 5)
    ev, (pos, rot) = rc.forward_kinematics(m, qs[0]), mdh_numpy(m, qs[0])
    assert np.allclose(ev.positions[:, 0], pos, atol=1e-12) and np.allclose(ev.rotations[:, 0], rot, atol=1e-12)
    return t_fk, t_np


def main(argv=None):
    args = options(__doc__, argv, repeat=50, baseline="fa10f9e", fk_poses=100_000, child=0, folder="")
    if args.child:
        return child(args.repeat, args.folder)
    print(f"# kinematics against {args.baseline}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
          f"{platform.machine()}, {os.cpu_count()} cores, numpy {np.__version__}, one BLAS thread, best of "
          f"{args.repeat}; load average before {os.getloadavg()[0]:.1f}\n")
    with tempfile.TemporaryDirectory() as tmp:
        src = baseline_sources(args.baseline, tmp)
        dirs = {label: os.path.join(tmp, label.replace(" ", "_")) for label in ("as found", "now")}
        for d in dirs.values():
            os.mkdir(d)
        found = {label: {} for label in dirs}
        for _ in range(2):
            for label, path in (("as found", src), ("now", None)):
                for n, t in child_figures(__file__, path, "--repeat", args.repeat, "--folder", dirs[label]).items():
                    prev = found[label].get(n, {"pass": np.inf, "step": np.inf})
                    found[label][n] = {k: min(prev[k], t[k]) for k in t}
        diff = {n: agree(*(os.path.join(dirs[label], f"{n}.npz") for label in dirs)) for n in map(str, POSES)}
    print("| poses | package | pass (ms) | pass + Jacobian of the identifiable geometric columns (ms) "
          "| the Jacobian alone: difference (ms) |")
    print("|---|---|---|---|---|")
    for n in map(str, POSES):
        for label in ("as found", "now"):
            t = found[label][n]
            print(f"| {n} | {label} | {t['pass'] * 1e3:.3f} | {t['step'] * 1e3:.3f} | "
                  f"{(t['step'] - t['pass']) * 1e3:.3f} |")
        a, b = found["as found"][n], found["now"][n]
        print(f"| {n} | now / as found | {b['pass'] / a['pass']:.2f}x | {b['step'] / a['step']:.2f}x | "
              f"{(b['step'] - b['pass']) / (a['step'] - a['pass']):.2f}x |")
        assert diff[n] < 1e-12, diff
        print(f"| {n} | largest relative difference | {diff[n]:.1e} | | |")
    t_fk, t_np = forward_kinematics_times(arm6r(False), args.fk_poses)
    print(f"\nforward kinematics at {args.fk_poses} poses: {t_fk * 1e3:.1f} ms "
          f"({t_fk / args.fk_poses * 1e6:.2f} us/pose) against plain numpy's {t_np * 1e3:.1f} ms "
          f"({t_np / args.fk_poses * 1e6:.2f} us/pose)")


if __name__ == "__main__":
    main()
