"""Time identification of a 6-joint arm and batched kinematics; compare with a finite-difference baseline.

Run: python benchmarks/bench_identify.py [--repeat 5]

"solve" is the library's own solve (``robocal.identification.solve``, as ``calibrate`` runs it) on
the identifiable parameters with robocal's analytic Jacobian. The baseline solves the same problem
with the same vectorised residual function but scipy's finite-difference Jacobian ('2-point').
``calibrate`` (the whole call: analysis, solve, covariance, checks, statistics) is timed as well.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
import warnings

import numpy as np
import scipy
from scipy.optimize import least_squares

import robocal as rc
from robocal.identification import Problem
from robocal.identification import solve as library_solve
from robocal.kinematics import parameter_vector

# the baseline's tolerances: those of the library's solve
SOLVER_TOL = 1e-10

DEG = np.pi / 180


def arm6r(masses=False):
    rows = [dict(joint="revolute"), dict(joint="revolute", alpha=-90 * DEG), dict(joint="revolute", d=0.45),
            dict(joint="revolute", alpha=-90 * DEG, r=0.45), dict(joint="revolute", alpha=90 * DEG),
            dict(joint="revolute", alpha=-90 * DEG)]
    if masses:
        for row, m, c in zip(rows, [20, 15, 10, 5, 2, 1], [(0, 0, -0.1), (0.2, 0, 0.05), (0.1, -0.02, 0.2),
                                                          (0, 0.05, 0), (0, 0.01, 0.05), (0.01, 0, 0.02)]):
            row.update(mass=m, com=c)
    limits = [(-170 * DEG, 170 * DEG), (-120 * DEG, 60 * DEG), (-60 * DEG, 160 * DEG), (-170 * DEG, 170 * DEG),
              (-110 * DEG, 110 * DEG), (-180 * DEG, 180 * DEG)]
    return rc.serial_model("arm6r", rows, markers=[("tool", (0.05, 0.02, 0.12))], joint_limits=limits,
                           base_position=(1.5, -0.4, 0.2))


def best_of(fn, repeat):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return min(times), out


def warm(fn, calls: int = 3) -> None:
    """Untimed calls first, as ``bench_busy.py`` makes: the layouts and analyses kept per model,
    the allocator's heap grown."""
    for _ in range(calls):
        fn()


def solve(model, data, families, jac):
    """A function running one solve: the library's (``jac``), or the finite-difference baseline."""
    ident = rc.identifiability(model, data, parameters=families)
    p0 = parameter_vector(model)

    def problem():
        # a new problem for every run: a problem keeps its last evaluations, and a solve repeated on
        # the same one would find them all kept
        return Problem(model, ident.identified, data=data, compliance="compliance" in families)

    if jac:
        return lambda: library_solve(problem(), p0)

    def run():
        prob = problem()
        return least_squares(lambda x: prob.residuals(prob.full(x, p0)), p0[prob.free_idx], jac="2-point",
                             method="lm", x_scale="jac", xtol=SOLVER_TOL, ftol=SOLVER_TOL, gtol=SOLVER_TOL)
    return run


def options(doc: str, argv, **defaults):
    """The script's options (``--name`` for each default, typed like it), robocal's warnings silenced:
    a benchmark times the work, not the checks' messages."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    for name, default in defaults.items():
        ap.add_argument(f"--{name.replace('_', '-')}", type=type(default), default=default)
    warnings.simplefilter("ignore", rc.RobocalWarning)
    return ap.parse_args(argv)


def main(argv=None):
    args = options(__doc__, argv, repeat=5, fk_poses=100_000)
    print(f"# robocal identification benchmark, {time.strftime('%Y-%m-%d')}, {platform.machine()}, "
          f"{os.cpu_count()} cores, numpy {np.__version__}, scipy {scipy.__version__}; best of {args.repeat}")
    print("\n## Geometric identification, 6R arm\n")
    print("| poses | solve, analytic J (ms) | solve, finite differences (ms) | speed-up | calibrate() (ms) | nfev |")
    print("|---|---|---|---|---|---|")
    m = arm6r(False)
    for n in (48, 1000, 10_000):
        _, data = rc.simulate(m, n, seed=1)
        rep = args.repeat if n <= 1000 else max(1, args.repeat // 2)
        t_an, sol = best_of(solve(m, data, ("geometric",), True), rep)
        t_fd, sol_fd = best_of(solve(m, data, ("geometric",), False), max(1, rep // 2))
        warm(lambda data=data: rc.calibrate(m, data))
        t_cal, _ = best_of(lambda data=data: rc.calibrate(m, data), rep)
        print(f"| {n} | {t_an * 1e3:.1f} | {t_fd * 1e3:.1f} | {t_fd / t_an:.1f}x | {t_cal * 1e3:.1f} | "
              f"{sol.nfev} (FD {sol_fd.nfev}) |")
    print("\n## Compliance against geometry alone, same data (6R arm with masses, compliant truth)\n")
    print("| poses | calibrate() geometric (ms) | calibrate() geometric + compliance (ms) | ratio | "
          "solve geometric (ms) | solve with compliance (ms) | ratio | solve with compliance, FD (ms) |")
    print("|---|---|---|---|---|---|---|---|")
    m = arm6r(True)
    both = ("geometric", "compliance")
    for n in (48, 1000, 10_000):
        _, data = rc.simulate(m, n, seed=1, parameters=both, true_compliance={"j2.k_theta": 4e-6, "j3.k_theta": 6e-6})
        rep = args.repeat if n <= 1000 else max(1, args.repeat // 2)
        warm(lambda data=data: rc.calibrate(m, data))
        t_g, _ = best_of(lambda data=data: rc.calibrate(m, data), rep)
        warm(lambda data=data: rc.calibrate(m, data, parameters=both))
        t_c, _ = best_of(lambda data=data: rc.calibrate(m, data, parameters=both), rep)
        s_g, _ = best_of(solve(m, data, ("geometric",), True), rep)
        s_c, _ = best_of(solve(m, data, both, True), rep)
        s_fd, _ = best_of(solve(m, data, both, False), 1)
        print(f"| {n} | {t_g * 1e3:.1f} | {t_c * 1e3:.1f} | {t_c / t_g:.1f}x | {s_g * 1e3:.1f} | {s_c * 1e3:.1f} | "
              f"{s_c / s_g:.1f}x | {s_fd * 1e3:.0f} |")
    m = arm6r(True)
    q = rc.random_configurations(m, args.fk_poses, rng=0)
    names = rc.identifiability(m).identified
    rc.forward_kinematics(m, q)  # first touch of the large arrays
    t_fk, _ = best_of(lambda: rc.forward_kinematics(m, q), 3)
    t_j, J = best_of(lambda: rc.jacobian(m, q, columns=names), 3)
    t_jall, _ = best_of(lambda: rc.jacobian(m, q), 3)
    print(f"\n## Batched kinematics, {args.fk_poses} poses\n")
    print("| computation | time (ms) |")
    print("|---|---|")
    print(f"| forward kinematics (positions and orientations) | {t_fk * 1e3:.0f} |")
    print(f"| forward kinematics + Jacobian, {len(names)} identifiable columns | {t_j * 1e3:.0f} |")
    print(f"| forward kinematics + Jacobian, all {len(rc.parameter_names(m))} columns | {t_jall * 1e3:.0f} |")


if __name__ == "__main__":
    main()
