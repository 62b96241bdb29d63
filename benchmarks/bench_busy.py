"""Time calibration and forward kinematics on an idle machine and with one core kept busy.

Run: python benchmarks/bench_busy.py [--repeat 10] [--fk-poses 100000]

Every figure is taken twice in one run: first as the machine is, then while a second process
(started and stopped by this script) keeps one core busy. Baselines in the same run:
scipy's finite-difference least squares on the same residuals (as in ``bench_identify.py``),
plain vectorised numpy forward kinematics (one (N, 4, 4) product per joint), and numpy's QR of
a tall matrix with BLAS left at its default threads, which is what stalls when a core is busy.
"""

from __future__ import annotations

import os
import platform
import subprocess
import sys
import time

import numpy as np
import scipy
from threadpoolctl import threadpool_info

import robocal as rc
from robocal.kinematics import parameter_vector

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_identify import arm6r, options, solve  # noqa: E402


def best_of(fn, repeat):
    """The best wall-clock and the best CPU time (this process, all its threads) of ``repeat`` runs."""
    wall, cpu = [], []
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        out = fn()
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return (min(wall), min(cpu)), out


def mdh_numpy(model, q):
    """Marker positions and orientations by plain vectorised numpy: one (N, 4, 4) product per joint."""
    p = parameter_vector(model)
    names = rc.parameter_names(model)
    N = q.shape[0]
    T = np.broadcast_to(np.eye(4), (N, 4, 4)).copy()
    T[:, :3, 3] = p[:3]
    T[:, :3, :3] = np.asarray(model.base_rotation)
    for j, f in enumerate(model.frames):
        al, d, th0, r = (p[names.index(f"{f.name}.{k}")] for k in ("alpha", "d", "theta", "r"))
        th = q[:, j] + th0
        ct, st, ca, sa = np.cos(th), np.sin(th), np.cos(al), np.sin(al)
        A = np.zeros((N, 4, 4))
        A[:, 0, 0], A[:, 0, 1], A[:, 0, 3] = ct, -st, d
        A[:, 1, 0], A[:, 1, 1], A[:, 1, 2], A[:, 1, 3] = ca * st, ca * ct, -sa, -r * sa
        A[:, 2, 0], A[:, 2, 1], A[:, 2, 2], A[:, 2, 3] = sa * st, sa * ct, ca, r * ca
        A[:, 3, 3] = 1.0
        T = T @ A
    tool = np.asarray(model.markers[0].position)
    return T[:, :3, :3] @ tool + T[:, :3, 3], T[:, :3, :3]


def figures(repeat: int, fk_poses: int) -> dict:
    """Every timed figure of one condition (seconds)."""
    out = {}
    m = arm6r(False)
    for n in (1000, 10_000):
        _, data = rc.simulate(m, n, seed=1)
        rep = repeat if n <= 1000 else max(2, repeat // 2)
        for _ in range(3):      # warm: the layouts and analyses kept per model, the allocator's heap grown
            rc.calibrate(m, data)
        out[f"calibrate {n}"], _ = best_of(lambda data=data: rc.calibrate(m, data), rep)
        if n == 1000:
            out[f"finite differences {n}"], _ = best_of(solve(m, data, ("geometric",), False), max(2, rep // 2))
    A = np.random.default_rng(0).standard_normal((3000, 35))
    out["numpy qr 3000x35 (default BLAS threads)"], _ = best_of(lambda: np.linalg.qr(A), repeat)
    q = rc.random_configurations(m, fk_poses, rng=0)
    rc.forward_kinematics(m, q)
    out[f"forward kinematics {fk_poses}"], ev = best_of(lambda: rc.forward_kinematics(m, q), 3)
    out[f"numpy forward kinematics {fk_poses}"], (pos, rot) = best_of(lambda: mdh_numpy(m, q), 3)
    assert np.allclose(ev.positions[:, 0], pos, atol=1e-12) and np.allclose(ev.rotations[:, 0], rot, atol=1e-12)
    return out


def main(argv=None):
    args = options(__doc__, argv, repeat=10, fk_poses=100_000)
    threads = [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]
    print(f"# robocal on a busy machine, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
          f"{platform.machine()}, {os.cpu_count()} cores, BLAS threads {threads}, numpy {np.__version__}, "
          f"scipy {scipy.__version__}; best of {args.repeat}; load average before "
          f"{os.getloadavg()[0]:.1f}")
    idle = figures(args.repeat, args.fk_poses)
    busy_proc = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        time.sleep(0.5)
        busy = figures(args.repeat, args.fk_poses)
    finally:
        busy_proc.terminate()
        busy_proc.wait()
    print("\n| figure | as found, wall (ms) | one core busy, wall (ms) | busy / as found | as found, CPU (ms) "
          "| one core busy, CPU (ms) |")
    print("|---|---|---|---|---|---|")
    for k in idle:
        (w0, c0), (w1, c1) = idle[k], busy[k]
        print(f"| {k} | {w0 * 1e3:.1f} | {w1 * 1e3:.1f} | {w1 / w0:.2f}x | {c0 * 1e3:.1f} | {c1 * 1e3:.1f} |")
    for name, f in (("as found", idle), ("busy", busy)):
        for i, clock in enumerate(("wall", "CPU")):
            fd, cal = f["finite differences 1000"][i], f["calibrate 1000"][i]
            fk, ref = f[f"forward kinematics {args.fk_poses}"][i], f[f"numpy forward kinematics {args.fk_poses}"][i]
            print(f"\n{name}, {clock} clock: calibrate at 1,000 poses {fd / cal:.1f}x faster than the "
                  "finite-difference "
                  f"solve alone; forward kinematics {fk / args.fk_poses * 1e6:.2f} us/pose against plain numpy's "
                  f"{ref / args.fk_poses * 1e6:.2f}")


if __name__ == "__main__":
    main()
