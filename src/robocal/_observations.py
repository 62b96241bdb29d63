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

from ._arrays import frozen, read_only
from ._contacts import Contacts
from ._kinematics import evaluate, evaluate_state, jacobian_columns, joint_turns, layout
from ._measurements import Measurements, Noise
from ._model import RobotModel
from ._parameters import parameter_vector
from ._problem import Problem

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


class ContactProblem:
    """Residuals and Jacobian of ``model`` on ``contacts`` (and optionally tracker ``data``) over the
    robot parameters ``free`` (names) and every nuisance parameter. Same interface as ``Problem``
    (what ``solve`` needs): ``free_idx``, ``full``, ``residuals``, ``jacobian``, ``row_kinds``.

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
        self.tracker = None
        self.tracker_scale = 1.0
        if data is not None:
            # whole, not in chunks: its rows stack with the contacts' in one Jacobian
            self.tracker = Problem(model, data, free, compliance=compliance, noise=noise, chunked=False)
            if not self.tracker.weighted:
                self.tracker_scale = 1.0 / (noise.position if noise is not None else Noise.of().position)
        self.qf = read_only(contacts.q @ model.coupling_matrix.T)
        self.turns = joint_turns(self.qf)   # evaluated at every step of a fit
        self.marker_idx = np.array([model.marker_names.index(n) for n in contacts.marker], dtype=int)
        self.sockets = contacts.groups("socket")
        self.free_planes = [g for g in contacts.groups("plane") if contacts.known_plane(g.target) is None]
        self.known_planes = [(g, kp) for g in contacts.groups("plane")
                             if (kp := contacts.known_plane(g.target)) is not None]
        self.bars = contacts.groups("bar")
        self.pairs = contacts.distance_pairs()
        self._cache: Any = None     # the last evaluation (the kinematics' state, a private type)
        self._initial_nuisance(parameter_vector(model))
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
        other.tracker, other.tracker_scale = self.tracker, self.tracker_scale
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
                                         orientations=False, turns=self.turns)
        return self._cache

    def _positions(self, p_robot: np.ndarray) -> np.ndarray:
        """(n_rows, 3) the marker of each contact row, in W."""
        st = self._state(p_robot)
        return st.ps.P[self.marker_idx, np.arange(len(self.marker_idx))]

    def positions(self, p: np.ndarray) -> np.ndarray:
        """(n_rows, 3) each contact row's marker position at the full vector ``p``."""
        return self._positions(p[:self.n_robot])

    def _plane(self, nu: np.ndarray, k: int):
        """Unit normal, offset and the derivatives of the normal over (a, b) of free plane k."""
        n0, t1, t2 = self.plane_axes[k]
        a, b, d = nu[3 * len(self.sockets) + 3 * k: 3 * len(self.sockets) + 3 * k + 3]
        v = n0 + a * t1 + b * t2
        L = np.linalg.norm(v)
        n = v / L
        return n, d, [(t - n * (n @ t)) / L for t in (t1, t2)]

    def planes(self, p: np.ndarray) -> list[tuple[np.ndarray, float]]:
        """(normal, offset) of each free plane at ``p``, in the order of ``free_planes``."""
        nu = p[self.n_robot:]
        return [self._plane(nu, k)[:2] for k in range(len(self.free_planes))]

    def points(self, p: np.ndarray) -> np.ndarray:
        """(n_sockets, 3) the socket points at ``p``, in the order of ``sockets``."""
        return p[self.n_robot:self.n_robot + 3 * len(self.sockets)].reshape(-1, 3)

    def _bar_sigma(self, g) -> float:
        length, s = self.contacts.bars[g.target]
        return float(np.sqrt(s ** 2 + np.sum(self.contacts.sigma[g.rows] ** 2)))

    def contact_errors(self, p: np.ndarray) -> dict:
        """Unweighted residuals per kind (m): ``socket`` (n, 3), ``plane`` (n,), ``bar`` (n_pairs,),
        ``distance`` (n_distances,), each with the standard deviations it is divided by."""
        c = self.contacts
        P = self.positions(p)
        pts = self.points(p)
        out = {"socket": ([P[g.rows] - pts[k] for k, g in enumerate(self.sockets)],
                          [c.sigma[g.rows] for g in self.sockets])}
        plane = [P[g.rows] @ n - d for g, (n, d) in zip(self.free_planes, self.planes(p))]
        plane += [P[g.rows] @ np.asarray(kp.normal) - kp.offset for g, kp in self.known_planes]
        out["plane"] = (plane, [c.sigma[g.rows] for g in self.free_planes]
                        + [c.sigma[g.rows] for g, _ in self.known_planes])
        out["bar"] = ([np.atleast_1d(np.linalg.norm(P[g.rows[0]] - P[g.rows[1]]) - c.bars[g.target][0])
                       for g in self.bars], [np.atleast_1d(self._bar_sigma(g)) for g in self.bars])
        where = {(g.placement, g.target): k for k, g in enumerate(self.sockets)}
        out["distance"] = ([np.atleast_1d(np.linalg.norm(pts[where[ga.placement, ga.target]]
                                                         - pts[where[gb.placement, gb.target]]) - d.length)
                            for d, ga, gb in self.pairs], [np.atleast_1d(d.sigma) for d, _, _ in self.pairs])
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

    def residuals(self, p: np.ndarray) -> np.ndarray:
        parts = []
        if self.tracker is not None:
            parts.append(self.tracker.residuals(p[:self.n_robot]) * self.tracker_scale)
        for kind, (r, s) in self.contact_errors(p).items():
            parts.append((r / (s[:, None] if kind == "socket" else s)).ravel())
        return np.concatenate(parts)

    def row_kinds(self) -> np.ndarray:
        """(n_rows,) index into ``ROW_KINDS`` of each row: each kind has its own noise."""
        parts = [] if self.tracker is None else [self.tracker.row_kinds()]
        c = self.contacts
        counts = {"socket": 3 * sum(len(g.rows) for g in self.sockets),
                  "plane": sum(len(g.rows) for g in c.groups("plane")), "bar": len(self.bars),
                  "distance": len(self.pairs)}
        parts += [np.full(n, ROW_KINDS.index(k), dtype=int) for k, n in counts.items()]
        return np.concatenate(parts)

    @property
    def n_rows(self) -> int:
        return len(self.row_kinds())

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
        k, nn = len(self.robot_idx), self.n_nuisance
        blocks = []
        if self.tracker is not None:
            Jt = self.tracker.jacobian(p[:self.n_robot]) * self.tracker_scale
            blocks.append(np.hstack([Jt, np.zeros((Jt.shape[0], nn))]))
        blocks += self._contact_jacobian(p, k, nn)
        return np.vstack(blocks)

    def _contact_jacobian(self, p: np.ndarray, k: int, nn: int) -> list[np.ndarray]:
        c = self.contacts
        Jm = self.marker_jacobian(p[:self.n_robot])
        P = self.positions(p)
        nu = p[self.n_robot:]
        blocks = []
        for i, g in enumerate(self.sockets):        # d(P - c)/dp, -I on the point
            B = np.zeros((len(g.rows), 3, k + nn))
            B[:, :, :k] = Jm[g.rows]
            B[:, :, k + 3 * i:k + 3 * i + 3] = -np.eye(3)
            blocks.append((B / c.sigma[g.rows][:, None, None]).reshape(-1, k + nn))
        for i, g in enumerate(self.free_planes):     # d(n . P - d): n on the robot, P dn and -1 on the plane
            n, _, dn = self._plane(nu, i)
            B = np.zeros((len(g.rows), k + nn))
            B[:, :k] = np.einsum("j,njk->nk", n, Jm[g.rows])
            col = k + 3 * len(self.sockets) + 3 * i
            B[:, col] = P[g.rows] @ dn[0]
            B[:, col + 1] = P[g.rows] @ dn[1]
            B[:, col + 2] = -1.0
            blocks.append(B / c.sigma[g.rows][:, None])
        for g, kp in self.known_planes:
            B = np.zeros((len(g.rows), k + nn))
            B[:, :k] = np.einsum("j,njk->nk", np.asarray(kp.normal), Jm[g.rows])
            blocks.append(B / c.sigma[g.rows][:, None])
        blocks += self._length_jacobian(p, Jm, P, k, nn)
        return blocks

    def _length_jacobian(self, p, Jm, P, k: int, nn: int) -> list[np.ndarray]:
        """Rows of ball bars (robot columns) and known distances (point columns): u . d(difference)."""
        blocks = []
        for g in self.bars:
            i, j = g.rows
            u = (P[i] - P[j]) / np.linalg.norm(P[i] - P[j])
            B = np.zeros((1, k + nn))
            B[0, :k] = u @ (Jm[i] - Jm[j]) / self._bar_sigma(g)
            blocks.append(B)
        pts = self.points(p)
        where = {(g.placement, g.target): s for s, g in enumerate(self.sockets)}
        for d, ga, gb in self.pairs:
            a, b = where[ga.placement, ga.target], where[gb.placement, gb.target]
            u = (pts[a] - pts[b]) / np.linalg.norm(pts[a] - pts[b])
            B = np.zeros((1, k + nn))
            B[0, k + 3 * a:k + 3 * a + 3] = u / d.sigma
            B[0, k + 3 * b:k + 3 * b + 3] = -u / d.sigma
            blocks.append(B)
        return blocks
