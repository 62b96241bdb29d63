"""Hypotheses along the campaign's order and across its rows (docs/diagnosis.md): rows shifted
against their readings, pose labels offset, a step or a drift of the base, the load or the whole
robot, a joint rehomed partway or drifting, joint readings that lag the measurements, a marker
elsewhere on some rows (a reflector in another nest, moved in its nest, the tool changed), marker
labels swapped on some rows.

Each returns candidates (``reference.Candidate``): what cheap statistics predict, and the repair to
refit or the columns to step when the prediction survives the screen."""

from __future__ import annotations

from dataclasses import replace
from functools import partial
from itertools import combinations
from typing import NamedTuple, cast

import numpy as np

from .._base.spatial import rotation_vector, small_rotation
from .._identification.holdout import ordered
from .._identification.points import Points
from .._identification.problem import Problem
from .._model.kinematics import loads_at
from .._model.measurements import Measurements, approach_of
from .._model.parameters import candidate_parameters, parameter_layout
from .._model.robot import Marker, Payload, RobotModel
from .joints import joint_columns
from .reference import (
    SPAN_SHARE,
    SURVIVE_FACTOR,
    Candidate,
    Linear,
    Outcome,
    Reference,
    Repair,
    mm,
    projected_gain,
    projected_products,
    refit,
    row_layout,
    with_arrays,
)
from .rigid import gross, moments, registered, rigid_misfit

# row shifts tried (rows from a row on hold the point of the pose this many rows later)
SHIFTS = (1, 2, 3, -1, -2, -3)
# the screen's lag is refined by refits at these multiples of it
LAG_TRIALS = (0.8, 1.0, 1.2)
# a change point is looked for with at least this share of the poses on each side
EDGE_SHARE = 0.05
# a marker is elsewhere on some rows, or its labels swapped, on at least this many rows
MIN_ROWS = 3
# a change point is first looked for at this many rows spread evenly, then about the best of them
SPLITS = 64
# a joint's gravity load this small against the largest is rounding: it rests on no side
LOAD_ROUNDING = 1e-9


def _predicted(ref: Reference, gain: float, freedom: float) -> float:
    """The factor a fit that lowers the reference's sum of squares by ``gain`` (``freedom``
    parameters more) divides its residual variance by."""
    after = max(ref.ssr - gain, 1e-300) / max(ref.dof - freedom, 1.0)
    return float(ref.ssr / ref.dof / after)


def _label(ref: Reference, pose: int) -> str:
    """The campaign label of a pose diagnosed."""
    return ref.campaign.labels[int(ref.rows[pose])]


# -- the order of the rows --------------------------------------------------------------------------

