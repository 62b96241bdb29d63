"""The published tracker campaigns in tests/data/real (a UR5 and a Barrett WAM) as robocal records.

Each file holds the target position (the nominal model's prediction, mm), the measured deviation
from it (mm; measured = target + deviation, see tests/data/real/README.md) and the joint angles
in degrees. The nominal models are the manufacturers' classic DH tables beside the data.
"""

from pathlib import Path

import numpy as np

import robocal as rc

HERE = Path(__file__).parent / "data" / "real"
FILES = HERE / "serial_robots_datasets"


def nominal(robot: str):
    """The nominal model of ``robot`` ("UR5" or "WAM") from its DH table."""
    return rc.io.read_dh_table(HERE / f"{robot.lower()}-dh.csv")


def campaign(robot: str, kind: str, model=None):
    """The ``kind`` ("grid": the fitted campaign, "random": the test poses) of ``robot`` as Measurements."""
    path = FILES / robot / f"3D_{robot}_uncalibrated_{kind}_cleaned.csv"
    table = np.genfromtxt(path, delimiter=",", names=True)
    joints = sorted((n for n in table.dtype.names if n.startswith("joint_")), key=lambda n: int(n.split("_")[1]))
    q = np.deg2rad(np.column_stack([table[n] for n in joints]))
    measured = np.column_stack([table[f"{a}_t"] + table[f"{a}_dif"] for a in "xyz"]) * 1e-3
    model = nominal(robot) if model is None else model
    return rc.Measurements(q=q, positions=measured[:, None, :], marker_names=model.marker_names[:1],
                           joint_names=model.joint_names, labels=tuple(f"step {int(s)}" for s in table["step_order"]),
                           source=str(path))


def subsets(n: int, rng):
    """``n`` random subsets (60 to 400 poses) of each real grid, drawn from ``rng`` in the order of the
    benchmarks' corpora: yields (robot, k, nominal model, the grid's subset)."""
    for robot in ("UR5", "WAM"):
        model = nominal(robot)
        grid = campaign(robot, "grid", model)
        for k in range(n):
            size = int(rng.integers(60, min(400, grid.n_poses) + 1))
            yield robot, k, model, grid.subset(np.sort(rng.choice(grid.n_poses, size, replace=False)))
