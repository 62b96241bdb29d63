"""A campaign from recorded streams: the moments the joints stand still, each paired with an
instrument's samples by time, averaged (docs/formats.md, "ROS bags").

A still moment is a run of joint samples where every joint's speed, its change over
``SPEED_SPAN`` seconds around the sample, stays within the bound of its kind (revolute rad/s,
prismatic m/s), lasting ``min_duration`` or more; a gap in the joint stream longer than ``max_gap``
ends it. Its joint readings are the mean of its samples. A marker's samples count from ``settle``
seconds after the moment starts (the arm rings as it stops) to its end, on the robot's clock (an
instrument stamp ``t`` is robot time ``t - clock_offset``). The marker is missing there with fewer
than ``min_samples`` samples, and moving when the means of the first and second half of its samples
lie further apart than both ``drift`` and 5 standard errors of that difference (from the noise of
successive samples, which a slow motion does not inflate); either way it is masked in that pose,
and a pose with no marker left is dropped. Every masked marker and dropped pose is listed with its
times.

A marker's point is the mean of its samples, and its standard deviation (``sigma``, and
``sigma_rot`` for a rotation) the scatter of the samples about it, the root mean square of the
per-axis standard deviations, over the square root of their number: the deviation of the mean of
independent samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from .._base.errors import DegenerateDataError, InputError
from .._model.measurements import Measurements
from .._model.robot import RobotModel

# the span over which a joint's speed is taken, s: long enough to average an encoder's noise, short
# enough that a moment's edges stay within a tenth of a second of the motion
SPEED_SPAN = 0.1
# a drift this many standard errors of the halves' difference is motion, not noise
DRIFT_SE = 5.0
# a deviation of exactly zero (a quantised or noiseless stream) is written as this, m and rad
SMALLEST_SIGMA = 1e-9


@dataclass(frozen=True)
class StillRules:
    """How still moments are found and paired (SI: rad/s, m/s, s, m); the defaults are in the
    command's units in docs/formats.md."""

    speed_revolute: float = np.deg2rad(0.1)
    speed_prismatic: float = 1e-4
    min_duration: float = 0.5
    settle: float = 0.2
    min_samples: int = 10
    drift: float = 2e-5
    clock_offset: float = 0.0
    max_gap: float = 0.25

    def __post_init__(self) -> None:
        for name in ("speed_revolute", "speed_prismatic", "min_duration", "min_samples", "drift", "max_gap"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and not isinstance(v, bool) and 0 < v < np.inf):
                raise InputError(f"must be a positive number, got {v!r}", where=f"rules.{name}")
        for name in ("settle", "clock_offset"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v)):
                raise InputError(f"must be a finite number, got {v!r}", where=f"rules.{name}")
        if self.min_samples < 2 or self.min_samples != int(self.min_samples):
            raise InputError(f"must be a whole number of 2 or more (a scatter needs two), got {self.min_samples!r}",
                             where="rules.min_samples")


@dataclass(frozen=True)
class Stream:
    """Samples of one instrument (or the joints): ``t`` (n,) seconds, increasing, ``values`` (n, k)
    in SI; for a marker ``rotations`` (n, 4) quaternions (x, y, z, w) or None."""

    name: str
    t: np.ndarray
    values: np.ndarray
    rotations: np.ndarray | None = None


@dataclass(frozen=True)
class Left:
    """A marker (or, with ``marker`` None, a pose) left out of a still moment from ``start`` to ``end`` (s)."""

    start: float
    end: float
    marker: str | None
    reason: str

    def __str__(self) -> str:
        what = f"marker {self.marker}" if self.marker else "pose dropped"
        return f"{self.start:.2f}-{self.end:.2f} s: {what}: {self.reason}"


def still_moments(joints: Stream, prismatic: np.ndarray, rules: StillRules) -> np.ndarray:
    """(n_moments, 2) first and last sample index of each still moment of ``joints``.

    ``prismatic`` (n_joints,) True for the joints whose speed bound is in m/s.
    """
    t, q = joints.t, joints.values
    if t.size < 2:
        return np.zeros((0, 2), dtype=int)
    i = np.arange(t.size)
    # the samples SPEED_SPAN apart around each, at least its neighbours (a slow stream)
    lo = np.minimum(np.searchsorted(t, t - SPEED_SPAN / 2, side="left"), np.maximum(i - 1, 0))
    hi = np.maximum(np.searchsorted(t, t + SPEED_SPAN / 2, side="right") - 1, np.minimum(i + 1, t.size - 1))
    span = np.maximum(t[hi] - t[lo], 1e-12)
    bound = np.where(prismatic, rules.speed_prismatic, rules.speed_revolute)
    still = np.all(np.abs(q[hi] - q[lo]) <= bound * span[:, None], axis=1) & (hi > lo)
    # runs of still samples, cut where the stream has a gap
    gap = np.concatenate([[True], np.diff(t) > rules.max_gap, [True]])     # before sample i; after the last
    before = np.concatenate([[False], still[:-1]])
    after = np.concatenate([still[1:], [False]])
    starts = np.flatnonzero(still & (~before | gap[:-1]))
    ends = np.flatnonzero(still & (~after | gap[1:]))
    runs = np.column_stack([starts, ends])
    return runs[t[ends] - t[starts] >= rules.min_duration]


