"""Hypotheses about the measured values (docs/diagnosis.md): a mirrored measurement frame, two axes
or two markers swapped, positions in another unit (or a model file in another unit), orientations in
another convention."""

from __future__ import annotations

from functools import partial
from itertools import combinations
from typing import cast

import numpy as np

from .._base.arrays import point_spread
from .._model.kinematics import evaluate
from .._model.measurements import Measurements
from .._model.parameters import model_from_vector, parameter_layout, parameter_vector
from .._model.robot import RobotModel
from .reference import Candidate, Reference, Repair, heavy_payload, with_arrays
from .rigid import gross, predicted, screen_data, screened_data

# known factors between length units, as the value read over the true one
LENGTH_FACTORS = {1e3: "millimetres read as metres", 1e-3: "metres read as millimetres",
                  10.0: "millimetres read as centimetres", 0.1: "centimetres read as millimetres",
                  25.4: "millimetres read as inches", 1 / 25.4: "inches read as millimetres"}
# the same factors said of a model file whose lengths are that many times too small
MODEL_UNITS = {1e3: "metres where millimetres", 1e-3: "millimetres where metres",
               10.0: "centimetres where millimetres", 0.1: "millimetres where centimetres",
               25.4: "inches where millimetres", 1 / 25.4: "millimetres where inches"}
# a robot's measured points spread between these (m): a repair that leaves them beyond is no robot's
PLAUSIBLE_SPREAD = (0.01, 50.0)


def _mirror(data: Measurements, axis: int) -> Measurements:
    M = np.ones(3)
    M[axis] = -1.0
    rot = None if data.rotations is None else data.rotations * M[:, None] * M[None, :]
    return with_arrays(data, positions=data.positions * M, rotations=rot)


def mirrored_frame(ref: Reference) -> list[Candidate]:
    """A left-handed measurement frame (one axis mirrored, or two axes swapped throughout): one axis
    mirrored (each of the three when the base pose is not identified, since then which one matters)."""
    if not gross(ref):
        return []
    axes = (0,) if ref.base_free else (0, 1, 2)
    misfits = [screened_data(ref, _mirror(screen_data(ref), a)) for a in axes]
    k = int(np.argmin(misfits))
    a = axes[k]
    which = "one axis" if ref.base_free else f"the {'xyz'[a]} axis"
    return [Candidate("mirrored frame", "the measurement frame is left-handed (an axis mirrored, or two axes swapped "
                      "in every marker's columns)", f"with {which} mirrored", "check the instrument's axis "
                      "convention and the order of the x, y, z columns", (), predicted(ref, misfits[k]), 0.0,
                      lambda: Repair(_mirror(ref.data, a)), absorbed=True)]


def _swap_axes(data: Measurements, marker: int, a: int, b: int) -> Measurements:
    pos = data.positions.copy()
    pos[:, marker, [a, b]] = pos[:, marker, [b, a]]
    return with_arrays(data, positions=pos)


def axes_swapped(ref: Reference) -> list[Candidate]:
    """Two axes swapped in one marker's columns (with two markers or more; in the only marker it is a
    mirrored frame): the swap the nominal robot matches best."""
    names = ref.data.marker_names
    if len(names) < 2 or not gross(ref):
        return []
    cands = [(m, a, b) for m in range(len(names)) for a, b in combinations(range(3), 2)]
    misfits = [screened_data(ref, _swap_axes(screen_data(ref), *c)) for c in cands]
    k = int(np.argmin(misfits))
    m, a, b = cands[k]
    return [Candidate("axes swapped", f"the {'xyz'[a]} and {'xyz'[b]} columns of marker {names[m]} are swapped",
                      "with them swapped back", f"swap the {'xyz'[a]} and {'xyz'[b]} columns of marker {names[m]} "
                      "back", (names[m],), predicted(ref, misfits[k]), 1.0,
                      lambda: Repair(_swap_axes(ref.data, m, a, b)))]


