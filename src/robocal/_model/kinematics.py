"""Forward kinematics and the identification Jacobian: one engine for every parameter family.

Every placement in the robot is a sequence of elementary motions ("steps"): a rotation about, or a
translation along, a coordinate axis of the frame reached so far.

* base (W -> frame 0): Trans(x_W, x) Trans(y_W, y) Trans(z_W, z) R_ref exp([rx, ry, rz]x) (a rotation vector)
* frame j (parent -> j): Rot(z, gamma) Trans(z, b) Rot(y, beta) Rot(x, alpha) Trans(x, d)
  Rot(z, theta) Trans(z, r)
* marker (its frame -> marker): Trans(x, x) Trans(y, y) Trans(z, z) R_ref exp([rx, ry, rz]x)

The derivative of a marker's pose with respect to a step's value is geometric: for a rotation about
unit axis u through point O it is ``[u x (P - O); u]``, for a translation along u it is ``[u; 0]``,
all in the measurement frame W (docs/method.md section 3). One pass over the steps, vectorised over
poses and looping over frames, gives positions, orientations and every column.

Compliance (docs/method.md section 2): theta, alpha and beta of frame i deflect by ``K * M``, M the
gravity moment about that step's own axis of every mass distal to it, computed on the undeformed
chain at the current parameters. Geometric columns then gain ``sum_p K_p dM_p/dx * column_p``, with
dM/dx from rigid-motion identities (see ``_add_corrections``).

Transmission errors (docs/conventions.md): the arm reaches each frame variable at
``q_eff = q + B(q) t``, B the basis of a frame's terms (q, the harmonics of q and of its motor's angle)
and t their values. The pass runs at q_eff; a term's column is its joint's whole column (compliance
and backlash included, as theta or r enter the chain exactly as q_eff does) times the basis at q.

A pass keeps its vectors component-major, one (3, N) row each (``_Pass``): elementwise work runs
over contiguous rows of poses, a frame's constant part is one (4 x 4) @ (4 x 3N) product with its
parent's axes and origin, and the Jacobian reads the rows of just the steps asked for. The layouts
callers use (``R`` (n_frames, N, 3, 3), ``O``, ``P``, ``U``, ``Q``) are views of it.
"""

from __future__ import annotations

import copy
import math
import threading
from dataclasses import dataclass, field
from typing import cast

import numpy as np

from .._base.arguments import (
    FLAG,
    accepts,
    is_a,
    masses_for,
    optional,
    parameter_columns,
    readings_of,
    rows_for,
    vector_of,
)
from .._base.arrays import read_only
from .._base.spatial import cross, left_jacobian, rot_matrix, small_rotation
from .._base.threads import one_blas_thread
from .measurements import approach_sides
from .parameters import (
    BASE_KINDS,
    FRAME_KINDS,
    MARKER_KINDS,
    parameter_layout,
    parameter_vector,
)
from .robot import TRANSMISSION_KINDS, RobotModel

N_BASE = len(BASE_KINDS)
# above this many poses, what needs no Jacobian is evaluated CHUNK_POSES poses at a time (and a
# problem of point data is solved on normal equations accumulated chunk by chunk, see _problem)
LARGE_POSES = 50_000
CHUNK_POSES = 10_000
N_MARKER = len(MARKER_KINDS)


class FrameStep:
    """The elementary motions placing a frame in its parent, in the order of docs/method.md section 1,
    ``X_pj = Rot(z, gamma) Trans(z, b) Rot(y, beta) Rot(x, alpha) Trans(x, d) Rot(z, theta)
    Trans(z, r)``: each one's offset in the frame's steps and in its parameters (``GEOMETRIC_KINDS``,
    the first of ``FRAME_KINDS``). Plain integers in a namespace: they index arrays in the passes'
    inner loops, where an enum member's lookup would cost ten times more."""

    GAMMA = 0
    B = 1
    BETA = 2
    ALPHA = 3
    D = 4
    THETA = 5
    R = 6


N_FRAME_STEPS = 7
ROTATION_STEPS = (FrameStep.GAMMA, FrameStep.BETA, FrameStep.ALPHA, FrameStep.THETA)
# the steps gravity deflects (docs/method.md section 2), each with its compliance's offset in the frame's
# parameters; a frame's compliant rows (3 per frame) follow this order
COMPLIANT = tuple((step, FRAME_KINDS.index(kind)) for step, kind in
                  ((FrameStep.THETA, "k_theta"), (FrameStep.ALPHA, "k_alpha"), (FrameStep.BETA, "k_beta")))
# the other two components of a cross product's component c: (a x b)_c = a_j b_k - a_k b_j
_CROSS_PAIRS = {0: (1, 2), 1: (2, 0), 2: (0, 1)}


class FrameRow:
    """The rows of a frame's block in a pass's vectors (``_Pass.vec``: each row one (3, N) block of
    vectors in W), as docs/method.md sections 1 and 3 name them (plain integers, as ``FrameStep``'s)."""

    X_AXIS = 0          # the frame's rotation, column by column, and its origin
    Y_AXIS = 1
    Z_AXIS = 2          # theta turns about it, r slides along it
    ORIGIN = 3
    D_AXIS = 4          # the x axis alpha turns about and d slides along
    BETA_AXIS = 5       # the parent's y axis once gamma turned it: beta turns about it
    BETA_POINT = 6      # b along the parent's z: the point of the beta and alpha axes
    THETA_POINT = 7     # then d along the d axis: the point of the theta axis


class MarkerRow:
    """The rows of a marker's block: its position, then the axes of its three rotation steps."""

    POSITION = 0
    ROTATION_AXES = 1


FRAME_ROWS, MARKER_ROWS = FrameRow.THETA_POINT + 1, MarkerRow.ROTATION_AXES + 3
# a frame's placement: its first rows, x, y, z and origin (homogeneous coordinates multiply them)
PLACEMENT_ROWS = FrameRow.ORIGIN + 1
# the rows of a pass's vectors, in order: a zero row (the point of a translation's column); the base's
# block (x, y, z and origin, as a frame's first rows, then its six step axes); a block of FRAME_ROWS
# per frame; a block of MARKER_ROWS per marker
ZERO_ROW = 0
BASE_ROW = 1
BASE_STEP_AXES = BASE_ROW + FrameRow.ORIGIN + 1
FRAME_ROW0 = BASE_STEP_AXES + N_BASE



@dataclass(frozen=True, eq=False)
class Layout:
    """Where each parameter sits in the full parameter vector, and how steps relate."""

    names: tuple[str, ...]
    n_params: int
    frame0: np.ndarray          # (n_frames,) index of each frame's first parameter
    marker0: np.ndarray         # (n_markers,) index of each marker's first parameter
    step_param: np.ndarray      # (n_steps,) parameter index moved by each step
    step_is_rot: np.ndarray     # (n_steps,) bool
    step_frame: np.ndarray      # (n_steps,) owning frame, -1 base, -2 - m for marker m
    marker_path: np.ndarray     # (n_markers, n_steps) bool: the step moves that marker
    compliant_steps: np.ndarray  # (3 n_frames,) step index of theta/alpha/beta of each frame
    compliant_params: np.ndarray  # (3 n_frames,) parameter index of the matching K
    anc: np.ndarray             # (3 n_frames, n_steps) step is proximal to the compliant step
    desc: np.ndarray            # (3 n_frames, n_steps) step is distal to it (moves masses only)
    subtree: np.ndarray         # (n_frames, n_frames) bool: [i, k] frame k is in the subtree of i
    param_step: np.ndarray      # (n_params,) step moved by each parameter, -1 for compliances
    param_compliant: np.ndarray  # (n_params,) row in compliant_steps of a compliance, else -1
    backlash_params: np.ndarray  # (n_frames,) parameter index of each frame's backlash, -1 if fixed
    joint_steps: np.ndarray     # (n_frames,) step its joint variable moves (theta or r), -1 if fixed
    param_backlash: np.ndarray  # (n_params,) frame of a backlash parameter, else -1
    transmission_params: np.ndarray  # (n_frames, n_terms) parameter index of each transmission term
    param_transmission: np.ndarray  # (n_params,) frame of a transmission term, else -1
    n_rows: int                 # rows of a pass's vectors
    frame_row: np.ndarray       # (n_frames,) first row of each frame's block
    parent_row: np.ndarray      # (n_frames,) first row of its parent's block (BASE_ROW for the root)
    marker_row: np.ndarray      # (n_markers,) first row of each marker's block
    step_rows: np.ndarray       # (2, 2, n_steps) [orientations] rows of each step's axis and point
    chain_params: np.ndarray    # indices of every parameter but the base's and the markers'
    # the correction plans made for this layout (``correction_plan``): immutable records, kept with it
    plans: dict = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        for value in vars(self).values():
            if isinstance(value, np.ndarray):
                read_only(value)



def layout(model: RobotModel) -> Layout:
    """The step structure of ``model`` over its parameter layout, made once per model object and kept
    with it (an immutable record: its arrays are read-only)."""
    return model.derived(layout, lambda: _make_layout(model))


# the most a model's workspace keeps (its problems' pass buffers, for the next ones)
WORKSPACE_BYTES = 32 << 20


class Workspace:
    """Pass buffers a model's problems gave back, kept for its next ones (``workspace(model)``).

    A calibration's passes are then written into memory the process already uses instead of fresh
    pages the system has to fault in: without it, at 1,000 poses, first writes to fresh pages take
    about a third of a repeated calibration's time. It is the model's own (it lives and dies with
    it) and changes nothing outside it. A buffer is taken by one evaluation of one problem, which
    owns it, and is given back by its owner when it is done with it (nothing of it handed out: what
    a problem returns is computed or copied from it), at most ``WORKSPACE_BYTES`` kept in all. What
    a buffer held is never read: a pass writes every row before it reads it, as it must with
    ``np.empty``.
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._spare: list[np.ndarray] = []

    def take(self, shape: tuple) -> np.ndarray:
        """A buffer of ``shape`` (float): a spare one if one has that shape, else a new one."""
        with self._lock:
            for k, a in enumerate(self._spare):
                if a.shape == shape:
                    return self._spare.pop(k)
        return np.empty(shape)

    def give(self, arrays: list) -> None:
        """Keep, for a later ``take``, ``arrays`` (buffers ``take`` gave, whose owner is done with
        them, in a list handed over and emptied here); the oldest spares go beyond the bound."""
        with self._lock:
            while arrays:
                a = arrays.pop()
                if a.flags.owndata and a.nbytes <= WORKSPACE_BYTES:
                    self._spare.append(a)
            while sum(a.nbytes for a in self._spare) > WORKSPACE_BYTES:
                self._spare.pop(0)


def workspace(model: RobotModel) -> Workspace:
    """The model's workspace: the pass buffers its problems gave back (kept with the model)."""
    return model.derived(workspace, Workspace)


def pass_buffers(st) -> list:
    """The buffers the passes of the evaluation ``st`` were written into (for ``Workspace.give``)."""
    return [ps.vec for ps in {id(ps): ps for ps in (st.ps, st.ps0) if ps is not None}.values()]


