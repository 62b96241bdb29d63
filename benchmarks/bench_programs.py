"""Time compensating a robot program of 10,000 targets (issue 28: under 2 s).

    python benchmarks/bench_programs.py --targets 10000 --repeat 3

An ABB RAPID module of a 6R arm, half jointtargets and half robtargets (random configurations
within the limits, away from the wrist and elbow singularities), each on its own line, the robtargets
moved to by a ``MoveL`` each with the tool ``tTool`` (the model's tool point); a calibrated model with
errors of 0.1 to 1 mm and 0.01 to 0.1 deg. Timed: reading the module, compensating it and the text
written back, best of ``--repeat`` runs; the baseline in the same run is ``rc.compensate`` on the
same joint targets as an array (what ``robocal compensate`` does with a CSV), and the Cartesian
half alone shows what the nominal inverse kinematics costs.
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

import robocal as rc
from robocal.io import compensate_program, read_program
from robocal.kinematics import posture
from robocal.sim import perturb_model

DEG = math.pi / 180


def arm() -> rc.RobotModel:
    """A 6R industrial arm with shoulder and elbow offsets (modified DH), about 1.1 m reach."""
    rows = [dict(r=0.40), dict(alpha=-90 * DEG, d=0.15, theta=-90 * DEG), dict(d=0.60),
            dict(alpha=-90 * DEG, d=0.12, r=0.62), dict(alpha=90 * DEG), dict(alpha=-90 * DEG)]
    limits = [(-170 * DEG, 170 * DEG), (-90 * DEG, 150 * DEG), (-180 * DEG, 75 * DEG),
              (-400 * DEG, 400 * DEG), (-125 * DEG, 125 * DEG), (-400 * DEG, 400 * DEG)]
    return rc.serial_model("bench6r", rows, markers=[("tool", (0.0, 0.0, 0.1))], joint_limits=limits)


def module(model: rc.RobotModel, n: int, rng) -> tuple[str, np.ndarray]:
    """A RAPID module of ``n`` targets (half joint, half Cartesian) and the joint targets' readings."""
    lo, hi = np.array([-160, -80, -170, -180, -120, -180]) * DEG, np.array([160, 140, 65, 180, 120, 180]) * DEG
    q = rng.uniform(lo, hi, (n, 6))
    # away from the wrist (axis 5 at 0) and elbow (axis 3 at -atan(0.62 / 0.12)) singularities, as a
    # taught program is: the calibrated robot cannot follow the nominal one into a stretched elbow
    q[:, 4] = np.where(np.abs(q[:, 4]) < 10 * DEG, 10 * DEG * np.sign(q[:, 4] + 1e-9), q[:, 4])
    elbow = -math.atan2(0.62, 0.12)
    q[:, 2] = np.where(np.abs(q[:, 2] - elbow) < 12 * DEG, elbow + 12 * DEG * np.sign(q[:, 2] - elbow + 1e-9),
                       q[:, 2])
    ev = rc.evaluate(model, q, orientations=True)
    bits = posture(model, q)
    lines, eax = ["MODULE Bench", "  ! generated targets"], "[9E9,9E9,9E9,9E9,9E9,9E9]"
    lines.append("  PERS tooldata tTool := [TRUE,[[0,0,100],[1,0,0,0]],[1,[0,0,0],[1,0,0,0],0,0,0]];")
    for i in range(n):
        if i % 2 == 0:
            lines.append(f"  CONST jointtarget j{i} := [[{','.join(f'{v:.4f}' for v in q[i] / DEG)}],{eax}];")
            continue
        x, y, z, w = Rotation.from_matrix(ev.rotations[i, 0]).as_quat()
        cf = [int(math.floor(q[i, j] / (math.pi / 2))) for j in (0, 3, 5)]
        cfx = int(4 * bits[i, 0] + 2 * bits[i, 1] + bits[i, 2])
        p = ev.positions[i, 0] * 1e3
        lines.append(f"  CONST robtarget p{i} := [[{p[0]:.3f},{p[1]:.3f},{p[2]:.3f}],[{w:.8f},{x:.8f},{y:.8f},"
                     f"{z:.8f}],[{cf[0]},{cf[1]},{cf[2]},{cfx}],{eax}];")
    motions = [f"    MoveL p{i}, v100, fine, tTool;" for i in range(1, n, 2)]
    return "\n".join(lines + ["  PROC main()", *motions, "  ENDPROC", "ENDMODULE", ""]), q[::2]


def best(fn, repeat: int) -> tuple[str, object]:
    """"wall W s (CPU C s)" of the best of ``repeat`` runs (the CPU time of this process: on a shared
    machine it says what the work costs when the wall time says how busy the machine is) and the output."""
    times, out = [], None
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        times.append((time.perf_counter() - t0, time.process_time() - c0))
    wall, cpu = min(times)
    return f"wall {wall:.3f} s (CPU {cpu:.3f} s)", out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--targets", type=int, default=10_000)
    ap.add_argument("--repeat", type=int, default=3, help="report the best of this many runs")
    args = ap.parse_args()
    nominal = arm()
    calibrated = perturb_model(nominal, rc.candidate_parameters(nominal, ("geometric",)), rng=1)
    text, q_joint = module(nominal, args.targets, np.random.default_rng(0))
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "bench.mod"
        path.write_text(text)
        compensate_program(read_program(path), nominal, calibrated)          # imports and first calls
        t_all, result = best(lambda: compensate_program(read_program(path), nominal, calibrated), args.repeat)
        t_read, program = best(lambda: read_program(path), args.repeat)
    t_base, _ = best(lambda: rc.compensate(calibrated, q_joint, nominal=nominal), args.repeat)
    flagged = len(result.flagged)
    print(f"{args.targets} targets ({len(q_joint)} joint, {args.targets - len(q_joint)} Cartesian), cores "
          f"{os.cpu_count()}, best of {args.repeat}:")
    print(f"  read + compensate + text written back  {t_all}   ({flagged} flagged)")
    print(f"  read alone                             {t_read}")
    print(f"  baseline: rc.compensate of the {len(q_joint)} joint targets as an array  {t_base}")
    print(f"  load average before: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
