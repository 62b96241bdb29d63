"""Hypotheses about the joint readings (docs/diagnosis.md): a joint that turns a little more or less
than its reading (its scale: a gear ratio off), a reading with the wrong sign, two joint columns
swapped, joint readings in another unit."""

from __future__ import annotations

from itertools import combinations

import numpy as np

from .._identification.problem import Problem
from .._model.parameters import joint_variable_names
from .reference import Candidate, Reference, Repair, projected_products, row_layout, with_arrays
from .rigid import gross, predicted, screen_data, screened_readings

# known factors between angle units, as the value read over the true one
ANGLE_FACTORS = {180 / np.pi: "degrees read as radians", np.pi / 180: "radians read as degrees"}
# ... and between the lengths of prismatic readings
READING_LENGTH_FACTORS = {1e3: "millimetres read as metres", 1e-3: "metres read as millimetres"}
# the family whose parameters carry a joint's scale and its periodic errors (docs/method.md)
TRANSMISSION = "transmission"
# a joint's scale within this (relative) may be the robot's own: a gear train's ratio is exact by its
# teeth, and belts, cables, heat and a gear's periodic error over the range stay below it (the
# published WAM's cable-driven j3 shows 0.996, the UR5's shoulder 1.0007); beyond it is a mistake (a
# ratio set wrong, a reading scaled), which the calibration cannot stand on
CARRIED_SCALE = 5e-3


def reading_columns(problem: Problem, p: np.ndarray) -> np.ndarray:
    """(n_rows, n_joints) the change of ``problem``'s weighted residual rows per unit change of each
    joint reading, at the full vector ``p``: the columns of the joint variables of the frames it
    drives (measured points or contacts alike; their nuisance columns left out)."""
    model = problem.model
    names = joint_variable_names(model)
    moving = [i for i, f in enumerate(model.frames) if f.joint != "fixed"]
    J = problem.over(tuple(names[i] for i in moving)).jacobian(p)[:, :len(moving)]
    return J @ model.coupling_matrix[moving]


def joint_columns(ref: Reference) -> np.ndarray:
    """``reading_columns`` of the reference's rows where the calibration took its Jacobian."""
    return ref.cached("joint_columns", lambda: reading_columns(ref.problem, ref.p if ref.at is None else ref.at))


def joint_scale(ref: Reference) -> list[Candidate]:
    """A joint that turns a little more or less than its reading (a gear ratio off): the joint whose
    scale lowers the reference's sum of squares most (one Gauss-Newton step each), refitted at that
    scale from the calibration."""
    data = ref.data
    pose = row_layout(ref)[0]
    C = joint_columns(ref) * data.q[pose]
    n_j = C.shape[1]
    M, b = projected_products(ref, C)
    norm = np.maximum(np.diag(M), 1e-300)
    gains = b ** 2 / norm                               # each joint's scale alone, one column each
    j = int(np.argmax(gains))
    s = float(-b[j] / norm[j])
    if not np.isfinite(s) or abs(s) > 0.5 or s == 0.0:
        return []
    name = ref.model.joint_names[j]
    freedom = 1.0 + np.log2(n_j)
    after = max(ref.ssr - gains[j], 1e-300) / max(ref.dof - freedom, 1.0)

    def repair():
        q = data.q.copy()
        q[:, j] *= 1.0 + s
        return Repair(with_arrays(data, q=q), registered=False)

    return [Candidate("joint scale", f"joint {name} moves {1.0 + s:.6g} times its reading (a gear ratio or a "
                      "reading scale off)", "with that scale", f"correct the gear ratio (or scale) of joint {name} in "
                      f"the controller or the readings; a robot whose joint turns so carries it in the "
                      f"'{TRANSMISSION}' parameters (--parameters geometric,{TRANSMISSION})", (name,),
                      ref.ssr / ref.dof / after, freedom, repair,
                      carried=abs(s) <= CARRIED_SCALE, beyond_robot=abs(s) > CARRIED_SCALE)]


def _changed(q: np.ndarray, joints, factor: float) -> np.ndarray:
    out = q.copy()
    out[:, joints] *= factor
    return out


def _swapped(q: np.ndarray, a: int, b: int) -> np.ndarray:
    out = q.copy()
    out[:, [a, b]] = out[:, [b, a]]
    return out


def _best(ref: Reference, options: list[tuple], absorbed: bool = False) -> list[Candidate]:
    """The candidate of ``options`` (words, readings change, freedom, items, fix, how) the nominal robot
    matches best on the screened poses, with the repair of the poses diagnosed (``absorbed``: a mistake
    a calibration can take up exactly, ``Candidate``)."""
    if not options:
        return []
    d = screen_data(ref)
    misfits = screened_readings(ref, [change(d.q) for _, change, *_ in options])
    k = int(np.argmin(misfits))
    (hypothesis, cause), change, freedom, items, fix, how = options[k]
    return [Candidate(hypothesis, cause, how, fix, items, predicted(ref, float(misfits[k])), freedom,
                      lambda: Repair(with_arrays(ref.data, q=change(ref.data.q))), absorbed=absorbed)]


def joint_sign(ref: Reference) -> list[Candidate]:
    """A joint reading with the wrong sign: the flip the nominal robot matches best, refitted from the
    nominal model."""
    if not gross(ref):
        return []
    names, n_j = ref.model.joint_names, ref.data.q.shape[1]
    return _best(ref, [(("joint sign", f"joint {names[j]}'s readings have the wrong sign"),
                        lambda q, j=j: _changed(q, [j], -1.0), np.log2(n_j), (names[j],),
                        f"reverse the sign of joint {names[j]}'s readings (or its direction in the model)",
                        "with its sign flipped") for j in range(n_j)], absorbed=True)


def joints_swapped(ref: Reference) -> list[Candidate]:
    """Two joint columns swapped (of the same kind): the swap the nominal robot matches best, refitted."""
    if not gross(ref):
        return []
    names, kinds = ref.model.joint_names, ref.model.reading_quantities
    pairs = [(a, b) for a, b in combinations(range(ref.data.q.shape[1]), 2) if kinds[a] == kinds[b]]
    return _best(ref, [(("joints swapped", f"the columns of joints {names[a]} and {names[b]} are swapped"),
                        lambda q, a=a, b=b: _swapped(q, a, b), np.log2(max(len(pairs), 2)), (names[a], names[b]),
                        f"swap the columns of joints {names[a]} and {names[b]}", "with them swapped back")
                       for a, b in pairs])


def reading_unit(ref: Reference) -> list[Candidate]:
    """Joint readings (all angles, or one joint) in degrees read as radians or the reverse, prismatic
    ones in millimetres read as metres or the reverse: the unit the nominal robot matches best."""
    if not gross(ref):
        return []
    quantities = np.array(ref.model.reading_quantities)
    options = []
    for quantity, factors in (("angle", ANGLE_FACTORS), ("length", READING_LENGTH_FACTORS)):
        joints = np.nonzero(quantities == quantity)[0]
        groups = ([list(joints)] if len(joints) else []) + ([[j] for j in joints] if len(joints) > 1 else [])
        for f, why in factors.items():
            for g in groups:
                names = tuple(ref.model.joint_names[j] for j in g)
                options.append((("unit factor", f"joint readings of {', '.join(names)}: {why}"),
                                lambda q, g=g, f=f: _changed(q, g, 1.0 / f), 1.0, names,
                                "declare the unit of those columns (e.g. j1_deg) and calibrate again", "in that unit"))
    return _best(ref, options, absorbed=True)
