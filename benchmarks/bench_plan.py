"""Pose selection and command start-up, each against a baseline in the same run.

    python benchmarks/bench_plan.py

1. ``select_poses`` (I- and D-optimal) on a 6R arm: 30 of 2,000 and 50 of 10,000 candidates,
   against the same greedy selection and exchanges without the incremental updates (each step
   inverts M and evaluates every candidate's gain with k x k products, as robocal did before),
   from the same start; the criterion each reaches is printed beside the times. The baseline is
   run at 2,000 candidates only (at 10,000 it takes minutes).
   CPU time is given beside wall time: on a machine shared by several jobs the wall time says
   more about the neighbours than about the code.
2. ``robocal --help`` (a new process) against ``python -c "import numpy"``.

BLAS runs single-threaded (set below): on a machine shared by several jobs, threaded BLAS on
these tall, thin products is many times slower, and the selection's products are small.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

import robocal as rc  # noqa: E402
from robocal.identification import design_problem  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from robots import arm6r  # noqa: E402


def baseline(B, W, n, criterion, start, sweeps=2):
    """The greedy selection with exchanges, every step from scratch (the reference for speed)."""
    k = B.shape[2]
    ridge = 1e-9 * np.eye(k)

    def gains(idx):
        M = np.einsum("pri,prj->ij", B[idx], B[idx]) + ridge
        Minv = np.linalg.inv(M)
        pool = np.setdiff1d(np.arange(len(B)), idx)
        Bp = B[pool]
        S = np.einsum("pri,ij,psj->prs", Bp, Minv, Bp) + np.eye(B.shape[1])
        if criterion == "D":
            return pool, np.linalg.slogdet(S)[1]
        G = Minv @ W @ Minv
        return pool, np.einsum("prr->p", np.linalg.solve(S, np.einsum("pri,ij,psj->prs", Bp, G, Bp)))

    chosen = list(start)
    while len(chosen) < n:
        pool, g = gains(chosen)
        chosen.append(int(pool[np.argmax(g)]))
    for _ in range(sweeps):
        for pos in range(n):
            pool, g = gains(chosen[:pos] + chosen[pos + 1:])
            chosen[pos] = int(pool[np.argmax(g)])
    return np.array(chosen)


def prediction(B, W, idx):
    k = B.shape[2]
    A = B[idx].reshape(-1, k)
    return float(np.trace(np.linalg.solve(A.T @ A + 1e-9 * np.eye(k), W)))


def bench_selection():
    model = arm6r()
    print("| candidates | poses | criterion | select_poses, wall (s) | select_poses, CPU (s) | baseline, wall (s) | "
          "speed-up | tr(W M^-1) robocal | baseline |")
    print("|---|---|---|---|---|---|---|---|---|")
    for n_cand, n in ((2000, 30), (10000, 50)):
        for criterion in ("I", "D"):
            t, c = time.perf_counter(), time.process_time()
            sel = rc.select_poses(model, n, n_candidates=n_cand, criterion=criterion, rng=1)
            t_new, c_new = time.perf_counter() - t, time.process_time() - c
            # the baseline on the same candidates and blocks, from the same random start
            rng = np.random.default_rng(1)
            q = rc.random_configurations(model, n_cand, rng)
            names = sel.parameters
            B = design_problem(model, q, names).pose_blocks(rc.parameter_vector(model))
            B = B / np.linalg.norm(B, axis=(0, 1))
            W = np.einsum("pri,prj->ij", B, B) / len(q)
            start = sel.indices[:len(names) // 3 + 1]          # greedy keeps the start in front
            t = time.perf_counter()
            ref = baseline(B, W, n, criterion, [int(i) for i in start]) if n_cand <= 2000 else None
            t_old = time.perf_counter() - t if ref is not None else float("nan")
            p_ref = f"{prediction(B, W, ref):.4f}" if ref is not None else "(not run: minutes)"
            print(f"| {n_cand} | {n} | {criterion} | {t_new:.2f} | {c_new:.2f} | {t_old:.2f} | {t_old / t_new:.1f}x | "
                  f"{sel.prediction_selected:.4f} | {p_ref} |")


def bench_startup(repeats=7):
    exe = Path(sys.executable)
    robocal = exe.parent / "robocal"
    rows = {"python -c 'import numpy'": [str(exe), "-c", "import numpy"],
            "robocal --help": [str(robocal), "--help"],
            "robocal plan --help": [str(robocal), "plan", "--help"]}
    best = {}
    for _ in range(repeats):
        for label, argv in rows.items():
            t = time.perf_counter()
            subprocess.run(argv, stdout=subprocess.DEVNULL, check=True)
            best[label] = min(best.get(label, np.inf), time.perf_counter() - t)
    print(f"\n| command | best of {repeats} (s) | vs import numpy |")
    print("|---|---|---|")
    base = best["python -c 'import numpy'"]
    for label, t in best.items():
        print(f"| {label} | {t:.3f} | {t / base:.2f}x |")


if __name__ == "__main__":
    bench_selection()
    bench_startup()
