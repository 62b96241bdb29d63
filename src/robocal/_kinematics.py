"""Forward kinematics and the identification Jacobian: one engine for every parameter family.

Every placement in the robot is a sequence of elementary motions ("steps"): a rotation about, or a
translation along, a coordinate axis of the frame reached so far.

* base (W -> frame 0): Trans(x_W, x) Trans(y_W, y) Trans(z_W, z) R_ref Rot(x, rx) Rot(y, ry) Rot(z, rz)
* frame j (parent -> j): Rot(z, gamma) Trans(z, b) Rot(y, beta) Rot(x, alpha) Trans(x, d)
  Rot(z, theta) Trans(z, r)
* marker (its frame -> marker): Trans(x, x) Trans(y, y) Trans(z, z) R_ref Rot(x, rx) Rot(y, ry) Rot(z, rz)

The derivative of a marker's pose with respect to a step's value is geometric: for a rotation about
unit axis u through point O it is ``[u x (P - O); u]``, for a translation along u it is ``[u; 0]``,
all in the measurement frame W (METHOD.md section 3). One pass over the steps, vectorised over
poses and looping over frames, gives positions, orientations and every column.

Compliance (METHOD.md section 2): theta, alpha and beta of frame i deflect by ``K * M``, M the
gravity moment about that step's own axis of every mass distal to it, computed on the undeformed
chain at the current parameters. Geometric columns then gain ``sum_p K_p dM_p/dx * column_p``, with
dM/dx from rigid-motion identities (see ``_moment_derivatives``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ._model import BASE_KINDS, FRAME_KINDS, MARKER_KINDS, RobotModel

N_BASE = len(BASE_KINDS)
N_FRAME = len(FRAME_KINDS)
N_MARKER = len(MARKER_KINDS)
# offsets of the geometric steps inside a frame's block (same order as FRAME_KINDS)
GAMMA, B, BETA, ALPHA, D, THETA, R = range(7)
K_THETA, K_ALPHA, K_BETA = 7, 8, 9
# (step offset deflected, compliance offset) pairs
COMPLIANT = ((THETA, K_THETA), (ALPHA, K_ALPHA), (BETA, K_BETA))
_ROT_PAIRS = {0: (1, 2), 1: (2, 0), 2: (0, 1)}


def _rot(E, axis, angle):
    """Frame columns E=[e0,e1,e2] turned by Rot(axis, angle) about their own axis (right product)."""
    i, j = _ROT_PAIRS[axis]
    c = np.cos(angle)
    s = np.sin(angle)
    if np.ndim(c):
        c = c[:, None]
        s = s[:, None]
    E = list(E)
    ei, ej = E[i], E[j]
    E[i] = ei * c + ej * s
    E[j] = ej * c - ei * s
    return E


def _rot_matrix(axis, angle) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    if axis == 0:
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == 1:
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


@dataclass(frozen=True)
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


def parameter_names(model: RobotModel) -> tuple[str, ...]:
    """Names of the full parameter vector: ``base.x``..., ``<frame>.<kind>``, ``<marker>.<kind>``."""
    return layout(model).names


@lru_cache(maxsize=64)
def layout(model: RobotModel) -> Layout:
    nf, nm = model.n_frames, len(model.markers)
    names = [f"base.{k}" for k in BASE_KINDS]
    frame0 = []
    for f in model.frames:
        frame0.append(len(names))
        names += [f"{f.name}.{k}" for k in FRAME_KINDS]
    marker0 = []
    for m in model.markers:
        marker0.append(len(names))
        names += [f"{m.name}.{k}" for k in MARKER_KINDS]

    step_param, step_is_rot, step_frame = [], [], []
    for k in range(N_BASE):
        step_param.append(k)
        step_is_rot.append(k >= 3)
        step_frame.append(-1)
    for i in range(nf):
        for k in range(7):
            step_param.append(frame0[i] + k)
            step_is_rot.append(k in (GAMMA, BETA, ALPHA, THETA))
            step_frame.append(i)
    for m in range(nm):
        for k in range(N_MARKER):
            step_param.append(marker0[m] + k)
            step_is_rot.append(k >= 3)
            step_frame.append(-2 - m)
    step_param = np.array(step_param)
    step_frame = np.array(step_frame)
    n_steps = len(step_param)

    ancestors = np.zeros((nf, nf), dtype=bool)  # [i, k]: k is i or an ancestor of i
    for i, f in enumerate(model.frames):
        ancestors[i, i] = True
        if f.parent >= 0:
            ancestors[i] |= ancestors[f.parent]
    subtree = ancestors.T.copy()  # [i, k]: k in subtree of i

    def frame_steps(i):
        return np.arange(N_BASE + 7 * i, N_BASE + 7 * i + 7)

    marker_path = np.zeros((nm, n_steps), dtype=bool)
    for m, mk in enumerate(model.markers):
        marker_path[m, :N_BASE] = True
        for k in np.nonzero(ancestors[mk.frame])[0]:
            marker_path[m, frame_steps(k)] = True
        s0 = N_BASE + 7 * nf + N_MARKER * m
        marker_path[m, s0:s0 + N_MARKER] = True

    csteps, cparams = [], []
    anc = np.zeros((3 * nf, n_steps), dtype=bool)
    desc = np.zeros((3 * nf, n_steps), dtype=bool)
    for i in range(nf):
        for c, (off, koff) in enumerate(COMPLIANT):
            row = 3 * i + c
            s = N_BASE + 7 * i + off
            csteps.append(s)
            cparams.append(frame0[i] + koff)
            anc[row, :N_BASE] = True
            for k in np.nonzero(ancestors[i])[0]:
                if k != i:
                    anc[row, frame_steps(k)] = True
            own = frame_steps(i)
            anc[row, own[own <= s]] = True
            desc[row, own[own > s]] = True
            for k in np.nonzero(subtree[i])[0]:
                if k != i:
                    desc[row, frame_steps(k)] = True
    return Layout(
        names=tuple(names), n_params=len(names), frame0=np.array(frame0, dtype=int),
        marker0=np.array(marker0, dtype=int), step_param=step_param,
        step_is_rot=np.array(step_is_rot), step_frame=step_frame, marker_path=marker_path,
        compliant_steps=np.array(csteps, dtype=int), compliant_params=np.array(cparams, dtype=int),
        anc=anc, desc=desc, subtree=subtree,
    )


def parameter_vector(model: RobotModel) -> np.ndarray:
    """The model's values in the layout of ``parameter_names`` (rotation corrections are 0)."""
    lay = layout(model)
    p = np.zeros(lay.n_params)
    p[0:3] = model.base_position
    for i, f in enumerate(model.frames):
        p[lay.frame0[i]:lay.frame0[i] + N_FRAME] = [getattr(f, k) for k in FRAME_KINDS]
    for m, mk in enumerate(model.markers):
        p[lay.marker0[m]:lay.marker0[m] + 3] = mk.position
    return p