def _make_layout(model: RobotModel) -> Layout:
    nf, nm = model.n_frames, len(model.markers)
    params = parameter_layout(model)
    names = params.names
    frame0, marker0 = params.frame0.tolist(), params.marker0.tolist()

    params_of_steps: list[int] = []
    step_is_rot: list[bool] = []
    frames_of_steps: list[int] = []
    for k in range(N_BASE):
        params_of_steps.append(k)
        step_is_rot.append(k >= 3)
        frames_of_steps.append(-1)
    for i in range(nf):
        for k in range(N_FRAME_STEPS):
            params_of_steps.append(frame0[i] + k)
            step_is_rot.append(k in ROTATION_STEPS)
            frames_of_steps.append(i)
    for m in range(nm):
        for k in range(N_MARKER):
            params_of_steps.append(marker0[m] + k)
            step_is_rot.append(k >= 3)
            frames_of_steps.append(-2 - m)
    step_param = np.array(params_of_steps)
    step_frame = np.array(frames_of_steps)
    n_steps = len(step_param)

    ancestors = np.zeros((nf, nf), dtype=bool)  # [i, k]: k is i or an ancestor of i
    for i, f in enumerate(model.frames):
        ancestors[i, i] = True
        if f.parent >= 0:
            ancestors[i] |= ancestors[f.parent]
    subtree = ancestors.T.copy()  # [i, k]: k in subtree of i

    marker_path = np.zeros((nm, n_steps), dtype=bool)
    for m, mk in enumerate(model.markers):
        marker_path[m, :N_BASE] = True
        for anc_frame in np.nonzero(ancestors[mk.frame])[0]:
            marker_path[m, _frame_steps(anc_frame)] = True
        s0 = N_BASE + N_FRAME_STEPS * nf + N_MARKER * m
        marker_path[m, s0:s0 + N_MARKER] = True
    csteps, cparams, anc, desc = _compliant_rows(frame0, ancestors, n_steps)
    param_step = np.full(len(names), -1, dtype=int)
    param_step[step_param] = np.arange(n_steps)
    param_compliant = np.full(len(names), -1, dtype=int)
    param_compliant[np.array(cparams, dtype=int)] = np.arange(len(cparams))
    bparams, jsteps, param_backlash = _backlash_layout(model, params)
    tparams = np.array(frame0, dtype=int)[:, None] + FRAME_KINDS.index(TRANSMISSION_KINDS[0]) + \
        np.arange(len(TRANSMISSION_KINDS))
    param_transmission = np.full(len(names), -1, dtype=int)
    param_transmission[tparams] = np.arange(nf)[:, None]
    rows = _vector_rows(model)
    return Layout(
        transmission_params=tparams.reshape(nf, len(TRANSMISSION_KINDS)), param_transmission=param_transmission,
        n_rows=rows[0], frame_row=rows[1], parent_row=rows[2], marker_row=rows[3], step_rows=rows[4],
        chain_params=np.array([k for k, pr in enumerate(params.parameters) if pr.role not in ("base", "marker")],
                              dtype=int),
        param_step=param_step, param_compliant=param_compliant, backlash_params=bparams, joint_steps=jsteps,
        param_backlash=param_backlash,
        names=tuple(names), n_params=len(names), frame0=np.array(frame0, dtype=int),
        marker0=np.array(marker0, dtype=int), step_param=step_param,
        step_is_rot=np.array(step_is_rot), step_frame=step_frame, marker_path=marker_path,
        compliant_steps=np.array(csteps, dtype=int), compliant_params=np.array(cparams, dtype=int),
        anc=anc, desc=desc, subtree=subtree,
    )


def _backlash_layout(model: RobotModel, params):
    """Per frame, the index of its backlash parameter and the step its joint variable moves (-1 for
    a fixed frame); per parameter, the frame of a backlash (else -1)."""
    nf = model.n_frames
    bparams = np.full(nf, -1, dtype=int)
    jsteps = np.full(nf, -1, dtype=int)
    for i, f in enumerate(model.frames):
        if f.joint != "fixed":
            rev = f.joint == "revolute"
            bparams[i] = params.by_name[f"{f.name}.backlash_{'theta' if rev else 'r'}"].index
            jsteps[i] = N_BASE + N_FRAME_STEPS * i + (FrameStep.THETA if rev else FrameStep.R)
    param_backlash = np.full(params.n_params, -1, dtype=int)
    param_backlash[bparams[bparams >= 0]] = np.nonzero(bparams >= 0)[0]
    return bparams, jsteps, param_backlash


def _vector_rows(model: RobotModel):
    """Where a pass keeps each frame's and marker's vectors, and per step the rows of its axis
    and of a point on it (ZERO_ROW for a translation), without and with orientations."""
    nf, nm = model.n_frames, len(model.markers)
    frame_row = FRAME_ROW0 + FRAME_ROWS * np.arange(nf)
    parent_row = np.array([BASE_ROW if f.parent < 0 else frame_row[f.parent] for f in model.frames], dtype=int)
    marker_row = FRAME_ROW0 + FRAME_ROWS * nf + MARKER_ROWS * np.arange(nm)
    axis = [BASE_STEP_AXES + k for k in range(N_BASE)]
    point = [ZERO_ROW] * 3 + [BASE_ROW + FrameRow.ORIGIN] * 3
    for r, pr in zip(frame_row, parent_row):
        # docs/method.md section 3: gamma turns about, and b slides along, the parent's z through its
        # origin; beta turns about its own axis, alpha about the d axis, both through b's point; d slides
        # along the d axis; theta turns about z through theta's point, r slides along z
        axis += [pr + FrameRow.Z_AXIS, pr + FrameRow.Z_AXIS, r + FrameRow.BETA_AXIS, r + FrameRow.D_AXIS,
                 r + FrameRow.D_AXIS, r + FrameRow.Z_AXIS, r + FrameRow.Z_AXIS]
        point += [pr + FrameRow.ORIGIN, ZERO_ROW, r + FrameRow.BETA_POINT, r + FrameRow.BETA_POINT, ZERO_ROW,
                  r + FrameRow.THETA_POINT, ZERO_ROW]
    turns = MarkerRow.ROTATION_AXES + np.arange(3)
    for mk, r in zip(model.markers, marker_row):
        fr = frame_row[mk.frame]
        axis += [fr + FrameRow.X_AXIS, fr + FrameRow.Y_AXIS, fr + FrameRow.Z_AXIS] + list(r + turns)
        point += [ZERO_ROW] * 3 + [r + MarkerRow.POSITION] * 3
    rows = np.array([[axis, point]] * 2, dtype=int)
    # without orientations a marker's rotation steps move nothing: the zero row
    for r in marker_row:
        rows[0][np.isin(rows[0], r + np.arange(MARKER_ROWS))] = ZERO_ROW
    return FRAME_ROW0 + FRAME_ROWS * nf + MARKER_ROWS * nm, frame_row, parent_row, marker_row, rows


def _frame_steps(i: int | np.integer) -> np.ndarray:
    return N_BASE + N_FRAME_STEPS * i + np.arange(N_FRAME_STEPS)


def _compliant_rows(frame0: list, ancestors: np.ndarray, n_steps: int):
    """Per compliant step (theta, alpha, beta of each frame): its step and compliance indices, and
    which steps are proximal (``anc``) and distal (``desc``) to it, (3 n_frames, n_steps) each."""
    nf = len(frame0)
    subtree = ancestors.T
    csteps, cparams = [], []
    anc = np.zeros((3 * nf, n_steps), dtype=bool)
    desc = np.zeros((3 * nf, n_steps), dtype=bool)
    for i in range(nf):
        for c, (off, koff) in enumerate(COMPLIANT):
            row = 3 * i + c
            s = N_BASE + N_FRAME_STEPS * i + off
            csteps.append(s)
            cparams.append(frame0[i] + koff)
            anc[row, :N_BASE] = True
            for k in np.nonzero(ancestors[i])[0]:
                if k != i:
                    anc[row, _frame_steps(k)] = True
            own = _frame_steps(i)
            anc[row, own[own <= s]] = True
            desc[row, own[own > s]] = True
            for k in np.nonzero(subtree[i])[0]:
                if k != i:
                    desc[row, _frame_steps(k)] = True
    return csteps, cparams, anc, desc


@dataclass
class _Pass:
    """The frames of one pass, stored component-major: ``vec`` (n_rows, 3, N) holds one (3, N) block
    of vectors per row (rows laid out by ``Layout.frame_row`` and ``marker_row``), so every
    elementwise operation runs over contiguous rows of poses and each frame's constant part is one
    small matrix product. ``R``, ``O``, ``P``, ``U``, ``Q`` are views of it in the layouts the
    callers use. The step axes and points are built when first asked for (residuals need none)."""

    vec: np.ndarray
    base_axes: np.ndarray  # (6, 3) axes of the base steps
    base_origin: np.ndarray  # (3,)
    base_rotation: np.ndarray  # (3, 3) frame 0 of the base, parent of the root frames
    model: RobotModel
    lay: Layout
    p: np.ndarray
    orientations: bool = False
    has_markers: bool = True
    pending: list = field(default_factory=list)  # (frame, rows of the (4, 4) product giving its step axes and points)
    cache: dict = field(default_factory=dict)
    moved_from: tuple | None = None  # (pass, dR, shift): the frame rows still to move from it (``moved_state``)

    def materialise(self) -> None:
        """Move every frame row from the pass this one was moved from (``moved_state``)."""
        if self.moved_from is not None:
            src, dR, shift = self.moved_from
            self.moved_from = None
            _move_rows(self.vec, src.vec, dR, shift, np.arange(self.model.n_frames))

    def _frames(self) -> np.ndarray:
        """(n_frames, FRAME_ROWS, 3, N) every frame's block."""
        self.materialise()
        nf = self.model.n_frames
        return self.vec[FRAME_ROW0:FRAME_ROW0 + FRAME_ROWS * nf].reshape((nf, FRAME_ROWS) + self.vec.shape[1:])

    @property
    def N(self) -> int:
        return self.vec.shape[2]

    @property
    def R(self) -> np.ndarray:
        """(n_frames, N, 3, 3) rotations R_W<frame> (a view)."""
        return self._frames()[:, FrameRow.X_AXIS:FrameRow.Z_AXIS + 1].transpose(0, 3, 2, 1)

    @property
    def O(self) -> np.ndarray:  # noqa: E743
        """(n_frames, N, 3) origins (a view)."""
        return self._frames()[:, FrameRow.ORIGIN].transpose(0, 2, 1)

    @property
    def P(self) -> np.ndarray | None:
        """(n_markers, N, 3) marker positions (a view; None for a frames-only pass)."""
        if not self.has_markers:
            return None
        nm, r0 = len(self.model.markers), FRAME_ROW0 + FRAME_ROWS * self.model.n_frames
        blocks = self.vec[r0:r0 + MARKER_ROWS * nm].reshape((nm, MARKER_ROWS) + self.vec.shape[1:])
        return blocks[:, MarkerRow.POSITION].transpose(0, 2, 1)

    @property
    def U(self) -> np.ndarray:
        """(n_steps, N, 3) step axes in W (marker rotation axes zero without orientations)."""
        return self._axes()[0]

    @property
    def Q(self) -> np.ndarray:
        """(n_steps, N, 3) a point on each rotation step's axis (zero for translations)."""
        return self._axes()[1]

    @property
    def RM(self) -> list:
        """Per marker its orientation (N, 3, 3) in W; empty without orientations."""
        if "RM" not in self.cache:
            self.cache["RM"] = _marker_rotations(self) if self.orientations else []
        return self.cache["RM"]

    def vectors(self, frames=None) -> np.ndarray:
        """``vec`` with the step axes and points filled in: the base's, the markers' and those of
        ``frames`` (indices; default every frame)."""
        filled = self.cache.setdefault("filled", set())
        wanted = set(range(self.model.n_frames)) if frames is None else set(frames)
        if wanted:
            self.materialise()
        if "base" not in filled or not wanted <= filled:
            _fill_step_vectors(self, wanted - filled, "base" not in filled)
            filled |= wanted | {"base"}
        return self.vec

    def _axes(self):
        if "axes" not in self.cache:
            rows = self.lay.step_rows[int(self.orientations)]
            vec = self.vectors()
            self.cache["axes"] = (vec[rows[0]].transpose(0, 2, 1), vec[rows[1]].transpose(0, 2, 1))
        return self.cache["axes"]


