"""Joint-only recordings: the marker touched something of known shape, no instrument measured it.

Each row is one pose: its joint readings, the marker that touched, what it touched (``kind`` and
``target``) and where the fixture stood (``placement``). Rows sharing a placement and a target form
a group, and the kind says what the group means:

- ``socket``: every pose of the group put the marker on one fixed point (a ball seated in a socket);
  the point is unknown, a nuisance of the fit;
- ``plane``: every pose of the group put the marker on one plane, unknown unless the target names a
  known plane (``planes``);
- ``bar``: the group is two poses whose markers lie a known length apart (a ball bar, ``bars``).

``distances`` state the spacing of two sockets of a plate, true on every placement holding both.
Everything is SI and in the measurement frame W (without an instrument, the robot's base frame).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .._base.arrays import frozen, read_only
from .._base.errors import InputError

CONTACT_KINDS = ("socket", "plane", "bar")


@dataclass(frozen=True)
class KnownDistance:
    """The distance (m) between sockets ``a`` and ``b`` of a plate, with its standard deviation (m)."""

    a: str
    b: str
    length: float
    sigma: float


@dataclass(frozen=True)
class KnownPlane:
    """The plane ``normal . x = offset`` in W (unit normal, offset in m)."""

    name: str
    normal: tuple[float, float, float]
    offset: float


@dataclass(frozen=True)
class Group:
    """The rows (indices into the recordings) of one placement and target, and their kind."""

    kind: str
    placement: str
    target: str
    rows: np.ndarray

    @property
    def label(self) -> str:
        return f"{self.placement}/{self.target}" if self.placement else self.target


@dataclass(frozen=True, eq=False)
class Contacts:
    """Joint readings of contacts, one row per pose (see the module's docs).

    Shapes: ``q`` (n_rows, n_joints) rad or m; ``marker``, ``kind``, ``target``, ``placement`` one
    string per row; ``sigma`` (n_rows,) the standard deviation of a contact in metres (per axis for
    a socket, along the normal for a plane; a bar's row states that of its end). ``bars`` maps a
    bar's name to its (length, sigma) in metres; ``notes`` what the reader decided for the user
    (the sockets read, the files skipped). The arrays are the record's own, read-only.
    """

    q: np.ndarray
    marker: tuple[str, ...]
    kind: tuple[str, ...]
    target: tuple[str, ...]
    placement: tuple[str, ...]
    sigma: np.ndarray
    distances: tuple[KnownDistance, ...] = ()
    planes: tuple[KnownPlane, ...] = ()
    bars: dict = field(default_factory=dict)
    joint_names: tuple[str, ...] = ()
    labels: tuple[str, ...] = ()
    source: str = ""
    sha256: str = ""
    notes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        q = np.atleast_2d(np.asarray(self.q, dtype=float))
        n = q.shape[0]
        src = self.source or "contacts"
        sigma = np.broadcast_to(np.asarray(self.sigma, dtype=float), (n,)).copy()
        # the record's own read-only arrays: nothing a caller does to theirs, or to these, changes it
        object.__setattr__(self, "q", frozen(q))
        object.__setattr__(self, "sigma", read_only(sigma))
        if not self.labels:
            object.__setattr__(self, "labels", tuple(f"row {i}" for i in range(n)))
        for name in ("marker", "kind", "target", "placement"):
            if len(getattr(self, name)) != n:
                raise InputError(f"{name} has {len(getattr(self, name))} entries for {n} rows", source=src)
        bad = [i for i in range(n) if self.kind[i] not in CONTACT_KINDS]
        if bad:
            raise InputError(f"kind {self.kind[bad[0]]!r} is not one of {', '.join(CONTACT_KINDS)}", source=src,
                             where=self.labels[bad[0]])
        if not np.all(np.isfinite(q)):
            raise InputError("joint reading is not a finite number", source=src,
                             where=self.labels[int(np.argwhere(~np.isfinite(q))[0][0])])
        if np.any(~(sigma > 0) | ~np.isfinite(sigma)):
            raise InputError("sigma must be a positive number", source=src,
                             where=self.labels[int(np.argmax(~(sigma > 0) | ~np.isfinite(sigma)))])
        self._check_groups(src)

    def _check_groups(self, src: str) -> None:
        for g in self.groups():
            if len({self.kind[i] for i in g.rows}) > 1:
                raise InputError(f"group {g.label!r} mixes kinds {sorted({self.kind[i] for i in g.rows})}",
                                 source=src, where=self.labels[g.rows[0]])
            if g.kind == "bar" and len(g.rows) != 2:
                raise InputError(f"ball bar {g.label!r} has {len(g.rows)} rows; each pair is two poses",
                                 source=src, where=self.labels[g.rows[0]])
            if g.kind == "bar" and g.target not in self.bars:
                raise InputError(f"ball bar {g.target!r} has no stated length", source=src,
                                 where=self.labels[g.rows[0]])
        for d in self.distances:
            if not (d.length > 0 and d.sigma > 0):
                raise InputError(f"distance {d.a}-{d.b}: length and sigma must be positive", source=src)
        for name, (length, s) in self.bars.items():
            if not (length > 0 and s > 0):
                raise InputError(f"ball bar {name!r}: length and sigma must be positive", source=src)

    @property
    def n_rows(self) -> int:
        return self.q.shape[0]

    def groups(self, kind: str | None = None) -> list[Group]:
        """The groups (placement, target) in order of first appearance, of one ``kind`` or all."""
        return [g for g in self._every_group if kind is None or g.kind == kind]

    @cached_property
    def _every_group(self) -> tuple[Group, ...]:
        """Every group, found once per record: the problems and the diagnosis ask at every step."""
        first: dict = {}
        for i, key in enumerate(zip(self.placement, self.target)):
            first.setdefault(key, []).append(i)
        return tuple(Group(self.kind[rows[0]], p, t, read_only(np.array(rows, dtype=int)))
                     for (p, t), rows in first.items())

    def known_plane(self, target: str) -> KnownPlane | None:
        return next((p for p in self.planes if p.name == target), None)

    def distance_pairs(self) -> list[tuple[KnownDistance, Group, Group]]:
        """Each known distance on each placement holding both of its sockets."""
        sockets = {(g.placement, g.target): g for g in self.groups("socket")}
        placements = dict.fromkeys(g.placement for g in sockets.values())
        return [(d, sockets[(p, d.a)], sockets[(p, d.b)]) for p in placements for d in self.distances
                if (p, d.a) in sockets and (p, d.b) in sockets]

    def subset(self, index) -> Contacts:
        """The rows selected by ``index`` (boolean mask or integer indices)."""
        idx = np.arange(self.n_rows)[index]

        def pick(t):
            return tuple(t[i] for i in idx)

        return Contacts(q=self.q[idx], marker=pick(self.marker), kind=pick(self.kind), target=pick(self.target),
                        placement=pick(self.placement), sigma=self.sigma[idx], distances=self.distances,
                        planes=self.planes, bars=self.bars, joint_names=self.joint_names, labels=pick(self.labels),
                        source=self.source, sha256=self.sha256, notes=self.notes)

    def placements(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(self.placement))

    def split_placements(self, held_out) -> tuple[Contacts, Contacts]:
        """(fit, validation): the rows of the placements ``held_out`` (names) kept apart."""
        held = np.array([p in set(held_out) for p in self.placement])
        return self.subset(~held), self.subset(held)
