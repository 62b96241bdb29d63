"""The measurement set: joint readings and what the instrument saw, in SI and the measurement frame."""

from __future__ import annotations

import weakref
from dataclasses import dataclass, field, fields, replace

import numpy as np

from .._base.arguments import (
    accepts,
    shaped,
)
from .._base.arrays import frozen, read_only
from .._base.errors import InputError, check_choice
from .._base.options import DEFAULT_INSTRUMENT, INSTRUMENT_NOISE


@accepts(q=shaped(None, None))
def approach_sides(q) -> np.ndarray:
    """+1 or -1 per pose and joint: the sign of the last move of that joint before reaching the pose.

    Poses are visited in row order, the first approached from the last (as in a cycle); a joint
    that does not move keeps the side it had (+1 if it never moves). ``q`` (n_poses, n_joints).

    Parameters
    ----------
    q : array_like, shape (n_poses, n_joints)
        Joint readings in the order they were visited.

    Returns
    -------
    numpy.ndarray, shape (n_poses, n_joints)
        Direction (+1 or -1) of each joint's last move.
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    step = np.sign(np.diff(q, axis=0, prepend=q[-1:]))
    n = len(q)
    # forward-fill over the rows where a joint did not move, cycling once so the first poses
    # inherit the side of the last move before them
    rows = np.arange(2 * n)[:, None]
    twice = np.vstack([step, step])
    last = np.maximum.accumulate(np.where(twice != 0, rows, -1), axis=0)[n:]
    sides = np.take_along_axis(twice, np.maximum(last, 0), axis=0)
    return np.where(last >= 0, sides, 1.0)


def approach_of(data: Measurements) -> np.ndarray:
    """(n_poses, n_joints) approach direction of each joint at each pose: the file's ``approach``
    columns (``extra["approach"]``) when it has them, else from the visiting order of the rows."""
    a = data.extra.get("approach")
    return approach_sides(data.q) if a is None else np.asarray(a, dtype=float)


@dataclass(frozen=True)
class Noise:
    """The expected scatter of measurements about a perfect model, one standard deviation per axis:
    ``position`` (m) and ``rotation`` (rad); ``source`` says where the figures come from;
    ``instrument`` the class of instrument (``INSTRUMENT_NOISE``) whose own noise the stated figures
    may exceed (a stated noise may hold the robot's repeatability too)."""

    position: float
    rotation: float
    source: str
    instrument: str = DEFAULT_INSTRUMENT

    @property
    def stated(self) -> bool:
        return self.source.startswith("stated")

    def instrument_share(self) -> tuple[float, float]:
        """The part of the figures (position m, rotation rad) that is the instrument's own: the class's
        noise at most, when the figures were stated."""
        p, r = INSTRUMENT_NOISE[self.instrument]
        return (min(self.position, p), min(self.rotation, r)) if self.stated else (self.position, self.rotation)

    @staticmethod
    def of(instrument: str = DEFAULT_INSTRUMENT, *, position: float | None = None,
           rotation: float | None = None) -> Noise:
        """An instrument class's noise (``INSTRUMENT_NOISE``), or the figures given, SI."""
        check_choice(instrument, INSTRUMENT_NOISE, "instrument")
        p, r = INSTRUMENT_NOISE[instrument]
        for name, v in (("position", position), ("rotation", rotation)):
            if v is not None and not (isinstance(v, (int, float)) and 0 < v < np.inf):
                raise InputError(f"must be a positive number, got {v!r}", where=f"noise {name}")
        given = [n for n, v in (("position", position), ("rotation", rotation)) if v is not None]
        source = f"{instrument} (default)" if not given else f"stated ({', '.join(given)})"
        return Noise(position=float(position or p), rotation=float(rotation or r), source=source,
                     instrument=instrument)


@dataclass(frozen=True, eq=False)
class Measurements:
    """Joint readings with measured marker positions (and optionally orientations) per pose.

    Shapes: ``q`` (n_poses, n_joints) in rad or m; ``positions`` (n_poses, n_markers, 3) in metres
    in the measurement frame W, NaN where a marker was not seen; ``mask`` (n_poses, n_markers) True
    where a position was measured (rows are masked, never dropped). ``rotations`` (n_poses,
    n_markers, 3, 3) marker orientations in W (``rot_mask`` likewise) or None for points only.
    ``sigma`` (n_poses, n_markers) position standard deviation per measurement in metres and
    ``sigma_rot`` in radians, or None (unweighted). ``payload_mass`` (n_poses,) kg or None.
    ``labels`` names each pose for messages (e.g. the CSV row). ``extra`` holds anything else a
    reader found; arrays with one entry per pose follow ``subset``. Every array is the record's own
    read-only copy.
    """

    q: np.ndarray
    positions: np.ndarray
    marker_names: tuple[str, ...]
    joint_names: tuple[str, ...] = ()
    mask: np.ndarray = None  # type: ignore[assignment]  # None: where the position is finite
    rotations: np.ndarray | None = None
    rot_mask: np.ndarray | None = None
    sigma: np.ndarray | None = None
    sigma_rot: np.ndarray | None = None
    payload_mass: np.ndarray | None = None
    labels: tuple[str, ...] = ()
    source: str = ""
    sha256: str = ""
    extra: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        q = np.atleast_2d(np.asarray(self.q, dtype=float))
        pos = np.asarray(self.positions, dtype=float)
        if pos.ndim == 2:
            pos = pos[:, None, :]
        n = q.shape[0]
        src = self.source or "measurements"
        if pos.shape != (n, len(self.marker_names), 3):
            raise InputError(f"positions must have shape ({n}, {len(self.marker_names)}, 3), got {pos.shape}",
                             source=src)
        if not np.all(np.isfinite(q)):
            r, c = np.argwhere(~np.isfinite(q))[0]
            raise InputError("joint reading is not a finite number", source=src,
                             where=f"{self._label(r)}, joint {c}")
        mask = self._position_mask(pos, src)
        rot, rmask = self._rotations(n, src)
        self._own_sigmas(mask, rmask, src)
        self._own_payload(n, src)
        # the record's arrays are its own and read-only: a caller's array changed later, or one
        # the record handed out written into, cannot change what it holds
        for name, value, dtype in (("q", q, float), ("positions", pos, float), ("mask", mask, bool),
                                   ("rotations", rot, float), ("rot_mask", rmask, bool),
                                   ("sigma", self.sigma, float), ("sigma_rot", self.sigma_rot, float),
                                   ("payload_mass", self.payload_mass, float)):
            object.__setattr__(self, name, None if value is None else frozen(value, dtype))
        object.__setattr__(self, "extra", {k: frozen(v, v.dtype) if isinstance(v, np.ndarray) else v
                                           for k, v in self.extra.items()})
        if not self.labels:
            object.__setattr__(self, "labels", tuple(f"pose {i}" for i in range(n)))

    def _position_mask(self, pos: np.ndarray, src: str) -> np.ndarray:
        """The mask given (or where ``pos`` is finite), checked against the positions."""
        mask = np.all(np.isfinite(pos), axis=2) if self.mask is None else np.asarray(self.mask, dtype=bool)
        if mask.shape != pos.shape[:2]:
            raise InputError("mask shape does not match positions", source=src)
        bad = mask & ~np.all(np.isfinite(pos), axis=2)
        if bad.any():
            r, m = np.argwhere(bad)[0]
            raise InputError(f"marker {self.marker_names[m]!r} position is not finite", source=src,
                             where=self._label(r))
        return mask

    def _rotations(self, n: int, src: str) -> tuple[np.ndarray | None, np.ndarray | None]:
        """The rotations (shape checked) and their mask (given, or where they are finite)."""
        rot, rmask = self.rotations, self.rot_mask
        if rot is not None:
            rot = np.asarray(rot, dtype=float)
            if rot.shape != (n, len(self.marker_names), 3, 3):
                raise InputError("rotations must have shape (n_poses, n_markers, 3, 3)", source=src)
            rmask = np.all(np.isfinite(rot), axis=(2, 3)) if rmask is None else np.asarray(rmask, dtype=bool)
        return rot, rmask

    def _own_sigmas(self, mask: np.ndarray, rmask: np.ndarray | None, src: str) -> None:
        """``sigma`` and ``sigma_rot`` one per pose and marker, positive wherever they are used."""
        for name in ("sigma", "sigma_rot"):
            s = getattr(self, name)
            if s is not None:
                s = np.broadcast_to(np.asarray(s, dtype=float), mask.shape).copy()
                used = mask if name == "sigma" else (rmask if rmask is not None else mask)
                if np.any(used & ~(s > 0)):
                    r, m = np.argwhere(used & ~(s > 0))[0]
                    raise InputError(f"{name} must be a positive number", source=src,
                                     where=f"{self._label(r)}, marker {self.marker_names[m]!r}")
                object.__setattr__(self, name, s)

    def _own_payload(self, n: int, src: str) -> None:
        """``payload_mass`` one per pose, finite and non-negative."""
        if self.payload_mass is not None:
            pm = np.broadcast_to(np.asarray(self.payload_mass, dtype=float), (n,)).copy()
            if np.any(~np.isfinite(pm) | (pm < 0)):
                r = int(np.argwhere(~np.isfinite(pm) | (pm < 0))[0][0])
                raise InputError("payload mass must be a non-negative number", source=src, where=self._label(r))
            object.__setattr__(self, "payload_mass", pm)

    def _label(self, i: int) -> str:
        return self.labels[i] if self.labels else f"pose {i}"

    @property
    def n_poses(self) -> int:
        return self.q.shape[0]

    @property
    def has_orientation(self) -> bool:
        return self.rotations is not None and bool(np.any(self.rot_mask))

    def subset(self, index) -> Measurements:
        """The poses selected by ``index`` (a slice, boolean mask or integer indices)."""
        idx: slice | np.ndarray
        if isinstance(index, slice):    # a block of poses (a chunk): cut by the slice itself, no index array
            idx = slice(*index.indices(self.n_poses))
            labels = self.labels[idx]
        else:
            idx = np.arange(self.n_poses)[index]
            labels = tuple(self._label_array()[idx].tolist())

        def cut(a):
            return None if a is None else a[idx]

        # the rows of a checked record pass every check again: the cut arrays are only made read-only
        part = _checked(
            self, q=self.q[idx], positions=self.positions[idx], mask=self.mask[idx], rotations=cut(self.rotations),
            rot_mask=cut(self.rot_mask), sigma=cut(self.sigma), sigma_rot=cut(self.sigma_rot),
            payload_mass=cut(self.payload_mass), labels=labels,
            extra={k: (read_only(v[idx]) if isinstance(v, np.ndarray) and v.shape[:1] == (self.n_poses,) else v)
                   for k, v in self.extra.items()},
        )
        object.__setattr__(part, "_cut_from", (weakref.ref(self), idx))
        return part

    def derived(self, key, make, rows) -> tuple:
        """The arrays ``make(self)`` derives from these readings (a tuple), made once per record and
        ``key`` while somebody holds them: the record keeps weak references only, so nothing made
        in one calibration outlives it or serves the next. A record ``subset`` cut from another
        whose arrays are held takes ``rows(arrays, index)`` of them (per-pose quantities: the rows
        of the whole's, the same numbers)."""
        memo = self.__dict__.get("_derived")
        if memo is None:
            object.__setattr__(self, "_derived", memo := {})
        held = _held(memo.get(key))
        if held is None:
            whole, index = self.__dict__.get("_cut_from", (lambda: None, None))
            of_whole = _held(getattr(whole(), "_derived", {}).get(key))
            held = tuple(rows(of_whole, index) if of_whole is not None else make(self))
            memo[key] = tuple(weakref.ref(a) for a in held)
        return held

    def _label_array(self) -> np.ndarray:
        """The labels as an object array, made once: picking thousands of them is then one take."""
        if "_labels" not in self.__dict__:
            object.__setattr__(self, "_labels", np.array(self.labels, dtype=object))
        return self.__dict__["_labels"]

    def split(self, n_validation: int | float, *, rng=None) -> tuple[Measurements, Measurements]:
        """Random split into (fit, validation); ``n_validation`` a count or a fraction. Each part keeps
        the approach directions of the visiting order of the whole (``approach_of``)."""
        rng = np.random.default_rng(rng)
        n_val = int(round(n_validation * self.n_poses)) if 0 < n_validation < 1 else int(n_validation)
        order = rng.permutation(self.n_poses)
        whole = self.with_approach()
        return whole.subset(np.sort(order[n_val:])), whole.subset(np.sort(order[:n_val]))

    def with_approach(self) -> Measurements:
        """These measurements with their approach directions stored (``extra["approach"]``), so that a
        subset keeps the directions of this visiting order."""
        if "approach" in self.extra:
            return self
        return replace(self, extra={**self.extra, "approach": approach_sides(self.q)})

    def without(self, aside: np.ndarray) -> Measurements:
        """The same poses with the points ``aside`` (n_poses, n_markers) masked: set aside, not deleted."""
        return replace(self, mask=self.mask & ~aside,
                       rot_mask=None if self.rot_mask is None else self.rot_mask & ~aside)


def _checked(record: Measurements, **cut) -> Measurements:
    """A record of ``record``'s fields with those in ``cut`` replaced by parts of its own checked,
    read-only arrays: built without ``__post_init__``'s checks and copies, which they pass already."""
    out = object.__new__(Measurements)
    for f in fields(Measurements):
        value = cut[f.name] if f.name in cut else getattr(record, f.name)
        object.__setattr__(out, f.name, read_only(value) if isinstance(value, np.ndarray) else value)
    return out


def _held(refs) -> tuple | None:
    """The arrays behind the weak references ``refs``, or None when any is gone (or none was kept)."""
    arrays = None if refs is None else tuple(r() for r in refs)
    return None if arrays is None or any(a is None for a in arrays) else arrays
