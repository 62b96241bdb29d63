"""The identification problem: one model on a stack of observation blocks, whatever was observed.

Measured points (and poses) of an instrument are one block (``Points``); contacts are blocks of
sockets, planes, ball bars and known distances (``ContactRows``). The full parameter vector is the
robot's (the model's layout) followed by the nuisance parameters of the contacts (socket points,
planes). Rows of every block are in the units the fit weighs them in: measured points in metres
when they are alone and state no deviation, else every row in its standard deviations.

What the solver, the identifiability analysis and the held-out scheme ask of a problem is the
``Solvable`` protocol; ``Problem`` is its one implementation. Beside it, each observation (a
measured point, a seating, a plane contact, a bar, a known distance) has a kind, a label, a hold-out
group (a fold of poses or series, a placement) and a stated deviation: what the steps of
``calibrate`` judge per kind.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Protocol, cast

import numpy as np

from .._base.arrays import frozen, read_only
from .._base.linalg import r_factor, reduced
from .._model.contacts import Contacts
from .._model.kinematics import layout
from .._model.measurements import Measurements, Noise
from .._model.parameters import parameter_layout, parameter_vector
from .._model.robot import RobotModel
from .contact_blocks import ContactRows
from .points import Points


class Solvable(Protocol):
    """What ``solve``, ``covariance`` and the analyses use of a problem."""

    free_idx: np.ndarray
    chunked: bool

    def full(self, x, p0) -> np.ndarray: ...

    def residuals(self, p) -> np.ndarray: ...

    def jacobian(self, p) -> np.ndarray: ...

    def jacobian_factor(self, p) -> np.ndarray: ...

    def normal_equations(self, p) -> tuple[np.ndarray, np.ndarray, float]: ...

    def row_kinds(self) -> np.ndarray | None: ...


# row kinds, in the order of ``Problem.row_kinds``' indices: each kind has its own noise
ROW_KINDS = ("position", "rotation", "socket", "plane", "bar", "distance")


class Labels(Sequence):
    """The observations' labels, made when read (a campaign may hold millions of points): a measured
    point's is "<pose label>, marker <name>", a contact's its own. ``taken(index)``: those of some."""

    def __init__(self, poses, markers, rows: np.ndarray, columns: np.ndarray, contacts: Sequence[str] = (),
                 index: np.ndarray | None = None):
        self._parts = (poses, markers, rows, columns, contacts)
        self._index = index

    def __len__(self) -> int:
        return len(self._parts[2]) + len(self._parts[4]) if self._index is None else len(self._index)

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        i = int(i if self._index is None else self._index[i])
        poses, markers, rows, columns, contacts = self._parts
        if i < 0:
            i += len(rows) + len(contacts)
        if i >= len(rows):
            return contacts[i - len(rows)]
        return f"{poses[rows[i]]}, marker {markers[columns[i]]}"

    def taken(self, index) -> Labels:
        """The labels of the observations ``index``, in that order."""
        index = np.asarray(index, dtype=int)
        return Labels(*self._parts, index=index if self._index is None else self._index[index])


@dataclass(frozen=True, eq=False)
class Observations:
    """Every observation of a problem, measured points first (pose by pose in the data's mask
    order), then the contacts' (``ContactRows`` order). ``kind`` ("tracker" or a contact kind),
    ``label`` (``Labels``), ``order`` (the pose or contact row: what consecutive means), ``placement``
    (contacts; "" for points)."""

    kind: tuple[str, ...]
    label: Labels
    order: np.ndarray
    placement: tuple[str, ...]
    n_points: int

    def __len__(self) -> int:
        return len(self.kind)

    def kinds(self) -> tuple[str, ...]:
        return tuple(self._masks)

    def of(self, kind: str) -> np.ndarray:
        """(n_observations,) read-only: those of ``kind``."""
        mask = self._masks.get(kind)
        return read_only(np.zeros(len(self.kind), dtype=bool)) if mask is None else mask

    @cached_property
    def _masks(self) -> dict[str, np.ndarray]:
        """Each kind's observations, in the order the kinds first appear: made once (a campaign may
        hold millions of points, all of one kind)."""
        out: dict[str, np.ndarray] = {}
        if self.n_points:
            out["tracker"] = np.zeros(len(self.kind), dtype=bool)
            out["tracker"][:self.n_points] = True
        rest = self.kind[self.n_points:]
        for k in dict.fromkeys(rest):
            mask = out.setdefault(k, np.zeros(len(self.kind), dtype=bool))
            mask[self.n_points:] |= np.array([x == k for x in rest], dtype=bool)
        return {k: read_only(m) for k, m in out.items()}


class Problem:
    """Residuals and Jacobian of ``model`` on its observation blocks over the robot parameters
    ``free`` (names) and every nuisance parameter: measured points ``data`` and/or ``contacts``.

    ``compliance``: gravity moments are evaluated (the model or ``free`` holds compliance);
    ``noise``: the instrument's, which weighs measured points without stated deviations beside
    contacts (and rotations against positions); ``chunked``: a large campaign of points alone is
    evaluated a chunk of poses at a time (``Points``).
    """

    def __init__(self, model: RobotModel, free: tuple[str, ...], *, data: Measurements | None = None,
                 contacts: Contacts | ContactRows | None = None, compliance: bool, noise: Noise | None = None,
                 chunked: bool | None = None):
        self.model, self.compliance, self.noise = model, compliance, noise
        self.lay = layout(model)
        self.n_robot = len(self.lay.names)
        alone = contacts is None
        self.points = None if data is None else Points(model, data, tuple(free), compliance=compliance, noise=noise,
                                                       chunked=chunked if alone else False)
        self.contacts = contacts if isinstance(contacts, ContactRows) or contacts is None else \
            ContactRows.of(model, contacts, free, compliance=compliance)
        # measured points stacked with contacts are in their noise's units, as every contact row is
        self.point_scale = 1.0
        if self.points is not None and not alone and not self.points.weighted:
            self.point_scale = 1.0 / (noise.position if noise is not None else Noise.of().position)
        self.chunked = self.points is not None and alone and self.points.chunked
        # the measured points' observation numbers, kept when some are set aside (``without``)
        self.point_mask = read_only(np.zeros((0, 0), dtype=bool) if data is None else data.mask.copy())
        self._point_index = np.full(self.point_mask.shape, -1)
        self._point_index[self.point_mask] = np.arange(int(self.point_mask.sum()))
        self._observations: Observations | None = None   # built once: the steps ask it often
        self._errors_at: tuple | None = None     # the last observation_errors: (bytes of the vector, errors)
        self._set_free(tuple(free))

    # ---- parameters -------------------------------------------------------------------------
    @property
    def nuisance0(self) -> np.ndarray:
        return self.contacts.nuisance0 if self.contacts is not None else np.zeros(0)

    @property
    def nuisance_names(self) -> tuple[str, ...]:
        return self.contacts.nuisance_names if self.contacts is not None else ()

    @property
    def nuisance_quantities(self) -> tuple[str, ...]:
        return self.contacts.nuisance_quantities if self.contacts is not None else ()

    @property
    def n_nuisance(self) -> int:
        return len(self.nuisance0)

    def _set_free(self, free: tuple[str, ...]) -> None:
        self._errors_at = None
        self.free_names = free
        self.robot_idx = parameter_layout(self.model).indices(free)
        self.free_idx = np.concatenate([self.robot_idx, self.n_robot + np.arange(self.n_nuisance)]).astype(int)

    def over(self, free: tuple[str, ...]) -> Problem:
        """The same problem over other free robot parameters (every nuisance stays free), keeping
        the evaluations already made."""
        other = copy.copy(self)
        if self.points is not None:
            other.points = self.points.over(tuple(free))
        other._set_free(tuple(free))
        return other

    @property
    def n_points(self) -> int:
        """The number of measured points observed (set aside or not)."""
        return int(self.point_mask.sum())

    def without(self, aside: np.ndarray) -> Problem:
        """The same problem with the observations ``aside`` (n_observations,) set aside too."""
        other = copy.copy(self)
        n = self.n_points
        if self.points is not None and aside[:n].any():
            points = np.zeros(self.point_mask.shape, dtype=bool)
            points[self.point_mask] = aside[:n]
            other.points = self.points.without(points)
        if self.contacts is not None and aside[n:].any():
            other.contacts = self.contacts.without(aside[n:])
        other._errors_at = None
        return other

    def start_vector(self, p_robot: np.ndarray | None = None) -> np.ndarray:
        """The full vector: the robot's parameters (default the model's) and the starting nuisance."""
        p_robot = parameter_vector(self.model) if p_robot is None else p_robot
        return np.concatenate([p_robot, self.nuisance0]) if self.n_nuisance else np.asarray(p_robot, dtype=float)

    def full(self, x, p0) -> np.ndarray:
        """The full parameter vector: ``p0`` with the free parameters set to ``x``."""
        p = np.array(p0, dtype=float)
        p[self.free_idx] = x
        return p

    def at_contact(self) -> Problem:
        """The same problem with the contacts at readings where the model meets them exactly
        (``ContactRows.at_contact``): what a structural analysis is made at."""
        if self.contacts is None:
            return self
        other = copy.copy(self)
        other.contacts = self.contacts.at_contact()
        other._errors_at = None
        return other

    # ---- evaluation ---------------------------------------------------------------------------
    @property
    def n_rows(self) -> int:
        return (0 if self.points is None else self.points.n_rows) + (0 if self.contacts is None else
                                                                     self.contacts.n_rows)

    def _at(self, p):
        return cast(ContactRows, self.contacts).at(p[:self.n_robot], p[self.n_robot:], self.robot_idx)

    def residuals(self, p) -> np.ndarray:
        """Weighted residuals of every block at the full vector ``p``, stacked."""
        if self.contacts is None:
            return cast(Points, self.points).residuals(p)
        parts = [] if self.points is None else [self.points.residuals(p[:self.n_robot]) * self.point_scale]
        return np.concatenate(parts + [self.contacts.residuals(self._at(p))])

    def jacobian(self, p) -> np.ndarray:
        """Weighted Jacobian of ``residuals`` over the free robot parameters, then every nuisance."""
        if self.contacts is None:
            return cast(Points, self.points).jacobian(p)
        at = self._at(p)
        if self.points is None:
            return self.contacts.jacobian(at)
        Jt = self.points.jacobian(p[:self.n_robot]) * self.point_scale
        return np.vstack([np.hstack([Jt, np.zeros((Jt.shape[0], self.n_nuisance))]), self.contacts.jacobian(at)])

    def jacobian_factor(self, p) -> np.ndarray:
        """An R factor (n_free, n_free) of the weighted Jacobian at ``p``."""
        if self.contacts is None:
            return cast(Points, self.points).jacobian_factor(p)
        return r_factor(self.jacobian(p))

    def reduced_jacobian(self, p) -> np.ndarray:
        """A (n_free, n_free) matrix with the Gram matrix of the weighted Jacobian at ``p`` (by QR:
        its columns may be dependent)."""
        if self.contacts is None:
            return cast(Points, self.points).reduced_jacobian(p)
        return reduced(self.jacobian(p))

    def normal_equations(self, p) -> tuple[np.ndarray, np.ndarray, float]:
        """The R factor, gradient and sum of squares at ``p`` (a large campaign chunk by chunk)."""
        if self.chunked:
            return cast(Points, self.points).normal_equations(p)
        J, r = self.jacobian(p), self.residuals(p)
        return r_factor(J), J.T @ r, float(r @ r)

    def row_kinds(self) -> np.ndarray:
        """(n_rows,) index into ``ROW_KINDS`` of each row."""
        parts = [] if self.points is None else [self.points.row_kinds()]
        if self.contacts is not None:
            parts.append(np.array([ROW_KINDS.index(k) for k in self.contacts.row_kinds()], dtype=int))
        return np.concatenate(parts) if parts else np.zeros(0, dtype=int)

    def backlash_sides(self, p) -> dict:
        """Per backlash parameter name, the sides in [-1, 1] its joint rests on at every pose and
        contact row, at the full vector ``p``."""
        parts = [b.backlash_sides(p[:self.n_robot]) for b in (self.points, self.contacts) if b is not None]
        names = dict.fromkeys(n for part in parts for n in part)
        return {n: np.concatenate([part[n] for part in parts if n in part]) for n in names}

    def compliance_moments(self, p) -> dict:
        """Per compliance parameter name, the gravity moments (N m) it multiplies at every pose and
        contact row, at the full vector ``p``."""
        parts = [b.compliance_moments(p[:self.n_robot]) for b in (self.points, self.contacts) if b is not None]
        names = dict.fromkeys(n for part in parts for n in part)
        return {n: np.concatenate([part[n] for part in parts if n in part]) for n in names}

    def contact_positions(self, p) -> np.ndarray:
        """(n_contact_rows, 3) each contact row's marker position at the full vector ``p``."""
        return cast(ContactRows, self.contacts).positions(p[:self.n_robot])

    def socket_points(self, p) -> np.ndarray:
        """(n_sockets, 3) the socket points at the full vector ``p``, in the contacts' socket order."""
        return p[self.n_robot:self.n_robot + 3 * len(cast(ContactRows, self.contacts).sockets)].reshape(-1, 3)

    # ---- observations -------------------------------------------------------------------------
    def observations(self) -> Observations:
        """Every observation's kind, label, order and placement (``Observations``), those set aside
        included."""
        if self._observations is None:
            self._observations = self._listed_observations()
        return self._observations

    def _listed_observations(self) -> Observations:
        kinds, placements, order = [], [], []
        n_points = self.n_points
        rows = markers = np.zeros(0, dtype=int)
        pose_labels: Sequence[str] = ()
        marker_names: Sequence[str] = ()
        if self.points is not None:
            d = self.points.data
            rows, markers = np.nonzero(self.point_mask)
            kinds += ["tracker"] * n_points
            pose_labels, marker_names = d.labels, d.marker_names
            placements += [""] * n_points
            order.append(rows)
        contact_labels: Sequence[str] = ()
        if self.contacts is not None:
            c = self.contacts
            kinds += list(c.obs_kind)
            contact_labels = tuple(c.obs_label)
            placements += list(c.obs_placement)
            order.append(c.obs_row)
        return Observations(tuple(kinds), Labels(pose_labels, marker_names, rows, markers, contact_labels),
                            read_only(np.concatenate(order) if order else np.zeros(0, dtype=int)),
                            tuple(placements), n_points)

    def row_observations(self) -> np.ndarray:
        """(n_rows,) the observation (index into ``observations``) each row belongs to."""
        parts = []
        if self.points is not None:
            poses, markers = self.points.row_points()
            parts.append(self._point_index[poses, markers])
        if self.contacts is not None:
            parts.append(self.n_points + self.contacts.row_observations())
        return np.concatenate(parts) if parts else np.zeros(0, dtype=int)

    def observation_groups(self) -> np.ndarray:
        """(n_observations,) the group each observation belongs to: a measured marker, or a socket,
        plane, ball bar or known distance (``ContactRows.obs_groups``)."""
        parts = []
        n_markers = 0
        if self.points is not None:
            n_markers = self.point_mask.shape[1]
            parts.append(np.nonzero(self.point_mask)[1])
        if self.contacts is not None:
            groups = np.zeros(len(self.contacts.obs_kind), dtype=int)
            for g, (_, _, idx) in enumerate(self.contacts.obs_groups):
                groups[idx] = n_markers + g
            parts.append(groups)
        return np.concatenate(parts) if parts else np.zeros(0, dtype=int)

    def row_labels(self) -> list[str]:
        """A label for each row: its observation's."""
        labels = self.observations().label
        return [labels[o] for o in self.row_observations()]

    def pieces(self, p, at=None):
        """``(jacobian, residuals, row observations)`` at ``p``: whole (the Jacobian at ``at`` when
        given: one kept from a solve that ended a tolerance away), or for a large campaign of points
        a chunk of poses at a time."""
        if not self.chunked:
            yield self.jacobian(p if at is None else at), self.residuals(p), self.row_observations()
            return
        for J, r, poses, markers in cast(Points, self.points).pieces(p):
            yield J, r, self._point_index[poses, markers]

    def observation_errors(self, p) -> dict:
        """Per kind, the errors (n, width) in m of the observations fitted, their stated standard
        deviations (n,) or None, and their indices among ``observations`` (n,), read-only. The last
        vector's are kept: the outliers, the scatter and the checks ask for the solution's in turn."""
        key = frozen(p).tobytes()
        if self._errors_at is not None and self._errors_at[0] == key:
            return self._errors_at[1]
        out: dict = {}
        if self.points is not None:
            d = self.points.data
            errors = self.points.errors(p[:self.n_robot])[d.mask]
            out["tracker"] = (errors, None if d.sigma is None else d.sigma[d.mask], self._point_index[d.mask])
        if self.contacts is not None:
            for kind, (e, s, o) in self.contacts.errors(self._at(p)).items():
                out[kind] = (e, s, self.n_points + o)
        out = {kind: tuple(None if a is None else read_only(a) for a in v) for kind, v in out.items()}
        self._errors_at = (key, out)
        return out
