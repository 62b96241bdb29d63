"""Measured points (and poses) as an observation block: residuals and the stacked Jacobian of one
model on one set of poses.

Identifiability, pose selection, simulation and identification all start here. Rows are ordered
marker by marker, then pose by pose (x, y, z), then, with orientations, the rotation rows in the
same order; each row is divided by its stated standard deviation when the data carry one.

A large campaign of point data (over ``LARGE_POSES`` poses) is evaluated ``CHUNK_POSES`` poses at a
time: its positions and residuals are assembled from the chunks, and instead of its Jacobian the
solve and the analysis take ``normal_equations`` (the Jacobian's R factor and gradient), so memory
grows with the parameters, not the poses.
"""

from __future__ import annotations

import copy
import weakref
from typing import cast

import numpy as np
from scipy.spatial.transform import Rotation

from .._base.arguments import FLAG, accepts, is_a, names_in, optional, readings_of, shaped
from .._base.arrays import frozen, read_only, vector_norms
from .._base.linalg import gram_factor, r_factor, reduced
from .._base.threads import one_blas_thread
from .._model.configurations import design_measurements
from .._model.kinematics import (
    CHUNK_POSES,
    LARGE_POSES,
    PLACEMENT_ROWS,
    Workspace,
    base_rotation_of,
    evaluate_state,
    frame_approach,
    jacobian_columns,
    layout,
    moved_state,
    moves_rigidly,
    pass_buffers,
    reading_turns,
    turns_at,
    workspace,
)
from .._model.measurements import Measurements, Noise, approach_of
from .._model.parameters import has_backlash_parameters, needs_compliance, parameter_layout, parameter_names
from .._model.robot import RobotModel

# A problem keeps its last evaluations (the calibration asks for the start again after the solve,
# and for the solution after the fit of the errors before it): up to STATES_KEPT, fewer for many
# poses so that they hold no more than about STATE_POSES poses' worth (one at the least). Ten keep
# the chosen fit's solution through the model choice's all-free design (four or five vectors) and
# the nominal's registration (two, passes of the chain under compliance)
STATES_KEPT = 10
STATE_POSES = 40_000
# a campaign evaluated in chunks keeps no evaluation, only the marker positions at this many vectors
POSITIONS_KEPT = 3


def _measured_rows(mask: np.ndarray, sigma: np.ndarray | None, default) -> tuple[list, list]:
    """Per marker (a column of ``mask``, n_poses x n_markers), the poses it was measured at and
    their weights: one over the stated deviation ``sigma`` (broadcast to ``mask``), else ``default``."""
    sel = [np.nonzero(mask[:, j])[0] for j in range(mask.shape[1])]
    sd = np.broadcast_to(sigma if sigma is not None else default, mask.shape)
    return sel, [1.0 / sd[s, j] for j, s in enumerate(sel)]


