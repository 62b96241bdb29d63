"""Contacts as observation blocks: residuals and exact Jacobians of sockets, planes, ball bars and
known distances, and each block's errors with its own unknowns taken from its own rows.

Joint-only recordings (``Contacts``) say where the marker was relative to things the fit does not
know: a socket's point, a plane. Those are nuisance parameters appended to the robot's parameter
vector, so a problem's full vector is ``[robot parameters (layout order); nuisance]``. Every
observation is a function of marker positions, so its Jacobian is the chain rule applied to the
marker position rows of the kinematic engine plus the nuisance columns. Each row is divided by its
stated standard deviation: rows of every kind are then in the same unit (standard deviations) and
stack with measured points in one fit.

Blocks, in the order rows are stacked: sockets (3 rows per seating: marker minus point), unknown
planes and known planes (1 row per contact: signed distance), ball bars (1 per pair: distance
minus length), known distances between sockets (1 per placement and pair). An unknown plane is
``n . x = d`` with ``n`` the unit vector along ``n0 + a t1 + b t2``: ``n0`` the plane's normal fitted
to the starting model's points, ``t1, t2`` perpendicular to it; its nuisance is ``a, b, d``.

A block's observations are what the outlier check judges and a held-out set predicts: a seating,
a plane contact, a bar, a known distance on a placement. ``own_errors`` gives each observation's
error with the block's unknowns taken from its rows alone (a socket's point at its seatings' mean,
a plane fitted to its contacts): what a placement the fit did not see shows, and what the kit's
figures (consistency, spacing error) are made of.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from .._base.arrays import frozen, read_only
from .._base.errors import InputError
from .._model.contacts import Contacts
from .._model.kinematics import evaluate, evaluate_state, frame_approach, jacobian_columns, joint_turns, layout
from .._model.measurements import approach_sides
from .._model.parameters import has_backlash_parameters, parameter_vector
from .._model.robot import RobotModel

CONTACT_KINDS = ("socket", "plane", "bar", "distance")
# what the rows of each kind fix when they alone fix it (a robust refit or an outlier step must keep them)
# kinds whose rows state a known length and carry the scale together (no one alone): never set aside,
# and kept linear under a robust loss, or the robot would shrink or grow to meet the others
TOGETHER = ("distance", "bar")
CARRIES = {"distance": "the scale", "bar": "the scale", "plane": "a plane's position", "socket": "a socket's point",
           "tracker": "a direction of the robot"}


def _tangents(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors perpendicular to the unit vector ``n`` and to each other."""
    a = np.eye(3)[int(np.argmin(np.abs(n)))]
    t1 = np.cross(n, a)
    t1 /= np.linalg.norm(t1)
    return t1, np.cross(n, t1)


def _best_plane(X: np.ndarray) -> tuple[np.ndarray, float]:
    """The unit normal and offset of the plane that fits the points ``X`` (n, 3) best."""
    c = X.mean(axis=0)
    n = np.linalg.svd(X - c)[2][-1]
    return n, float(n @ c)


def _contact_targets(contacts: Contacts, X: np.ndarray) -> np.ndarray:
    """(n_rows, 3) where each row's marker meets its contact exactly, near ``X``: a socket's rows at
    their centroid, a plane's projected onto it (the known one, else the best-fitting), bars as they are."""
    T = X.copy()
    for g in contacts.groups("socket"):
        T[g.rows] = X[g.rows].mean(axis=0)
    for g in contacts.groups("plane"):
        kp = contacts.known_plane(g.target)
        n, d = _best_plane(X[g.rows]) if kp is None else (np.asarray(kp.normal), kp.offset)
        T[g.rows] -= np.outer(X[g.rows] @ n - d, n)
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


class At:
    """One evaluation point shared by every block: the robot's part of the full vector, the
    nuisance part, and (made when a block first asks) the contact rows' marker positions ``P``
    (n_rows, 3) and their Jacobian ``Jm`` (n_rows, 3, k) over the ``k`` free robot parameters, the
    ``nn`` nuisance columns after them."""

    def __init__(self, rows: ContactRows, robot: np.ndarray, nuisance: np.ndarray, robot_idx: np.ndarray):
        self.rows, self.robot, self.nu, self.robot_idx = rows, robot, nuisance, robot_idx
        self.k, self.nn = len(robot_idx), len(nuisance)
        self._P: np.ndarray | None = None
        self._Jm: np.ndarray | None = None

    @property
    def P(self) -> np.ndarray:
        if self._P is None:
            self._P = self.rows.positions(self.robot)
        return self._P

    @property
    def Jm(self) -> np.ndarray:
        if self._Jm is None:
            self._Jm = self.rows.marker_jacobian(self.robot, self.robot_idx)
        return self._Jm

    def zeros(self, *shape: int) -> np.ndarray:
        return np.zeros((*shape, self.k + self.nn))