def _small_rotation(rx, ry, rz) -> np.ndarray:
    return _rot_matrix(0, rx) @ _rot_matrix(1, ry) @ _rot_matrix(2, rz)


def _as_tuple3x3(R) -> tuple:
    return tuple(tuple(float(v) for v in row) for row in R)


def model_from_vector(model: RobotModel, p: np.ndarray) -> RobotModel:
    """A new model holding the values ``p`` (rotation corrections composed into stored rotations)."""
    from dataclasses import replace

    lay = layout(model)
    p = np.asarray(p, dtype=float)
    Rb = np.asarray(model.base_rotation) @ _small_rotation(*p[3:6])
    frames = tuple(
        replace(f, **{k: float(p[lay.frame0[i] + j]) for j, k in enumerate(FRAME_KINDS)})
        for i, f in enumerate(model.frames)
    )
    markers = []
    for m, mk in enumerate(model.markers):
        q = p[lay.marker0[m]:lay.marker0[m] + N_MARKER]
        R = np.asarray(mk.rotation) @ _small_rotation(*q[3:6])
        markers.append(replace(mk, position=tuple(float(v) for v in q[:3]), rotation=_as_tuple3x3(R)))
    return model.replace(
        base_position=tuple(float(v) for v in p[0:3]), base_rotation=_as_tuple3x3(Rb),
        frames=frames, markers=tuple(markers),
    )


@dataclass(frozen=True)
class _Pass:
    E: list          # per frame [e0, e1, e2] (N, 3) each
    O: list          # per frame origin (N, 3)
    U: np.ndarray    # (n_steps, N, 3) step axes
    Q: np.ndarray    # (n_steps, N, 3) points on rotation axes
    P: np.ndarray    # (n_markers, N, 3) marker positions
    RM: list         # per marker [e0, e1, e2] orientation columns