def campaign(joints: Stream, markers: tuple[Stream, ...], model: RobotModel, rules: StillRules, *,
             source: str = "") -> tuple[Measurements, tuple[Left, ...], tuple[str, ...]]:
    """The measurements of ``markers`` at the still moments of ``joints`` (values in the model's
    joint order), what was left out, and a note per marker on its samples' scatter.

    Each pose is one still moment: its readings the mean of the joint samples, each marker the mean
    of its samples there, with the deviation of that mean (``sigma``; ``sigma_rot`` with rotations).
    """
    moments = still_moments(joints, np.array([k == "length" for k in model.reading_quantities]), rules)
    if not len(moments):
        raise DegenerateDataError(f"{source}: no still moment of {rules.min_duration:g} s or more in {joints.name} "
                                  f"(every joint within {np.rad2deg(rules.speed_revolute):g} deg/s, "
                                  f"{rules.speed_prismatic * 1e3:g} mm/s)")
    start, end = joints.t[moments[:, 0]], joints.t[moments[:, 1]]
    q = _means(joints.values, *_gather(moments[:, 0], moments[:, 1] + 1), len(moments))
    seen = [_marker(m, start + rules.settle, end, rules) for m in markers]
    kept = np.any([s.measured for s in seen], axis=0)
    left = [Left(start[i], end[i], m.name, why) for m, s in zip(markers, seen) for i, why in s.why.items()]
    left += [Left(start[i], end[i], None, "no marker measured") for i in np.flatnonzero(~kept)]
    left.sort(key=lambda x: (x.start, x.marker or ""))
    if not kept.any():
        raise DegenerateDataError(f"{source}: none of the {len(moments)} still moments has a marker measured ("
                                  f"{'; '.join(map(str, left[:3]))}...): check the instrument's topic and "
                                  "--clock-offset")
    data = Measurements(q=q[kept], positions=np.stack([s.positions for s in seen], axis=1)[kept],
                        marker_names=tuple(m.name for m in markers), joint_names=model.joint_names,
                        mask=np.column_stack([s.measured for s in seen])[kept],
                        sigma=np.column_stack([s.sigma for s in seen])[kept],
                        labels=tuple(f"t={a:.2f}s" for a in start[kept]), source=source,
                        **_rotation_fields(seen, kept))
    notes = tuple(f"marker {m.name}: samples scatter {np.nanmedian(s.scatter[kept]) * 1e3:.4f} mm per axis (median "
                  f"over the poses), {np.nanmedian(s.sigma[kept]) * 1e3:.4f} mm as the deviation of their mean "
                  "(the sigma written)" for m, s in zip(markers, seen) if s.measured[kept].any())
    return data, tuple(left), notes