def shifted_rows(n: int, row: int, k: int, *, cyclic: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The rows of readings and of points to pair when, from ``row`` on, each row holds the point of
    the pose ``k`` rows later (a missed shot for k > 0, an extra one for k < 0): (reading rows, point
    rows). Without ``cyclic`` the rows left without a partner are dropped.

    >>> [a.tolist() for a in shifted_rows(5, 2, 1)]
    [[0, 1, 3, 4], [0, 1, 2, 3]]
    >>> [a.tolist() for a in shifted_rows(4, 0, -1, cyclic=True)]
    [[3, 0, 1, 2], [0, 1, 2, 3]]
    """
    r = np.arange(n)
    if cyclic:
        return np.where(r >= row, row + (r - row + k) % max(n - row, 1), r), r
    src = np.where(r >= row, r + k, r)
    keep = (r < row) | ((src >= row) & (src < n))
    return src[keep], r[keep]


def paired(data: Measurements, q_rows: np.ndarray, point_rows: np.ndarray) -> Measurements:
    """The readings of ``q_rows`` with the measured values of ``point_rows``."""
    base = data.with_approach().subset(q_rows)

    def take(a):
        return None if a is None else a[point_rows]

    return replace(base, positions=data.positions[point_rows], mask=data.mask[point_rows],
                   rotations=take(data.rotations), rot_mask=take(data.rot_mask), sigma=take(data.sigma),
                   sigma_rot=take(data.sigma_rot))


def _campaign_positions(ref: Reference) -> np.ndarray:
    """The nominal robot's marker positions at every pose of the campaign."""
    from .reference import nominal_positions

    if ref.campaign.n_poses == ref.data.n_poses:
        return ref.positions0
    return ref.cached("campaign_positions", lambda: nominal_positions(ref.model, ref.campaign))


def _shift_misfits(P: np.ndarray, data: Measurements, k: int) -> np.ndarray:
    """(n,) per row i the rigid misfit per point of the nominal positions ``P`` to the points when,
    from row i on, each row holds the point of the pose ``k`` rows later: cumulative sums of the
    rigid match's statistics, so every row is tried at once."""
    n = data.n_poses
    same = moments(P, data.positions, data.mask)
    r = np.arange(n)
    src = np.clip(r + k, 0, n - 1)
    moved = moments(P[src], data.positions, data.mask) * ((r + k >= 0) & (r + k < n))[:, None]
    before = np.vstack([np.zeros(18), np.cumsum(same, axis=0)])             # rows < i
    after = np.vstack([np.cumsum(moved[::-1], axis=0)[::-1], np.zeros(18)])  # rows >= j
    i = np.arange(n)
    total = before[i] + after[np.minimum(i + max(0, -k), n)]
    return rigid_misfit(total) / np.maximum(total[:, 0], 1.0)


def _rigid_whole(ref: Reference) -> tuple[np.ndarray, float]:
    """The nominal robot's positions along the whole campaign, and its rigid match's misfit per point."""
    data, P = ref.campaign, _campaign_positions(ref)
    return P, float(rigid_misfit(moments(P, data.positions, data.mask).sum(0))) / max(data.mask.sum(), 1)


def rows_shifted(ref: Reference) -> list[Candidate]:
    """From some row on, each row holds the point of another pose (a missed or an extra shot): every
    row and shift in ``SHIFTS`` screened at once by a rigid match of the nominal robot."""
    data, n = ref.campaign, ref.campaign.n_poses
    if n < 8 or not gross(ref):
        return []
    P, whole = _rigid_whole(ref)
    best = (whole, 0, 0)
    for k in SHIFTS:
        m = _shift_misfits(P, data, k)[1: n - 2]
        j = int(np.argmin(m))
        if m[j] < best[0]:
            best = (float(m[j]), j + 1, k)
    misfit, row, k = best
    if k == 0:
        return []
    label = data.labels[row]
    what = "next" if k == 1 else (f"{k} rows later" if k > 0 else ("previous" if k == -1 else f"{-k} rows earlier"))
    pose = f"the {what} pose's point" if abs(k) == 1 else f"the point of the pose {what}"
    q_rows, p_rows = shifted_rows(n, row, k)
    return [Candidate("rows shifted", f"rows from {label} on hold {pose} ({'a missed' if k > 0 else 'an extra'} "
                      "shot)", "with that shift", f"re-pair the rows from {label} on with their poses (or remove "
                      "them) and calibrate again", (label,), whole / max(misfit, 1e-300), 2.0 + np.log2(n),
                      lambda: Repair(paired(data, q_rows, p_rows), pose_rows=p_rows))]


def pose_labels_offset(ref: Reference) -> list[Candidate]:
    """Readings and points joined with pose labels off by a few (P00.. against P01..): every row holds
    another pose's point, cyclically or with the rows at the end left unpaired."""
    data, n = ref.campaign, ref.campaign.n_poses
    if n < 8 or not gross(ref):
        return []
    P, whole = _rigid_whole(ref)
    best = (whole, 0, False)
    for k in SHIFTS:
        for cyclic in (False, True):
            qr, pr = shifted_rows(n, 0, k, cyclic=cyclic)
            mo = moments(P[qr], data.positions[pr], data.mask[pr]).sum(0)
            v = float(rigid_misfit(mo)) / max(mo[0], 1.0)
            if v < best[0]:
                best = (v, k, cyclic)
    misfit, k, cyclic = best
    if k == 0:
        return []
    later = "later" if k > 0 else "earlier"
    q_rows, p_rows = shifted_rows(n, 0, k, cyclic=cyclic)
    return [Candidate("pose labels offset", f"readings and points are paired {abs(k)} pose(s) apart: each row "
                      f"holds the point of the pose {abs(k)} row(s) {later}" + (" (the rows wrap around)" if cyclic
                                                                              else ""),
                      "with the points moved by that offset", "join the readings and the points on the right pose "
                      "labels (check the first label of each file)", (), whole / max(misfit, 1e-300),
                      1.0 + np.log2(2 * len(SHIFTS)), lambda: Repair(paired(data, q_rows, p_rows), pose_rows=p_rows))]


# -- a step or a drift along the campaign ----------------------------------------------------------

def _groups(ref: Reference) -> list[tuple]:
    """(what changes, columns of the reference's Jacobian or ``"load"``) of the groups a step or a
    drift may move: the base (the instrument against the robot), the load, the whole robot (only when
    the calibration shows a mistake, ``Reference.shows``: the costliest, and another robot partway
    leaves a misfit)."""
    def make():
        lay = parameter_layout(ref.start)
        fam = np.array([lay[n].family for n in ref.names])
        out: list[tuple] = []
        if np.any(fam == "base"):
            out.append(("the measurement frame against the robot (the instrument bumped or the robot moved)",
                        np.nonzero(fam == "base")[0]))
        if any(f.mass for f in ref.start.frames) and np.any(fam == "compliance"):
            out.append(("the load on the robot (a payload the data do not state)", "load"))
        if ref.shows:
            out.append(("the robot itself (another robot, or a load the model does not know)",
                        np.arange(len(ref.names))))
        return out

    return ref.cached("groups", make)


def _columns(ref: Reference, cols) -> np.ndarray:
    return ref.cached("load", lambda: _load_columns(ref)) if isinstance(cols, str) else ref.J[:, cols]


def _load_columns(ref: Reference) -> np.ndarray:
    """(n_rows, n_joints) how the joints' torsional compliances bend the robot under a unit mass at
    its last frame (the robot's own masses left out), at the calibration's values."""
    return load_columns(ref.model, ref.problem.model, ref.p, ref.data, ref.noise)


def load_columns(model: RobotModel, at: RobotModel, p: np.ndarray, data: Measurements, noise) -> np.ndarray:
    """(n_rows, n_joints) the rows of ``data`` per unit torsional compliance of each joint under a unit
    mass at the last frame, the links massless, at the values ``p`` of the model ``at`` (the
    calibration's: its compliances, and rotation corrections of ``at``'s stored rotations, which the
    calibration's own fit takes from the nominal and a diagnosis from scratch from the calibrated
    model): on the nominal ``model``'s massless copy kept with it (``unloaded``, its structure made
    once), ``at``'s stored rotations entering as corrections of its own."""
    bare = unloaded(model)
    names = tuple(n for n in candidate_parameters(model, ("compliance",)) if n.endswith(".k_theta"))
    loaded = with_arrays(data, payload_mass=np.ones(data.n_poses))
    prob = Problem(bare, names, data=loaded, compliance=True, noise=noise)
    lay = parameter_layout(bare)
    q = np.array(p[:lay.n_params], dtype=float)
    q[3:6] = rotation_vector(np.asarray(model.base_rotation).T @ np.asarray(at.base_rotation)
                             @ small_rotation(*q[3:6]))
    for m, (mk, mc) in enumerate(zip(model.markers, at.markers)):
        at_rows = slice(lay.marker0[m] + 3, lay.marker0[m] + 6)
        q[at_rows] = rotation_vector(np.asarray(mk.rotation).T @ np.asarray(mc.rotation) @ small_rotation(*q[at_rows]))
    return np.array(prob.jacobian(q))


def unloaded(model: RobotModel) -> RobotModel:
    """``model`` with massless links and a unit payload at its last frame (no other payloads), made
    once and kept with it."""
    return model.derived(unloaded, lambda: model.replace(
        frames=tuple(replace(f, mass=0.0) for f in model.frames), payload=Payload(mass=1.0), other_payloads=()))


def _row_pose(ref: Reference) -> np.ndarray:
    return row_layout(ref)[0]


def split_gains(ref: Reference, columns: list[np.ndarray], edges: list[int], alone: list[bool] | None = None
                ) -> list[tuple[int, float, int | None]]:
    """For each of ``columns`` (n_rows, g) and its ``edges`` (poses kept on each side), the pose from
    which letting parameters with those columns change lowers the sum of squares most, by how much
    (one Gauss-Newton step, from the gradient and Gram matrices summed over the poses after each
    split), and None; or, where ``alone`` says so, letting one of its columns change, the best one
    (its index last instead of None). First on a coarse grid of ``SPLITS`` rows, then row by row
    about its best. The sums of every set of columns with the same edge come from one pass over the
    rows by pose (``Z^T J`` and ``Z^T [Z, r]`` between consecutive grid rows, summed from the end);
    the rows about a best one are summed pose by pose up to the next grid row and added to its sums."""
    J, Zr, first = _split_rows(ref, columns)
    n = ref.data.n_poses
    ends = np.cumsum([Z.shape[1] for Z in columns])
    alone = alone or [False] * len(columns)
    out: list[tuple[int, float, int | None]] = [(n // 2, 0.0, 0 if a else None) for a in alone]
    for edge in sorted(set(edges)):
        if n - 2 * edge < 0:
            continue
        which = [k for k, e in enumerate(edges) if e == edge]
        z = slice(int(ends[which[0]] - columns[which[0]].shape[1]), int(ends[which[-1]]))
        coarse = np.unique(np.linspace(edge, n - edge, min(SPLITS, n - 2 * edge + 1)).round().astype(int))
        sums = _suffix_sums(J, Zr, z, first, coarse)
        step = int(coarse[1] - coarse[0]) if len(coarse) > 1 else 1
        for k in which:
            own = slice(int(ends[k] - columns[k].shape[1]), int(ends[k]))
            row, gain, col = _best_split([s[:, own.start - z.start:own.stop - z.start] for s in sums], own, coarse,
                                         ref.gram_inverse, alone=alone[k])
            if col is not None:         # that column alone from here on
                own = slice(own.start + col, own.start + col + 1)
            if step > 1:                      # the rows about it, each
                at = slice(own.start - z.start, own.stop - z.start)
                near = np.arange(max(edge, row - step), min(n - edge, row + step) + 1)
                c = int(np.searchsorted(coarse, near[-1]))
                fine = _near_sums(J, Zr, own, first, near, int(coarse[c]), [s[c, at] for s in sums])
                row, gain, _ = _best_split(fine, own, near, ref.gram_inverse)
            out[k] = (row, gain, col)
    return out


def _split_rows(ref: Reference, columns: list[np.ndarray]) -> tuple[_ByPose, np.ndarray, np.ndarray]:
    """The Jacobian's rows in the rows' pose order (stably: as they are when they are in order), and
    ``columns`` with the residuals last in that order, and each pose's first row in that order
    (n_poses + 1 bounds)."""
    pose = _row_pose(ref)
    order = None if np.all(pose[1:] >= pose[:-1]) else np.argsort(pose, kind="stable")
    by_pose = slice(None) if order is None else order
    first = np.searchsorted(pose[by_pose], np.arange(ref.data.n_poses + 1))
    Zr = np.empty((len(pose), sum(Z.shape[1] for Z in columns) + 1))
    at = 0
    for Z in columns + [ref.r[:, None]]:
        Zr[:, at:at + Z.shape[1]] = Z[by_pose]
        at += Z.shape[1]
    return _ByPose(ref.J, order), Zr, first


class _ByPose(NamedTuple):
    """A matrix's rows in pose order: ``order`` (None: as they are) picks them block by block, so that
    rows kept marker by marker (several markers) are not copied whole."""

    rows: np.ndarray
    order: np.ndarray | None

    def __len__(self) -> int:
        return len(self.rows)

    def block(self, a: int, b: int) -> np.ndarray:
        return self.rows[a:b] if self.order is None else self.rows[self.order[a:b]]

    def at(self, index: np.ndarray) -> np.ndarray:
        return self.rows[index if self.order is None else self.order[index]]


def _best_split(sums: list[np.ndarray], own: slice, bounds: np.ndarray, inverse: np.ndarray, *, alone: bool = False
                ) -> tuple[int, float, int | None]:
    """The bound whose split takes most away, how much, and None: ``sums`` (``Z^T J`` and ``Z^T [Z_all,
    r]`` over the poses after each bound, ``Z`` the columns ``own`` of ``Z_all``), the sum of squares
    each split's Gauss-Newton step takes away. ``alone``: each column of ``Z`` on its own, the best
    one's index in place of None."""
    HG, ZR = sums
    g, ZZ = ZR[..., -1], ZR[..., own]
    p = len(inverse)
    if alone:                                   # the diagonal of the matrix below: one column at a time
        m = np.diagonal(ZZ, axis1=1, axis2=2) - np.einsum("sgp,sgp->sg", HG @ inverse, HG)
        gains = g ** 2 / (m * (1.0 + 1e-10) + 1e-300)
        at, col = divmod(int(np.argmax(gains)), gains.shape[1])
        return int(bounds[at]), float(max(gains[at, col], 0.0)), col
    M = ZZ - (HG.reshape(-1, p) @ inverse).reshape(HG.shape) @ np.swapaxes(HG, 1, 2)
    ridge = (1e-10 * np.trace(M, axis1=1, axis2=2)[:, None, None] + 1e-300) * np.eye(M.shape[-1])
    gains = np.einsum("si,si->s", g, np.linalg.solve(M + ridge, g[..., None])[..., 0])
    j = int(np.argmax(gains))
    return int(bounds[j]), float(max(gains[j], 0.0)), None


def _suffix_sums(J: _ByPose, Zr: np.ndarray, z: slice, first: np.ndarray, bounds: np.ndarray
                 ) -> list[np.ndarray]:
    """``Z^T J`` and ``Z^T Zr`` (each (len(bounds), g, ...)) over the rows of the poses from each of
    ``bounds`` (ascending) on, ``Z`` the columns ``z`` of ``Zr`` (the rows by pose): block by block
    from the last, each added to the sums after it (no copy of the rows)."""
    start = first[bounds]
    ends = np.append(start[1:], len(J))
    HG = np.empty((len(bounds), z.stop - z.start, J.rows.shape[1]))
    ZR = np.empty((len(bounds), z.stop - z.start, Zr.shape[1]))
    Zt = Zr[:, z].T
    for k, (a, b) in enumerate(zip(start[::-1].tolist(), ends[::-1].tolist())):
        np.matmul(Zt[:, a:b], J.block(a, b), out=HG[k])
        np.matmul(Zt[:, a:b], Zr[a:b], out=ZR[k])
        if k:                           # numpy's cumsum runs down the first axis element by element
            HG[k] += HG[k - 1]
            ZR[k] += ZR[k - 1]
    return [HG[::-1], ZR[::-1]]


def _block_sums(Zr: np.ndarray, z, start: np.ndarray, ends: np.ndarray, J: _ByPose | None = None
                ) -> np.ndarray:
    """(len(start), g, w) ``Z^T Zr`` (or ``Z^T J``) over the rows ``start[k]:ends[k]`` of each block,
    ``Z`` the columns ``z`` of ``Zr``: one batched product, each block padded with zero rows to the
    longest."""
    size = ends - start
    width = int(size.max()) if len(size) else 0
    pad = (np.arange(width) < size[:, None])[..., None]
    rows = np.where(pad[..., 0], start[:, None] + np.arange(width), 0)
    Zb = np.where(pad, Zr[rows], 0.0)
    return np.swapaxes(Zb[..., z], 1, 2) @ (Zb if J is None else np.where(pad, J.at(rows), 0.0))


def _near_sums(J: _ByPose, Zr: np.ndarray, own: slice, first: np.ndarray, near: np.ndarray, bound: int,
               after: list[np.ndarray]) -> list[np.ndarray]:
    """``_suffix_sums`` of the columns ``own`` of ``Zr`` from each of ``near`` (consecutive poses) on,
    from ``after``, those sums from pose ``bound`` (>= near's last) on: each pose's rows before
    ``bound`` summed (``_block_sums``), then from the end onto ``after``."""
    poses = np.arange(near[0], bound)
    start, ends = first[poses], first[poses + 1]
    out = []
    for part, tail in zip((_block_sums(Zr, own, start, ends, J), _block_sums(Zr, own, start, ends)), after):
        sums = np.concatenate([part, tail[None]])
        out.append(np.cumsum(sums[::-1], axis=0)[::-1][:len(near)])
    return out


def _determined(ref: Reference, freedom: int) -> bool:
    """Whether a hypothesis adding ``freedom`` parameters leaves at least as many residual degrees of
    freedom as it adds: one that leaves fewer fits systematic residuals of any origin."""
    return len(ref.r) - len(ref.names) - freedom >= freedom


def _splits(ref: Reference) -> dict:
    """Every split search of the screen in one go (``split_gains``): per group a step may move (its
    words, ``_groups``) and per marker that may have moved from a row on (its index,
    ``_movable_markers``), the best row and the sum of squares a step there takes away."""
    def make():
        n = ref.data.n_poses
        edge = max(MIN_ROWS, int(EDGE_SHARE * n))
        keys: list = []
        columns, edges = [], []
        for what, cols in _groups(ref):
            Z = _columns(ref, cols)
            side = max(edge, Z.shape[1] // 3 + 2)      # each side holds more rows than the group has parameters
            if n - 2 * side >= 1 and _determined(ref, Z.shape[1]):
                keys.append(what), columns.append(Z), edges.append(side)
        for m, name in _movable_markers(ref):
            keys.append(m), columns.append(marker_columns(ref, name)), edges.append(edge)
        alone = [False] * len(keys)
        if steppable := _steppable_joints(ref):
            keys.append("joints"), columns.append(joint_columns(ref)[:, steppable]), edges.append(edge)
            alone.append(True)
        return dict(zip(keys, split_gains(ref, columns, edges, alone)))

    return ref.cached("splits", make)


def step_change(ref: Reference) -> list[Candidate]:
    """A step along the campaign's order: from some row on the base, the load or the whole robot
    differs (a bumped instrument, a payload, a sister robot); each group's best row from cumulative
    sums of the calibration's gradient and Gram matrix, its columns stepped."""
    n = ref.data.n_poses
    splits = _splits(ref)
    out = []
    for what, cols in _groups(ref):
        if what not in splits:
            continue
        Z = _columns(ref, cols)
        row, gain, _ = splits[what]
        freedom = Z.shape[1] + np.log2(max(n, 2))
        label = _label(ref, row)
        out.append(Candidate("step change", f"from {label} on, {what} changed", "", f"look at what happened at "
                             f"{label}; calibrate the rows before and after it apart, or measure again", (label,),
                             _predicted(ref, gain, freedom), np.log2(max(n, 2)),
                             partial(_stepped, ref, Z, row), generic=what.startswith("the robot")))
    return out


def _steppable_joints(ref: Reference) -> list[int]:
    """The joints ``joint_rehomed`` steps: those whose reading moves the points diagnosed, when the
    data leave room for a parameter more."""
    J = joint_columns(ref)
    return [j for j in range(J.shape[1]) if np.any(J[:, j])] if _determined(ref, 1) else []


def joint_rehomed(ref: Reference) -> list[Candidate]:
    """A joint rehomed partway (or its encoder slipped, or lost counts): from some row on, one joint's
    readings are off its position by a constant more than before. The joint whose step takes most
    away (one column each, searched together with ``step_change``'s), the choice of the joint and of
    the row counted against it."""
    steppable = _steppable_joints(ref)
    if not steppable:
        return []
    row, gain, col = _splits(ref)["joints"]
    j = steppable[cast(int, col)]
    Z = joint_columns(ref)[:, [j]]
    M, b = projected_products(ref, Z * (_row_pose(ref) >= row)[:, None])
    if not M[0, 0] > 0:
        return []
    name, size = _joint_offset(ref, j, float(b[0] / M[0, 0]))     # from that row on
    label = _label(ref, row)
    freedom = np.log2(max(ref.data.n_poses, 2)) + np.log2(max(len(steppable), 2))
    return [Candidate("joint rehomed", f"from {label} on, joint {name} reads {size} than before at the same "
                      "position (the joint rehomed, or its encoder slipped)", "",
                      f"home joint {name} again and check its encoder; calibrate the rows before and after {label} "
                      "apart, or measure again", (label, name), _predicted(ref, gain, 1.0 + freedom), freedom,
                      partial(_stepped, ref, Z, row))]


def _joint_offset(ref: Reference, j: int, off: float) -> tuple[str, str]:
    """Joint ``j``'s name, and ``off`` (its readings less its position, rad or m) in words: "0.1 deg
    more" or "0.2 mm less"."""
    return ref.model.joint_names[j], f"{_reading_size(ref, j, abs(off))} {'more' if off > 0 else 'less'}"


def _reading_size(ref: Reference, j: int, v: float) -> str:
    """``v`` of joint ``j``'s reading (rad or m) in words: "0.1 deg" or "0.2 mm"."""
    return f"{np.degrees(v):.3g} deg" if ref.model.reading_quantities[j] == "angle" else mm(v)


def _stepped(ref: Reference, Z: np.ndarray, row: int) -> Linear:
    """The columns ``Z`` on the rows of the poses from ``row`` on (0 before): made only for a step that
    survives the screen."""
    return Linear(Z * (_row_pose(ref) >= row)[:, None])


def drift(ref: Reference) -> list[Candidate]:
    """A slow drift along the campaign's order (warming up, the instrument creeping): the base, the load
    or the whole robot changing in proportion to the row (its columns stepped). The whole robot's is
    its own (it grows as it warms up): ``carried``."""
    t = ref.rows[_row_pose(ref)] / max(ref.campaign.n_poses - 1, 1) - 0.5
    out = []
    for what, cols in _groups(ref):
        Z = _columns(ref, cols) * t[:, None]
        if not _determined(ref, Z.shape[1]):
            continue
        gain = projected_gain(ref, Z)
        first, last = ref.campaign.labels[0], ref.campaign.labels[-1]
        out.append(Candidate("drift", f"{what.split(' (')[0]} drifts slowly along the campaign (warming up, the "
                             "instrument creeping)", "", "let the robot and the instrument warm up, check the "
                             "instrument's reference, measure again", (first, last),
                             _predicted(ref, gain, Z.shape[1]), 0.0, partial(Linear, Z),
                             generic=what.startswith("the robot"), carried=what.startswith("the robot")))
    return out + _joint_drift(ref, t)


def _joint_drift(ref: Reference, t: np.ndarray) -> list[Candidate]:
    """One joint's readings drifting off its position in proportion to the row (a joint warming up, an
    encoder creeping): the joint whose drift takes most away, one column each, the choice counted
    against it."""
    steppable = _steppable_joints(ref)
    if not steppable:
        return []
    Z = joint_columns(ref)[:, steppable] * t[:, None]
    M, b = projected_products(ref, Z)
    d = np.diag(M)
    gains = np.where(d > 0, b ** 2 / np.where(d > 0, d, 1.0), 0.0)
    k = int(np.argmax(gains))
    if not d[k] > 0:
        return []
    name, size = _joint_offset(ref, steppable[k], float(b[k] / d[k]))   # last row against first
    first, last = ref.campaign.labels[0], ref.campaign.labels[-1]
    freedom = np.log2(max(len(steppable), 2))
    return [Candidate("drift", f"joint {name}'s readings drift slowly off its position along the campaign, {size} "
                      f"at {last} than at {first} (the joint warming up, or its encoder creeping)", "",
                      f"let the robot warm up before measuring, check joint {name}'s encoder, measure again",
                      (first, last, name), _predicted(ref, float(gains[k]), 1.0 + freedom),
                      freedom, partial(Linear, Z[:, [k]]))]


def _lost_motion_sides(ref: Reference) -> dict:
    """(n_poses, n_joints) per way a joint can rest in its lost motion, the side of its gap it rests
    on at each pose diagnosed, as the model's backlash takes it (+1: above its reading; docs/
    conventions.md, backlash): behind its last move (``approach``), and with link masses where its
    gravity load pushes it (``gravity``)."""
    sides = {"approach": -approach_of(ref.data)}
    if ref.start.has_masses:
        loads = _gravity_loads(ref)
        # a load at rounding's level (a joint whose distal masses sit on its axis) has no side
        sides["gravity"] = np.where(np.abs(loads) > LOAD_ROUNDING * np.abs(loads).max(initial=0.0), np.sign(loads), 0.0)
    return sides


def _gravity_loads(ref: Reference) -> np.ndarray:
    """(n_poses, n_joints) each joint's gravity load at the poses diagnosed, at the calibration's
    values (a model with masses), made once: on the problem's model, whose layout exists (the
    calibrated model's would be built anew each call, at about the cost of the loads themselves)."""
    prob, data = ref.problem, ref.data
    return ref.cached("gravity loads", lambda: loads_at(prob.model, prob.lay, ref.p, data.q,
                                                        payload_mass=data.payload_mass))


def compliance_left_out(ref: Reference) -> list[Candidate]:
    """Joints that give under the robot's own weight (joint compliance) where the calibration left
    compliance out, on a model with masses: each loaded joint's reading column times its gravity load
    (docs/method.md section 2, the joint's deflection ``k * load``), all together, as a calibration
    with compliance frees them. The robot's own, which a model carries."""
    lay = parameter_layout(ref.model)
    if not ref.start.has_masses or any(lay[n].family == "compliance" for n in ref.names):
        return []
    loads = _gravity_loads(ref)
    loaded = [j for j in _steppable_joints(ref) if np.ptp(loads[:, j]) > LOAD_ROUNDING * np.abs(loads).max()]
    if not loaded or not _determined(ref, len(loaded)):
        return []
    Z = joint_columns(ref)[:, loaded] * loads[row_layout(ref)[0]][:, loaded]
    names = tuple(ref.model.joint_names[j] for j in loaded)
    return [Candidate("compliance left out", f"the joints give under the robot's own weight ({', '.join(names)}: "
                      "joint compliance), which the model leaves out", "", "calibrate it (--parameters "
                      "geometric,compliance)", names, _predicted(ref, projected_gain(ref, Z), Z.shape[1]),
                      0.0, partial(Linear, Z), carried=True)]


def lost_motion(ref: Reference) -> list[Candidate]:
    """Lost motion (backlash) the calibration leaves out: a joint resting a constant off its reading,
    on the side of its gap behind its last move in the campaign's order or where its gravity load
    pushes it (docs/conventions.md, backlash). The joint and side whose lost motion takes most away
    (one column each: its reading's column times its side at each pose), the choice counted against
    it. A side that never changes is a joint offset (its column within the calibration's span:
    nothing to tell), and a gap the other way (the arm ahead of its reading, as a lagging log puts
    it) is no lost motion."""
    lay = parameter_layout(ref.model)
    if any(lay[n].family == "backlash" for n in ref.names):
        return []
    steppable = _steppable_joints(ref)
    if not steppable:
        return []
    pose = row_layout(ref)[0]
    J = joint_columns(ref)[:, steppable]
    kinds = list(_lost_motion_sides(ref).items())
    Z = np.hstack([J * side[pose][:, steppable] for _, side in kinds])
    M, b = projected_products(ref, Z)
    d = np.diag(M)
    apart = d > SPAN_SHARE * np.sum(Z ** 2, axis=0)         # columns the calibration's own do not hold
    gains = np.where(apart, b ** 2 / np.where(apart, d, 1.0), 0.0)
    k = int(np.argmax(gains))
    # the columns move the readings: the position sits -b/d off them along the side, half the gap
    half = float(-b[k] / d[k]) if apart[k] else 0.0
    if not half > 0:
        return []
    how, j = kinds[k // len(steppable)][0], steppable[k % len(steppable)]
    name = ref.model.joint_names[j]
    when = "when approached from either side" if how == "approach" else "as its gravity load turns over"
    fix = f"calibrate it (--parameters geometric,backlash --backlash-side {how})"
    if how == "approach":
        fix += ", or approach every pose from the same side"
    freedom = np.log2(max(Z.shape[1], 2))
    return [Candidate("lost motion", f"joint {name} stops about {_reading_size(ref, j, 2 * half)} apart {when} "
                      "(lost motion, backlash), which the model leaves out", "", fix, (name,),
                      _predicted(ref, float(gains[k]), 1.0 + freedom), freedom, partial(Linear, Z[:, [k]]),
                      carried=True)]


# -- the joint readings against the measurements ------------------------------------------------------

def readings_lag(ref: Reference) -> list[Candidate]:
    """The joint readings lag (or lead) the measurements: on a path, each pose's readings are those of a
    fraction of a row earlier. The readings' change along the rows, as one column, screens it and gives
    the lag (one Gauss-Newton step); the readings moved by that lag are refitted from the calibration (a
    lag of half a row on a fast path is too far from linear for the step alone to judge)."""
    from .joints import joint_columns

    q = ref.data.q
    if ref.data.n_poses < 8:
        return []
    dq = np.gradient(q, axis=0)
    C = joint_columns(ref)                                    # (n_rows, n_joints) per unit reading change
    Z = np.einsum("rj,rj->r", C, dq[_row_pose(ref)])[:, None]
    M, b = projected_products(ref, Z)
    m, v = float(M[0, 0]), float(b[0])
    gain = max(v * v / m, 0.0) if m != 0.0 else 0.0      # the pseudo-inverse's gain of one column
    lag = -v / max(m, 1e-300)
    # a candidate predicted below the screen's bar is never refitted: whether the poses lie along a
    # path (the dearer test) then changes nothing
    if (not np.isfinite(lag) or abs(lag) > max(SHIFTS) or lag == 0.0 or _predicted(ref, gain, 1.0) < SURVIVE_FACTOR
            or not ordered(q)):
        return []
    return [Candidate("readings lag", _lag_words(lag), "with the readings moved by that lag", "synchronise the joint "
                      "log with the instrument (a time offset between them), or measure at rest", (),
                      _predicted(ref, gain, 1.0), 1.0, partial(_unlagged_repair, ref, lag),
                      restated=lambda _: _lag_words(_refined_lag(ref, lag)))]


def _lag_words(lag: float) -> str:
    return (f"the joint readings {'lag' if lag > 0 else 'lead'} the measurements by about {abs(lag):.2g} of a row: "
            "each pose's readings are those of another moment along the path")


def _moved_readings(ref: Reference, lag: float) -> Repair:
    return Repair(with_arrays(ref.data, q=unlagged(ref.data.q, lag)), registered=False)


def _unlagged_repair(ref: Reference, lag: float) -> Repair:
    """The poses diagnosed with the readings moved by the lag ``_refined_lag`` finds from ``lag``."""
    return _moved_readings(ref, _refined_lag(ref, lag))


def _refined_lag(ref: Reference, lag: float) -> float:
    """The lag (rows) from the screen's ``lag`` (one Gauss-Newton step from no lag: off by a tenth or
    two of a half-row lag on a fast path) to the vertex of a parabola through the refits' sums of
    squares at LAG_TRIALS times it, kept within the trials' span."""
    def make():
        trials = lag * np.asarray(LAG_TRIALS)
        ssr = []
        for t in trials:
            out = refit(ref, _moved_readings(ref, float(t)))
            if out is None:
                return lag
            ssr.append(out.ssr)
        a, b, _ = np.polyfit(trials, ssr, 2)
        if not a > 0:
            return float(trials[int(np.argmin(ssr))])
        return float(np.clip(-b / (2 * a), trials.min(), trials.max()))

    return ref.cached(f"lag {lag!r}", make)


def unlagged(q: np.ndarray, lag: float, steps: int = 4) -> np.ndarray:
    """The readings ``q`` (n_poses, n_joints) along a path moved ``lag`` rows later: the readings ``u``
    with ``u - lag * gradient(u) = q`` (a log that lags by ``lag`` rows), by fixed-point steps; a first
    order step alone leaves a fast path's curvature."""
    u = q.copy()
    for _ in range(steps):
        u = q + lag * np.gradient(u, axis=0)
    return u


# -- a marker elsewhere on some rows, labels swapped on some rows -----------------------------------------

def _marker_frame_residuals(ref: Reference) -> np.ndarray:
    """(n_poses, n_markers, 3) the calibration's residuals (calibrated minus measured) in the frame each
    marker is fixed to (0 where not measured): its position rows' columns for its own position are
    that frame's axes in W (weighted as the rows are), so no evaluation more is needed."""
    def make():
        poses, metres = row_layout(ref)
        markers = cast(Points, ref.problem.points).row_points()[1]
        out = np.zeros(ref.errors.shape)
        for m, name in enumerate(ref.data.marker_names):
            rows = np.nonzero((markers == m) & np.isfinite(metres))[0]      # x, y, z of each pose in turn
            axes = (marker_columns(ref, name)[rows] * metres[rows, None]).reshape(-1, 3, 3)
            at = poses[rows[::3]]
            out[at, m] = np.einsum("nji,nj->ni", axes, ref.errors[at, m])
        return out

    return ref.cached("marker_frame_residuals", make)


def _two_groups(v: np.ndarray) -> tuple[np.ndarray, float]:
    """Split the vectors ``v`` (n, 3) in two groups about their principal direction, the split whose
    groups' means lie furthest apart: the rows of the smaller group and the sum of squares the two
    means take up."""
    n = len(v)
    if n < 2 * MIN_ROWS:
        return np.zeros(0, dtype=int), 0.0
    c = v - v.mean(0)
    order = np.argsort(c @ np.linalg.eigh(c.T @ c)[1][:, -1], kind="stable")
    s = np.cumsum(c[order], axis=0)[:-1]
    k = np.arange(1, n)
    between = np.sum(s ** 2, axis=1) * n / (k * (n - k))
    j = MIN_ROWS - 1 + int(np.argmax(between[MIN_ROWS - 1:n - MIN_ROWS]))
    first, rest = order[:j + 1], order[j + 1:]
    return np.sort(rest if len(rest) <= len(first) else first), float(between[j])


def _added_column(a: np.ndarray | None, m: int, on: np.ndarray, fill) -> np.ndarray | None:
    """``a`` (n, n_markers, ...) with one more marker column: marker ``m``'s values on the rows ``on``,
    ``fill`` elsewhere."""
    if a is None:
        return None
    where = on.reshape((-1,) + (1,) * (a.ndim - 2))
    return np.concatenate([a, np.where(where, a[:, m], fill)[:, None]], axis=1)


def _with_marker_on(ref: Reference, m: int, rows: np.ndarray) -> Repair:
    """The poses diagnosed with marker ``m`` on ``rows`` read as another marker of the same frame
    (its position free), refitted from the calibration."""
    d = ref.data
    name = d.marker_names[m]
    other = f"{name}'"
    mk = ref.start.markers[ref.start.marker_names.index(name)]
    model = ref.start.replace(markers=ref.start.markers + (Marker(other, mk.frame, mk.position, mk.rotation,
                                                                   mk.rotation_known),))
    on = np.zeros(d.n_poses, dtype=bool)
    on[rows] = True
    moved = on[:, None] & (np.arange(len(d.marker_names)) == m)
    mask = np.concatenate([d.mask & ~moved, (on & d.mask[:, m])[:, None]], axis=1)
    rot_mask = None if d.rot_mask is None else np.concatenate([d.rot_mask & ~moved, (on & d.rot_mask[:, m])[:, None]],
                                                              axis=1)
    pos = cast(np.ndarray, _added_column(d.positions, m, on, np.nan))
    data = replace(d.with_approach(), positions=np.where(mask[..., None], pos, np.nan), mask=mask, rot_mask=rot_mask,
                   marker_names=d.marker_names + (other,), rotations=_added_column(d.rotations, m, on, np.nan),
                   sigma=_added_column(d.sigma, m, on, 1.0), sigma_rot=_added_column(d.sigma_rot, m, on, 1.0))
    lay = parameter_layout(model)
    own = ("x", "y", "z") + (("rx", "ry", "rz") if d.has_orientation else ())
    nominal = ref.model.replace(markers=ref.model.markers + (replace(
        ref.model.markers[ref.model.marker_names.index(name)], name=other),))
    return Repair(data, model=model, registered=False, nominal=nominal,
                  names=ref.refit_names + tuple(f"{other}.{k}" for k in own if f"{other}.{k}" in lay.names))


def marker_columns(ref: Reference, name: str) -> np.ndarray:
    """(n_rows, 3) the reference's residual rows per unit move of marker ``name`` on the robot: the
    calibration's own columns when it fitted that position, else evaluated."""
    names = tuple(f"{name}.{k}" for k in ("x", "y", "z"))
    if all(n in ref.names for n in names):
        return ref.J[:, [ref.names.index(n) for n in names]]
    return ref.columns(names)


def _movable_markers(ref: Reference) -> list[tuple[int, str]]:
    """(index, name) of the markers ``marker_elsewhere`` tests: seen on ``4 * MIN_ROWS`` rows or more,
    their position fitted."""
    seen = ref.data.mask.sum(axis=0)
    return [(m, name) for m, name in enumerate(ref.data.marker_names)
            if seen[m] >= 4 * MIN_ROWS and any(n.startswith(f"{name}.") for n in ref.names)]


def marker_elsewhere(ref: Reference) -> list[Candidate]:
    """A marker elsewhere on the robot on some rows: from one row on (the tool changed, the reflector
    moved in its nest: the row from cumulative sums of the calibration's gradient and Gram matrix with
    the marker's columns) or on rows here and there (a reflector put in another nest: the calibration's
    residuals in the marker's own frame split in two groups); the rows refitted as another marker.
    Only markers whose position the calibration fitted: one held at the model's (``known``) misfits on
    every row when the model has it wrong, and freeing it on nearly every row would name a move."""
    E = _marker_frame_residuals(ref)
    n_all = ref.data.n_poses
    splits = _splits(ref)
    out = []
    for m, name in _movable_markers(ref):
        seen = np.nonzero(ref.data.mask[:, m])[0]
        row, gain_tail, _ = splits[m]
        some, gain_some = _two_groups(E[seen, m])
        tail = _predicted(ref, gain_tail, 3.0 + np.log2(n_all))
        scattered = _predicted(ref, _metres_to_rows(ref, gain_some), 3.0 + len(some))
        if tail >= scattered:
            rows, predicted, freedom = seen[seen >= row], tail, 3.0 + np.log2(n_all)
            where = f"from {_label(ref, row)} on"
            said = f"the rows {where}"
            cause = f"{where}, marker {name} sat elsewhere on the robot: the tool changed, or the reflector moved " \
                    "in its nest"
        else:
            rows, predicted, freedom = seen[some], scattered, 3.0 + len(some)
            listed = f"{len(rows)} rows ({', '.join(_label(ref, r) for r in rows[:4])}" \
                + (" ..." if len(rows) > 4 else "") + ")"
            said = f"the {listed}"
            cause = f"marker {name} sat elsewhere on {listed}: a reflector put in another nest"
        if not MIN_ROWS <= len(rows) < len(seen):
            continue
        out.append(Candidate("marker moved", cause, "with those rows as another marker", f"calibrate {said} "
                             "as a marker of their own (or apart), or measure them again with the reflector in its "
                             "nest", (name, _label(ref, rows[0])), predicted, freedom,
                             partial(_with_marker_on, ref, m, rows), beyond_robot=True,
                             restated=partial(_moved_by, cause, name)))
    return out


def _moved_by(cause: str, name: str, out: Outcome) -> str:
    """``cause`` with how far marker ``name`` moved: its rows' marker from the rest's in the refit."""
    lay = parameter_layout(out.model)
    names = out.model.marker_names
    a, b = lay.marker0[names.index(name)], lay.marker0[names.index(f"{name}'")]
    return cause + f" ({mm(float(np.linalg.norm(out.p[b:b + 3] - out.p[a:a + 3])))} away)"


def _metres_to_rows(ref: Reference, ss: float) -> float:
    """A sum of squares in metres as one of the reference's rows (their stated deviations, when weighted)."""
    metres = row_layout(ref)[1]
    pos = np.isfinite(metres)
    return ss / float(np.mean(metres[pos] ** 2)) if pos.any() else ss


def _swapped_rows(P: np.ndarray, d, a: int, b: int) -> tuple[np.ndarray, float, float]:
    """The rows where markers ``a`` and ``b``'s points match the nominal robot's ``P`` (registered on the
    rows not swapped) far better swapped, and the sums of squares as measured and with them swapped."""
    both = d.mask[:, a] & d.mask[:, b]
    rows = np.zeros(0, dtype=int)
    for _ in range(2):              # registered on every row, then on the rows not swapped
        keep = d.mask.copy()
        keep[rows] = False
        Pr = registered(P, d.positions, keep)
        now = np.sum((Pr[:, a] - d.positions[:, a]) ** 2 + (Pr[:, b] - d.positions[:, b]) ** 2, axis=1)
        swapped = np.sum((Pr[:, a] - d.positions[:, b]) ** 2 + (Pr[:, b] - d.positions[:, a]) ** 2, axis=1)
        rows = np.nonzero(both & (swapped < now / 4.0))[0]
    return rows, float(np.sum(now[both])), float(np.sum(np.where(np.isin(np.arange(len(now)), rows), swapped,
                                                                 now)[both]))


def labels_swapped(ref: Reference) -> list[Candidate]:
    """Two markers' labels swapped on some rows (not all: that is markers swapped): the rows where the
    nominal robot, rigidly placed on the others, matches the points far better swapped."""
    d = ref.data
    if len(d.marker_names) < 2:
        return []
    best = None
    for a, b in combinations(range(len(d.marker_names)), 2):
        rows, now, after = _swapped_rows(ref.positions0, d, a, b)
        if MIN_ROWS <= len(rows) < (d.mask[:, a] & d.mask[:, b]).sum() and (best is None or now / after > best[0]):
            best = (now / max(after, 1e-300), a, b, rows)
    if best is None:
        return []
    ratio, a, b, rows = best
    names = (d.marker_names[a], d.marker_names[b])

    def repair():
        pos = d.positions.copy()
        pos[np.ix_(rows, [a, b])] = pos[np.ix_(rows, [b, a])]
        return Repair(with_arrays(d, positions=pos))

    listed = ", ".join(_label(ref, r) for r in rows[:4]) + (" ..." if len(rows) > 4 else "")
    return [Candidate("labels swapped", f"markers {names[0]} and {names[1]} are swapped on {len(rows)} of the "
                      f"rows ({listed})", "with them swapped back on those rows", f"swap the columns (or labels) of "
                      f"markers {names[0]} and {names[1]} back on those rows", names, ratio, float(len(rows)), repair)]
