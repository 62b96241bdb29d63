"""Contact observations beside measured points: residuals and exact Jacobians, alone or with a tracker.

Joint-only recordings (``Contacts``) say where the marker was relative to things the fit does not
know: a socket's point, a plane. Those are nuisance parameters appended to the robot's parameter
vector, so a problem's full vector is ``[robot parameters (layout order); nuisance]``. Every
observation is a function of marker positions, so its Jacobian is the chain rule applied to the
marker position rows of ``_kinematics`` plus the nuisance columns. Each row is divided by its stated
standard deviation: rows of every kind are then in the same unit (standard deviations) and can be
stacked in one fit.

Row kinds, in the order rows are stacked: tracker positions and rotations (``Problem``), socket
rows (3 per pose: marker minus point), plane rows (1 per pose: signed distance to the plane), ball
bars (1 per pair: distance minus length), known distances between sockets (1 per placement and
pair). An unknown plane is ``n . x = d`` with ``n`` the unit vector along ``n0 + a t1 + b t2``: ``n0``
the plane's normal fitted to the starting model's points, ``t1, t2`` perpendicular to it; its
nuisance parameters are ``a, b, d``.
"""

from __future__ import annotations

import copy
from dataclasses import replace
from typing import Any

import numpy as np

from .._base.arrays import frozen, read_only
from .._base.errors import InputError
from .._base.linalg import r_factor
from .._model.contacts import Contacts
from .._model.kinematics import evaluate, evaluate_state, frame_approach, jacobian_columns, joint_turns, layout
from .._model.measurements import Measurements, Noise, approach_sides
from .._model.parameters import has_backlash_parameters, parameter_vector
from .._model.robot import RobotModel
from .problem import Problem

ROW_KINDS = ("position", "rotation", "socket", "plane", "bar", "distance")