def swap_markers(data: Measurements, a: int, b: int) -> Measurements:
    """``data`` with markers ``a`` and ``b``'s columns swapped."""
    idx = np.arange(len(data.marker_names))
    idx[[a, b]] = idx[[b, a]]

    def take(x):
        return None if x is None else x[:, idx]

    return with_arrays(data, positions=data.positions[:, idx], mask=data.mask[:, idx], rotations=take(data.rotations),
                       rot_mask=take(data.rot_mask), sigma=take(data.sigma), sigma_rot=take(data.sigma_rot))


def markers_swapped(ref: Reference) -> list[Candidate]:
    """Two markers' columns swapped (names or columns): the swap the nominal robot matches best."""
    names = ref.data.marker_names
    pairs = list(combinations(range(len(names)), 2))
    if not pairs or not gross(ref):
        return []
    misfits = [screened_data(ref, swap_markers(screen_data(ref), *p)) for p in pairs]
    k = int(np.argmin(misfits))
    a, b = pairs[k]
    return [Candidate("markers swapped", f"markers {names[a]} and {names[b]} are swapped", "with them swapped back",
                      f"swap the columns (or names) of markers {names[a]} and {names[b]}", (names[a], names[b]),
                      predicted(ref, misfits[k]), 1.0, lambda: Repair(swap_markers(ref.data, a, b)))]


def model_scaled(model: RobotModel, s: float, *, markers: bool = True) -> RobotModel:
    """``model`` with every length of its frames (and, with ``markers``, of its markers and base) times ``s``."""
    lay = parameter_layout(model)
    p = parameter_vector(model)
    for par in lay.parameters:
        if par.quantity == "length" and (par.family == "frames" or markers and par.family in ("markers", "base")):
            p[par.index] *= s
    return model_from_vector(model, p)


def position_unit(ref: Reference) -> list[Candidate]:
    """Positions in another unit than declared, or a model file in another unit (its lengths in metres
    where millimetres were declared): the factor the nominal robot matches best. Which of the two
    files is wrong, the fit cannot tell (one is the other scaled); the sizes can: the file whose
    repair leaves a robot or a measured cloud of no plausible size is not the one at fault."""
    if not gross(ref):
        return []
    d = screen_data(ref)
    factors = list(LENGTH_FACTORS)
    misfits = [screened_data(ref, with_arrays(d, positions=d.positions / f)) for f in factors]
    k = int(np.argmin(misfits))
    f, why = factors[k], LENGTH_FACTORS[factors[k]]
    cloud = point_spread(ref.data.positions[ref.data.mask]) / f
    if PLAUSIBLE_SPREAD[0] <= cloud <= PLAUSIBLE_SPREAD[1]:
        return [Candidate("unit factor", f"positions: {why}", "in that unit", "declare the unit of the position "
                          "columns (e.g. x_mm) and calibrate again", (), predicted(ref, misfits[k], f), 1.0,
                          lambda: Repair(with_arrays(ref.data, positions=ref.data.positions / f), scale=f),
                          absorbed=True)]
    model = model_scaled(ref.model, f)
    return [Candidate("model unit", f"the model file's lengths are in {MODEL_UNITS[f]} were declared",
                      "with the model's lengths in that unit", "declare the model file's length unit (units: "
                      "{length: ...}) or convert its lengths, and calibrate again", (),
                      predicted(ref, misfits[k], f), 1.0, lambda: Repair(ref.data, model=model), model_file=True,
                      absorbed=True)]