def _kinematic_pass(model: RobotModel, lay: Layout, p: np.ndarray, qf: np.ndarray, defl=None,
                    orientations: bool = False) -> _Pass:
    N = qf.shape[0]
    n_steps = len(lay.step_param)
    U = np.zeros((n_steps, N, 3))
    Q = np.zeros((n_steps, N, 3))
    # base: translations along W's axes, then the reference rotation and small corrections
    U[0, :, 0] = 1.0
    U[1, :, 1] = 1.0
    U[2, :, 2] = 1.0
    Ob = np.broadcast_to(p[0:3], (N, 3))
    Rref = np.asarray(model.base_rotation, dtype=float)
    Eb = [np.broadcast_to(Rref[:, k], (N, 3)) for k in range(3)]
    for k in range(3):
        U[3 + k] = Eb[k]
        Q[3 + k] = Ob
        if p[3 + k] != 0.0:
            Eb = _rot(Eb, k, p[3 + k])
    E_frames: list = [None] * model.n_frames
    O_frames: list = [None] * model.n_frames
    for i, f in enumerate(model.frames):
        if f.parent < 0:
            E, O = Eb, Ob
        else:
            E, O = E_frames[f.parent], O_frames[f.parent]
        s0 = N_BASE + 7 * i
        v = p[lay.frame0[i]:lay.frame0[i] + 7]
        q = qf[:, i]
        d_th = d_al = d_be = 0.0
        if defl is not None:
            d_th, d_al, d_be = defl[i]
        # gamma, b
        U[s0 + GAMMA] = E[2]
        Q[s0 + GAMMA] = O
        if v[GAMMA] != 0.0:
            E = _rot(E, 2, v[GAMMA])
        U[s0 + B] = E[2]
        if v[B] != 0.0:
            O = O + v[B] * E[2]
        # beta, alpha
        U[s0 + BETA] = E[1]
        Q[s0 + BETA] = O
        if v[BETA] != 0.0 or np.ndim(d_be):
            E = _rot(E, 1, v[BETA] + d_be)
        U[s0 + ALPHA] = E[0]
        Q[s0 + ALPHA] = O
        if v[ALPHA] != 0.0 or np.ndim(d_al):
            E = _rot(E, 0, v[ALPHA] + d_al)
        # d
        U[s0 + D] = E[0]
        if v[D] != 0.0:
            O = O + v[D] * E[0]
        # theta, r (the joint variable moves one of them)
        U[s0 + THETA] = E[2]
        Q[s0 + THETA] = O
        th = v[THETA] + d_th + (q if f.joint == "revolute" else 0.0)
        if np.ndim(th) or th != 0.0:
            E = _rot(E, 2, th)
        U[s0 + R] = E[2]
        rr = v[R] + (q if f.joint == "prismatic" else 0.0)
        if np.ndim(rr) or rr != 0.0:
            O = O + (rr[:, None] if np.ndim(rr) else rr) * E[2]
        E_frames[i] = E
        O_frames[i] = np.broadcast_to(O, (N, 3))
    P = np.zeros((len(model.markers), N, 3))
    RM = []
    for m, mk in enumerate(model.markers):
        E, O = E_frames[mk.frame], O_frames[mk.frame]
        s0 = N_BASE + 7 * model.n_frames + N_MARKER * m
        v = p[lay.marker0[m]:lay.marker0[m] + N_MARKER]
        for k in range(3):
            U[s0 + k] = E[k]
        Pm = O + v[0] * E[0] + v[1] * E[1] + v[2] * E[2]
        P[m] = Pm
        if orientations:
            Rm = np.asarray(mk.rotation, dtype=float)
            Em = [E[0] * Rm[0, c] + E[1] * Rm[1, c] + E[2] * Rm[2, c] for c in range(3)]
            for k in range(3):
                U[s0 + 3 + k] = Em[k]
                Q[s0 + 3 + k] = Pm
                if v[3 + k] != 0.0:
                    Em = _rot(Em, k, v[3 + k])
            RM.append(Em)
    return _Pass(E=E_frames, O=O_frames, U=U, Q=Q, P=P, RM=RM)