def _gather(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The sample indices of the windows ``[lo, hi)`` one after another, and the window of each."""
    n = np.maximum(hi - lo, 0)
    owner = np.repeat(np.arange(lo.size), n)
    first = np.repeat(np.cumsum(n) - n, n)
    return np.arange(n.sum()) - first + np.repeat(lo, n), owner


def _means(values: np.ndarray, idx: np.ndarray, owner: np.ndarray, n_windows: int) -> np.ndarray:
    """(n_windows, k) mean of ``values[idx]`` per window (NaN for an empty one), taken about each
    window's first sample so that large coordinates keep their small differences."""
    first = np.full(n_windows, -1)
    first[owner[::-1]] = idx[::-1]
    ref = np.where(first[:, None] >= 0, values[np.maximum(first, 0)], 0.0)
    x = values[idx] - ref[owner]
    count = np.bincount(owner, minlength=n_windows).astype(float)
    sums = np.column_stack([np.bincount(owner, x[:, j], n_windows) for j in range(x.shape[1])])
    with np.errstate(invalid="ignore", divide="ignore"):
        return ref + sums / count[:, None]


@dataclass(frozen=True)
class _Seen:
    """A marker over the still moments: ``positions`` (n, 3), ``sigma`` (n,) the deviation of each
    mean and ``scatter`` (n,) its samples', NaN where not ``measured``; ``quats`` (n, 4) and
    ``sigma_rot`` (n,) or None; and why each left-out moment was."""

    positions: np.ndarray
    sigma: np.ndarray
    scatter: np.ndarray
    measured: np.ndarray
    quats: np.ndarray | None
    sigma_rot: np.ndarray | None
    why: dict


def _marker(m: Stream, start: np.ndarray, end: np.ndarray, rules: StillRules) -> _Seen:
    """Marker stream ``m`` over the moments ``[start, end]`` (robot time)."""
    t = m.t - rules.clock_offset
    lo, hi = np.searchsorted(t, start, side="left"), np.searchsorted(t, end, side="right")
    n = np.maximum(hi - lo, 0)
    idx, owner = _gather(lo, hi)
    mean = _means(m.values, idx, owner, len(lo))
    dev = m.values[idx] - mean[owner]
    with np.errstate(invalid="ignore", divide="ignore"):
        var = np.column_stack([np.bincount(owner, dev[:, j] ** 2, len(lo)) for j in range(3)]) / (n - 1)[:, None]
        scatter = np.sqrt(var.mean(axis=1))
        half = (idx - lo[owner]) >= n[owner] // 2
        halves = _means(m.values, idx, owner * 2 + half, 2 * len(lo)).reshape(len(lo), 2, 3)
        drift = np.linalg.norm(halves[:, 1] - halves[:, 0], axis=1)
        se = _noise(m.values, idx, owner, n) * np.sqrt(1.0 / np.maximum(n // 2, 1) + 1.0 / np.maximum(n - n // 2, 1))
        sigma = np.maximum(scatter / np.sqrt(n), SMALLEST_SIGMA)
    why = {int(i): f"missing ({n[i]} sample(s), {rules.min_samples} needed)"
           for i in np.flatnonzero(n < rules.min_samples)}
    why.update({int(i): f"moving ({drift[i] * 1e3:.3f} mm between the means of the halves of its {n[i]} samples)"
                for i in np.flatnonzero((n >= rules.min_samples) & (drift > np.maximum(rules.drift, DRIFT_SE * se)))})
    measured = np.ones(len(lo), dtype=bool)
    measured[list(why)] = False
    quats, sigma_rot = (None, None) if m.rotations is None else _mean_rotations(m.rotations, idx, owner, n)
    return _Seen(np.where(measured[:, None], mean, np.nan), np.where(measured, sigma, np.nan),
                 np.where(measured, scatter, np.nan), measured, quats,
                 None if sigma_rot is None else np.where(measured, sigma_rot, np.nan), why)


def _noise(values: np.ndarray, idx: np.ndarray, owner: np.ndarray, n: np.ndarray) -> np.ndarray:
    """(n_windows,) the samples' noise per axis from the differences of successive samples in each
    window: unlike their scatter about the mean, not inflated by a marker that moves."""
    step = values[idx[1:]] - values[idx[:-1]]
    same = owner[1:] == owner[:-1]
    sums = np.bincount(owner[1:][same], np.sum(step[same] ** 2, axis=1), n.size)
    return np.sqrt(sums / (6 * np.maximum(n - 1, 1)))


def _mean_rotations(quats: np.ndarray, idx: np.ndarray, owner: np.ndarray, n: np.ndarray):
    """(mean quaternions (n_windows, 4), their deviation (n_windows,) rad): each sample's sign aligned
    with its window's first, the normalised mean, and the root mean square of the rotation vectors
    from it, per axis, over the square root of their number."""
    n_windows = n.size
    x = quats[idx]
    first = np.zeros((n_windows, 4))
    first[owner[::-1]] = x[::-1]
    x = x * np.where(np.sum(x * first[owner], axis=1) < 0, -1.0, 1.0)[:, None]
    mean = np.column_stack([np.bincount(owner, x[:, j], n_windows) for j in range(4)])
    norm = np.linalg.norm(mean, axis=1)
    mean = np.where(norm[:, None] > 0, mean / np.where(norm > 0, norm, 1.0)[:, None], [0.0, 0.0, 0.0, 1.0])
    if not idx.size:
        return mean, np.full(n_windows, np.nan)
    spread = (Rotation.from_quat(mean[owner]).inv() * Rotation.from_quat(x)).as_rotvec()
    with np.errstate(invalid="ignore", divide="ignore"):
        scatter = np.sqrt(np.bincount(owner, np.sum(spread ** 2, axis=1), n_windows) / (3 * np.maximum(n - 1, 1)))
        return mean, np.maximum(scatter / np.sqrt(n), SMALLEST_SIGMA)


def _rotation_fields(seen: list[_Seen], kept: np.ndarray) -> dict:
    """The rotations, their mask and scatter of the kept poses, for the markers whose stream has
    them (the identity, unmeasured, for the others); none when no stream has them."""
    if all(s.quats is None for s in seen):
        return {}
    eye = np.broadcast_to(np.eye(3), (kept.size, 3, 3))
    rotations = np.stack([eye if s.quats is None else Rotation.from_quat(s.quats).as_matrix() for s in seen], axis=1)
    rot_mask = np.column_stack([s.measured & (s.quats is not None) for s in seen])
    sigma_rot = np.column_stack([np.full(kept.size, np.nan) if s.sigma_rot is None else s.sigma_rot for s in seen])
    return {"rotations": rotations[kept], "rot_mask": rot_mask[kept], "sigma_rot": sigma_rot[kept]}