def rotation_convention(ref: Reference) -> list[Candidate]:
    """Measured orientations in another convention: their inverses, Euler angles of one sequence read as
    the same letters intrinsic for extrinsic (or the reverse), quaternions read with the scalar at the
    other end. Screened only when the orientation fit failed (the rotations misfit beyond what any
    robot leaves)."""
    from scipy.spatial.transform import Rotation

    data = ref.data
    if not data.has_orientation or all(c.name != "orientation fit" or c.status == "pass" for c in ref.result.checks):
        return []
    rot_mask = cast(np.ndarray, data.rot_mask)
    R = np.where(rot_mask[..., None, None], cast(np.ndarray, data.rotations), np.eye(3))
    flat = Rotation.from_matrix(R.reshape(-1, 3, 3))
    quat = flat.as_quat()
    cands = [("the measured rotations are the inverses (transposes) of the marker orientations",
              np.swapaxes(R, -1, -2)),
             ("quaternions with the scalar last were read as scalar first",
              Rotation.from_quat(np.roll(quat, -1, axis=1)).as_matrix().reshape(R.shape)),
             ("quaternions with the scalar first were read as scalar last",
              Rotation.from_quat(np.roll(quat, 1, axis=1)).as_matrix().reshape(R.shape))]
    for seq in ("xyz", "zyx", "zyz", "XYZ", "ZYX", "ZYZ"):
        other = seq.swapcase()
        cands.append((f"Euler angles in the sequence {seq} were read as {other} "
                      f"({'intrinsic' if other.isupper() else 'extrinsic'} for "
                      f"{'intrinsic' if seq.isupper() else 'extrinsic'})",
                      Rotation.from_euler(other, flat.as_euler(seq)).as_matrix().reshape(R.shape)))
    Rp = evaluate(ref.start, data.q, orientations=True, payload_mass=data.payload_mass).rotations[
        :, [ref.start.marker_names.index(n) for n in data.marker_names]]
    now = _dispersion(Rp, R, rot_mask)
    spread = [_dispersion(Rp, Rh, rot_mask) for _, Rh in cands]
    order = np.argsort(spread)[:2]
    # the orientation fit failed: the two conventions closest to the predicted orientations are refitted
    return [Candidate("rotation convention", cands[k][0], "in that convention", "declare the orientation convention "
                      "of the rotation columns (--orientation)", (), np.inf if now > spread[k] else 1.0,
                      1.0 + np.log2(len(cands)),
                      partial(_with_rotations, data, rot_mask, cands[k][1]))
            for k in order]


def _with_rotations(data: Measurements, rot_mask: np.ndarray, rotations: np.ndarray) -> Repair:
    """The repair of ``data`` whose measured orientations are ``rotations`` (where ``rot_mask``)."""
    return Repair(with_arrays(data, rotations=np.where(rot_mask[..., None, None], rotations, np.nan)),
                  registered=False)


def _dispersion(Rp: np.ndarray, Rm: np.ndarray, mask: np.ndarray) -> float:
    """How far the rotations between predicted (``Rp``) and measured (``Rm``) orientations are from one
    rotation on either side (the base's and the marker's, which a fit takes up): the smaller of the
    two spreads of ``Rp Rm^T`` and ``Rm^T Rp`` about their means."""
    out = []
    for D in (Rp @ np.swapaxes(Rm, -1, -2), np.swapaxes(Rm, -1, -2) @ Rp):
        for j in range(D.shape[1]):
            Dj = D[mask[:, j], j]
            if len(Dj):
                out.append((j, float(np.mean(np.sum((Dj - Dj.mean(0)) ** 2, axis=(1, 2))))))
    by: dict[int, float] = {}
    for j, v in out:
        by[j] = min(v, by.get(j, np.inf))
    return float(sum(by.values()))


def payload_unit(ref: Reference) -> list[Candidate]:
    """A payload column in grams read as kilograms: payloads heavier than ``HEAVY_PAYLOAD`` times the
    robot's links (the model's masses), refitted a thousand times lighter. Fitted with compliance,
    the compliances shrink a thousandfold and take the payloads up: only the robot's weight tells."""
    data = ref.data
    if not heavy_payload(ref.model, data):
        return []
    links = sum(f.mass for f in ref.model.frames)
    masses = cast(np.ndarray, data.payload_mass)
    return [Candidate("unit factor", f"payload masses: grams read as kilograms (up to {np.max(masses):.4g} "
                      f"kg read, over {links:.4g} kg of the robot's links)", "in kilograms", "declare the payload "
                      "column's unit (payload_kg) and calibrate again", ("payload",), np.inf, 1.0,
                      lambda: Repair(with_arrays(data, payload_mass=masses / 1e3), registered=False),
                      absorbed=True)]