def _mass_sums(model: RobotModel, lay: Layout, ps: _Pass, payload_mass):
    """First moments ``C1`` (n_frames, N, 3) and masses ``msub`` (n_frames, N) of every subtree."""
    nf = model.n_frames
    N = ps.P.shape[1]
    own_c1 = np.zeros((nf, N, 3))
    own_m = np.zeros((nf, N))
    for i, f in enumerate(model.frames):
        if f.mass > 0:
            E, O = ps.E[i], ps.O[i]
            c = O + f.com[0] * E[0] + f.com[1] * E[1] + f.com[2] * E[2]
            own_c1[i] += f.mass * c
            own_m[i] += f.mass
    pl = model.payload
    pm = pl.mass if payload_mass is None else payload_mass
    if np.any(np.asarray(pm) > 0):
        k = pl.frame if pl.frame >= 0 else nf - 1
        E, O = ps.E[k], ps.O[k]
        c = O + pl.com[0] * E[0] + pl.com[1] * E[1] + pl.com[2] * E[2]
        pm = np.broadcast_to(np.asarray(pm, dtype=float), (N,))
        own_c1[k] += pm[:, None] * c
        own_m[k] += pm
    C1 = np.einsum("ik,kna->ina", lay.subtree.astype(float), own_c1)
    msub = lay.subtree.astype(float) @ own_m
    return C1, msub


def _moments(model, lay, ps, C1, msub):
    """Gravity moments ``M`` (3 n_frames, N) about each compliant step's axis, and ``A = C1 - m O``."""
    g = np.asarray(model.gravity, dtype=float)
    frame_of = np.repeat(np.arange(model.n_frames), 3)
    u = ps.U[lay.compliant_steps]                     # (P, N, 3)
    A = C1[frame_of] - msub[frame_of][..., None] * ps.Q[lay.compliant_steps]
    M = np.einsum("pna,pna->pn", u, np.cross(A, g))
    return M, A, u


def _moment_derivatives(model, lay, ps, C1, msub, A, u):
    """dM_p/d(step value) for every compliant p and every step: (P, N, n_steps).

    A proximal rotation (axis w) turns the axis and all masses distal to p rigidly; that leaves the
    moment as if gravity turned by -w instead: dM = -u . (A x (w x g)). A proximal translation
    changes nothing. A distal step moves only the masses distal to itself (subtree of its frame j):
    rotation dM = u . ((w x (C1_j - m_j Q)) x g), translation dM = u . ((m_j w) x g).
    """
    g = np.asarray(model.gravity, dtype=float)
    n_steps = len(lay.step_param)
    robot_steps = np.nonzero(lay.step_frame >= -1)[0]
    W = ps.U[robot_steps]                                      # (S', N, 3)
    rot = lay.step_is_rot[robot_steps]
    frame = lay.step_frame[robot_steps]
    # proximal part
    wg = np.cross(W, g)                                        # (S', N, 3)
    wg[~rot] = 0.0
    uxA = np.cross(u, A)                                       # (P, N, 3)
    d_anc = -np.einsum("sna,pna->psn", wg, uxA)
    # distal part: D_s = w x (C1_j - m_j Q) for rotations, m_j w for translations
    fj = np.where(frame >= 0, frame, 0)
    Bv = C1[fj] - msub[fj][..., None] * ps.Q[robot_steps]
    Dv = np.where(rot[:, None, None], np.cross(W, Bv), msub[fj][..., None] * W)
    Dv[frame < 0] = 0.0
    gxu = np.cross(g, u)                                       # (P, N, 3)
    d_desc = np.einsum("sna,pna->psn", Dv, gxu)
    out = np.zeros((u.shape[0], u.shape[1], n_steps))
    anc = lay.anc[:, robot_steps]
    desc = lay.desc[:, robot_steps]
    out[:, :, robot_steps] = np.where(anc[:, None, :], d_anc.transpose(0, 2, 1), 0.0) + \
        np.where(desc[:, None, :], d_desc.transpose(0, 2, 1), 0.0)
    return out


@dataclass(frozen=True)
class Evaluation:
    """Marker poses and, when asked, the Jacobian over the full parameter vector.

    ``positions`` (N, n_markers, 3) in W; ``rotations`` (N, n_markers, 3, 3) or None;
    ``jacobian`` (N, n_markers, 6, n_params) or None (rows: dx, dy, dz, then rotation in W);
    ``moments`` (N, 3 n_frames) gravity moments (theta, alpha, beta per frame) or None.
    """

    positions: np.ndarray
    rotations: np.ndarray | None
    jacobian: np.ndarray | None
    moments: np.ndarray | None
    frames: np.ndarray | None = None