def joint_turns(qf: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """cos (n_frames, N) and (sin, -sin) (n_frames, 2, 1, N) of the frame variables ``qf``
    (N, n_frames), read-only: what a pass turns each frame by. A caller that evaluates the same
    readings again (a problem, at every step of a fit) makes them once and hands them to
    ``kinematic_pass`` (``turns``)."""
    qt = np.ascontiguousarray(qf.T)
    return read_only(np.cos(qt)), read_only(_signed_sines(qt))


def reading_turns(model: RobotModel, data, qf: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``joint_turns(qf)`` of ``data``'s frame variables ``qf`` (its readings through the model's
    couplings), made once per record and couplings and kept with the record
    (``Measurements.derived``): the problems made on one campaign, and on the folds cut from it,
    share them."""
    C = model.coupling_matrix
    return data.derived(("joint turns", C.shape, C.tobytes()), lambda _: joint_turns(qf), turns_at)


def turns_at(turns: tuple, index) -> tuple[np.ndarray, np.ndarray]:
    """The poses ``index`` of ``joint_turns``' cosines and sines, read-only."""
    cos_q, sin_q = turns
    return read_only(cos_q[:, index]), read_only(sin_q[..., index])


def _signed_sines(angle: np.ndarray) -> np.ndarray:
    """(..., 2, 1, N) sin and -sin of ``angle`` (..., N), as ``_turn_rows`` takes them."""
    out = np.empty(angle.shape[:-1] + (2, 1, angle.shape[-1]))
    np.sin(angle, out=out[..., 0, 0, :])
    np.negative(out[..., 0, 0, :], out=out[..., 1, 0, :])
    return out


def _place(Vt: np.ndarray, parent: np.ndarray, out: np.ndarray) -> None:
    """out (k, 3, N) = the vectors whose parent-frame coordinates (homogeneous: 0 for a direction,
    1 for a point) are the rows of Vt (k, 4), placed by the parent's x, y, z, origin ``parent``:
    (4, 3, N), or (4, 3) for the base, the same at every pose.
    Reference: docs/method.md section 1: a frame's vectors from its parent's, X_W<frame> = X_W<parent> X_pj."""
    if parent.ndim == 2:
        out[...] = (Vt @ parent)[:, :, None]
    else:
        np.matmul(Vt, parent.reshape(4, -1), out=out.reshape(len(Vt), -1))


def _turn_rows(block: np.ndarray, room: np.ndarray, c, ss) -> None:
    """The x and y axes (xc, yc) of a frame's ``block`` turned about z per pose, in place:
    x = c xc + s yc, y = c yc - s xc, with c (N,) and ``ss`` the (s, -s) of ``_signed_sines``;
    ``room`` (2, 3, N) scratch. Reference: docs/method.md section 1: the joint's Rot(z, theta) of X_pj."""
    xy = block[FrameRow.X_AXIS:FrameRow.Y_AXIS + 1]
    np.multiply(xy[::-1], ss, out=room)       # (yc, xc) s, -s
    xy *= c
    xy += room


def kinematic_pass(model: RobotModel, lay: Layout, p: np.ndarray, qf: np.ndarray, defl=None,
                   orientations: bool = False, frames_only: bool = False, turns=None, take=np.empty) -> _Pass:
    """One pass down the tree. Per frame, its constant part (the parent's turn, offsets, and
    theta's offset) is one (4 x 4) @ (4 x 3N) product; only the joint's turn varies per pose.

    ``frames_only``: frame poses without marker positions (the undeformed chain under compliance
    needs no more). Step axes and points (``U``, ``Q``) and marker orientations are built on
    first use. ``turns``: ``joint_turns(qf)`` when the caller holds them (default: made here);
    ``take``: where the pass's buffer comes from (a ``Workspace.take``; default a new array).
    Reference: docs/method.md section 1 (X_pj down the tree, the base and the markers)."""
    N = qf.shape[0]
    base_axes, Rb = _base_placement(model, p)
    vec = take((lay.n_rows, 3, N))
    room = np.empty((2, 3, N))               # scratch for the joints' turns, frame after frame
    vec[ZERO_ROW] = 0.0
    ps = _Pass(vec=vec, base_axes=base_axes, base_origin=p[0:3], base_rotation=Rb, model=model, lay=lay, p=p,
               orientations=orientations, has_markers=not frames_only)
    base = np.vstack([Rb.T, p[0:3]])                       # (4, 3) the base's x, y, z and origin
    cos_q, sin_q = joint_turns(qf) if turns is None else turns             # sin_q: (sin, -sin)
    for i, f in enumerate(model.frames):
        r0 = lay.frame_row[i]
        parent = base if f.parent < 0 else vec[lay.parent_row[i]:lay.parent_row[i] + PLACEMENT_ROWS]
        v = p[lay.frame0[i]:lay.frame0[i] + N_FRAME_STEPS].tolist()
        d_th, d_al, d_be = (0.0, 0.0, 0.0) if defl is None else defl[i]
        rev = f.joint == "revolute"
        if isinstance(d_al, np.ndarray) or isinstance(d_be, np.ndarray):
            _deflected_frame(vec, r0, parent, v, v[FrameStep.BETA] + d_be, v[FrameStep.ALPHA] + d_al,
                             v[FrameStep.THETA] + d_th + (qf[:, i] if rev else 0.0))
        else:
            ps.pending.append((i, _constant_frame(vec, r0, parent, v, v[FrameStep.BETA] + d_be,
                                                  v[FrameStep.ALPHA] + d_al, d_th,
                                                  qf[:, i] if rev else None, cos_q[i], sin_q[i], room)))
        if f.joint == "prismatic":
            vec[r0 + FrameRow.ORIGIN] += qf[:, i] * vec[r0 + FrameRow.Z_AXIS]
    if not frames_only:
        _marker_positions(ps)
    return ps


def _constant_frame(vec, r0, parent, v, be, al, d_th, q, cos_q, sin_q, room) -> list:
    """Fill a frame's rows X_AXIS to ORIGIN from its parent's when beta and alpha are the same at every
    pose (``v`` the frame's values as floats): docs/method.md section 1's X_pj, its constant part
    (gamma, b, beta, alpha, d, theta's offset, r) placed by one (4 x 4) product and the joint's turn
    per pose, applied in place (``room``: (2, 3, N) scratch). Return the rows of
    the (4, 4) product giving its step axes and points (rows D_AXIS on). The constant 3-vectors are
    a few scalars: plain floats."""
    cg, sg = math.cos(v[FrameStep.GAMMA]), math.sin(v[FrameStep.GAMMA])
    cb, sb = math.cos(be), math.sin(be)
    ca, sa = math.cos(al), math.sin(al)
    # in the parent's frame: Rot(z, gamma)'s y (the beta axis, yg); after Rot(y, beta) the x (the d
    # axis) and z (zb); after Rot(x, alpha) the y and z: y = ca yg + sa zb, z = ca zb - sa yg
    # written out component by component: list comprehensions over 3-vectors cost more than the math
    x0, x1, x2 = cg * cb, sg * cb, -sb
    zb0, zb1, zb2 = cg * sb, sg * sb, cb
    y0, y1, y2 = -ca * sg + sa * zb0, ca * cg + sa * zb1, sa * zb2
    z0, z1, z2 = ca * zb0 + sa * sg, ca * zb1 - sa * cg, ca * zb2
    b, d, r = v[FrameStep.B], v[FrameStep.D], v[FrameStep.R]
    per_pose = isinstance(d_th, np.ndarray)
    # theta's constant offset (and a constant deflection) turns the constant part
    t0 = v[FrameStep.THETA] + (0.0 if per_pose else d_th)
    c0, s0 = math.cos(t0), math.sin(t0)
    xt = (c0 * x0 + s0 * y0, c0 * x1 + s0 * y1, c0 * x2 + s0 * y2, 0.0)
    yt = (c0 * y0 - s0 * x0, c0 * y1 - s0 * x1, c0 * y2 - s0 * x2, 0.0)
    z = (z0, z1, z2, 0.0)
    origin = (d * x0 + r * z0, d * x1 + r * z1, b + d * x2 + r * z2, 1.0)
    # x and y land before the joint's turn, which is then applied in place
    _place(np.array((xt, yt, z, origin)), parent, vec[r0 + FrameRow.X_AXIS:r0 + FrameRow.ORIGIN + 1])
    if q is not None or per_pose:
        if per_pose:
            ang = d_th if q is None else q + d_th
            cos_q, sin_q = np.cos(ang), _signed_sines(ang)
        _turn_rows(vec[r0:r0 + FRAME_ROWS], room, cos_q, sin_q)
    # in the parent's frame: the d axis, the beta axis (Rot(z, gamma)'s y), b's point, theta's point
    return [(x0, x1, x2, 0.0), (-sg, cg, 0.0, 0.0), (0.0, 0.0, b, 1.0), (d * x0, d * x1, b + d * x2, 1.0)]


def _deflected_frame(vec, r0, parent, v, be, al, th) -> None:
    """Fill every row of a frame whose beta or alpha is deflected pose by pose (``be``, ``al``
    scalars or (N,)), turning the parent's axes pose by pose where they vary; ``th`` its full
    theta, (N,) or a scalar: docs/method.md section 1's X_pj step by step, at the deflected values
    of section 2."""
    Rg = rot_matrix(2, v[FrameStep.GAMMA])
    G = np.empty((4, 3, vec.shape[2] if parent.ndim > 2 else 1))
    Vt = np.zeros((4, 4))
    Vt[:3, :3] = Rg.T
    Vt[3] = (0.0, 0.0, v[FrameStep.B], 1.0)
    _place(Vt, parent, G)
    gx, gy, gz, pb = G
    cb, sb = np.cos(be), np.sin(be)
    x = cb * gx - sb * gz                                 # after Rot(y, beta)
    zb = sb * gx + cb * gz
    ca, sa = np.cos(al), np.sin(al)
    z = vec[r0 + FrameRow.Z_AXIS]
    z[...] = ca * zb - sa * gy                        # after Rot(x, alpha)
    y = ca * gy + sa * zb
    vec[r0 + FrameRow.BETA_AXIS] = gy
    vec[r0 + FrameRow.D_AXIS] = x
    vec[r0 + FrameRow.BETA_POINT] = pb
    vec[r0 + FrameRow.THETA_POINT] = pb + v[FrameStep.D] * x
    vec[r0 + FrameRow.ORIGIN] = vec[r0 + FrameRow.THETA_POINT] + v[FrameStep.R] * z
    c, s = np.cos(th), np.sin(th)
    vec[r0 + FrameRow.X_AXIS] = c * x + s * y
    vec[r0 + FrameRow.Y_AXIS] = c * y - s * x


def _base_placement(model: RobotModel, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The axes (6, 3) of the base steps and the rotation of frame 0 in W."""
    return base_rotation_of(model.base_rotation, *p[3:6].tolist())


def base_rotation_of(reference: tuple, x: float, y: float, z: float) -> tuple[np.ndarray, np.ndarray]:
    """R = R_ref exp([v]x) for the rotation vector v = (x, y, z); a change dv turns the base about
    the columns of R_ref J_l(v) in W, J_l the left Jacobian (``left_jacobian``).
    Reference: docs/method.md section 1 and docs/conventions.md (the base pose's rotation vector)."""
    Rref = np.asarray(reference, dtype=float)
    t = math.sqrt(x * x + y * y + z * z)
    K = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    K2 = K @ K
    # exp: I + sin t / t K + (1 - cos t) / t^2 K^2; J_l: I + (1 - cos t) / t^2 K + (t - sin t) / t^3 K^2
    if t < 1e-8:
        R, J = np.eye(3) + K + 0.5 * K2, np.eye(3) + 0.5 * K
    else:
        a, b, c = math.sin(t) / t, (1.0 - math.cos(t)) / t ** 2, (t - math.sin(t)) / t ** 3
        R, J = np.eye(3) + a * K + b * K2, np.eye(3) + b * K + c * K2
    return np.vstack([np.eye(3), (Rref @ J).T]), Rref @ R


def _frame_block(ps: _Pass, k: int) -> np.ndarray:
    """(4, 3, N) frame k's x, y, z and origin."""
    if ps.moved_from is not None and all(mk.frame != k for mk in ps.model.markers):
        ps.materialise()          # a moved pass holds the markers' frames only
    r0 = ps.lay.frame_row[k]
    return ps.vec[r0:r0 + PLACEMENT_ROWS]


def moved_state(st, p: np.ndarray, take=np.empty):
    """The evaluation at ``p`` from ``st``, a geometric one (no compliance, no backlash) at values
    that differ from ``p`` in the base and the markers only: the chain is the same, moved rigidly
    by the change of the base. Only the markers' frames are moved at once (what their positions
    and the base's and markers' columns need); the other frames are moved when first asked for.
    A fit of the base and markers alone evaluates this way, without a pass down the chain.
    Reference: docs/method.md section 1: the base pose X_WB moves every frame rigidly."""
    old = st.ps
    src = old if old.moved_from is None else old.moved_from[0]
    lay = src.lay
    base_axes, Rb = _base_placement(src.model, p)
    dR = Rb @ src.base_rotation.T
    shift = p[0:3] - dR @ src.base_origin               # a point x goes to dR x + shift
    vec = take(src.vec.shape)
    vec[ZERO_ROW] = 0.0
    _move_rows(vec, src.vec, dR, shift, sorted({mk.frame for mk in src.model.markers}), block=PLACEMENT_ROWS)
    ps = _Pass(vec=vec, base_axes=base_axes, base_origin=p[0:3], base_rotation=Rb, model=src.model, lay=lay, p=p,
               orientations=src.orientations, has_markers=src.has_markers, pending=src.pending,
               moved_from=(src, dR, shift))
    if ps.has_markers:
        _marker_positions(ps)
    return _State(ps=ps, compliance=False, ks=p[lay.compliant_params], readings=st.readings)


def moves_rigidly(lay: Layout, a: np.ndarray, b: np.ndarray) -> bool:
    """Whether parameter vectors ``a`` and ``b`` differ in the base and marker values only."""
    return bool(np.array_equal(a[lay.chain_params], b[lay.chain_params]))


def _move_rows(dst: np.ndarray, src: np.ndarray, dR: np.ndarray, shift: np.ndarray, frames, block: int = FRAME_ROWS):
    """The first ``block`` rows of each frame in ``frames`` of ``src`` turned by ``dR`` into ``dst``, and
    its points (ORIGIN, BETA_POINT, THETA_POINT) shifted by ``shift``.
    Reference: docs/method.md section 1: X_WB moves every frame rigidly."""
    for k in frames:
        r0 = FRAME_ROW0 + FRAME_ROWS * int(k)
        rows = src[r0:r0 + block]
        dst[r0:r0 + block] = (dR @ rows.transpose(1, 0, 2).reshape(3, -1)).reshape(3, block, -1).transpose(1, 0, 2)
        for off in (FrameRow.ORIGIN, FrameRow.BETA_POINT, FrameRow.THETA_POINT):
            if off < block:
                dst[r0 + off] += shift[:, None]


def _marker_positions(ps: _Pass) -> None:
    """Fill the marker rows with the marker positions in W.
    Reference: docs/method.md section 1: a marker is a point in its frame."""
    model, lay, p = ps.model, ps.lay, ps.p
    for m, mk in enumerate(model.markers):
        v = np.append(p[lay.marker0[m]:lay.marker0[m] + 3], 1.0)
        r = lay.marker_row[m]
        _place(v[None], _frame_block(ps, mk.frame), ps.vec[r + MarkerRow.POSITION:r + MarkerRow.POSITION + 1])


def _marker_rotations(ps: _Pass) -> list:
    """Per marker its orientation (N, 3, 3) in W (a view of a component-major array).
    Reference: docs/method.md section 1 and docs/conventions.md (a marker's rotation correction)."""
    model, lay, p = ps.model, ps.lay, ps.p
    out = []
    for m, mk in enumerate(model.markers):
        v = p[lay.marker0[m] + 3:lay.marker0[m] + 6]
        C = np.asarray(mk.rotation, dtype=float) @ small_rotation(*v)
        out.append(_columns(C, _frame_block(ps, mk.frame)).transpose(2, 1, 0))
    return out


def _columns(C: np.ndarray, frame: np.ndarray) -> np.ndarray:
    """(k, 3, N) the frame's rotation times the columns of C (3, k). Reference: docs/method.md section 1."""
    Vt = np.zeros((C.shape[1], 4))
    Vt[:, :3] = C.T
    out = np.empty((C.shape[1],) + frame.shape[1:])
    _place(Vt, frame, out)
    return out


def _fill_step_vectors(ps: _Pass, frames: set, base_and_markers: bool) -> None:
    """Fill the rows the step axes and points come from: the base's frame and step axes and the
    markers' rotation axes (with orientations), when ``base_and_markers``; the beta and d axes
    and the points on the beta/alpha and theta axes of the frames ``frames``.
    Reference: docs/method.md section 3: each step's axis u and a point O on it."""
    model, lay, p, vec = ps.model, ps.lay, ps.p, ps.vec
    base = np.vstack([ps.base_rotation.T, ps.base_origin])
    for i, axes in ps.pending:
        if i not in frames:
            continue
        r0 = lay.frame_row[i]
        parent = base if model.frames[i].parent < 0 else vec[lay.parent_row[i]:lay.parent_row[i] + PLACEMENT_ROWS]
        _place(np.array(axes), parent, vec[r0 + FrameRow.D_AXIS:r0 + FrameRow.THETA_POINT + 1])
    if not base_and_markers:
        return
    vec[BASE_ROW + FrameRow.X_AXIS:BASE_ROW + FrameRow.Z_AXIS + 1] = ps.base_rotation.T[:, :, None]
    vec[BASE_ROW + FrameRow.ORIGIN] = ps.base_origin[:, None]
    vec[BASE_STEP_AXES:BASE_STEP_AXES + N_BASE] = ps.base_axes[:, :, None]
    for m, mk in enumerate(model.markers):
        r = lay.marker_row[m]
        if not ps.has_markers:
            vec[r + MarkerRow.POSITION] = np.nan    # a frames-only pass has no marker to turn about
        if ps.orientations:
            v = p[lay.marker0[m] + 3:lay.marker0[m] + 6]
            C = np.asarray(mk.rotation, dtype=float) @ left_jacobian(v)
            vec[r + MarkerRow.ROTATION_AXES:r + MARKER_ROWS] = _columns(C, _frame_block(ps, mk.frame))


def mass_sums(model: RobotModel, lay: Layout, ps: _Pass, payload_mass):
    """First moments ``C1`` (3, n_frames, N), component-major, and masses ``msub`` (n_frames, N) of
    every subtree. Reference: docs/method.md section 2: the masses m_k and centres c_k distal to each frame."""
    nf, N = model.n_frames, ps.N
    mass = np.array([f.mass for f in model.frames], dtype=float)
    com = np.ones((nf, 1, 4))
    com[:, 0, :3] = [f.com for f in model.frames]
    frames = ps._frames()[:, :PLACEMENT_ROWS].reshape(nf, PLACEMENT_ROWS, 3 * N)
    own_c1 = np.matmul(com, frames).reshape(nf, 3, N)
    own_c1 *= mass[:, None, None]
    own_m = np.repeat(mass[:, None], N, axis=1)
    for n, pl in enumerate(model.payloads):
        # a measurement's payload column varies the first payload only
        pm = pl.mass if payload_mass is None or n > 0 else payload_mass
        if np.any(np.asarray(pm) > 0):
            k = pl.frame if pl.frame >= 0 else nf - 1
            c = np.append(np.asarray(pl.com, dtype=float), 1.0) @ frames[k]
            pm = np.broadcast_to(np.asarray(pm, dtype=float), (N,))
            own_c1[k] += pm * c.reshape(3, N)
            own_m[k] += pm
    sub = lay.subtree.astype(float)
    return sub @ own_c1.transpose(1, 0, 2), sub @ own_m


def compliant_vectors(model: RobotModel, ps: _Pass):
    """Axes ``u`` and points ``Q`` of every compliant step (theta, alpha, beta of each frame) and the
    parents' origins ``Op``, component-major ((3, 3 n_frames, N) and (3, n_frames, N)), once per pass.
    Reference: docs/method.md section 2: the axis u_p and point O_p of each compliant step."""
    if "compliant" not in ps.cache:
        lay, vec = ps.lay, ps.vectors()
        u = vec[(lay.frame_row[:, None] + [FrameRow.Z_AXIS, FrameRow.D_AXIS, FrameRow.BETA_AXIS]).ravel()]
        # theta turns about its own point, alpha and beta about the point b along the parent's z
        Q = vec[(lay.frame_row[:, None] + [FrameRow.THETA_POINT, FrameRow.BETA_POINT, FrameRow.BETA_POINT]).ravel()]
        Op = vec[lay.parent_row + FrameRow.ORIGIN]
        ps.cache["compliant"] = (u.transpose(1, 0, 2), Q.transpose(1, 0, 2), Op.transpose(1, 0, 2))
    return ps.cache["compliant"]


def joint_moments(model, ps, C1, msub):
    """Gravity moments ``M`` (3 n_frames, N) about each compliant step's axis; with the axes ``u``
    and ``A = C1 - m Q`` (3, 3 n_frames, N), component-major.
    Reference: docs/method.md section 2: M_p = sum_k ((c_k - O_p) x (m_k g)) . u_p."""
    g = np.asarray(model.gravity, dtype=float)
    u, Q, _ = compliant_vectors(model, ps)
    A = np.repeat(C1, 3, axis=1)
    A -= np.repeat(msub, 3, axis=0) * Q
    gA = _gcross_cm(g, A, np.empty_like(A))
    M = u[0] * gA[0]
    M += u[1] * gA[1]
    M += u[2] * gA[2]
    return np.negative(M, out=M), A, u                             # u . (A x g)


def _runs(idx) -> tuple:
    """(first, stop, offset) of each run of consecutive values in ``idx``."""
    idx = [int(v) for v in idx]
    runs, k = [], 0
    while k < len(idx):
        j = k
        while j + 1 < len(idx) and idx[j + 1] == idx[j] + 1:
            j += 1
        runs.append((idx[k], idx[j] + 1, k))
        k = j + 1
    return tuple(runs)


def _cross_cm(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> np.ndarray:
    """a x b for component-major stacks (3, ...), written into ``out``."""
    for i, (j, k) in _CROSS_PAIRS.items():
        np.multiply(a[j], b[k], out=out[i])
        out[i] -= a[k] * b[j]
    return out


def _gcross_cm(g, w: np.ndarray, out: np.ndarray) -> np.ndarray:
    """g x w for a constant vector g and a component-major stack w (3, ...)."""
    for i, (j, k) in _CROSS_PAIRS.items():
        np.multiply(w[k], g[j], out=out[i])
        out[i] -= g[k] * w[j]
    return out


@dataclass(frozen=True, eq=False)
class _CorrectionPlan:
    """Which step columns get compliance corrections and how the sums over compliances are built.

    Rows are the corrected steps in step order. Part 0 sums over the compliances a step is distal
    to, part 1 over those it is proximal to (translations ride along there with a zero vector, so
    that rows sharing a sum stay contiguous). Rows with the same pair of sums form a group and
    share a slot holding both; each distinct sum is built once, from a smaller one.
    """

    rows: tuple              # (step, frame or -1 for the base, offset in the frame) per row, in step order
    out_runs: tuple          # ``_runs`` of the step columns the rows correct
    rot: np.ndarray          # (n_rows,) 1.0 for rotations
    n_base: int              # the first rows are base rotations
    axis_of: np.ndarray      # (n_rows - n_base,) compliant row whose axis (and A) each frame row takes
    translations: np.ndarray  # (k,) rows of translations, and their frames
    translation_frames: np.ndarray
    parent_z: tuple          # (row, frame) of gamma and b rows: the parent's z axis
    n_slots: int
    fills: tuple             # (slot, part, source slot or -1, compliance items): how each sum is made
    groups: tuple            # (row0, row1, slot): rows [row0, row1) use that slot

    def __post_init__(self) -> None:
        for value in vars(self).values():
            if isinstance(value, np.ndarray):
                read_only(value)


def correction_plan(model: RobotModel, lay: Layout, steps: np.ndarray, act: np.ndarray) -> _CorrectionPlan | None:
    """The plan for these step columns and active compliances, made once per layout and kept with it
    (under the index tuples, compared by value; the plan is immutable)."""
    key = (tuple(steps.tolist()), tuple(act.tolist()))
    if key not in lay.plans:
        lay.plans.setdefault(key, _make_correction_plan(lay, np.array(key[0], dtype=int), np.array(key[1], dtype=int)))
    return lay.plans[key]


def _make_correction_plan(lay, steps, act) -> _CorrectionPlan | None:
    rot = lay.step_is_rot[steps]
    anc = lay.anc[act][:, steps]
    desc = lay.desc[act][:, steps]
    # a proximal translation changes no moment: only rotations count as proximal
    live = (anc & rot).any(axis=0) | desc.any(axis=0)
    cols = np.nonzero(live)[0]
    cols = cols[np.argsort(steps[cols], kind="stable")]
    if not len(cols):
        return None
    rsteps = steps[cols]
    frame = lay.step_frame[rsteps]
    rows = tuple((int(s), int(f), int(s - N_BASE - N_FRAME_STEPS * f) if f >= 0 else -1) for s, f in zip(rsteps, frame))
    n_base = int(np.sum(frame == -1))
    parent_z = tuple((r, f) for r, (_, f, o) in enumerate(rows) if o in (FrameStep.GAMMA, FrameStep.B))
    tra = np.nonzero(~rot[cols])[0]
    pairs = [(frozenset(np.nonzero(desc[:, c])[0]), frozenset(np.nonzero(anc[:, c])[0])) for c in cols]
    slot_of, groups = _slot_groups(pairs)
    return _CorrectionPlan(rows=rows, out_runs=_runs(cols), rot=rot[cols].astype(float), n_base=n_base,
                           axis_of=_axis_rows(rows[n_base:]), translations=tra, translation_frames=frame[tra],
                           parent_z=parent_z, n_slots=len(slot_of), fills=_fills(slot_of), groups=groups)


# a frame step's axis is that of a compliant step of its frame (d: alpha's, r: theta's)
_SAME_AXIS = {FrameStep.BETA: FrameStep.BETA, FrameStep.ALPHA: FrameStep.ALPHA, FrameStep.D: FrameStep.ALPHA,
              FrameStep.THETA: FrameStep.THETA, FrameStep.R: FrameStep.THETA}


def _axis_rows(frame_rows) -> np.ndarray:
    """The compliant row whose axis (and A) each of ``frame_rows`` (step, frame, offset) takes."""
    return np.array([3 * f + _COMPLIANT_ROW[_SAME_AXIS.get(o, FrameStep.THETA)] for _, f, o in frame_rows], dtype=int)


def _slot_groups(pairs: list) -> tuple[dict, tuple]:
    """The slot of each distinct pair of sums (distal, proximal compliances), and the groups: runs
    of consecutive rows with the same pair, as (row0, row1, slot)."""
    slot_of: dict[tuple[frozenset, frozenset], int] = {}
    groups, r = [], 0
    while r < len(pairs):
        r1 = r + 1
        while r1 < len(pairs) and pairs[r1] == pairs[r]:
            r1 += 1
        groups.append((r, r1, slot_of.setdefault(pairs[r], len(slot_of))))
        r = r1
    return slot_of, tuple(groups)


def _fills(slot_of: dict) -> tuple:
    """How each slot's sums are made (``_CorrectionPlan.fills``): each distinct sum once, smallest
    first, from the largest one already built inside it."""
    fills = []
    for part in (0, 1):
        built: dict[frozenset, int] = {}
        for s in sorted({pair[part] for pair in slot_of}, key=len):
            users = [slot for pair, slot in slot_of.items() if pair[part] == s]
            if s:
                base: frozenset = max((t for t in built if t < s), key=len, default=frozenset())
                fills.append((users[0], part, built[base] if base else -1, tuple(int(i) for i in sorted(s - base))))
                built[s] = users[0]
                users = users[1:]
            fills += [(slot, part, built.get(s, -1), ()) for slot in users]   # copies, or zeros
    return tuple(fills)


# frame step -> row of its compliance within the frame
_COMPLIANT_ROW = {off: c for c, (off, _) in enumerate(COMPLIANT)}


def _plan_vectors(model, st, plan) -> np.ndarray:
    """(6, n_rows, N) per corrected step, on the undeformed chain: the vector dotted with the distal sum
    (``w x (C1_j - m_j Q)`` for a rotation of frame j, ``m_j w`` for a translation), then ``g x w``
    dotted with the proximal sum (zero for translations).
    Reference: docs/method.md section 3: the geometric columns' correction through the compliances."""
    ps = st.ps0
    g = np.asarray(model.gravity, dtype=float)
    n_rows, N, nb = len(plan.rows), st.M.shape[1], plan.n_base
    W = np.empty((3, n_rows, N))                  # axes
    lever = np.empty((3, n_rows, N))              # C1_j - m_j Q for rotations (anything finite for others)
    W[:, :nb] = ps.base_axes[[s for s, _, _ in plan.rows[:nb]]].T[:, :, None]
    lever[:, :nb] = W[:, :nb]
    W[:, nb:] = st.u[:, plan.axis_of]
    lever[:, nb:] = st.A[:, plan.axis_of]
    for r, j in plan.parent_z:
        parent = model.frames[j].parent
        W[:, r] = (ps.R[parent][:, :, 2].T if parent >= 0 else ps.base_rotation[:, 2:])
        if plan.rot[r]:
            np.subtract(st.C1[:, j], st.msub[j] * compliant_vectors(model, ps)[2][:, j], out=lever[:, r])
    V = np.empty((6, n_rows, N))
    _cross_cm(W, lever, V[:3])
    V[:3, :nb] = 0.0                              # the base is distal to no compliance
    V[:3, plan.translations] = W[:, plan.translations] * st.msub[plan.translation_frames]
    _gcross_cm(g, W, V[3:])
    V[3:] *= plan.rot[:, None]
    return V


def _add_corrections(model, st, plan, act, cpa, cols) -> None:
    """Add ``sum_p K_p dM_p/d(step) column_p`` to the step columns ``cols`` (S, N, rows).

    ``cpa`` (rows, P', N): component-major columns of the active compliant steps. dM_p/d(step),
    for a step of axis w:

    * proximal rotation: it turns the axis and all masses distal to p rigidly, which leaves the
      moment as if gravity turned by -w instead: dM = -u . (A x (w x g)) = (g x w) . (u x A);
    * proximal translation: nothing changes;
    * distal step (its frame j in p's subtree): only the masses distal to itself move:
      rotation dM = u . ((w x (C1_j - m_j Q)) x g) = D . (g x u) with D = w x (C1_j - m_j Q),
      translation the same with D = m_j w.

    Both are a dot product of a per-step vector with a per-p vector, so the sums over p of
    ``K_p (g x u_p) column_p`` and ``K_p (u_p x A_p) column_p`` are taken first, each distinct sum
    once, growing along the chain.
    Reference: docs/method.md section 3.
    """
    if plan not in st.cache:
        g = np.asarray(model.gravity, dtype=float)
        u = st.u[:, act] * st.ks[act][:, None]
        DA = np.empty((6,) + u.shape[1:])
        _gcross_cm(g, u, DA[:3])
        _cross_cm(u, st.A[:, act], DA[3:])
        st.cache[plan] = (DA.transpose(1, 0, 2), _plan_vectors(model, st, plan))
    DA, V = st.cache[plan]
    rows, N = cpa.shape[0], cpa.shape[2]
    T = DA[:, :, None, :] * cpa.transpose(1, 0, 2)[:, None, :, :]     # (P', 6, rows, N)
    S = np.empty((plan.n_slots, 6, rows, N))
    for slot, part, src, items in plan.fills:
        lo = 3 * part
        dst = S[slot, lo:lo + 3]
        if not items:
            dst[...] = S[src, lo:lo + 3] if src >= 0 else 0.0
            continue
        first, rest = (S[src, lo:lo + 3], items) if src >= 0 else (T[items[0], lo:lo + 3], items[1:])
        if not rest:
            dst[...] = first
            continue
        np.add(first, T[rest[0], lo:lo + 3], out=dst)
        for i in rest[1:]:
            dst += T[i, lo:lo + 3]
    corr = np.empty((len(plan.rows), rows, N))
    for r0, r1, slot in plan.groups:
        np.add.reduce(V[:, r0:r1, None, :] * S[slot][:, None], axis=0, out=corr[r0:r1])
    for c0, c1, r0 in plan.out_runs:
        for b in range(rows):
            cols[c0:c1, :, b] += corr[r0:r0 + c1 - c0, b]


def _compliant_columns(model, lay, ps, m, csel, rows) -> np.ndarray:
    """(rows, len(csel), N) component-major columns of the compliant steps ``csel`` (rows of
    ``compliant_steps``) for marker m.
    Reference: docs/method.md section 3: a rotation about u through O moves P by u x (P - O)."""
    u, Q, _ = compliant_vectors(model, ps)
    u = u[:, csel]
    lever = np.subtract(ps.P[m].T[:, None, :], Q[:, csel])
    out = np.empty((rows,) + u.shape[1:])
    _cross_cm(u, lever, out[:3])
    if rows == 6:
        out[3:] = u
    on = lay.marker_path[m, lay.compliant_steps[csel]]
    if not on.all():
        out[:, ~on] = 0.0
    return out


@dataclass(frozen=True)
class Evaluation:
    """Marker poses and, when asked, the Jacobian over the full parameter vector.

    ``positions`` (N, n_markers, 3) in W; ``rotations`` (N, n_markers, 3, 3) or None;
    ``jacobian`` (N, n_markers, 6, n_params) or None (rows: dx, dy, dz, then rotation in W);
    ``moments`` (N, 3 n_frames) gravity moments (theta, alpha, beta per frame) or None.
    Its arrays are its own, read-only.
    """

    positions: np.ndarray
    rotations: np.ndarray | None
    jacobian: np.ndarray | None
    moments: np.ndarray | None
    frames: np.ndarray | None = None

    def __post_init__(self) -> None:
        for value in vars(self).values():
            if isinstance(value, np.ndarray):
                read_only(value)


# poses per block of the step columns: smaller temporaries, served again from memory just freed
# instead of fresh pages (calibrate at 10,000 poses about 4 % faster; no change at 1,000)
COLUMN_BLOCK = 4096


def _step_columns(lay: Layout, ps: _Pass, m: int, steps: np.ndarray, rows: int = 6, out=None) -> np.ndarray:
    """(len(steps), N, rows) columns of the given steps for marker m, zero off its path.

    Column-major (one contiguous block per parameter): what the solver wants, and cheap to fill.
    ``rows`` 3 gives the position part only. ``out``: where to write them instead of a new array.
    The columns are computed component-major from the pass's rows, for the asked steps only, and
    written component by component (a strided copy, much cheaper than a transposing one), in
    blocks of poses.
    Reference: docs/method.md section 3: [u x (P - O); u] for a rotation, [u; 0] for a translation.
    """
    on = lay.marker_path[m, steps]
    is_rot = lay.step_is_rot[steps]
    rot = np.nonzero(is_rot & on)[0]
    tra = np.nonzero(~is_rot & on)[0]
    if out is None:
        out = np.empty((len(steps), ps.N, rows))
    if len(rot) + len(tra) < len(steps):
        out[~on] = 0.0
    vec = ps.vectors(lay.step_frame[steps[lay.step_frame[steps] >= 0]].tolist())
    axis, point = lay.step_rows[int(ps.orientations)]
    rows_of = (axis[steps[rot]], point[steps[rot]], lay.marker_row[m], axis[steps[tra]])
    for a in range(0, ps.N, COLUMN_BLOCK):
        _column_block(vec, rows_of, rot, tra, slice(a, a + COLUMN_BLOCK), out)
    return out


def _column_block(vec, rows_of, rot, tra, poses: slice, out) -> None:
    """``_step_columns`` at the poses ``poses``: rotations ``rot`` (axis rows, point rows, marker
    row) and translations ``tra`` (axis rows) of ``rows_of``, into ``out``. Reference: docs/method.md section 3."""
    rot_axes, rot_points, marker, tra_axes = rows_of
    rows = out.shape[2]
    if len(rot):
        u = vec[rot_axes, :, poses]                                        # (S, 3, n)
        lever = vec[rot_points, :, poses]
        np.subtract(vec[marker, :, poses], lever, out=lever)
        part, other = np.empty((2,) + u.shape[:1] + u.shape[2:])
        for c, (j, k) in _CROSS_PAIRS.items():                               # u x lever
            np.multiply(u[:, j], lever[:, k], out=part)
            np.multiply(u[:, k], lever[:, j], out=other)
            out[rot, poses, c] = np.subtract(part, other, out=part)
        for c in range(3, rows):
            out[rot, poses, c] = u[:, c - 3]
    if len(tra):
        u = vec[tra_axes, :, poses]
        for c in range(3):
            out[tra, poses, c] = u[:, c]
        if rows == 6:
            out[tra, poses, 3:] = 0.0


@dataclass
class _State:
    """One evaluation at parameters p: the kinematic pass and, with compliance, the moments."""

    ps: _Pass
    compliance: bool
    ks: np.ndarray
    ps0: _Pass | None = None
    C1: np.ndarray | None = None
    msub: np.ndarray | None = None
    M: np.ndarray | None = None
    A: np.ndarray | None = None
    u: np.ndarray | None = None
    cache: dict = field(default_factory=dict)   # what the Jacobian derives from this state
    backlash: _Backlash | None = None
    readings: np.ndarray | None = None          # (N, n_frames) the frame variables read, before transmission


@dataclass(frozen=True)
class _Backlash:
    """Where each joint rests in its lost motion at each pose: q_eff = q + b s.

    ``b`` (n_frames,) the half lost motion (0 for fixed frames); ``sides`` s (N, n_frames) in
    [-1, 1]; ``slope`` ds/dL (N, n_frames) for the gravity-sided model (None for approach-sided);
    ``loads`` L (N, n_frames), N m or N, or None.
    """

    b: np.ndarray
    sides: np.ndarray
    slope: np.ndarray | None
    loads: np.ndarray | None


def evaluate_state(model: RobotModel, lay: Layout, p: np.ndarray, qf: np.ndarray, *, compliance: bool,
                   orientations: bool, payload_mass=None, backlash: bool = False, approach=None,
                   turns=None, take=np.empty) -> _State:
    """The kinematic pass at ``p`` and readings ``qf`` (N, n_frames), with gravity moments when
    ``compliance``, and joints resting in their lost motion when ``backlash`` (``approach``
    (N, n_frames) the direction of each frame variable's last move, see ``frame_approach``;
    None: from the row order of ``qf``). ``turns``: ``joint_turns(qf)`` when the caller holds them;
    ``take``: where the passes' buffers come from (see ``kinematic_pass``). Where ``p`` holds
    transmission terms the chain is evaluated at the variables the arm reaches (``transmitted``).
    Reference: docs/method.md sections 1 and 2, docs/conventions.md (backlash, transmission)."""
    t = p[lay.transmission_params]
    if np.any(t):
        if backlash and approach is None:       # the readings' order, not the reached variables', sets sides
            approach = approach_sides(qf)
        st = _evaluate_state(model, lay, p, transmitted(model, qf, t), compliance=compliance,
                             orientations=orientations, payload_mass=payload_mass, backlash=backlash,
                             approach=approach, turns=None, take=take)
    else:
        st = _evaluate_state(model, lay, p, qf, compliance=compliance, orientations=orientations,
                             payload_mass=payload_mass, backlash=backlash, approach=approach, turns=turns, take=take)
    st.readings = qf
    return st


def transmission_basis(model: RobotModel, qf: np.ndarray) -> np.ndarray:
    """(N, n_frames, n_terms) each transmission term's function of the frame variables read ``qf``
    (N, n_frames), in the order of ``TRANSMISSION_KINDS``: q, cos q, sin q, cos 2q, sin 2q, then the
    same two harmonics of the motor angle n q (n the frame's reduction). Zero for a fixed frame.
    Reference: docs/conventions.md (transmission)."""
    moving = np.array([f.joint != "fixed" for f in model.frames])
    angles = qf[..., None] * _rates(model)                                      # (N, nf, 4)
    waves = np.stack([np.cos(angles), np.sin(angles)], axis=-1).reshape(angles.shape[:2] + (8,))
    return np.concatenate([qf[..., None], waves], axis=-1) * moving[:, None]


def transmitted(model: RobotModel, qf: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(N, n_frames) the frame variables the arm reaches, q + B(q) t, at readings ``qf`` with the
    transmission terms ``t`` (n_frames, n_terms). Reference: docs/conventions.md (transmission)."""
    return qf + np.einsum("nft,ft->nf", transmission_basis(model, qf), t)


def transmission_slope(model: RobotModel, lay: Layout, p: np.ndarray, qf: np.ndarray) -> np.ndarray:
    """(N, n_frames) d q_eff / d q: how fast each reached frame variable turns with its reading
    (1 without transmission terms). Reference: docs/conventions.md (transmission)."""
    t = p[lay.transmission_params]
    w = _rates(model)                                                            # (nf, 4)
    a = qf[..., None] * w                                                        # (N, nf, 4)
    return 1.0 + t[:, 0] + np.sum(w * (t[:, 2::2] * np.cos(a) - t[:, 1::2] * np.sin(a)), axis=-1)


def _rates(model: RobotModel) -> np.ndarray:
    """(n_frames, 4) the rates of the harmonics: 1, 2, n, 2n (n the frame's reduction ratio)."""
    n = np.array([f.reduction for f in model.frames])
    return np.stack([np.ones_like(n), 2.0 * np.ones_like(n), n, 2.0 * n], axis=-1)


def _evaluate_state(model: RobotModel, lay: Layout, p: np.ndarray, qf: np.ndarray, *, compliance: bool,
                    orientations: bool, payload_mass, backlash: bool, approach, turns, take) -> _State:
    """``evaluate_state`` at the frame variables ``qf`` the arm reaches."""
    if backlash:
        return _backlash_state(model, lay, p, qf, compliance=compliance, orientations=orientations,
                               payload_mass=payload_mass, approach=approach, turns=turns, take=take)
    turns = joint_turns(qf) if turns is None else turns
    ks = p[lay.compliant_params]
    if not compliance:
        return _State(ps=kinematic_pass(model, lay, p, qf, orientations=orientations, turns=turns, take=take),
                      compliance=False, ks=ks)
    deflects = bool(np.any(ks != 0.0))
    # with every compliance zero the deflected chain is the undeformed one: one pass serves both
    ps0 = kinematic_pass(model, lay, p, qf, orientations=orientations and not deflects, frames_only=deflects,
                         turns=turns, take=take)
    C1, msub = mass_sums(model, lay, ps0, payload_mass)
    M, A, u = joint_moments(model, ps0, C1, msub)
    if not deflects:
        return _State(ps=ps0, compliance=True, ks=ks, ps0=ps0, C1=C1, msub=msub, M=M, A=A, u=u)
    # a zero compliance deflects nothing: a scalar keeps that frame's constant part constant
    defl = [k * Mk if k else 0.0 for k, Mk in zip(ks, M)]
    ps = kinematic_pass(model, lay, p, qf, defl=[tuple(defl[3 * i:3 * i + 3]) for i in range(model.n_frames)],
                        orientations=orientations, turns=turns, take=take)
    return _State(ps=ps, compliance=True, ks=ks, ps0=ps0, C1=C1, msub=msub, M=M, A=A, u=u)


def frame_approach(model: RobotModel, approach) -> np.ndarray:
    """(N, n_frames) direction (+1, -1) of each frame variable's last move, from the joints'
    (N, n_joints) through the couplings (0 for fixed frames)."""
    return np.sign(np.asarray(approach, dtype=float) @ model.coupling_matrix.T)


def _frame_loads(model: RobotModel, lay: Layout, ps0: _Pass, M: np.ndarray, msub: np.ndarray) -> np.ndarray:
    """(N, n_frames) gravity load on each frame's joint variable on the undeformed chain ``ps0``:
    the moment about a revolute axis, the weight along a prismatic one (see ``gravity_loads``).
    Reference: docs/method.md section 2 (the moments) and docs/conventions.md (backlash)."""
    g = np.asarray(model.gravity, dtype=float)
    loads = np.zeros((M.shape[1], model.n_frames))
    for i, f in enumerate(model.frames):
        if f.joint == "revolute":
            loads[:, i] = M[3 * i]
        elif f.joint == "prismatic":
            loads[:, i] = msub[i] * (ps0.R[i][:, :, 2] @ g)
    return loads


def _backlash_state(model, lay, p, qf, *, compliance, orientations, payload_mass, approach, turns, take) -> _State:
    """The state with each joint at q + b s (docs/conventions.md, backlash). Gravity moments,
    loads and sides are taken on the undeformed chain at the readings, so neither depends on b.
    Reference: docs/conventions.md (backlash) on docs/method.md section 1."""
    N, nf = qf.shape
    moving = lay.backlash_params >= 0
    b = np.where(moving, p[np.maximum(lay.backlash_params, 0)], 0.0)
    a = approach_sides(qf) if approach is None else np.asarray(approach, dtype=float)
    gravity = model.backlash_side == "gravity"
    ks = p[lay.compliant_params] if compliance else np.zeros(len(lay.compliant_params))
    ps0 = C1 = msub = M = A = u = loads = slope = None
    if gravity or compliance:
        # the load derivatives need the steps' axes on this chain, so not frames only
        ps0 = kinematic_pass(model, lay, p, qf, orientations=False, frames_only=not gravity, turns=turns, take=take)
        C1, msub = mass_sums(model, lay, ps0, payload_mass)
        M, A, u = joint_moments(model, ps0, C1, msub)
    if gravity:
        assert ps0 is not None and M is not None and msub is not None    # made above: gravity is on
        loads = _frame_loads(model, lay, ps0, M, msub)
        F = np.array([f.backlash_friction for f in model.frames])
        w = np.array([f.backlash_width for f in model.frames])
        sides = np.tanh((loads - a * F) / w)
        slope = (1.0 - sides ** 2) / w
    else:
        sides = -a
    sides = sides * moving
    defl = None
    if compliance and np.any(ks != 0.0):
        assert M is not None                # made above: compliance is on
        d = [k * Mk if k else 0.0 for k, Mk in zip(ks, M)]
        defl = [tuple(d[3 * i:3 * i + 3]) for i in range(nf)]
    ps = kinematic_pass(model, lay, p, qf + sides * b, defl=defl, orientations=orientations, take=take)
    return _State(ps=ps, compliance=compliance, ks=ks, ps0=ps0, C1=C1, msub=msub, M=M, A=A, u=u,
                  backlash=_Backlash(b=b, sides=sides, slope=slope, loads=loads))


def jacobian_columns(model: RobotModel, lay: Layout, st: _State, cols_idx: np.ndarray, m: int,
                      rows: int = 6) -> np.ndarray:
    """(len(cols_idx), N, rows) Jacobian columns of marker m for the parameters ``cols_idx``.
    Reference: docs/method.md section 3 (J dxi, compliance columns by the chain rule)."""
    frame_of = lay.param_transmission[cols_idx]
    terms = frame_of >= 0
    if not terms.any():
        return _parameter_columns(model, lay, st, cols_idx, m, rows)
    out = np.zeros((len(cols_idx), cast(np.ndarray, st.ps.P).shape[1], rows))
    if not terms.all():
        out[~terms] = _parameter_columns(model, lay, st, cols_idx[~terms], m, rows)
    _transmission_columns(model, lay, st, cols_idx[terms], frame_of[terms], m, out, np.nonzero(terms)[0])
    return out


def _transmission_columns(model, lay, st, cols, frames, m, out, where) -> None:
    """Transmission terms' columns into ``out[where]``: q_eff = q + B(q) t, so a term's column is
    its joint's whole column (theta or r: they enter the chain as q_eff does) times its basis
    function at the readings. Reference: docs/conventions.md (transmission), docs/method.md section 3."""
    steps = lay.joint_steps[frames]
    moving = steps >= 0
    if not moving.any():
        return
    joints, slot = np.unique(lay.step_param[steps[moving]], return_inverse=True)
    joint_cols = _parameter_columns(model, lay, st, joints, m, out.shape[2])
    if "transmission_basis" not in st.cache:
        st.cache["transmission_basis"] = transmission_basis(model, cast(np.ndarray, st.readings))
    basis = st.cache["transmission_basis"]
    term = cols - lay.transmission_params[frames, 0]
    for k, c in enumerate(np.nonzero(moving)[0]):
        out[where[c]] = joint_cols[slot[k]] * basis[:, frames[c], term[c], None]


def _parameter_columns(model: RobotModel, lay: Layout, st: _State, cols_idx: np.ndarray, m: int,
                       rows: int = 6) -> np.ndarray:
    """``jacobian_columns`` of every parameter but the transmission terms."""
    if st.backlash is not None:
        return _backlash_columns(model, lay, st, cols_idx, m, rows)
    step_of = lay.param_step[cols_idx]
    is_step = step_of >= 0
    steps = step_of[is_step]
    if not st.compliance:
        if is_step.all():
            return _step_columns(lay, st.ps, m, steps, rows)
        out = np.zeros((len(cols_idx), cast(np.ndarray, st.ps.P).shape[1], rows))
        out[is_step] = _step_columns(lay, st.ps, m, steps, rows)
        return out
    out = np.empty((len(cols_idx), cast(np.ndarray, st.ps.P).shape[1], rows))
    # step columns written in place when they are one block (the usual order: geometry, then K)
    sblock = _block(is_step)
    cols = _step_columns(lay, st.ps, m, steps, rows, out=None if sblock is None else out[sblock])
    k_slot = lay.param_compliant[cols_idx]
    is_k = k_slot >= 0
    kk = k_slot[is_k]
    act = np.nonzero(st.ks)[0]
    plan = correction_plan(model, lay, steps, act) if len(act) else None
    # compliant columns needed: the active ones (corrections), then those of requested K not among them
    csel = act if plan is not None else act[:0]
    csel = np.concatenate([csel, [k for k in kk if k not in set(csel.tolist())]]).astype(int)
    cpc = _compliant_columns(model, lay, st.ps, m, csel, rows)                # (rows, len(csel), N)
    if plan is not None:
        _add_corrections(model, st, plan, act, cpc[:, :len(act)], cols)
    if sblock is None:
        out[is_step] = cols
    where = {int(c): i for i, c in enumerate(csel)}
    ki = [where[int(k)] for k in kk]
    kblock = _block(is_k)
    for b in range(rows):
        out[is_k if kblock is None else kblock, :, b] = cpc[b, ki] * cast(np.ndarray, st.M)[kk]
    rest = ~is_step & ~is_k          # backlash: not a step, nothing moves without its state
    if rest.any():
        out[rest] = 0.0
    return out


def _backlash_columns(model, lay, st, cols_idx, m, rows) -> np.ndarray:
    """Columns under backlash, q_eff = q + b s: a backlash's is its joint's column (on the
    deflected chain, without compliance corrections: the moments are taken at the readings) times
    s; under the gravity-sided model every column also gains ``b ds/dL dL/dx`` times it.
    Reference: docs/method.md section 3 and docs/conventions.md (backlash)."""
    bare = copy.copy(st)
    bare.backlash = None
    out = jacobian_columns(model, lay, bare, cols_idx, m, rows)
    bl = st.backlash
    frames = np.nonzero(lay.backlash_params >= 0)[0]
    joint_cols = _step_columns(lay, st.ps, m, lay.joint_steps[frames], rows)      # (F, N, rows)
    slot = {int(i): k for k, i in enumerate(frames)}
    fb = lay.param_backlash[cols_idx]
    for c in np.nonzero(fb >= 0)[0]:
        out[c] = bl.sides[:, fb[c], None] * joint_cols[slot[int(fb[c])]]
    if bl.slope is None:
        return out
    steps = lay.param_step[cols_idx]
    has = steps >= 0
    for i in frames:
        if bl.b[i] == 0.0 or not has.any():
            continue
        dL = _load_derivatives(model, lay, st, int(i), steps[has])                  # (S, N)
        out[has] += (bl.b[i] * bl.slope[:, i] * dL)[:, :, None] * joint_cols[slot[int(i)]][None]
    return out


def _load_derivatives(model, lay, st, i: int, steps: np.ndarray) -> np.ndarray:
    """(len(steps), N) derivative of frame i's joint load (``_frame_loads``) by each step's value,
    on the undeformed chain. Revolute, L = u . (A x g): a proximal rotation about w turns the axis
    and the distal masses rigidly, dL = w . ((u x A) x g); a distal step of frame j moves the
    masses distal to it, dL = w . ((C1_j - m_j Q) x (g x u)) for a rotation through Q, m_j w .
    (g x u) for a translation. Prismatic, L = m (u . g): dL = m w . (u x g) for a proximal
    rotation, nothing else changes it. Reference: docs/method.md section 2 and docs/conventions.md (backlash)."""
    g = np.asarray(model.gravity, dtype=float)
    ps0, row = st.ps0, 3 * i
    N = ps0.O.shape[1]
    u = st.u[:, row].T                                                              # (N, 3)
    w = ps0.U[steps]                                                                # (S, N, 3)
    rot = lay.step_is_rot[steps]
    prox = lay.anc[row, steps] & rot
    dL = np.zeros((len(steps), N))
    if model.frames[i].joint == "prismatic":
        dL[prox] = np.einsum("snk,nk->sn", w[prox], st.msub[i][:, None] * cross(u, g))
        return dL
    dL[prox] = np.einsum("snk,nk->sn", w[prox], cross(cross(u, st.A[:, row].T), g))
    gu = cross(g, u)
    for k in np.nonzero(lay.desc[row, steps])[0]:
        s, j = steps[k], lay.step_frame[steps[k]]
        if rot[k]:
            lever = st.C1[:, j].T - st.msub[j][:, None] * ps0.Q[s]
            dL[k] = np.sum(w[k] * cross(lever, gu), axis=1)
        else:
            dL[k] = st.msub[j] * np.sum(w[k] * gu, axis=1)
    return dL


def _block(mask: np.ndarray) -> slice | None:
    """The slice selecting the True entries of ``mask`` when they are consecutive, else None."""
    pos = np.nonzero(mask)[0]
    if len(pos) and pos[-1] - pos[0] == len(pos) - 1:
        return slice(int(pos[0]), int(pos[-1]) + 1)
    return None


def _names(args) -> tuple[str, ...]:
    return layout(args["model"]).names


_JOINTS = lambda args: args["model"].n_joints  # noqa: E731
_MODEL_AND_READINGS = dict(model=is_a(RobotModel), q=readings_of(), payload_mass=masses_for())


@accepts(**_MODEL_AND_READINGS, p=optional(vector_of(lambda args: len(_names(args)))), jacobian=FLAG,
         orientations=FLAG, compliance=optional(FLAG), frames=FLAG, columns=parameter_columns(_names),
         backlash=optional(FLAG), approach=optional(rows_for("q", _JOINTS)))
@one_blas_thread
def evaluate(model: RobotModel, q: np.ndarray, p: np.ndarray | None = None, *, jacobian: bool = False,
             orientations: bool = False, compliance: bool | None = None, payload_mass=None,
             frames: bool = False, columns=None, backlash: bool | None = None, approach=None) -> Evaluation:
    """Evaluate the model (or the values ``p`` in its layout) at joint readings ``q`` (N, n_joints).

    ``columns``: indices into the parameter vector of the Jacobian columns wanted (default all);
    the Jacobian's last axis then follows ``columns``.

    ``compliance``: apply gravity deflections (default: when the model has compliance) and, with
    ``jacobian``, include the compliance columns and corrections.
    ``backlash``: joints rest in their lost motion (default: when the values hold a backlash or
    backlash columns are asked for); ``approach`` (N, n_joints) the direction of each joint's last
    move (default: from the row order of ``q``, the first pose approached from the last).
    Reference: docs/method.md sections 1 to 3.

    Parameters
    ----------
    {model, q}
    p : array_like, shape (n_params,), optional
        Values in the model's parameter layout (``parameter_names``); None: the model's own.
    jacobian : bool
        Compute the identification Jacobian too.
    orientations : bool
        Compute the markers' orientations too.
    compliance : bool, optional
        Apply gravity deflections (None: when the values hold a compliance).
    {payload_mass}
    frames : bool
        Return every frame's pose too.
    columns : sequence of int, optional
        Indices into the parameter vector of the Jacobian columns wanted (None: all).
    backlash : bool, optional
        Joints rest in their lost motion (None: when the values hold a backlash or backlash columns
        are asked for).
    approach : array_like, shape (n_poses, n_joints), optional
        Direction (+1 or -1) of each joint's last move (None: from the row order of ``q``).

    Returns
    -------
    Evaluation
        Marker positions (n_poses, n_markers, 3) in W, m, and what else was asked for.
    """
    lay = layout(model)
    q = _readings(model, q)
    p = parameter_vector(model) if p is None else np.asarray(p, dtype=float)
    cols_idx = np.arange(lay.n_params) if columns is None else np.asarray(columns, dtype=int)
    if compliance is None:
        compliance = bool(np.any(p[lay.compliant_params] != 0.0))
    if backlash is None:
        backlash = _holds_backlash(lay, p) or (jacobian and bool(np.any(lay.param_backlash[cols_idx] >= 0)))
    if len(q) > LARGE_POSES and not (jacobian or frames or backlash):
        return _evaluate_in_chunks(model, q, p, orientations=orientations, compliance=compliance,
                                   payload_mass=payload_mass)
    ws = workspace(model)
    st = evaluate_state(model, lay, p, q @ model.coupling_matrix.T, compliance=compliance,
                        orientations=orientations or jacobian, payload_mass=payload_mass, backlash=backlash,
                        approach=None if approach is None else frame_approach(model, approach), take=ws.take)
    out = _evaluation(model, lay, st, cols_idx if jacobian else None, orientations=orientations or jacobian,
                      frames=frames)
    buffers = pass_buffers(st)
    del st
    ws.give(buffers)
    return out


def _readings(model: RobotModel, q) -> np.ndarray:
    """``q`` as (N, n_joints) floats; another number of columns is a ValueError."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if q.shape[1] != model.n_joints:
        raise ValueError(f"q must have {model.n_joints} columns, got {q.shape[1]}")
    return q


def _holds_backlash(lay: Layout, p: np.ndarray) -> bool:
    """Whether the values ``p`` hold a lost motion."""
    return bool(np.any(p[lay.backlash_params[lay.backlash_params >= 0]] != 0.0))


def _evaluation(model: RobotModel, lay: Layout, st: _State, cols_idx: np.ndarray | None, *, orientations: bool,
                frames: bool) -> Evaluation:
    """What ``evaluate`` returns from the state ``st``: the Jacobian's columns ``cols_idx`` (None:
    no Jacobian), the orientations and every frame's pose when asked. Copies: the evaluation's
    arrays are its own, and the passes' buffers go back to the model's workspace."""
    ps = st.ps
    J = None
    if cols_idx is not None:
        J = np.stack([jacobian_columns(model, lay, st, cols_idx, m).transpose(1, 2, 0)
                      for m in range(len(model.markers))], axis=1)
    return Evaluation(positions=cast(np.ndarray, ps.P).transpose(1, 0, 2).copy(),
                      rotations=np.stack(ps.RM, axis=1) if orientations and ps.RM else None, jacobian=J,
                      moments=None if st.M is None else st.M.T, frames=_frame_poses(ps) if frames else None)


def _frame_poses(ps: _Pass) -> np.ndarray:
    """(N, n_frames, 4, 4) every frame's pose ``X_W<frame>`` in the pass ``ps``."""
    out = np.zeros((ps.N, ps.model.n_frames, 4, 4))
    for i in range(ps.model.n_frames):
        out[:, i, :3, :3] = ps.R[i]
        out[:, i, :3, 3] = ps.O[i]
        out[:, i, 3, 3] = 1.0
    return out


def _evaluate_in_chunks(model: RobotModel, q: np.ndarray, p: np.ndarray, *, orientations: bool, compliance: bool,
                        payload_mass) -> Evaluation:
    """``evaluate`` of positions (and orientations, moments) ``CHUNK_POSES`` poses at a time, each
    chunk's pass in one buffer of the model's workspace and its results written straight into the
    outputs. The call allocates its outputs and little more: were the chunks' results gathered and
    joined, their memory (twice the outputs') would grow the C heap at each call and go back to
    the system after it, and each call would fault fresh pages in, or not, depending on what the
    process had allocated and freed before (benchmarks/bench_fk_processes.py)."""
    ws = workspace(model)
    n, nm = len(q), len(model.markers)
    positions = np.empty((n, nm, 3))
    rotations = np.empty((n, nm, 3, 3)) if orientations and nm else None
    moments = None
    for a in range(0, n, CHUNK_POSES):
        rows = slice(a, a + CHUNK_POSES)
        pm = payload_mass if np.ndim(payload_mass) == 0 else np.asarray(payload_mass)[rows]
        st = evaluate_state(model, layout(model), p, q[rows] @ model.coupling_matrix.T, compliance=compliance,
                            orientations=orientations, payload_mass=pm, backlash=False, approach=None, take=ws.take)
        positions[rows] = cast(np.ndarray, st.ps.P).transpose(1, 0, 2)
        if rotations is not None:
            for m, rm in enumerate(st.ps.RM):
                rotations[rows, m] = rm
        if st.M is not None:
            moments = np.empty((n, len(st.M))) if moments is None else moments
            moments[rows] = st.M.T
        buffers = pass_buffers(st)
        del st
        ws.give(buffers)
    return Evaluation(positions=positions, rotations=rotations, jacobian=None, moments=moments)


@accepts(**_MODEL_AND_READINGS)
@one_blas_thread
def gravity_loads(model: RobotModel, q, *, payload_mass=None) -> np.ndarray:
    """Generalised gravity force on each joint (N, n_joints): N m for revolute, N for prismatic.

    Positive where gravity would move the joint's reading upwards: for a revolute frame, the
    moment about its joint axis of every mass distal to it; for a prismatic one, that mass times
    gravity's component along the axis. Couplings map frame loads to joints by virtual work
    (``C^T``). Computed on the undeformed chain, as the compliance moments are.
    Reference: docs/method.md section 2.

    Parameters
    ----------
    {model, q, payload_mass}

    Returns
    -------
    numpy.ndarray, shape (n_poses, n_joints)
        The load on each joint, N m or N.
    """
    return loads_at(model, layout(model), parameter_vector(model), _readings(model, q), payload_mass=payload_mass)


def loads_at(model: RobotModel, lay: Layout, p: np.ndarray, q: np.ndarray, *, payload_mass=None) -> np.ndarray:
    """``gravity_loads`` of ``model`` with its values set to ``p`` (compliances ignored), for a caller
    that holds the model's layout ``lay``: (N, n_joints) at readings ``q`` (N, n_joints). One pass
    of the frames alone (no marker, no step axis): a joint's moment is taken about its axis through
    the frame's origin, which lies on it."""
    qf = q @ model.coupling_matrix.T
    t = p[lay.transmission_params]
    ps = kinematic_pass(model, lay, p, transmitted(model, qf, t) if np.any(t) else qf, frames_only=True)
    C1, msub = mass_sums(model, lay, ps, payload_mass)
    frames = ps._frames()
    z, origin = frames[:, FrameRow.Z_AXIS], frames[:, FrameRow.ORIGIN]                  # (n_frames, 3, N)
    g = np.asarray(model.gravity, dtype=float)
    A = C1.transpose(1, 0, 2) - msub[:, None] * origin       # first moments about each origin
    w = _gcross_cm(g, z.transpose(1, 0, 2), np.empty((3,) + msub.shape)).transpose(1, 0, 2)   # g x z
    kind = np.array([f.joint for f in model.frames])
    # revolute: (A x g) . z = A . (g x z); prismatic: the weight along the axis
    loads = np.where((kind == "revolute")[:, None], np.einsum("fcn,fcn->fn", A, w),
                     np.where((kind == "prismatic")[:, None], msub * np.einsum("fcn,c->fn", z, g), 0.0))
    return loads.T @ model.coupling_matrix


@accepts(**_MODEL_AND_READINGS, frames=FLAG)
def forward_kinematics(model: RobotModel, q, *, frames: bool = False, payload_mass=None) -> Evaluation:
    """Marker positions (N, n_markers, 3) and orientations in W at readings ``q`` (N, n_joints).

    With ``frames=True`` also every frame's pose ``X_W<frame>`` as (N, n_frames, 4, 4).
    Reference: docs/method.md section 1.

    Parameters
    ----------
    {model, q}
    frames : bool
        Return every frame's pose too.
    {payload_mass}

    Returns
    -------
    Evaluation
        ``positions`` (n_poses, n_markers, 3) and ``rotations`` (n_poses, n_markers, 3, 3) in W.

    >>> import numpy as np
    >>> from robocal.kinematics import serial_model
    >>> m = serial_model("r", [dict(joint="revolute")], markers=[("tool", (1.0, 0, 0))])
    >>> forward_kinematics(m, [[np.pi / 2]]).positions.round(12)
    array([[[0., 1., 0.]]])
    """
    return evaluate(model, q, orientations=True, frames=frames, payload_mass=payload_mass)


@accepts(**_MODEL_AND_READINGS, compliance=optional(FLAG), columns=parameter_columns(_names, by_name=True))
def jacobian(model: RobotModel, q, *, compliance: bool | None = None, payload_mass=None,
             columns=None) -> np.ndarray:
    """Identification Jacobian (N, n_markers, 6, n_params) over ``parameter_names(model)``.

    ``columns``: parameter indices or names to compute (default all, in layout order).
    Reference: docs/method.md section 3.

    Parameters
    ----------
    {model, q}
    compliance : bool, optional
        Include gravity deflections and the compliance columns (None: when the model has compliance).
    {payload_mass}
    columns : sequence of int or str, optional
        Parameter indices or names of the columns computed (None: all, in layout order).

    Returns
    -------
    numpy.ndarray, shape (n_poses, n_markers, 6, n_columns)
        Derivatives of each marker's position (m) and small rotation (rad) by each parameter.
    """
    if columns is not None:
        names = layout(model).names
        columns = [names.index(c) if isinstance(c, str) else int(c) for c in columns]
    return evaluate(model, q, jacobian=True, compliance=compliance, payload_mass=payload_mass,
                    columns=columns).jacobian