class Block:
    """One kind of observation over some rows: its unweighted ``errors`` (n_obs, width) in m, the
    standard deviations ``sigma`` (n_obs,) they are divided by, the weighted Jacobian of
    ``errors / sigma`` over the free robot columns then every nuisance column, and ``own_errors``
    (the errors with the block's unknowns taken from its own rows). ``obs``: the observations'
    indices among the contacts' (``ContactRows.observations``); ``rows``: the contact rows each
    reads (n_obs, rows per observation)."""

    kind = ""
    width = 1
    sigma: np.ndarray
    obs: np.ndarray

    @property
    def n_rows(self) -> int:
        return self.width * len(self.sigma)

    def errors(self, at: At) -> np.ndarray:
        raise NotImplementedError

    def own_errors(self, P: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def residuals(self, at: At) -> np.ndarray:
        return (self.errors(at) / self.sigma[:, None]).ravel()

    def fill(self, at: At, out: np.ndarray) -> None:
        """The weighted Jacobian of the block's rows written into ``out`` (n_rows, k + nn), zeros."""
        raise NotImplementedError


class SocketBlock(Block):
    """The marker seated in one socket: marker minus the socket's unknown point (nuisance columns
    ``col``..``col + 2``), 3 rows per seating. The socket blocks lead the rows: ``ContactRows.jacobian``
    fills theirs at once (``ContactRows.socket_run``)."""

    kind, width = "socket", 3

    def __init__(self, rows: np.ndarray, col: int, sigma: np.ndarray, obs: np.ndarray):
        self.rows, self.col, self.sigma, self.obs = rows, col, sigma, obs

    def errors(self, at: At) -> np.ndarray:
        return at.P[self.rows] - at.nu[self.col:self.col + 3]

    def own_errors(self, P: np.ndarray) -> np.ndarray:
        X = P[self.rows]
        return X - X.mean(axis=0)


class PlaneBlock(Block):
    """The marker on an unknown plane ``n . x = d`` (nuisance ``a, b, d`` at ``col``): the signed
    distance, one row per contact; ``axes``: the plane's starting normal and two tangents."""

    kind = "plane"

    def __init__(self, rows: np.ndarray, col: int, axes: tuple, sigma: np.ndarray, obs: np.ndarray):
        self.rows, self.col, self.axes, self.sigma, self.obs = rows, col, axes, sigma, obs

    def plane(self, nu: np.ndarray):
        """Unit normal, offset and the derivatives of the normal over (a, b)."""
        n0, t1, t2 = self.axes
        a, b, d = nu[self.col:self.col + 3]
        v = n0 + a * t1 + b * t2
        L = np.linalg.norm(v)
        n = v / L
        return n, d, [(t - n * (n @ t)) / L for t in (t1, t2)]

    def errors(self, at: At) -> np.ndarray:
        n, d, _ = self.plane(at.nu)
        return (at.P[self.rows] @ n - d)[:, None]

    def own_errors(self, P: np.ndarray) -> np.ndarray:
        X = P[self.rows]
        n, d = _best_plane(X)
        return (X @ n - d)[:, None]

    def fill(self, at: At, out: np.ndarray) -> None:
        n, _, dn = self.plane(at.nu)                 # n on the robot, P dn and -1 on the plane
        out[:, :at.k] = np.einsum("j,njk->nk", n, at.Jm[self.rows])
        col = at.k + self.col
        out[:, col] = at.P[self.rows] @ dn[0]
        out[:, col + 1] = at.P[self.rows] @ dn[1]
        out[:, col + 2] = -1.0
        out /= self.sigma[:, None]


class KnownPlaneBlock(Block):
    """The marker on a plane known in W: the signed distance, robot columns only."""

    kind = "plane"

    def __init__(self, rows: np.ndarray, normal, offset: float, sigma: np.ndarray, obs: np.ndarray):
        self.rows, self.normal, self.offset, self.sigma, self.obs = rows, np.asarray(normal, dtype=float), offset, \
            sigma, obs

    def errors(self, at: At) -> np.ndarray:
        return self.own_errors(at.P)

    def own_errors(self, P: np.ndarray) -> np.ndarray:
        return (P[self.rows] @ self.normal - self.offset)[:, None]

    def fill(self, at: At, out: np.ndarray) -> None:
        out[:, :at.k] = np.einsum("j,njk->nk", self.normal, at.Jm[self.rows])
        out /= self.sigma[:, None]


class BarBlock(Block):
    """A ball bar between the markers of rows ``i`` and ``j``: their distance minus its length."""

    kind = "bar"

    def __init__(self, i: int, j: int, length: float, sigma: float, obs: int):
        self.i, self.j, self.length, self.sigma, self.obs = i, j, length, np.array([sigma]), np.array([obs])
        self.rows = np.array([i, j])

    def errors(self, at: At) -> np.ndarray:
        return self.own_errors(at.P)

    def own_errors(self, P: np.ndarray) -> np.ndarray:
        return np.array([[np.linalg.norm(P[self.i] - P[self.j]) - self.length]])

    def fill(self, at: At, out: np.ndarray) -> None:
        d = at.P[self.i] - at.P[self.j]
        out[0, :at.k] = (d / np.linalg.norm(d)) @ (at.Jm[self.i] - at.Jm[self.j]) / self.sigma[0]


class DistanceBlock(Block):
    """A known distance between two sockets' points (nuisance columns ``col_a``, ``col_b``): their
    distance minus the length. ``rows_a``, ``rows_b``: the two sockets' seatings (their mean
    centres are the points a placement the fit did not see gives)."""

    kind = "distance"

    def __init__(self, col_a: int, col_b: int, length: float, sigma: float, rows_a, rows_b, obs: int):
        self.col_a, self.col_b, self.length, self.sigma = col_a, col_b, length, np.array([sigma])
        self.rows_a, self.rows_b, self.obs = rows_a, rows_b, np.array([obs])
        self.rows = np.concatenate([rows_a, rows_b])

    def errors(self, at: At) -> np.ndarray:
        a, b = at.nu[self.col_a:self.col_a + 3], at.nu[self.col_b:self.col_b + 3]
        return np.array([[np.linalg.norm(a - b) - self.length]])

    def own_errors(self, P: np.ndarray) -> np.ndarray:
        return np.array([[np.linalg.norm(P[self.rows_a].mean(axis=0) - P[self.rows_b].mean(axis=0)) - self.length]])

    def fill(self, at: At, out: np.ndarray) -> None:
        a, b = at.nu[self.col_a:self.col_a + 3], at.nu[self.col_b:self.col_b + 3]
        u = (a - b) / np.linalg.norm(a - b) / self.sigma[0]
        out[0, at.k + self.col_a:at.k + self.col_a + 3] = u
        out[0, at.k + self.col_b:at.k + self.col_b + 3] = -u


class ContactRows:
    """``model`` evaluated at the readings of ``contacts``, and the blocks of their observations.

    Observations, in the order of ``observations``: each seating, plane contact, ball bar and known
    distance (per placement and pair), block by block. ``aside`` (n_obs,): observations set aside
    (their rows leave the blocks; the evaluation is shared). The nuisance parameters start at the
    points and planes of ``model`` (``nuisance0``); joints rest in their lost motion as the rows are
    visited, in file order, when ``backlash``.
    """

    def __init__(self, model: RobotModel, contacts: Contacts, *, compliance: bool, backlash: bool,
                 aside: np.ndarray | None = None, q: np.ndarray | None = None):
        self.model, self.contacts, self.compliance = model, contacts, compliance
        self.lay = layout(model)
        q = contacts.q if q is None else q
        self.qf = read_only(q @ model.coupling_matrix.T)
        self.turns = joint_turns(self.qf)   # evaluated at every step of a fit
        self.backlash = backlash
        self.approach = frame_approach(model, approach_sides(contacts.q)) if backlash else None
        markers = model.marker_names
        self.marker_idx = np.array([markers.index(n) for n in contacts.marker], dtype=int)
        self.sockets = contacts.groups("socket")
        self.free_planes = [g for g in contacts.groups("plane") if contacts.known_plane(g.target) is None]
        self.known_planes = [(g, kp) for g in contacts.groups("plane")
                             if (kp := contacts.known_plane(g.target)) is not None]
        self.bars = contacts.groups("bar")
        self.pairs = contacts.distance_pairs()
        self._cache: Any = None     # the last evaluation (the kinematics' state, a private type)
        self._initial_nuisance(parameter_vector(model))
        self._observations()
        self.aside = np.zeros(len(self.obs_kind), dtype=bool) if aside is None else np.asarray(aside, dtype=bool)
        self._set_blocks()

    @classmethod
    def of(cls, model: RobotModel, contacts: Contacts, names, *, compliance: bool) -> ContactRows:
        """The rows of ``contacts`` on ``model`` with joints in their lost motion when the model or the
        parameters ``names`` hold a backlash."""
        backlash = model.has_backlash or has_backlash_parameters(model, names)
        return cls(model, contacts, compliance=compliance, backlash=backlash)

    # ---- nuisance and observations ------------------------------------------------------------
    def _initial_nuisance(self, p_robot: np.ndarray) -> None:
        """Points at the mean of the model's marker positions, planes fitted to them."""
        P = self.positions(p_robot)
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
        self.nuisance0 = read_only(np.array(values, dtype=float))
        self.nuisance_names = tuple(names)
        self.nuisance_quantities = tuple(quantities)
        self._check_distinct(P)

    def _check_distinct(self, P: np.ndarray) -> None:
        """A stated distance between two points that the readings put at one place has no direction to
        fit along: the seatings' readings coincide (copied files), which no model explains."""
        for d, ga, gb in self.pairs:
            if np.linalg.norm(P[ga.rows].mean(axis=0) - P[gb.rows].mean(axis=0)) < 1e-9 and d.length > 0:
                raise InputError(f"sockets {d.a} and {d.b} of placement {ga.placement or '-'} sit at one point at the "
                                 f"model's readings (their seatings' joint readings coincide), so their stated "
                                 f"distance of {d.length * 1e3:.3f} mm cannot be fitted: check both sockets' seatings",
                                 source=self.contacts.source or "contacts")
        for g in self.bars:
            if np.linalg.norm(P[g.rows[0]] - P[g.rows[1]]) < 1e-9 and self.contacts.bars[g.target][0] > 0:
                raise InputError(f"the ball bar {g.label}'s two ends have the same joint readings, so its length "
                                 f"cannot be fitted: check its rows", source=self.contacts.source or "contacts")

    def _observations(self) -> None:
        """Each observation's kind, label, placement, first row and the rows it reads, in block order."""
        c, lab = self.contacts, self.contacts.labels
        kinds, labels, placements, first = [], [], [], []
        for g in self.sockets:
            kinds += ["socket"] * len(g.rows)
            said = g.label
            labels += [f"{lab[i]} ({said})" for i in g.rows]
            placements += [g.placement] * len(g.rows)
            first += list(g.rows)
        for g in self.free_planes + [g for g, _ in self.known_planes]:
            kinds += ["plane"] * len(g.rows)
            labels += [f"{lab[i]} ({c.target[i]})" for i in g.rows]
            placements += [g.placement] * len(g.rows)
            first += list(g.rows)
        for g in self.bars:
            kinds.append("bar")
            labels.append(f"{lab[g.rows[0]]}, {lab[g.rows[1]]} ({g.label})")
            placements.append(g.placement)
            first.append(int(g.rows[0]))
        for d, ga, _ in self.pairs:
            kinds.append("distance")
            labels.append(f"{ga.placement}: {d.a}-{d.b}")
            placements.append(ga.placement)
            first.append(int(ga.rows[-1]))
        # the observations of each socket, plane, bar and known distance (what the kit's figures are per)
        groups, k = [], 0
        for kind, items in (("socket", [(g.label, len(g.rows)) for g in self.sockets]),
                            ("plane", [(g.label, len(g.rows)) for g in self.free_planes + [g for g, _ in
                                                                                         self.known_planes]]),
                            ("bar", [(g.label, 1) for g in self.bars]),
                            ("distance", [(f"{ga.placement}: {d.a}-{d.b}", 1) for d, ga, _ in self.pairs])):
            for label, n in items:
                groups.append((kind, label, np.arange(k, k + n)))
                k += n
        self.obs_groups = tuple(groups)
        self.obs_kind = tuple(kinds)
        self.obs_label = tuple(labels)
        self.obs_placement = tuple(placements)
        self.obs_row = np.array(first, dtype=int)

    def _set_blocks(self) -> None:
        """``blocks``: those of the observations kept, in the order rows are stacked, the socket blocks
        first; ``socket_run``: how many socket blocks lead, and their rows, each row's point column and
        deviation concatenated (``jacobian`` fills them at once)."""
        c, keep = self.contacts, ~self.aside
        n_points = 3 * len(self.sockets)
        blocks: list[Block] = []
        k = 0
        for i, g in enumerate(self.sockets):
            o = np.arange(k, k + len(g.rows))[keep[k:k + len(g.rows)]]
            blocks.append(SocketBlock(g.rows[o - k], 3 * i, c.sigma[g.rows[o - k]], o))
            k += len(g.rows)
        for i, g in enumerate(self.free_planes):
            o = np.arange(k, k + len(g.rows))[keep[k:k + len(g.rows)]]
            blocks.append(PlaneBlock(g.rows[o - k], n_points + 3 * i, self.plane_axes[i], c.sigma[g.rows[o - k]], o))
            k += len(g.rows)
        for g, kp in self.known_planes:
            o = np.arange(k, k + len(g.rows))[keep[k:k + len(g.rows)]]
            blocks.append(KnownPlaneBlock(g.rows[o - k], kp.normal, kp.offset, c.sigma[g.rows[o - k]], o))
            k += len(g.rows)
        for g in self.bars:
            if keep[k]:
                blocks.append(BarBlock(g.rows[0], g.rows[1], c.bars[g.target][0],
                                       float(np.sqrt(c.bars[g.target][1] ** 2 + np.sum(c.sigma[g.rows] ** 2))), k))
            k += 1
        where = {(g.placement, g.target): 3 * s for s, g in enumerate(self.sockets)}
        for d, ga, gb in self.pairs:
            if keep[k]:
                blocks.append(DistanceBlock(where[ga.placement, ga.target], where[gb.placement, gb.target], d.length,
                                            d.sigma, ga.rows, gb.rows, k))
            k += 1
        self.blocks = tuple(b for b in blocks if len(b.sigma))
        sockets = [b for b in self.blocks if isinstance(b, SocketBlock)]
        self.socket_run = (len(sockets), np.concatenate([b.rows for b in sockets] or [np.zeros(0, dtype=int)]),
                           np.concatenate([np.full(len(b.rows), b.col) for b in sockets] or [np.zeros(0, dtype=int)]),
                           np.concatenate([b.sigma for b in sockets] or [np.zeros(0)]))

    def without(self, aside: np.ndarray) -> ContactRows:
        """The same rows with the observations ``aside`` (n_obs,) set aside too (the evaluation shared)."""
        other = object.__new__(ContactRows)
        other.__dict__.update(self.__dict__)
        other.aside = self.aside | np.asarray(aside, dtype=bool)
        other._set_blocks()
        return other

    def at_contact(self) -> ContactRows:
        """The same rows at readings nudged so that the model meets every contact exactly (each
        socket row's marker on its socket's centroid, each plane row's on its plane: ``met_readings``).

        Identifiability is structural: a rigid motion of the robot is absorbed by the unknown points
        exactly when the contacts hold, but at a start whose points scatter by millimetres a base
        rotation's columns differ from the points' by that scatter, and the analysis would call it
        identifiable. The nudge is of the size of that scatter over the reach (milliradians)."""
        q = met_readings(self.model, self.contacts, self.marker_idx)
        other = ContactRows(self.model, replace(self.contacts, q=q), compliance=self.compliance, backlash=False,
                            aside=self.aside)
        other.backlash, other.approach = self.backlash, self.approach     # the nudge moves no joint's side
        other._cache = None                                                 # made without them
        return other

    @property
    def n_nuisance(self) -> int:
        return len(self.nuisance0)

    @property
    def n_rows(self) -> int:
        return sum(b.n_rows for b in self.blocks)

    # ---- evaluation ---------------------------------------------------------------------------
    def _state(self, p_robot: np.ndarray):
        """The evaluation at ``p_robot``, the last one kept (its pass holds a read-only copy of the
        values it was made at, compared by value)."""
        if self._cache is None or not np.array_equal(self._cache.ps.p, p_robot):
            self._cache = evaluate_state(self.model, self.lay, frozen(p_robot), self.qf, compliance=self.compliance,
                                         orientations=False, turns=self.turns, backlash=self.backlash,
                                         approach=self.approach)
        return self._cache

    def positions(self, p_robot: np.ndarray) -> np.ndarray:
        """(n_rows, 3) the marker of each contact row, in W."""
        st = self._state(p_robot)
        return st.ps.P[self.marker_idx, np.arange(len(self.marker_idx))]

    def marker_jacobian(self, p_robot: np.ndarray, robot_idx: np.ndarray) -> np.ndarray:
        """(n_rows, 3, k) the position Jacobian of each contact row's marker over the parameters
        ``robot_idx``."""
        st = self._state(p_robot)
        seated = np.unique(self.marker_idx)
        if len(seated) == 1:        # every row's marker: the columns as they come, viewed row-major
            return jacobian_columns(self.model, self.lay, st, robot_idx, int(seated[0]), 3).transpose(1, 2, 0)
        out = np.zeros((len(self.marker_idx), 3, len(robot_idx)))
        for m in seated:
            rows = np.nonzero(self.marker_idx == m)[0]
            cols = jacobian_columns(self.model, self.lay, st, robot_idx, int(m), 3)   # (k, N, 3)
            out[rows] = cols[:, rows, :].transpose(1, 2, 0)
        return out

    def compliance_moments(self, p_robot: np.ndarray) -> dict:
        """Per compliance parameter name, the gravity moments (n_rows,) it multiplies (N m) at ``p_robot``."""
        if not self.compliance:
            return {}
        st = self._state(p_robot)
        names = self.lay.names
        return {names[k]: st.M[row].copy() for row, k in enumerate(self.lay.compliant_params)}

    def backlash_sides(self, p_robot: np.ndarray) -> dict:
        """Per backlash parameter name, the sides (n_rows,) in [-1, 1] its joint rests on at ``p_robot``."""
        if not self.backlash:
            return {}
        st = self._state(p_robot)
        names = self.lay.names
        return {names[k]: st.backlash.sides[:, i].copy() for i, k in enumerate(self.lay.backlash_params) if k >= 0}

    def at(self, robot: np.ndarray, nuisance: np.ndarray, robot_idx: np.ndarray) -> At:
        return At(self, robot, nuisance, robot_idx)

    def residuals(self, at: At) -> np.ndarray:
        return np.concatenate([b.residuals(at) for b in self.blocks]) if self.blocks else np.zeros(0)

    def jacobian(self, at: At) -> np.ndarray:
        """The weighted Jacobian of every block's rows, in block order: each written into its rows, the
        socket blocks, which lead (``socket_run``), at once: a campaign holds one per placement and socket."""
        out = at.zeros(self.n_rows)
        lead, rows, cols, sigma = self.socket_run
        row = 3 * len(rows)
        if lead:
            B = out[:row].reshape(len(rows), 3, at.k + at.nn)    # d(P - c)/dp, -I on the point
            B[:, :, :at.k] = at.Jm[rows]
            B[np.arange(len(rows))[:, None], np.arange(3), at.k + cols[:, None] + np.arange(3)] = -1.0
            B /= sigma[:, None, None]
        for b in self.blocks[lead:]:
            b.fill(at, out[row:row + b.n_rows])
            row += b.n_rows
        return out

    def row_kinds(self) -> list[str]:
        """The kind of each row, in the order of ``residuals``."""
        return [b.kind for b in self.blocks for _ in range(b.n_rows)]

    def row_observations(self) -> np.ndarray:
        """(n_rows,) the observation each row belongs to."""
        parts = [np.repeat(b.obs, b.width) for b in self.blocks]
        return np.concatenate(parts) if parts else np.zeros(0, dtype=int)

    def errors(self, at: At) -> dict:
        """Per kind, (errors (n, width) m, sigma (n,), observations (n,)) of the observations kept."""
        out: dict = {}
        for b in self.blocks:
            e, s, o = out.setdefault(b.kind, ([], [], []))
            e.append(b.errors(at))
            s.append(b.sigma)
            o.append(b.obs)
        return {k: (np.concatenate(e), np.concatenate(s), np.concatenate(o)) for k, (e, s, o) in out.items()}

    def own_errors(self, p_robot: np.ndarray) -> np.ndarray:
        """(n_obs, 3) each observation's errors (m; plane, bar and distance in the first column, NaN
        beside) with every block's unknowns from its own rows, set-aside observations included."""
        P = self.positions(p_robot)
        out = np.full((len(self.obs_kind), 3), np.nan)
        for b in self.all_blocks():
            out[b.obs, :b.width] = b.own_errors(P)
        return out

    def all_blocks(self) -> tuple:
        """The blocks of every observation, those set aside included."""
        if not self.aside.any():
            return self.blocks
        other = object.__new__(ContactRows)
        other.__dict__.update(self.__dict__)
        other.aside = np.zeros_like(self.aside)
        other._set_blocks()
        return other.blocks

    def sigma(self) -> np.ndarray:
        """(n_obs,) each observation's stated standard deviation (m)."""
        out = np.empty(len(self.obs_kind))
        for b in self.all_blocks():
            out[b.obs] = b.sigma
        return out