class Points:
    """Residuals and Jacobian of ``model`` on ``data`` over the free parameters ``free`` (names).

    The Jacobian is returned column-major (a transposed view): one contiguous row per parameter, so
    J^T J and J^T r are products of contiguous rows.
    ``residuals`` and ``jacobian`` at the same parameters share one kinematic pass. Joints rest in
    their lost motion when the model has backlash or ``free`` holds some, on the sides of the
    model's ``backlash_side`` (the approach directions from ``approach_of(data)``). ``chunked``:
    evaluate ``CHUNK_POSES`` poses at a time and solve on normal equations (default: point data of
    over ``LARGE_POSES`` poses; data with orientations or lost motion are evaluated whole); such a
    problem keeps the marker positions of its last ``kept_positions`` vectors (none for one
    evaluated once at each, as a fold held out is).
    """

    def __init__(self, model: RobotModel, data: Measurements, free: tuple[str, ...], *, compliance: bool,
                 noise: Noise | None = None, chunked: bool | None = None, kept_positions: int = POSITIONS_KEPT):
        self.model = model
        self.data = data
        self.noise = noise
        self.lay = layout(model)
        self.free_idx = self._indices(free)
        self.compliance = compliance
        self.backlash = model.has_backlash or has_backlash_parameters(model, free)
        self.approach = frame_approach(model, approach_of(data)) if self.backlash else None
        self.qf = read_only(data.q @ model.coupling_matrix.T)
        self._turns: tuple | None = None   # the cosines and sines of ``qf``, made at the first evaluation
        self._chunk_turns: list = []   # each chunk's, made at its first evaluation (shared with ``over``'s)
        self.marker_idx = np.array([model.marker_names.index(n) for n in data.marker_names], dtype=int)
        self.use_rot = data.has_orientation
        # 6D rows mix metres and radians: without stated deviations, each part is weighed by its noise
        self.weighted = data.sigma is not None or (self.use_rot and noise is not None)
        self.sel, self.w = _measured_rows(data.mask, data.sigma,
                                          noise.position if noise is not None and self.weighted else 1.0)
        self.meas = [data.positions[s, j] for j, s in enumerate(self.sel)]
        self._every_point = bool(data.mask.all())     # every marker measured at every pose: nothing to blank
        if self.use_rot and data.rot_mask is not None:
            self.sel_r, self.w_r = _measured_rows(data.rot_mask, data.sigma_rot,
                                                  noise.rotation if noise is not None else 1.0)
        self._kept = _Kept(workspace(model), kept_positions)    # shared with the problems ``over`` makes
        if chunked is None:
            chunked = data.n_poses > LARGE_POSES
        # orientations and lost motion are evaluated whole
        self.chunked = chunked and not (self.use_rot or self.backlash)

    def _chunks(self):
        """The problem over each chunk of ``CHUNK_POSES`` poses in turn (made when reached, so that
        one chunk's evaluation is held at a time)."""
        for c, a in enumerate(range(0, self.data.n_poses, CHUNK_POSES)):
            sub = Points(self.model, self.data.subset(slice(a, a + CHUNK_POSES)), (), compliance=self.compliance,
                         noise=self.noise, chunked=False)
            sub.free_idx = self.free_idx
            if c < len(self._chunk_turns):
                sub._turns = self._chunk_turns[c]
            yield sub
            if c == len(self._chunk_turns) and sub._turns is not None:
                self._chunk_turns.append(sub._turns)

    @one_blas_thread
    def normal_equations(self, p) -> tuple[np.ndarray, np.ndarray, float]:
        """At ``p``: the R factor (n_free, n_free) of the weighted Jacobian (``R^T R = J^T J``), the
        gradient ``J^T r`` and the sum of squared weighted residuals, taken chunk by chunk (what a
        large campaign is solved on; a problem held whole is solved on its Jacobian). The factor
        comes from the Gram matrix while it is well conditioned (as ``r_factor``'s), else by QR."""
        G, g, cost = self._chunk_sums(p, None)
        R = gram_factor(G)
        return (self._chunk_sums(p, reduced)[0], g, cost) if R is None else (R, g, cost)

    def _chunk_sums(self, p, factor) -> tuple[np.ndarray, np.ndarray, float]:
        """The Gram matrix of the weighted Jacobian (with ``factor``, its R factor of the chunks
        stacked in turn), its gradient and sum of squares at ``p``, chunk by chunk; taken from the
        last R factor made (the analysis' of more columns at the start) when it was made at ``p``.
        The marker positions the chunks evaluated are kept with those of other vectors."""
        key, free = frozen(p).tobytes(), tuple(self.free_idx.tolist())
        made = self._kept.sums
        if made is not None and made[0] == key and set(free) <= set(made[1]):
            cols = [made[1].index(c) for c in free]
            R = made[2][:, cols]
            return (factor(R) if factor else R.T @ R), made[3][cols], made[4]
        k = len(free)
        G, g, cost = np.zeros((0 if factor else k, k)), np.zeros(k), 0.0
        positions = []
        for sub in self._chunks():
            J, r = sub.jacobian(p), sub.residuals(p)
            G = factor(np.vstack([G, J])) if factor else G + J.T @ J
            g += J.T @ r
            cost += float(r @ r)
            positions.append(sub._positions(p).copy())
        self._keep_positions(key, read_only(np.concatenate(positions, axis=1)))
        if factor:
            self._kept.sums = (key, free, read_only(G), read_only(g), cost)
        return G, g, cost

    def reduced_jacobian(self, p) -> np.ndarray:
        """The R factor of the weighted Jacobian at ``p`` (by QR: the candidates' columns may be
        dependent): a (k, k) matrix with the same Gram matrix, which is all the identifiability
        analysis needs."""
        return self._chunk_sums(p, reduced)[0] if self.chunked else self._factor(p, reduced)

    def jacobian_factor(self, p) -> np.ndarray:
        """An R factor (n_free, n_free) of the weighted Jacobian at ``p`` (``r_factor``), taken from
        the factor of more columns when one was made at ``p`` (the analysis' at the start)."""
        return self._factor(p, r_factor)

    def _factor(self, p, make) -> np.ndarray:
        kept = self._state(p).cache.setdefault("factors", {})
        free = tuple(self.free_idx.tolist())
        R = _taken(kept, free, lambda R, cols: make(R[:, cols]))
        if R is None:
            R = kept[free] = read_only(make(self.jacobian(p)))
        return R

    def _indices(self, free) -> np.ndarray:
        return parameter_layout(self.model).indices(free)

    def over(self, free: tuple[str, ...]) -> Points:
        """The same problem over other free parameters, keeping the evaluation already made."""
        other = copy.copy(self)
        other.free_idx = self._indices(free)
        return other

    @property
    def n_rows(self) -> int:
        return 3 * sum(len(s) for s in self.sel) + (3 * sum(len(s) for s in self.sel_r) if self.use_rot else 0)

    def row_kinds(self) -> np.ndarray:
        """(n_rows,) 0 for position rows, 1 for rotation rows: their noise differs in kind."""
        n_pos = 3 * sum(len(s) for s in self.sel)
        return np.concatenate([np.zeros(n_pos, dtype=int), np.ones(self.n_rows - n_pos, dtype=int)])

    def row_points(self) -> tuple[np.ndarray, np.ndarray]:
        """(n_rows,) each row's pose and (data) marker index, in the order of ``residuals``."""
        poses = [np.repeat(s, 3) for s in self.sel] + ([np.repeat(s, 3) for s in self.sel_r] if self.use_rot else [])
        markers = [np.full(3 * len(s), j) for j, s in enumerate(self.sel)]
        if self.use_rot:
            markers += [np.full(3 * len(s), j) for j, s in enumerate(self.sel_r)]
        if not poses:
            return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
        return np.concatenate(poses), np.concatenate(markers)

    def pieces(self, p):
        """``(jacobian, residuals, row poses, row markers)`` at ``p``, whole or, for a campaign solved in
        chunks, a chunk of poses at a time (row poses then index the whole campaign's poses)."""
        if not self.chunked:
            yield self.jacobian(p), self.residuals(p), *self.row_points()
            return
        for a, sub in zip(range(0, self.data.n_poses, CHUNK_POSES), self._chunks()):
            poses, markers = sub.row_points()
            yield sub.jacobian(p), sub.residuals(p), a + poses, markers

    def without(self, aside: np.ndarray) -> Points:
        """The same problem with the measured points ``aside`` (n_poses, n_markers) set aside (masked)."""
        free = tuple(self.lay.names[i] for i in self.free_idx)
        return Points(self.model, self.data.without(aside), free, compliance=self.compliance,
                      noise=self.noise, chunked=self.chunked)

    def full(self, x, p0) -> np.ndarray:
        """The full parameter vector: ``p0`` with the free parameters set to ``x``."""
        p = np.array(p0, dtype=float)
        p[self.free_idx] = x
        return p

    def _state(self, p):
        """The evaluation at ``p``, kept with the last few (``STATES_KEPT``, newest last). Each is
        found by the values it was made at: the bytes of a read-only float copy of them, which its
        pass holds, so a caller changing their own array afterwards cannot be served a stale one."""
        p = frozen(p)
        key = p.tobytes()
        kept = self._kept
        states = kept.states
        st = states.pop(key, None)
        if st is None:
            # a geometric chain that only the base and markers moved from a kept evaluation is that one moved
            near = None if self.compliance or self.backlash else next(
                (s for s in reversed(states.values()) if moves_rigidly(self.lay, s.ps.p, p)), None)
            if near is None and self._turns is None:
                self._turns = reading_turns(self.model, self.data, self.qf)
            st = moved_state(near, p, take=kept.workspace.take) if near is not None else evaluate_state(
                self.model, self.lay, p, self.qf, compliance=self.compliance, orientations=self.use_rot,
                payload_mass=self.data.payload_mass, backlash=self.backlash, approach=self.approach,
                turns=self._turns, take=kept.workspace.take)
            near = None
            if len(states) >= max(1, min(STATES_KEPT, STATE_POSES // max(self.data.n_poses, 1))):
                kept.drop_oldest()
        states[key] = st
        return st

    def moved_positions(self, p, moved: np.ndarray, which: np.ndarray) -> np.ndarray | None:
        """(n_poses, n_data_markers, 3) the marker positions of each pose at the vector ``which`` picks
        for it among ``moved`` (k, n_params), vectors that differ from ``p`` in the base and markers
        only: the frames of the evaluation at ``p`` moved rigidly by the change of the base, the
        markers' offsets applied in their frames. Exact when the chain is geometric at ``p`` (no
        compliance there, no lost motion, not in chunks); None otherwise. Models refitted in their
        base and markers alone are evaluated this way without a pass down the chain.
        Reference: docs/method.md section 1: X_WB moves every frame rigidly; a marker is a point in its frame."""
        p, moved = frozen(p), np.asarray(moved, dtype=float)
        if self.chunked or self.backlash or not all(moves_rigidly(self.lay, p, v) for v in moved) or (
                self.compliance and np.any(p[self.lay.compliant_params])):
            return None
        ps = self._state(p).ps
        turns = np.array([base_rotation_of(self.model.base_rotation, *v[3:6].tolist())[1] @ ps.base_rotation.T
                          for v in moved])
        shifts = moved[:, 0:3] - turns @ ps.base_origin          # a point x goes to dR x + shift
        turn, out = turns[which], np.empty((len(which), len(self.marker_idx), 3))
        for j, m in enumerate(self.marker_idx):
            r0 = self.lay.frame_row[self.model.markers[m].frame]
            x, y, z, o = ps.vec[r0:r0 + PLACEMENT_ROWS]                   # the marker's frame in W at p
            v = moved[:, self.lay.marker0[m]:self.lay.marker0[m] + 3][which].T
            at_p = v[0] * x + v[1] * y + v[2] * z + o                      # (3, n_poses)
            out[:, j] = turn[:, :, 0] * at_p[0, :, None] + turn[:, :, 1] * at_p[1, :, None] + \
                turn[:, :, 2] * at_p[2, :, None] + shifts[which]
        return out

    def _positions(self, p) -> np.ndarray:
        """(n_model_markers, n_poses, 3) marker positions at ``p``; a campaign evaluated in chunks
        keeps those of its last ``kept_positions`` vectors (the checks ask for the solution's often)."""
        if not self.chunked:
            return self._state(p).ps.P
        key = frozen(p).tobytes()
        P = self._kept.positions.get(key)
        if P is None:
            # copies: a chunk's positions are a view that would keep its whole evaluation alive
            P = read_only(np.concatenate([sub._positions(p).copy() for sub in self._chunks()], axis=1))
        self._keep_positions(key, P)
        return P

    def _keep_positions(self, key: bytes, P: np.ndarray) -> None:
        """Keep ``P``, the marker positions at the vector whose bytes are ``key``, as the newest."""
        kept = self._kept.positions
        kept.pop(key, None)
        while kept and len(kept) >= self._kept.n_positions:
            kept.pop(next(iter(kept)))
        if self._kept.n_positions:
            kept[key] = P

    def positions_at(self, p, rows) -> np.ndarray:
        """(n_rows, n_data_markers, 3) the marker positions at ``p`` of the poses ``rows`` (indices or
        a slice) alone: one pass at their readings, with their payloads and approach directions,
        kept nowhere (a fold's model at the fold's poses)."""
        if self._turns is None and not self.chunked:
            self._turns = reading_turns(self.model, self.data, self.qf)
        mass, approach = self.data.payload_mass, self.approach
        st = evaluate_state(self.model, self.lay, p, self.qf[rows], compliance=self.compliance, orientations=False,
                            payload_mass=None if mass is None else mass[rows], backlash=self.backlash,
                            approach=None if approach is None else approach[rows],
                            turns=None if self._turns is None else turns_at(self._turns, rows))
        return cast(np.ndarray, st.ps.P)[self.marker_idx].transpose(1, 0, 2)

    def predicted(self, p):
        """Marker positions (n_poses, n_data_markers, 3) and orientations (or None) at ``p``."""
        pos = self._positions(p)[self.marker_idx].transpose(1, 0, 2)
        if not self.use_rot:
            return pos, None
        st = self._state(p)
        rot = np.stack([st.ps.RM[m] for m in self.marker_idx], axis=1)
        return pos, rot

    def errors(self, p) -> np.ndarray:
        """(n_poses, n_data_markers, 3) predicted minus measured positions, NaN where not measured."""
        return self.errors_of(self.predicted(p)[0])

    def errors_of(self, pos: np.ndarray) -> np.ndarray:
        """``errors`` of the predicted positions ``pos`` (n_poses, n_data_markers, 3)."""
        if self._every_point:
            return np.subtract(pos, self.data.positions, order="C")
        return np.where(self.data.mask[..., None], pos - self.data.positions, np.nan)

    def error_norms(self, p) -> np.ndarray:
        """(n_poses, n_data_markers) position error norms, NaN where not measured."""
        return vector_norms(self.errors(p))

    def rotation_errors(self, p) -> np.ndarray | None:
        """(n_poses, n_data_markers, 3) rotation vectors (rad, in W) of R_pred R_meas^T, NaN where no
        orientation was measured; None for point data."""
        if not self.use_rot:
            return None
        st = self._state(p)
        out = np.full(self.data.positions.shape, np.nan)
        for j, s in enumerate(self.sel_r):
            out[s, j] = self._rotation_errors(st, j)
        return out

    def _rotation_errors(self, st, j) -> np.ndarray:
        """(n, 3) rotation vectors of R_pred R_meas^T in W for marker j's measured orientations."""
        s = self.sel_r[j]
        Rp = st.ps.RM[self.marker_idx[j]][s]
        assert self.data.rotations is not None  # rows of orientations exist only with them
        Rm = self.data.rotations[s, j]
        return Rotation.from_matrix(Rp @ np.swapaxes(Rm, -1, -2)).as_rotvec()

    @one_blas_thread
    def residuals(self, p) -> np.ndarray:
        P = self._positions(p)
        # unweighted rows of a marker measured at every pose: its positions as they are (w is 1)
        parts = [((P[m] if len(s) == len(P[m]) else P[m][s]) - meas).ravel() if not self.weighted else
                 ((P[m][s] - meas) * w[:, None]).ravel()
                 for m, s, meas, w in zip(self.marker_idx, self.sel, self.meas, self.w)]
        if self.use_rot:
            st = self._state(p)
            parts += [(self._rotation_errors(st, j) * w[:, None]).ravel() for j, w in enumerate(self.w_r)]
        return np.concatenate(parts)

    @one_blas_thread
    def jacobian(self, p) -> np.ndarray:
        """Weighted Jacobian of ``residuals`` over the free parameters: (n_rows, n_free), column-major.

        Kept with the evaluation at ``p``: asked again, or for fewer parameters (the solve after
        the analysis, at the same start), its columns are taken instead of built again; asked for
        more (a model choice freeing more than the fit that evaluated ``p``), only the others are built."""
        st = self._state(p)
        kept = st.cache.setdefault("jacobians", {})
        free = tuple(self.free_idx.tolist())
        Jt = _taken(kept, free, lambda Jt, rows: Jt[rows])
        if Jt is None:
            Jt = kept[free] = read_only(self._grown(st, kept, free))
        return Jt.T

    def _grown(self, st, kept: dict, free: tuple) -> np.ndarray:
        """(n_free, n_rows) the transposed weighted Jacobian at ``st`` over ``free``: the rows of the
        largest one kept for some of them, and the others built (a column does not depend on which
        others are built with it)."""
        have = max((h for h in kept if set(h) < set(free)), key=len, default=())
        if not have:
            return self._jacobian_rows(st, self.free_idx)
        where = {c: i for i, c in enumerate(free)}
        missing = [c for c in free if c not in have]
        out = np.empty((len(free), kept[have].shape[1]))
        out[[where[c] for c in have]] = kept[have]
        out[[where[c] for c in missing]] = self._jacobian_rows(st, np.array(missing, dtype=int))
        return out

    def _jacobian_rows(self, st, idx: np.ndarray) -> np.ndarray:
        """(len(idx), n_rows) the transposed weighted Jacobian at the evaluation ``st`` over the
        parameters ``idx``."""
        rows = 6 if self.use_rot else 3
        k = len(idx)
        cols = [jacobian_columns(self.model, self.lay, st, idx, m, rows) for m in self.marker_idx]
        parts = []
        for C, s, w in zip(cols, self.sel, self.w):
            if len(s) == C.shape[1] and not self.weighted:
                parts.append(C[:, :, :3].reshape(k, -1))
            else:
                parts.append((C[:, s, :3] * w[None, :, None]).reshape(k, -1))
        if self.use_rot:
            parts += [(C[:, s, 3:] * w[None, :, None]).reshape(k, -1) for C, s, w in zip(cols, self.sel_r, self.w_r)]
        return parts[0] if len(parts) == 1 else np.concatenate(parts, axis=1)

    def compliance_moments(self, p) -> dict:
        """Per compliance parameter name, the gravity moments (n_poses,) it multiplies (N m), at ``p``."""
        if not self.compliance:
            return {}
        if self.chunked:
            parts = [sub.compliance_moments(p) for sub in self._chunks()]
            return {n: np.concatenate([part[n] for part in parts]) for n in parts[0]}
        st = self._state(p)
        names = self.lay.names
        return {names[k]: st.M[row].copy() for row, k in enumerate(self.lay.compliant_params)}

    def backlash_sides(self, p) -> dict:
        """Per backlash parameter name, the sides (n_poses,) in [-1, 1] its joint rests on at ``p``."""
        if not self.backlash:
            return {}
        st = self._state(p)
        names = self.lay.names
        return {names[k]: st.backlash.sides[:, i].copy() for i, k in enumerate(self.lay.backlash_params) if k >= 0}

    @one_blas_thread
    def pose_blocks(self, p) -> np.ndarray:
        """(n_poses, rows_per_pose, n_free) unweighted Jacobian grouped by pose (all markers seen)."""
        st = self._state(p)
        rows = 6 if self.use_rot else 3
        cols = [jacobian_columns(self.model, self.lay, st, self.free_idx, m, rows) for m in self.marker_idx]
        return np.concatenate([C.transpose(1, 2, 0) for C in cols], axis=1)


class _Kept:
    """The evaluations a problem keeps, newest last (shared with the problems ``over`` makes from it:
    the same poses). Their pass buffers are the problem's own, taken from the model's workspace: an
    evaluation it drops gives them back, unless a kept one was moved from it (it reads them until
    it goes too), and all go back when the last of these problems goes. Nothing else holds them:
    what the problem hands out is computed or copied from them, never a view."""

    def __init__(self, ws: Workspace, n_positions: int = POSITIONS_KEPT):
        self.workspace = ws
        self.n_positions = n_positions
        self.states: dict = {}     # the bytes of the parameters' read-only copy -> the evaluation there
        self.read: list = []       # dropped evaluations a kept one was moved from
        self.positions: dict = {}  # the same bytes -> marker positions, for a campaign evaluated in chunks
        self.sums: tuple | None = None   # such a campaign's last R factor: (bytes, free, R, gradient, cost)
        weakref.finalize(self, _give_back, ws, self.states, self.read)

    def drop_oldest(self) -> None:
        self.read.append(self.states.pop(next(iter(self.states))))
        sources = {id(st.ps.moved_from[0]) for st in self.states.values() if st.ps.moved_from is not None}
        free = [st for st in self.read if id(st.ps) not in sources]
        self.read[:] = [st for st in self.read if id(st.ps) in sources]
        self.workspace.give([b for st in free for b in pass_buffers(st)])


def _give_back(ws: Workspace, states: dict, read: list) -> None:
    buffers = [b for st in list(states.values()) + read for b in pass_buffers(st)]
    states.clear()
    read.clear()
    ws.give(buffers)


def _taken(kept: dict, free: tuple, take):
    """What an evaluation keeps for the parameters ``free`` (indices): ``kept[free]``, or
    ``take(entry, positions of free in it)`` from an entry kept for more parameters; None if neither."""
    for have, entry in kept.items():
        if have == free:
            return entry
        if set(free) <= set(have):
            where = {c: i for i, c in enumerate(have)}
            return take(entry, [where[c] for c in free])
    return None


# a problem's free parameters: names of the model's parameters
_PARAMETERS = names_in(lambda a: parameter_names(a["model"]))


@accepts(model=is_a(RobotModel), q=readings_of(), names=_PARAMETERS, orientation=FLAG,
         approach=optional(shaped(None, None)))
def design_problem(model: RobotModel, q, names, orientation: bool = False, approach=None) -> Points:
    """The problem of ``names`` at readings ``q`` with nothing measured: its Jacobian is the design's.

    Parameters
    ----------
    {model, q}
    names : sequence of str
        The free parameters.
    orientation : bool
        Whether orientations are measured.
    {approach}

    Returns
    -------
    Points
        The measured-points block of the design; its Jacobian is the design's.
    """
    return Points(model, design_measurements(model, q, orientation, approach=approach), tuple(names),
                   compliance=needs_compliance(model, names))