def _tangents(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors perpendicular to the unit vector ``n`` and to each other."""
    a = np.eye(3)[int(np.argmin(np.abs(n)))]
    t1 = np.cross(n, a)
    t1 /= np.linalg.norm(t1)
    return t1, np.cross(n, t1)


def _contact_targets(contacts: Contacts, X: np.ndarray) -> np.ndarray:
    """(n_rows, 3) where each row's marker meets its contact exactly, near ``X``: a socket's rows at
    their centroid, a plane's projected onto it (the known one, else the best-fitting), bars as they are."""
    T = X.copy()
    for g in contacts.groups("socket"):
        T[g.rows] = X[g.rows].mean(axis=0)
    for g in contacts.groups("plane"):
        kp = contacts.known_plane(g.target)
        c = X[g.rows].mean(axis=0)
        n = np.linalg.svd(X[g.rows] - c)[2][-1] if kp is None else np.asarray(kp.normal)
        T[g.rows] -= np.outer(X[g.rows] @ n - (n @ c if kp is None else kp.offset), n)
    return T


def met_readings(model: RobotModel, contacts: Contacts, marker_idx: np.ndarray, iterations: int = 3,
                 h: float = 1e-7) -> np.ndarray:
    """Readings near the contacts' at which ``model`` meets every contact exactly (least-norm
    Newton steps on the joints; the marker Jacobian over the readings by forward differences)."""
    rows = np.arange(contacts.n_rows)
    q = contacts.q.copy()
    T = _contact_targets(contacts, evaluate(model, q).positions[rows, marker_idx])
    for _ in range(iterations):
        P = evaluate(model, q).positions[rows, marker_idx]
        J = np.stack([(evaluate(model, q + h * e).positions[rows, marker_idx] - P) / h
                      for e in np.eye(model.n_joints)], axis=2)
        JJt = J @ J.transpose(0, 2, 1) + 1e-12 * np.eye(3)      # damped: a pose near a singularity stays put
        q = q + (J.transpose(0, 2, 1) @ np.linalg.solve(JJt, (T - P)[..., None]))[..., 0]
    return q


class _At:
    """One evaluation point shared by every block: the full vector ``p``, the robot's part, the
    nuisance part, and (made when a block first asks) the contact rows' marker positions ``P``
    (n_rows, 3) and their Jacobian ``Jm`` (n_rows, 3, n_free_robot); ``k`` free robot columns then
    ``nn`` nuisance columns."""

    def __init__(self, problem: ContactProblem, p: np.ndarray):
        self.problem, self.p = problem, p
        self.robot, self.nu = p[:problem.n_robot], p[problem.n_robot:]
        self.k, self.nn = len(problem.robot_idx), problem.n_nuisance
        self._P: np.ndarray | None = None
        self._Jm: np.ndarray | None = None

    @property
    def P(self) -> np.ndarray:
        if self._P is None:
            self._P = self.problem._positions(self.robot)
        return self._P

    @property
    def Jm(self) -> np.ndarray:
        if self._Jm is None:
            self._Jm = self.problem.marker_jacobian(self.robot)
        return self._Jm

    def zeros(self, *shape: int) -> np.ndarray:
        return np.zeros((*shape, self.k + self.nn))


class _Block:
    """One kind of observation over some rows: its unweighted ``errors`` (m), the standard deviations
    ``sigma`` they are divided by (one per observation), and the weighted Jacobian of
    ``errors / sigma`` over the free robot columns then every nuisance column. ``kind`` names it in
    ``ROW_KINDS``; ``width`` is the number of rows per observation (3 for a socket's marker)."""

    kind = ""
    width = 1
    sigma: np.ndarray

    @property
    def n_rows(self) -> int:
        return self.width * len(self.sigma)

    def errors(self, at: _At) -> np.ndarray:
        raise NotImplementedError

    def residuals(self, at: _At) -> np.ndarray:
        e = self.errors(at)
        return (e / (self.sigma[:, None] if self.width > 1 else self.sigma)).ravel()

    def jacobian(self, at: _At) -> np.ndarray:
        raise NotImplementedError


class SocketBlock(_Block):
    """The marker seated in one socket: marker minus the socket's unknown point (nuisance columns
    ``col``..``col + 2``), 3 rows per seating."""

    kind, width = "socket", 3

    def __init__(self, rows: np.ndarray, col: int, sigma: np.ndarray):
        self.rows, self.col, self.sigma = rows, col, sigma

    def point(self, at: _At) -> np.ndarray:
        return at.nu[self.col:self.col + 3]

    def errors(self, at: _At) -> np.ndarray:
        return at.P[self.rows] - self.point(at)

    def jacobian(self, at: _At) -> np.ndarray:
        B = at.zeros(len(self.rows), 3)         # d(P - c)/dp, -I on the point
        B[:, :, :at.k] = at.Jm[self.rows]
        B[:, :, at.k + self.col:at.k + self.col + 3] = -np.eye(3)
        return (B / self.sigma[:, None, None]).reshape(-1, at.k + at.nn)


class PlaneBlock(_Block):
    """The marker on an unknown plane ``n . x = d`` (nuisance ``a, b, d`` at ``col``): the signed
    distance, one row per contact; ``axes``: the plane's starting normal and two tangents."""

    kind = "plane"

    def __init__(self, rows: np.ndarray, col: int, axes: tuple, sigma: np.ndarray):
        self.rows, self.col, self.axes, self.sigma = rows, col, axes, sigma

    def plane(self, at: _At):
        """Unit normal, offset and the derivatives of the normal over (a, b)."""
        n0, t1, t2 = self.axes
        a, b, d = at.nu[self.col:self.col + 3]
        v = n0 + a * t1 + b * t2
        L = np.linalg.norm(v)
        n = v / L
        return n, d, [(t - n * (n @ t)) / L for t in (t1, t2)]

    def errors(self, at: _At) -> np.ndarray:
        n, d, _ = self.plane(at)
        return at.P[self.rows] @ n - d

    def jacobian(self, at: _At) -> np.ndarray:
        n, _, dn = self.plane(at)                 # n on the robot, P dn and -1 on the plane
        B = at.zeros(len(self.rows))
        B[:, :at.k] = np.einsum("j,njk->nk", n, at.Jm[self.rows])
        col = at.k + self.col
        B[:, col] = at.P[self.rows] @ dn[0]
        B[:, col + 1] = at.P[self.rows] @ dn[1]
        B[:, col + 2] = -1.0
        return B / self.sigma[:, None]


class KnownPlaneBlock(_Block):
    """The marker on a plane known in W: the signed distance, robot columns only."""

    kind = "plane"

    def __init__(self, rows: np.ndarray, normal, offset: float, sigma: np.ndarray):
        self.rows, self.normal, self.offset, self.sigma = rows, np.asarray(normal, dtype=float), offset, sigma

    def errors(self, at: _At) -> np.ndarray:
        return at.P[self.rows] @ self.normal - self.offset

    def jacobian(self, at: _At) -> np.ndarray:
        B = at.zeros(len(self.rows))
        B[:, :at.k] = np.einsum("j,njk->nk", self.normal, at.Jm[self.rows])
        return B / self.sigma[:, None]


class BarBlock(_Block):
    """A ball bar between the markers of rows ``i`` and ``j``: their distance minus its length."""

    kind = "bar"

    def __init__(self, i: int, j: int, length: float, sigma: float):
        self.i, self.j, self.length, self.sigma = i, j, length, np.array([sigma])

    def errors(self, at: _At) -> np.ndarray:
        return np.atleast_1d(np.linalg.norm(at.P[self.i] - at.P[self.j]) - self.length)

    def jacobian(self, at: _At) -> np.ndarray:
        d = at.P[self.i] - at.P[self.j]
        B = at.zeros(1)
        B[0, :at.k] = (d / np.linalg.norm(d)) @ (at.Jm[self.i] - at.Jm[self.j]) / self.sigma[0]
        return B


class DistanceBlock(_Block):
    """A known distance between two sockets' points (nuisance columns ``col_a``, ``col_b``): their
    distance minus the length."""

    kind = "distance"

    def __init__(self, col_a: int, col_b: int, length: float, sigma: float):
        self.col_a, self.col_b, self.length, self.sigma = col_a, col_b, length, np.array([sigma])

    def errors(self, at: _At) -> np.ndarray:
        a, b = at.nu[self.col_a:self.col_a + 3], at.nu[self.col_b:self.col_b + 3]
        return np.atleast_1d(np.linalg.norm(a - b) - self.length)

    def jacobian(self, at: _At) -> np.ndarray:
        a, b = at.nu[self.col_a:self.col_a + 3], at.nu[self.col_b:self.col_b + 3]
        u = (a - b) / np.linalg.norm(a - b) / self.sigma[0]
        B = at.zeros(1)
        B[0, at.k + self.col_a:at.k + self.col_a + 3] = u
        B[0, at.k + self.col_b:at.k + self.col_b + 3] = -u
        return B


class MeasuredBlock:
    """Measured points (and poses) of a tracker: the rows of a ``Problem`` over the same robot
    parameters, divided by ``scale`` (1 / the position noise when the data state no deviation),
    with zero nuisance columns."""

    kind = "tracker"

    def __init__(self, problem: Problem, scale: float):
        self.problem, self.scale = problem, scale

    def over(self, free: tuple[str, ...]) -> MeasuredBlock:
        return MeasuredBlock(self.problem.over(free), self.scale)

    @property
    def n_rows(self) -> int:
        return self.problem.n_rows

    def row_kinds(self) -> np.ndarray:
        return self.problem.row_kinds()

    def residuals(self, at: _At) -> np.ndarray:
        return self.problem.residuals(at.robot) * self.scale

    def jacobian(self, at: _At) -> np.ndarray:
        Jt = self.problem.jacobian(at.robot) * self.scale
        return np.hstack([Jt, np.zeros((Jt.shape[0], at.nn))])


class ContactProblem:
    """Residuals and Jacobian of ``model`` on ``contacts`` (and optionally tracker ``data``) over the
    robot parameters ``free`` (names) and every nuisance parameter: the stack of its observation
    blocks (``blocks``: measured points first, then sockets, unknown planes, known planes, ball
    bars, known distances), each with its own residual and exact Jacobian. Same interface as
    ``Problem`` (what ``solve`` needs): ``free_idx``, ``full``, ``residuals``, ``jacobian``,
    ``jacobian_factor``, ``row_kinds``, ``chunked``.

    Tracker rows without stated deviations are divided by ``noise.position`` so that they weigh
    against the contacts by their noise. The nuisance parameters start at the points and planes of
    ``model`` (``start_vector``).
    """

    def __init__(self, model: RobotModel, contacts: Contacts, free: tuple[str, ...], *, compliance: bool,
                 data: Measurements | None = None, noise: Noise | None = None):
        self.model, self.contacts, self.compliance = model, contacts, compliance
        self.chunked = False       # what ``solve`` asks: the Jacobian is formed whole
        self.lay = layout(model)
        self.n_robot = len(self.lay.names)
        self.tracker: MeasuredBlock | None = None
        if data is not None:
            # whole, not in chunks: its rows stack with the contacts' in one Jacobian
            tracker = Problem(model, data, free, compliance=compliance, noise=noise, chunked=False)
            scale = 1.0 if tracker.weighted else 1.0 / (noise.position if noise is not None else Noise.of().position)
            self.tracker = MeasuredBlock(tracker, scale)
        self.qf = read_only(contacts.q @ model.coupling_matrix.T)
        self.turns = joint_turns(self.qf)   # evaluated at every step of a fit
        # joints resting in their lost motion: approached as the rows are visited, in file order
        self.backlash = model.has_backlash or has_backlash_parameters(model, free)
        self.approach = frame_approach(model, approach_sides(contacts.q)) if self.backlash else None
        self.marker_idx = np.array([model.marker_names.index(n) for n in contacts.marker], dtype=int)
        self.sockets = contacts.groups("socket")
        self.free_planes = [g for g in contacts.groups("plane") if contacts.known_plane(g.target) is None]
        self.known_planes = [(g, kp) for g in contacts.groups("plane")
                             if (kp := contacts.known_plane(g.target)) is not None]
        self.bars = contacts.groups("bar")
        self.pairs = contacts.distance_pairs()
        self._cache: Any = None     # the last evaluation (the kinematics' state, a private type)
        self._initial_nuisance(parameter_vector(model))
        self._check_distinct()
        self.blocks = self._blocks()
        self._set_free(free)

    # ---- parameters -------------------------------------------------------------------------
    def _initial_nuisance(self, p_robot: np.ndarray) -> None:
        """Points at the mean of the model's marker positions, planes fitted to them."""
        P = self._positions(p_robot)
        values, names, quantities = [], [], []
        for g in self.sockets:
            values += list(P[g.rows].mean(axis=0))
            names += [f"{g.label}.{k}" for k in "xyz"]
            quantities += ["length"] * 3
        self.plane_axes = []
        for g in self.free_planes:
            X = P[g.rows]
            c = X.mean(axis=0)
            n0 = np.linalg.svd(X - c)[2][-1] if len(X) >= 3 else np.array([0.0, 0.0, 1.0])
            self.plane_axes.append((n0, *_tangents(n0)))
            values += [0.0, 0.0, float(n0 @ c)]
            names += [f"{g.label}.a", f"{g.label}.b", f"{g.label}.d"]
            quantities += ["angle", "angle", "length"]
        self.nuisance0 = np.array(values, dtype=float)
        self.nuisance_names = tuple(names)
        self.nuisance_quantities = tuple(quantities)

    def _socket_columns(self) -> dict:
        """Each socket's first nuisance column, by (placement, socket)."""
        return {(g.placement, g.target): 3 * s for s, g in enumerate(self.sockets)}

    def _check_distinct(self) -> None:
        """A stated distance between two points that the readings put at one place has no direction to
        fit along: the seatings' readings coincide (copied files), which no model explains."""
        where = self._socket_columns()
        nu = self.nuisance0
        for d, ga, gb in self.pairs:
            a, b = where[ga.placement, ga.target], where[gb.placement, gb.target]
            if np.linalg.norm(nu[a:a + 3] - nu[b:b + 3]) < 1e-9 and d.length > 0:
                raise InputError(f"sockets {d.a} and {d.b} of placement {ga.placement or '-'} sit at one point at the "
                                 f"model's readings (their seatings' joint readings coincide), so their stated "
                                 f"distance of {d.length * 1e3:.3f} mm cannot be fitted: check both sockets' seatings",
                                 source=self.contacts.source or "contacts")
        P = self._positions(parameter_vector(self.model))
        for g in self.bars:
            if np.linalg.norm(P[g.rows[0]] - P[g.rows[1]]) < 1e-9 and self.contacts.bars[g.target][0] > 0:
                raise InputError(f"the ball bar {g.label}'s two ends have the same joint readings, so its length "
                                 f"cannot be fitted: check its rows", source=self.contacts.source or "contacts")

    def _blocks(self) -> tuple:
        """The contact blocks, in the order rows are stacked (after the tracker's)."""
        c = self.contacts
        n_points = 3 * len(self.sockets)
        blocks: list[_Block] = [SocketBlock(g.rows, 3 * i, c.sigma[g.rows]) for i, g in enumerate(self.sockets)]
        blocks += [PlaneBlock(g.rows, n_points + 3 * i, self.plane_axes[i], c.sigma[g.rows])
                   for i, g in enumerate(self.free_planes)]
        blocks += [KnownPlaneBlock(g.rows, kp.normal, kp.offset, c.sigma[g.rows]) for g, kp in self.known_planes]
        blocks += [BarBlock(g.rows[0], g.rows[1], c.bars[g.target][0],
                            float(np.sqrt(c.bars[g.target][1] ** 2 + np.sum(c.sigma[g.rows] ** 2))))
                   for g in self.bars]
        where = self._socket_columns()
        blocks += [DistanceBlock(where[ga.placement, ga.target], where[gb.placement, gb.target], d.length, d.sigma)
                   for d, ga, gb in self.pairs]
        return tuple(blocks)

    def _set_free(self, free: tuple[str, ...]) -> None:
        index = {n: i for i, n in enumerate(self.lay.names)}
        self.free_names = tuple(free)
        self.robot_idx = np.array([index[n] for n in free], dtype=int)
        self.free_idx = np.concatenate([self.robot_idx, self.n_robot + np.arange(len(self.nuisance0))]).astype(int)
        if self.tracker is not None:
            self.tracker = self.tracker.over(tuple(free))

    def over(self, free: tuple[str, ...]) -> ContactProblem:
        """The same problem over other free robot parameters (every nuisance stays free)."""
        other = copy.copy(self)
        other._set_free(free)
        return other

    def at_contact(self) -> ContactProblem:
        """The same problem at readings nudged so that the model meets every contact exactly: each
        socket row's marker on its socket's centroid, each plane row's on its plane (``met_readings``).

        Identifiability is structural: a rigid motion of the robot is absorbed by the unknown points
        exactly when the contacts hold, but at a start whose points scatter by millimetres a base
        rotation's columns differ from the points' by that scatter, and the analysis would call it
        identifiable. The nudge is of the size of that scatter over the reach (milliradians)."""
        contacts = replace(self.contacts, q=met_readings(self.model, self.contacts, self.marker_idx))
        other = ContactProblem(self.model, contacts, self.free_names, compliance=self.compliance, noise=None)
        other.tracker, other.approach = self.tracker, self.approach     # the nudge moves no joint's side
        other._cache = None
        return other

    def start_vector(self, p_robot: np.ndarray | None = None) -> np.ndarray:
        """The full vector: the robot's parameters (default the model's) and the starting nuisance."""
        p_robot = parameter_vector(self.model) if p_robot is None else p_robot
        return np.concatenate([p_robot, self.nuisance0])

    def full(self, x, p0) -> np.ndarray:
        p = np.array(p0, dtype=float)
        p[self.free_idx] = x
        return p

    @property
    def n_nuisance(self) -> int:
        return len(self.nuisance0)

    # ---- evaluation ---------------------------------------------------------------------------
    def _state(self, p_robot: np.ndarray):
        """The evaluation at ``p_robot``, the last one kept (its pass holds a read-only copy of the
        values it was made at, compared by value)."""
        if self._cache is None or not np.array_equal(self._cache.ps.p, p_robot):
            self._cache = evaluate_state(self.model, self.lay, frozen(p_robot), self.qf, compliance=self.compliance,
                                         orientations=False, turns=self.turns, backlash=self.backlash,
                                         approach=self.approach)
        return self._cache

    def _positions(self, p_robot: np.ndarray) -> np.ndarray:
        """(n_rows, 3) the marker of each contact row, in W."""
        st = self._state(p_robot)
        return st.ps.P[self.marker_idx, np.arange(len(self.marker_idx))]

    def positions(self, p: np.ndarray) -> np.ndarray:
        """(n_rows, 3) each contact row's marker position at the full vector ``p``."""
        return self._positions(p[:self.n_robot])

    def planes(self, p: np.ndarray) -> list[tuple[np.ndarray, float]]:
        """(normal, offset) of each free plane at ``p``, in the order of ``free_planes``."""
        at = _At(self, p)
        return [b.plane(at)[:2] for b in self.blocks if isinstance(b, PlaneBlock)]

    def points(self, p: np.ndarray) -> np.ndarray:
        """(n_sockets, 3) the socket points at ``p``, in the order of ``sockets``."""
        return p[self.n_robot:self.n_robot + 3 * len(self.sockets)].reshape(-1, 3)

    def contact_errors(self, p: np.ndarray) -> dict:
        """Unweighted residuals per kind (m): ``socket`` (n, 3), ``plane`` (n,), ``bar`` (n_pairs,),
        ``distance`` (n_distances,), each with the standard deviations it is divided by."""
        at = _At(self, p)
        out: dict = {k: ([], []) for k in ("socket", "plane", "bar", "distance")}
        for b in self.blocks:
            out[b.kind][0].append(b.errors(at))
            out[b.kind][1].append(b.sigma)
        return {k: (np.concatenate(r) if r else np.zeros((0, 3) if k == "socket" else 0),
                    np.concatenate(s) if s else np.zeros(0)) for k, (r, s) in out.items()}

    def contact_labels(self) -> dict:
        """Per kind, a label for each residual of ``contact_errors`` (rows, pairs, distances)."""
        lab = self.contacts.labels
        rows = [g.rows for g in self.free_planes] + [g.rows for g, _ in self.known_planes]
        return {"socket": [f"{lab[i]} ({g.label})" for g in self.sockets for i in g.rows],
                "plane": [f"{lab[i]} ({self.contacts.target[i]})" for r in rows for i in r],
                "bar": [f"{lab[g.rows[0]]}, {lab[g.rows[1]]} ({g.label})" for g in self.bars],
                "distance": [f"{ga.placement}: {d.a}-{d.b}" for d, ga, _ in self.pairs]}

    def row_labels(self) -> list[str]:
        """A label for each row of ``residuals``: the tracker's rows by number, then each contact's."""
        out = [] if self.tracker is None else [f"tracker row {i + 1}" for i in range(self.tracker.n_rows)]
        labels = self.contact_labels()
        out += [f"{lab} ({axis})" for lab in labels["socket"] for axis in "xyz"]
        return out + [f"{lab} ({kind})" for kind in ("plane", "bar", "distance") for lab in labels[kind]]

    def _stack(self) -> list:
        return ([] if self.tracker is None else [self.tracker]) + list(self.blocks)

    def residuals(self, p: np.ndarray) -> np.ndarray:
        """Weighted residuals of every block at the full vector ``p``, stacked."""
        at = _At(self, p)
        return np.concatenate([b.residuals(at) for b in self._stack()])

    def row_kinds(self) -> np.ndarray:
        """(n_rows,) index into ``ROW_KINDS`` of each row: each kind has its own noise."""
        parts = [] if self.tracker is None else [self.tracker.row_kinds()]
        parts += [np.full(b.n_rows, ROW_KINDS.index(b.kind), dtype=int) for b in self.blocks]
        return np.concatenate(parts) if parts else np.zeros(0, dtype=int)

    @property
    def n_rows(self) -> int:
        return sum(b.n_rows for b in self._stack())

    def marker_jacobian(self, p_robot: np.ndarray) -> np.ndarray:
        """(n_rows, 3, n_free_robot) the position Jacobian of each contact row's marker."""
        st = self._state(p_robot)
        out = np.zeros((len(self.marker_idx), 3, len(self.robot_idx)))
        for m in np.unique(self.marker_idx):
            rows = np.nonzero(self.marker_idx == m)[0]
            cols = jacobian_columns(self.model, self.lay, st, self.robot_idx, int(m), 3)   # (k, N, 3)
            out[rows] = cols[:, rows, :].transpose(1, 2, 0)
        return out

    def jacobian(self, p: np.ndarray) -> np.ndarray:
        """Weighted Jacobian of ``residuals`` over the free robot parameters, then every nuisance."""
        at = _At(self, p)
        return np.vstack([b.jacobian(at) for b in self._stack()])

    def jacobian_factor(self, p: np.ndarray) -> np.ndarray:
        """An R factor (n_free, n_free) of the weighted Jacobian at ``p`` (``r_factor``)."""
        return r_factor(self.jacobian(p))