def _step_columns(lay: Layout, ps: _Pass, m: int) -> np.ndarray:
    """(N, 6, n_steps) columns of every step for marker m (zero off its path)."""
    U, Q = ps.U, ps.Q
    P = ps.P[m]
    lin = np.where(lay.step_is_rot[:, None, None], np.cross(U, P[None] - Q), U)
    ang = np.where(lay.step_is_rot[:, None, None], U, 0.0)
    cols = np.concatenate([lin, ang], axis=2)                   # (S, N, 6)
    cols[~lay.marker_path[m]] = 0.0
    return cols.transpose(1, 2, 0)


def evaluate(model: RobotModel, q: np.ndarray, p: np.ndarray | None = None, *, jacobian: bool = False,
             orientations: bool = False, compliance: bool | None = None, payload_mass=None,
             frames: bool = False) -> Evaluation:
    """Evaluate the model (or the values ``p`` in its layout) at joint readings ``q`` (N, n_joints).

    ``compliance``: apply gravity deflections (default: when the model has compliance) and, with
    ``jacobian``, include the compliance columns and corrections.
    """
    lay = layout(model)
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if q.shape[1] != model.n_joints:
        raise ValueError(f"q must have {model.n_joints} columns, got {q.shape[1]}")
    p = parameter_vector(model) if p is None else np.asarray(p, dtype=float)
    qf = q @ model.coupling_matrix.T
    ks = p[lay.compliant_params]
    if compliance is None:
        compliance = bool(np.any(ks != 0.0))
    need_or = orientations or jacobian
    M = None
    if compliance:
        ps0 = _kinematic_pass(model, lay, p, qf, orientations=False)
        C1, msub = _mass_sums(model, lay, ps0, payload_mass)
        M, A, u = _moments(model, lay, ps0, C1, msub)
        defl = (ks[:, None] * M).reshape(model.n_frames, 3, -1)
        defl_list = [tuple(defl[i]) for i in range(model.n_frames)]
        ps = _kinematic_pass(model, lay, p, qf, defl=defl_list, orientations=need_or)
    else:
        ps = _kinematic_pass(model, lay, p, qf, orientations=need_or)
    positions = ps.P.transpose(1, 0, 2)
    rotations = None
    if need_or and ps.RM:
        rotations = np.stack([np.stack(Em, axis=-1) for Em in ps.RM], axis=1)
    J = None
    if jacobian:
        N = q.shape[0]
        J = np.zeros((N, len(model.markers), 6, lay.n_params))
        if compliance:
            dM = _moment_derivatives(model, lay, ps0, C1, msub, A, u)     # (P, N, S)
            kdM = ks[:, None, None] * dM
        for m in range(len(model.markers)):
            cols = _step_columns(lay, ps, m)                            # (N, 6, S)
            Jm = cols.copy()
            if compliance:
                cp = cols[:, :, lay.compliant_steps]                       # (N, 6, P)
                Jm += np.einsum("nap,pns->nas", cp, kdM)
                J[:, m][:, :, lay.compliant_params] = cp * M.T[:, None, :]
            J[:, m][:, :, lay.step_param] = Jm
    frames_out = None
    if frames:
        frames_out = np.zeros((q.shape[0], model.n_frames, 4, 4))
        for i in range(model.n_frames):
            frames_out[:, i, :3, :3] = np.stack(ps.E[i], axis=-1)
            frames_out[:, i, :3, 3] = ps.O[i]
            frames_out[:, i, 3, 3] = 1.0
    return Evaluation(positions=positions, rotations=rotations, jacobian=J,
                      moments=None if M is None else M.T, frames=frames_out)


def forward_kinematics(model: RobotModel, q, *, frames: bool = False, payload_mass=None) -> Evaluation:
    """Marker positions (N, n_markers, 3) and orientations in W at readings ``q`` (N, n_joints).

    With ``frames=True`` also every frame's pose ``X_W<frame>`` as (N, n_frames, 4, 4).

    >>> import numpy as np
    >>> from robocal._model import serial_model
    >>> m = serial_model("r", [dict(joint="revolute")], markers=[("tool", (1.0, 0, 0))])
    >>> forward_kinematics(m, [[np.pi / 2]]).positions.round(12)
    array([[[0., 1., 0.]]])
    """
    return evaluate(model, q, orientations=True, frames=frames, payload_mass=payload_mass)


def jacobian(model: RobotModel, q, *, compliance: bool | None = None, payload_mass=None) -> np.ndarray:
    """Identification Jacobian (N, n_markers, 6, n_params) over ``parameter_names(model)``."""
    return evaluate(model, q, jacobian=True, compliance=compliance, payload_mass=payload_mass).jacobian
