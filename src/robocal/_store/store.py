"""The store of calibrations: each robot's history, the changes between its calibrations, robots
of one type side by side, and verifications against the stored calibrated model.

A store is one SQLite file (the default) or a PostgreSQL database given by URL (the ``store-pg``
extra), with the same tables (docs/store.md). The schema carries its version and is upgraded in
place when a newer robocal opens it. Every write is one transaction: a process killed while
recording, or two processes recording at once, lose nothing and leave nothing half-written.
Values are SI, as in result files.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
import zlib
from collections.abc import Sequence
from contextlib import contextmanager, suppress
from dataclasses import dataclass, replace
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from .._accuracy.verification import DEFAULT_ALPHA as VERIFY_ALPHA
from .._accuracy.verification import SEATINGS, Accuracy, Verification, verify
from .._base.arguments import (
    FLAG,
    FRACTION,
    INSTANT,
    MAPPING,
    MAPPING_LIKE,
    PATH,
    TEXT,
    accepts,
    each_a,
    in_range,
    is_a,
    names_in,
    optional,
    whole,
)
from .._base.errors import InputError, excerpt
from .._files.model import model_from_dict, model_to_dict
from .._files.result import plain, result_to_dict
from .._identification.holdout import REGISTERED_ON_IT
from .._identification.result import CalibrationResult
from .._model.contacts import Contacts
from .._model.measurements import Measurements
from .._model.parameters import FAMILIES
from .._model.robot import RobotModel

SCHEMA_VERSION = 3
ENVIRONMENT = "ROBOCAL_STORE"
# the share of unchanged robots (histories) or of fleets in which a change is named
DEFAULT_ALPHA = 0.05
# the parameters whose changes are judged: the base and the markers are placed anew for each campaign
JUDGED_FAMILIES = ("frames", "compliance", "backlash", "transmission")
# the share of a history's alpha spent on the overall chi-square test of each pair of calibrations
# ("something changed"); the single-parameter tests get the rest (Bonferroni between the two)
OVERALL_SHARE = 0.2
# directions of a combined covariance (in its correlation form) whose eigenvalue is below this
# share of the largest are not identified and left out of the tests: for correlations kept at
# double precision, and at single precision (stores written before schema version 3)
RCOND = {8: 1e-10, 4: 1e-4}
MAX_NAME = 200
# the largest standard deviation judged: its square, a variance, still a float
MAX_STD = 1e150
# a parameter one calibration fits this many standard deviations from its nominal and the other
# holds at nominal (or leaves out) is carried by the other's estimates: without correlations to take
# it back to nominal with, the two are not compared
APART_SIGMAS = 3.0
# seconds a write waits for another process's write lock, and before it says it waits
LOCK_WAIT = 120.0
WAIT_NOTICE = 1.0


# -- where the store is ---------------------------------------------------------------------------

def _name(value, name, _):
    check_name(value, name)


_FAMILIES = names_in(lambda _: [f for f in FAMILIES if f != "geometric"], "a parameter family")
_JUDGED = dict(alpha=FRACTION, families=_FAMILIES)

@accepts(environ=optional(MAPPING_LIKE))
def default_store_path(environ=None) -> Path:
    """The store used when none is named: ``$XDG_DATA_HOME/robocal/store.sqlite`` (by default
    ``~/.local/share/robocal/store.sqlite``).

    Parameters
    ----------
    environ : mapping, optional
        The environment variables (None: ``os.environ``).

    Returns
    -------
    pathlib.Path
        The default store's file.
    """
    environ = os.environ if environ is None else environ
    base = environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(base) / "robocal" / "store.sqlite"


@accepts(option=optional(PATH), environ=optional(MAPPING_LIKE))
def store_location(option: str | None = None, environ=None) -> str:
    """The store to open: ``option`` (``--store``), else ``$ROBOCAL_STORE``, else the default path.

    Parameters
    ----------
    option : str or os.PathLike, optional
        The store named (a SQLite file or a ``postgresql://`` URL).
    environ : mapping, optional
        The environment variables (None: ``os.environ``).

    Returns
    -------
    str
        The store's file path or URL.
    """
    environ = os.environ if environ is None else environ
    return str(option or environ.get(ENVIRONMENT) or default_store_path(environ))


def is_url(location: str) -> bool:
    return bool(re.match(r"postgres(ql)?://", str(location)))


def _check_scheme(location: str) -> None:
    """A URL of any scheme but PostgreSQL's is refused: never taken as a relative path."""
    scheme = re.match(r"([A-Za-z][A-Za-z0-9+.-]*)://", location)
    if scheme and not is_url(location):
        raise InputError(f"a store is a SQLite file or a postgresql:// URL; robocal has no {scheme[1]!r} back-end",
                         source=shown_location(location))


def shown_location(location: str) -> str:
    """The location as messages show it: a URL's password hidden."""
    return re.sub(r"(://[^:/@]*:)[^@]*@", r"\1***@", str(location))


# -- records --------------------------------------------------------------------------------------

class Estimate(NamedTuple):
    """One stored parameter: SI ``unit``, its ``family``, the nominal value, the estimate and its
    standard deviation."""

    name: str
    unit: str
    family: str
    nominal: float
    estimate: float
    std: float


@dataclass(frozen=True, eq=False)
class StoredCalibration:
    """One calibration of one robot as the store keeps it.

    ``calibrated_at``/``recorded_at`` ISO 8601 UTC; ``fingerprint`` SHA-256 of the input files'
    SHA-256s (``inputs``: input name -> SHA-256); ``checks`` (name, status, summary) of each check;
    ``accuracy`` the position accuracy reached (None when the result has no error statistics): of
    the measured points when it has any, else of its held-out seatings; ``seatings_accuracy`` that of
    its held-out seatings when it fitted or held out measured points too (``accuracy_for``);
    ``in_use`` the result's predicted accuracy in use when it has one; ``limit_m`` the limit of
    absolute accuracy when known; the models by the SHA-256 of their file form
    (``Store.model``). ``correlation`` (n, n) the correlation of the estimates (in their order),
    or None. ``id`` is None before it is stored.
    """

    robot: str
    robot_type: str | None
    calibrated_at: str
    recorded_at: str
    fingerprint: str
    verdict: str
    checks: tuple[tuple[str, str, str], ...]
    estimates: tuple[Estimate, ...]
    accuracy: Accuracy | None
    in_use: dict | None
    limit_m: float | None
    nominal_model: str
    calibrated_model: str
    source: str = ""
    inputs: tuple[tuple[str, str], ...] = ()
    id: int | None = None
    correlation: np.ndarray | None = None
    seatings_accuracy: Accuracy | None = None

    def estimate(self, name: str) -> Estimate | None:
        return next((e for e in self.estimates if e.name == name), None)

    @property
    def frame_unfixed(self) -> bool:
        """Nothing the calibration fitted fixes the instrument's frame (contacts alone, judged on
        measured points with base and tool registered on them): a verification with measured points
        registers the base on them."""
        use = self.in_use or {}
        return use.get("method") == REGISTERED_ON_IT and \
            not (use.get("fit_after") or {}).get("n")

    def accuracy_for(self, data) -> Accuracy | None:
        """The accuracy at calibration a verification by ``data`` is held against: of the held-out
        seatings for seatings (``Contacts``), else ``accuracy`` (``verify`` refuses the other kind)."""
        if isinstance(data, Contacts) and self.seatings_accuracy is not None:
            return self.seatings_accuracy
        return self.accuracy


@dataclass(frozen=True)
class StoredVerification:
    """One verification as the store keeps it (metres); ``calibration_id`` the calibration it was
    held against; ``sockets`` the sockets of a verification by seatings (0: measured points)."""

    robot: str
    calibration_id: int
    verified_at: str
    verdict: str
    rms: float
    mean: float
    p95: float
    max: float
    ap_max: float
    then_rms: float
    ratio: float
    threshold: float
    n_points: int
    registered_base: bool
    source: str = ""
    fingerprint: str = ""
    id: int | None = None
    sockets: int = 0


@dataclass(frozen=True)
class Change:
    """A parameter between two consecutive calibrations: ``before`` (at ``since``) and ``after`` (at
    ``at``), SI. ``sigma``: the test of "this parameter alone moved", in standard deviations of
    the combined uncertainty of both calibrations (with their correlations when stored; without
    them, the change over its combined standard deviation); ``shift`` the move it estimates;
    ``named`` when beyond the history's threshold. NaN ``sigma``: the parameter's change is not
    identified apart from the others' (its direction lies where the combined covariance is singular)."""

    name: str
    unit: str
    since: str
    at: str
    before: float
    after: float
    sigma: float
    named: bool
    shift: float = math.nan

    @property
    def delta(self) -> float:
        return self.after - self.before


@dataclass(frozen=True)
class Overall:
    """Whether anything changed between two consecutive calibrations (at ``since`` and ``at``): the
    chi-square of the judged parameters' differences against their combined covariance, on the
    ``dof`` directions both identify; ``p`` its p-value; ``named`` when below the history's level
    for it (``OVERALL_SHARE`` of its alpha, Šidák over the pairs)."""

    since: str
    at: str
    chi2: float
    dof: int
    p: float
    named: bool
    apart: tuple[str, ...] = ()

    @property
    def compared(self) -> bool:
        """Whether the two were compared: not when ``apart`` names parameters one identified away
        from nominal that the other did not identify, whose estimates then carry them."""
        return not self.apart


@dataclass(frozen=True, eq=False)
class History:
    """A robot's calibrations (oldest first), its verifications, and every parameter's change
    between consecutive calibrations judged at ``threshold`` standard deviations, and each pair's
    overall test (``overall``): together they name a change in an unchanged robot's whole history
    with a chance of at most ``alpha`` (the single-parameter tests at the Šidák bound of
    ``1 - OVERALL_SHARE`` of it, the overall tests at the rest)."""

    robot: str
    calibrations: tuple[StoredCalibration, ...]
    verifications: tuple[StoredVerification, ...]
    comparisons: tuple[Change, ...]
    threshold: float
    alpha: float
    families: tuple[str, ...]
    overall: tuple[Overall, ...] = ()

    @property
    def changes(self) -> tuple[Change, ...]:
        """The named changes, largest first."""
        return tuple(sorted((c for c in self.comparisons if c.named), key=lambda c: -abs(c.sigma)))

    @property
    def parameter_names(self) -> tuple[str, ...]:
        seen: dict[str, None] = {}
        for c in self.calibrations:
            seen.update((e.name, None) for e in c.estimates)
        return tuple(seen)

    def series(self, name: str) -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
        """(dates, estimates, standard deviations) of one parameter over the calibrations holding it."""
        rows = [(c.calibrated_at, e.estimate, e.std) for c in self.calibrations if (e := c.estimate(name))]
        return (tuple(r[0] for r in rows), np.array([r[1] for r in rows], dtype=float),
                np.array([r[2] for r in rows], dtype=float))


@dataclass(frozen=True)
class Outlier:
    """A robot whose latest value of a parameter stands out from its type's: ``z`` robust standard
    deviations from the type's median."""

    robot: str
    name: str
    unit: str
    value: float
    median: float
    z: float


class Latest(NamedTuple):
    """A robot's latest calibration as the type comparison lists it: its id, date, verdict and
    accuracy RMS (metres, None when unknown) and what it is of (``Accuracy.source``)."""

    robot: str
    id: int
    calibrated_at: str
    verdict: str
    accuracy_rms: float | None
    accuracy_source: str = ""


@dataclass(frozen=True, eq=False)
class TypeComparison:
    """The latest calibration of each robot of one type, side by side.

    ``values``/``stds`` (n_robots, n_names) SI, NaN where a robot's calibration lacks the
    parameter; ``median`` and ``spread`` (1.4826 median absolute deviation, or the median standard
    deviation when the robots agree closer than that) per name; ``z`` the robust distances (a
    robot whose standard deviation exceeds the median one: in that spread widened by the excess);
    ``outliers`` those beyond ``threshold`` (Šidák over all robots and parameters at ``alpha``),
    largest first. A robot whose calibration identifies parameters most of the type's do not is
    compared as it would be with those held at nominal (``_as_held``), and listed in ``held`` with
    them; without stored correlations, where one of them is beyond ``APART_SIGMAS`` of nominal, it
    is not compared (its estimates carry it; NaN) and listed in ``apart``. A robot whose calibration
    holds at nominal parameters most of the type's identify (a weak one for its poses) is compared
    against the robots that identify at least what it does, as they would be with those held too,
    and listed in ``conditioned`` with them (its ``z`` row; ``median`` and ``spread`` are those of
    the robots that identify every parameter most do); ``uncalibrated`` names those of them whose
    family its calibration has no parameter of (not calibrated, rather than weak for its poses).
    "Most": more than half.
    """

    robot_type: str
    latest: tuple[Latest, ...]
    names: tuple[str, ...]
    units: tuple[str, ...]
    values: np.ndarray
    stds: np.ndarray
    median: np.ndarray
    spread: np.ndarray
    z: np.ndarray
    threshold: float
    alpha: float
    outliers: tuple[Outlier, ...]
    held: tuple[tuple[str, tuple[str, ...]], ...] = ()
    apart: tuple[tuple[str, tuple[str, ...]], ...] = ()
    conditioned: tuple[tuple[str, tuple[str, ...]], ...] = ()
    uncalibrated: tuple[tuple[str, tuple[str, ...]], ...] = ()

    @property
    def robots(self) -> tuple[str, ...]:
        return tuple(c.robot for c in self.latest)

    @property
    def compared(self) -> int:
        """How many (robot, parameter) pairs were compared with the type (finite ``z``)."""
        return int(np.sum(np.isfinite(self.z)))


# -- judgement: pure functions ----------------------------------------------------------------------

@accepts(alpha=FRACTION, m=whole(0))
def sidak_threshold(alpha: float, m: int) -> float:
    """The |z| beyond which at least one of ``m`` independent standard normal variables falls with
    probability ``alpha`` (two-sided, Šidák).

    Parameters
    ----------
    alpha : float
        The chance, in (0, 1).
    m : int
        The number of variables (>= 0; 0 counts as 1).

    Returns
    -------
    float
        The threshold, standard deviations.

    >>> round(sidak_threshold(0.05, 1), 3), round(sidak_threshold(0.05, 20), 3)
    (1.96, 3.016)
    """
    from scipy.special import ndtri  # the normal quantile, without importing scipy.stats (1.8 s)

    if not 0 < alpha < 1:
        raise InputError(f"must be between 0 and 1, got {alpha!r}", where="alpha")
    per = -math.expm1(math.log1p(-alpha) / max(int(m), 1))
    return float(-ndtri(per / 2))


@accepts(calibrations=each_a(StoredCalibration), **_JUDGED)
def judge_changes(calibrations, *, alpha: float = DEFAULT_ALPHA, families=JUDGED_FAMILIES):
    """Every parameter's change between consecutive calibrations (sorted by date) and the threshold.

    Each parameter is tested as the only one that moved, the others held where the two
    calibrations' combined covariance ``S`` puts them: the generalised least-squares shift along it
    of the differences ``d``, ``(e' S^+ d) / (e' S^+ e)``, over its standard deviation
    ``1 / sqrt(e' S^+ e)`` (``S^+`` the pseudo-inverse on the directions ``S`` identifies); the
    largest beyond the threshold is named, freed, and the others tested again (docs/store.md).

    Parameters
    ----------
    calibrations : sequence of StoredCalibration
        One robot's calibrations, in any order.
    alpha : float
        The chance of naming a change anywhere in the history of a robot that did not change, with
        the overall tests of ``judge_overall`` (these tests get ``1 - OVERALL_SHARE`` of it).
    families : tuple of str
        The parameter families judged (the base and markers are placed anew for each campaign).

    Returns
    -------
    (tuple of Change, float)
        The comparisons, and the threshold in standard deviations they were judged against.
    """
    pairs = _pairs(calibrations, families)
    threshold = sidak_threshold(alpha * (1.0 - OVERALL_SHARE),
                                sum(int(np.sum(_identified(_pseudo_inverse(p.C, p.rcond)[0]) > 0)) for p in pairs))
    return tuple(c for p in pairs for c in _snooped(p.names, p.template, p.d, p.C, p.rcond, threshold)), threshold


@accepts(calibrations=each_a(StoredCalibration), **_JUDGED)
def judge_overall(calibrations, *, alpha: float = DEFAULT_ALPHA, families=JUDGED_FAMILIES) -> tuple[Overall, ...]:
    """Whether anything changed between consecutive calibrations (sorted by date): the chi-square of
    the judged parameters' differences against their combined covariance.

    Parameters
    ----------
    calibrations : sequence of StoredCalibration
        One robot's calibrations, in any order.
    alpha : float
        As for ``judge_changes``: these tests get ``OVERALL_SHARE`` of it, Šidák over the pairs.
    families : tuple of str
        The parameter families judged.

    Returns
    -------
    tuple of Overall
        One per pair of consecutive calibrations.
    """
    from scipy.special import chdtrc  # the chi-square survival function, without scipy.stats

    pairs = _pairs(calibrations, families)
    level = -math.expm1(math.log1p(-alpha * OVERALL_SHARE) / max(len(pairs), 1))
    out = []
    for pair in pairs:
        Sp, rank = _pseudo_inverse(pair.C, pair.rcond)
        stat = float(pair.d @ Sp @ pair.d) if rank else 0.0
        p = float(chdtrc(rank, stat)) if rank else 1.0
        out.append(Overall(pair.since, pair.at, stat, rank, p, p < level, pair.apart))
    return tuple(out)


class _Pair(NamedTuple):
    """Two consecutive calibrations' common judged parameters: their names, the changes to fill in,
    the differences, the combined covariance, the share of its largest eigenvalue below which a
    direction is not identified; the dates; ``apart``: parameters one fits away from nominal and
    the other does not identify (then nothing is compared)."""

    names: list
    template: list
    d: np.ndarray
    C: np.ndarray
    rcond: float
    since: str
    at: str
    apart: tuple[str, ...]


def _pairs(calibrations, families) -> list[_Pair]:
    ordered = sorted(calibrations, key=lambda c: (c.calibrated_at, c.id or 0))
    read = [_Estimates.of(c) for c in ordered]
    return [_pair(a, b, ea, eb, families) for a, b, ea, eb in zip(ordered, ordered[1:], read, read[1:])]


class _Estimates(NamedTuple):
    """What a judgement reads of one calibration: each estimate's (name, unit, family), their (n, 3)
    nominal, estimate and standard deviation, and their correlation as kept (None when not stored;
    read from the store, its stored bytes, decoded only where used: damage is then said with
    ``label``, the calibration's)."""

    layout: Sequence[tuple[str, str, str]]
    values: np.ndarray
    kept: Any
    label: str = ""

    @classmethod
    def of(cls, c: StoredCalibration) -> _Estimates:
        return cls(tuple((e.name, e.unit, e.family) for e in c.estimates),
                   np.array([e[3:] for e in c.estimates], dtype=float).reshape(-1, 3), c.correlation)

    def correlation(self) -> np.ndarray | None:
        if self.kept is None or isinstance(self.kept, np.ndarray):
            return self.kept
        try:
            return _unpacked(self.kept, len(self.layout))
        except ValueError as e:
            raise ValueError(f"{self.label}: {e}") from None

    def itemsize(self) -> int:
        """The bytes per kept correlation (4 before schema version 3), 8 without any."""
        if self.kept is None:
            return 8
        if isinstance(self.kept, np.ndarray):
            return self.kept.dtype.itemsize
        n = len(self.layout) * (len(self.layout) + 1) // 2
        return 4 if n and len(bytes(self.kept)) == 4 * n else 8


def _judged(e: _Estimates, families) -> dict:
    """name -> index in ``e`` of the finite estimates with a positive standard deviation whose variance
    is a number (a deviation of 1e300, damage or no information, is not judged)."""
    x, std = e.values[:, 1], e.values[:, 2]
    ok = np.isfinite(x) & (std > 0) & (std < MAX_STD)
    return {name: k for k, (name, _, family) in enumerate(e.layout) if ok[k] and family in families}


def _covariance(e: _Estimates, index: list) -> np.ndarray:
    std = e.values[index, 2]
    r = e.correlation()
    if r is None:
        return np.diag(std ** 2)
    return np.asarray(r[np.ix_(index, index)], dtype=float) * np.outer(std, std)


def _pseudo_inverse(C: np.ndarray, rcond: float = RCOND[8]) -> tuple[np.ndarray, int]:
    """The pseudo-inverse of a covariance on the directions it identifies (eigenvalues of its
    correlation form above ``rcond`` of the largest), and their number.

    >>> Sp, rank = _pseudo_inverse(np.array([[4.0, 4.0], [4.0, 4.0]]))
    >>> rank, np.round(Sp * 16, 6).tolist()
    (1, [[1.0, 1.0], [1.0, 1.0]])
    """
    if not C.size:
        return C.copy(), 0
    s = np.sqrt(np.diag(C))
    vals, vecs = np.linalg.eigh(C / np.outer(s, s))
    keep = vals > rcond * vals.max()
    V = vecs[:, keep]
    return (V / vals[keep]) @ V.T / np.outer(s, s), int(keep.sum())


def _identified(Sp: np.ndarray) -> np.ndarray:
    """The information ``e' S^+ e`` along each parameter, zero where it is not identified."""
    info = np.diag(Sp).copy()
    info[info <= 1e-12 * max(float(info.max(initial=0.0)), 1e-300)] = 0.0
    return info


def _held_apart(a: _Estimates, b: _Estimates, ja: dict, jb: dict) -> tuple[str, ...]:
    """The judged parameters one of ``a`` and ``b`` (``ja``, ``jb``: their judged estimates) fits more
    than ``APART_SIGMAS`` from nominal and the other does not identify, where the one has no stored
    correlations to take them back to nominal with (``_as_held``): the other holds them at nominal (or
    leaves out their family), so the parameters that absorb them carry their offset, and the two
    calibrations' estimates differ with no change of the robot."""
    return _carried(a, ja, jb) + _carried(b, jb, ja)


def _carried(e: _Estimates, mine: dict, other) -> tuple[str, ...]:
    """The parameters of ``mine`` (judged estimates of ``e``) not in ``other`` (names) that ``e`` fits beyond
    ``APART_SIGMAS`` of nominal with no stored correlations to take them back to nominal with."""
    if e.kept is not None:
        return ()
    v = e.values
    return tuple(name for name, k in mine.items()
                 if name not in other and abs(v[k, 1] - v[k, 0]) > APART_SIGMAS * v[k, 2])


def _as_held(e: _Estimates, keep: list, held: list, rcond: float) -> tuple[np.ndarray, np.ndarray]:
    """The estimates ``keep`` (indices in ``e``) and their covariance as ``e``'s calibration would have
    given them with the parameters ``held`` at their nominal values, as another calibration that does
    not identify them holds them: conditioned on that (least squares is Gaussian conditioning on the
    estimates' covariance: ``x_k - C_kh C_hh^+ (x_h - nominal_h)``, ``C_kk - C_kh C_hh^+ C_hk``).
    Without stored correlations, or with nothing held, the estimates as they are."""
    x = e.values[keep, 1]
    if not held or e.kept is None:
        return x, _covariance(e, keep)
    full = _covariance(e, keep + held)
    n = len(keep)
    gain = full[:n, n:] @ _pseudo_inverse(full[n:, n:], rcond)[0]
    off = e.values[held, 1] - e.values[held, 0]
    return x - gain @ off, full[:n, :n] - gain @ full[n:, :n]


def _pair(a: StoredCalibration, b: StoredCalibration, ea: _Estimates, eb: _Estimates, families) -> _Pair:
    """Two calibrations' common judged parameters (``_Pair``): ``RCOND`` at the coarser precision of
    their kept correlations. A parameter one identifies and the other does not is taken to its
    nominal in the one (``_as_held``), so both estimate the same thing; the changes' before and after
    are then those estimates. Nothing is compared when that cannot be done and it matters
    (``_held_apart``)."""
    ja, jb = _judged(ea, families), _judged(eb, families)
    kept = min(ea.itemsize(), eb.itemsize())
    apart = _held_apart(ea, eb, ja, jb)
    names = [] if apart else [n for n in jb if n in ja]
    ia, ib = [ja[n] for n in names], [jb[n] for n in names]
    xa, Ca = _as_held(ea, ia, [k for n, k in ja.items() if n not in jb], RCOND[kept])
    xb, Cb = _as_held(eb, ib, [k for n, k in jb.items() if n not in ja], RCOND[kept])
    template = [Change(n, eb.layout[kb][1], a.calibrated_at, b.calibrated_at, float(va), float(vb), math.nan,
                       False) for n, kb, va, vb in zip(names, ib, xa, xb)]
    return _Pair(names, template, xb - xa, Ca + Cb, RCOND[kept], a.calibrated_at, b.calibrated_at, apart)


def _w_tests(d: np.ndarray, C: np.ndarray, rest: np.ndarray, rcond: float = RCOND[8]) -> np.ndarray:
    """The test of each parameter in ``rest`` moving alone, the others outside ``rest`` free (Baarda's
    w): its generalised least-squares shift over its standard deviation, ``(S^+ d)_k / sqrt(S^+_kk)``
    with ``S^+`` the pseudo-inverse of the covariance of ``rest`` on the directions it identifies;
    NaN where a parameter's move is not identified. Without correlations: the change over its
    combined standard deviation."""
    Cr = C[np.ix_(rest, rest)]
    if not np.all(np.isfinite(Cr)):
        return d[rest] / np.sqrt(np.diag(Cr))
    Sp, _ = _pseudo_inverse(Cr, rcond)
    info = _identified(Sp)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(info > 0, (Sp @ d[rest]) / np.sqrt(info), np.nan)


def _snooped(names: list, template: list, d: np.ndarray, C: np.ndarray, rcond: float, threshold: float) -> list:
    """Iterative data snooping: name the parameter whose w test is largest beyond ``threshold``, free
    it, test the others again, until none is beyond. A named change carries the w of the step that
    named it and the shift estimated with every named parameter free; the others their last w."""
    if not names:
        return []
    sigma = np.full(len(names), np.nan)
    named: list[int] = []
    rest = np.arange(len(names))
    while rest.size:
        w = _w_tests(d, C, rest, rcond)
        k = int(np.argmax(np.nan_to_num(np.abs(w), nan=-1.0)))
        if not abs(w[k]) > threshold:
            sigma[rest] = w
            break
        sigma[rest[k]] = w[k]
        named.append(int(rest[k]))
        rest = np.delete(rest, k)
    shift = d.copy()
    if named:
        A = np.array(named)
        W, _ = _pseudo_inverse(C, rcond)
        with suppress(np.linalg.LinAlgError):     # else the changes themselves stand for the shifts
            shift[A] = np.linalg.solve(W[np.ix_(A, A)], (W @ d)[A])
    return [replace(t, sigma=float(z), named=i in named, shift=float(x))
            for i, (t, z, x) in enumerate(zip(template, sigma, shift))]


@accepts(robot_type=_name, calibrations=each_a(StoredCalibration), **_JUDGED)
def compare_type(robot_type: str, calibrations, *, alpha: float = DEFAULT_ALPHA,
                 families=JUDGED_FAMILIES) -> TypeComparison:
    """Robots of one type side by side: which ones stand out, parameter by parameter.

    Parameters
    ----------
    robot_type : str
        The type compared.
    calibrations : sequence of StoredCalibration
        The latest calibration of each robot of the type.
    alpha : float
        The chance of naming any robot in a fleet whose robots are alike.
    families : tuple of str
        The parameter families compared.

    Returns
    -------
    TypeComparison
    """
    cals = sorted(calibrations, key=lambda c: c.robot)
    latest = [Latest(c.robot, c.id or 0, c.calibrated_at, c.verdict, c.accuracy.rms if c.accuracy else None,
                     c.accuracy.source if c.accuracy else "") for c in cals]
    return _type_compared(robot_type, latest, [_Estimates.of(c) for c in cals], alpha, families)


def _type_compared(robot_type: str, latest: list, cals: list, alpha: float, families) -> TypeComparison:
    """``compare_type`` of the robots ``latest`` (by robot) and their calibrations' ``_Estimates``."""
    judged = [_judged(c, families) for c in cals]
    common = _most_identify(judged)
    on_common = [_on_common(c, j, common) for c, j in zip(cals, judged)]
    held = tuple((r.robot, extra) for r, c, (extra, far, _, _) in zip(latest, cals, on_common)
                 if extra and not far and c.kept is not None)
    apart = tuple((r.robot, far) for r, (_, far, _, _) in zip(latest, on_common) if far)
    gaps = [frozenset() if far else frozenset(common.difference(j)) for j, (_, far, _, _) in zip(judged, on_common)]
    names, units, values, stds = _matrix([(layout, v) for *_, layout, v in on_common], families)
    median, spread, z = _robust_z(values, stds, [not g for g in gaps])
    centre = np.broadcast_to(median, values.shape).copy()
    col = {n: j for j, n in enumerate(names)}
    for gap in sorted(set(gaps) - {frozenset()}, key=sorted):
        _against_holding(gap, cals, judged, common, gaps, families, (col, centre, z))
    threshold = sidak_threshold(alpha, int(np.sum(np.isfinite(z))))
    hits = np.argwhere(np.abs(np.nan_to_num(z)) > threshold)
    outliers = sorted((Outlier(latest[i].robot, names[j], units[j], float(values[i, j]), float(centre[i, j]),
                               float(z[i, j])) for i, j in hits), key=lambda o: -abs(o.z))
    return TypeComparison(robot_type, tuple(latest), names, tuple(units), values, stds, median, spread, z, threshold,
                          alpha, tuple(outliers), held, apart,
                          tuple((r.robot, tuple(sorted(g))) for r, g in zip(latest, gaps) if g),
                          _uncalibrated(latest, cals, judged, gaps))


def _most_identify(judged: list) -> set:
    """The parameters more than half the calibrations (``_judged`` each) identify."""
    count: dict[str, int] = {}
    for j in judged:
        count.update((n, count.get(n, 0) + 1) for n in j)
    return {n for n, k in count.items() if 2 * k > len(judged)}


def _uncalibrated(latest: list, cals: list, judged: list, gaps: list) -> tuple:
    """(robot, the parameters of its ``gaps`` of families its calibration has no parameter of) of each
    robot with any: parameters it did not calibrate, rather than left weak by its poses."""
    family = {n: c.layout[k][2] for c, j in zip(cals, judged) for n, k in j.items()}
    out = []
    for r, c, gap in zip(latest, cals, gaps):
        own = {f for _, _, f in c.layout}
        if none := tuple(sorted(n for n in gap if family[n] not in own)):
            out.append((r.robot, none))
    return tuple(out)


def _against_holding(gap: frozenset, cals: list, judged: list, common: set, gaps: list, families, into) -> None:
    """The rows of ``z`` (and of ``centre``, their reference) of the robots whose calibrations hold
    ``gap`` (common parameters) at nominal, against the type as it would be with ``gap`` held too:
    the robots that identify at least what they do (each other one holds parameters they identify,
    which theirs carry), conditioned on ``gap`` at nominal (``_on_common``). Their estimates carry
    ``gap``'s offsets (another subset of poses may leave other parameters weak), so against the
    type's estimates as they are, such robots stood out with no change of the robot."""
    col, centre, z = into
    members = [k for k, g in enumerate(gaps) if g <= gap]
    rows = [_on_common(cals[k], judged[k], common - gap) for k in members]
    names, _, values, stds = _matrix([(layout, v) for *_, layout, v in rows], families)
    median, _, zg = _robust_z(values, stds, [True] * len(members))
    cols = np.array([col[n] for n in names], dtype=int)
    for r, k in enumerate(members):
        if gaps[k] == gap:
            z[k] = np.nan
            z[k, cols], centre[k, cols] = zg[r], median


def _matrix(estimates: list, families) -> tuple[tuple[str, ...], list[str], np.ndarray, np.ndarray]:
    """(names, units, values, stds) of robots' (layout, (n, 3) nominal/estimate/std) estimates in the
    ``families`` compared: one row per robot, NaN where a robot's calibration lacks a parameter."""
    col: dict[str, int] = {}
    units: list[str] = []
    where: dict[int, tuple] = {}           # per layout: (rows kept, their columns)
    for layout, _ in estimates:
        if id(layout) not in where:
            keep = [k for k, (_, _, family) in enumerate(layout) if family in families]
            for k in keep:
                if layout[k][0] not in col:
                    col[layout[k][0]] = len(col)
                    units.append(layout[k][1])
            where[id(layout)] = (np.array(keep, dtype=int), np.array([col[layout[k][0]] for k in keep], dtype=int))
    values = np.full((len(estimates), len(col)), np.nan)
    stds = np.full_like(values, np.nan)
    for i, (layout, v) in enumerate(estimates):
        keep, cols = where[id(layout)]
        values[i, cols], stds[i, cols] = v[keep, 1], v[keep, 2]
    return tuple(col), units, values, stds


def _robust_z(values: np.ndarray, stds: np.ndarray, reference) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(median, spread, z): the median of the ``reference`` rows per column, their robust spread (1.4826
    median absolute deviation, at least their median standard deviation) and every row's distance from
    the median in its own spread; NaN in a column fewer than three reference robots have (no
    reference). A robot whose standard deviation exceeds the median one has its spread widened by
    that excess (in variance): one calibrated on fewer poses than most is held to what its estimates
    can say, not to what the others' say."""
    rows = np.asarray(reference, dtype=bool)
    ref = values[rows]
    nothing = np.full(values.shape[1], np.nan)
    with np.errstate(invalid="ignore"), _quiet_nan():
        median = np.nanmedian(ref, axis=0) if ref.size else nothing
        spread = 1.4826 * np.nanmedian(np.abs(ref - median), axis=0) if ref.size else nothing
        typical = np.nanmedian(stds[rows], axis=0) if ref.size else nothing
        spread = np.fmax(spread, typical)
        # only ever wider: a robot's stated deviation below the typical one is no reason to hold it
        # closer (a calibration that fits better than its type's states a smaller one, while its
        # estimates as compared carry what the type's do)
        own = spread ** 2 + np.fmax(np.nan_to_num(stds ** 2 - typical ** 2, nan=0.0), 0.0)
        z = (values - median) / np.where(own > 0, np.sqrt(own), np.nan)
    z[:, np.sum(np.isfinite(ref), axis=0) < 3] = np.nan      # a median of fewer is no reference
    return median, spread, z


def _on_common(c: _Estimates, judged: dict, common: set):
    """``c``'s estimates of the ``common`` parameters as it would give them with its others held at
    nominal (``_as_held``): (those others, those it cannot hold (``_carried``: then none is kept),
    the kept ones' (name, unit, family), their (n, 3) nominal/estimate/std)."""
    extra = tuple(n for n in judged if n not in common)
    far = _carried(c, judged, common)
    keep = [] if far else [judged[n] for n in judged if n in common]
    layout = [c.layout[k] for k in keep]
    if not extra or c.kept is None:         # nothing to hold, or nothing to hold it with: as they are
        return extra, far, layout, c.values[keep].reshape(-1, 3)
    x, C = _as_held(c, keep, [judged[n] for n in extra], RCOND[c.itemsize()])
    return extra, far, layout, np.column_stack([c.values[keep, 0], x, np.sqrt(np.maximum(np.diag(C), 0.0))])


@contextmanager
def _quiet_nan():
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)   # all-NaN columns: their median is NaN, as meant
        yield


@accepts(d=MAPPING, seatings=optional(FLAG))
def accuracy_at_calibration(d: dict, *, seatings: bool | None = None) -> Accuracy | None:
    """The position accuracy a result (its file form) reached as its instrument saw it, what a
    verification measured the same way is held against: the held-out poses' RMS error when the
    result has held-out poses (scaled up by the degrees of freedom a registration of base and tool
    on them took), else the fitted poses' errors as its cross-validation predicted them
    (each by a model fitted without it, the instrument's noise in: new poses are predicted so, and
    a robot with effects the model leaves out shows more error there than on the fitted poses),
    else the fitted poses' RMS error scaled up by the degrees of freedom the fit took
    (``sqrt(n_rows / (n_rows - n_parameters))``). (The accuracy in use, ``in_use``, is the robot's
    with the instrument's noise taken out: kept, and shown, but not comparable with a measured
    verification.) Of seatings: the held-out seatings' distances from their sockets' centres
    (source ``SEATINGS``), what a verification by seatings is held against. Of a calibration from
    measured points and seatings together, each kind's own: a socket's seatings scatter otherwise
    than a tracker's points, and a verification holds one kind.

    Parameters
    ----------
    d : dict
        The result in its file form (``result_to_dict``).
    seatings : bool, optional
        True: the seatings' accuracy; False: the measured points'; None: the measured points' when
        the result fitted or held out measured points, else the seatings'.

    Returns
    -------
    Accuracy or None
        The accuracy, or None when the result has none of that kind.
    """
    points = None if seatings else _points_at_calibration(d)
    if points is not None or seatings is False:
        return points
    return _seatings_at_calibration(d)


def _points_at_calibration(d: dict) -> Accuracy | None:
    """``accuracy_at_calibration`` of the measured points: held out, else cross-validated, else fitted."""
    stats, use = d.get("stats") or {}, d.get("in_use") or {}
    crossed, grouping = None, str(use.get("grouping") or "cross-validation")
    if isinstance(d.get("contacts"), dict):     # how the points were held out, before how the placements were
        grouping = grouping.split("; ")[0]
    if use.get("method") == "cross-validation":
        # the measured points alone; a result written before ``measured_points`` with contacts beside
        # has their seatings in ``measured_after`` too
        crossed = use["measured_points"] if "measured_points" in use else \
            None if isinstance(d.get("contacts"), dict) else use.get("measured_after")
    held = stats.get("validation_after")
    registered = use.get("method") == REGISTERED_ON_IT
    for figures, source, taken in ((held, "held-out poses", _registered_on(d, held) if registered else 0),
                                   (crossed, f"fitted poses held out, {grouping}", 0)):
        if isinstance(figures, dict) and figures.get("n") and _positive(figures.get("rms")):
            n = int(figures["n"])
            return Accuracy(rms=float(figures["rms"]) * math.sqrt(3 * n / (3 * n - taken)),
                            mean=_float(figures.get("mean")), n=n - taken // 3,
                            source=source + (f" with base and tool registered on them, over the degrees of "
                                             f"freedom that leaves ({taken} taken)" if taken else ""),
                            p95=_float(figures.get("p95")), max=_float(figures.get("max")))
    return _fitted_at_calibration(d)


def _registered_on(d: dict, held) -> int:
    """The degrees of freedom a registration of base and tool on the held-out poses (``held``, their
    statistics) took: the base's six and three per marker (0 when that would leave fewer than one
    point's)."""
    markers = (d.get("calibrated_model") or {}).get("markers")
    taken = 6 + 3 * max(len(markers) if isinstance(markers, list) else 1, 1)
    n = held.get("n") if isinstance(held, dict) else 0
    return taken if isinstance(n, int) and 3 * n - taken >= 3 else 0


def _fitted_at_calibration(d: dict) -> Accuracy | None:
    """The fitted poses' RMS error scaled up by the degrees of freedom the fit took, None without."""
    fit = (d.get("stats") or {}).get("fit_after") or {}
    if not (fit.get("n") and _positive(fit.get("rms"))):
        return None
    rows = int((d.get("identifiability") or {}).get("n_rows") or 0)
    k = len(d.get("parameters") or [])
    scale = math.sqrt(rows / (rows - k)) if rows > k > 0 else 1.0
    n = max(int(fit["n"]) - math.ceil(k / 3), 1)
    return Accuracy(rms=float(fit["rms"]) * scale, mean=_float(fit.get("mean")), n=n, source="fitted poses",
                    max=_float(fit.get("max")))


def _seatings_at_calibration(d: dict) -> Accuracy | None:
    """A calibration from contacts alone: its held-out seatings' distances from their sockets' mean
    centres (the held-out placements', else each placement predicted by the others), their RMS over
    the degrees of freedom the sockets' centres leave (three components each), what a verification
    by seatings is held against, with the scatter of the placements' mean squares beyond their
    seatings' number; None without a socket seated twice."""
    c = d.get("contacts") or {}
    held: dict = next((h["seatings_m"] for h in (c.get("validation_after"), c.get("held_out_by_placement"))
                 if isinstance(h, dict) and h.get("seatings_m")), {})
    sockets = {k: np.asarray(v, dtype=float) for k, v in held.items() if len(v) >= 2}
    if not sockets or not all(np.all(np.isfinite(v)) for v in sockets.values()):
        return None
    by: dict = {}
    for k, v in sockets.items():           # per placement: its squares and degrees of freedom
        ss, dof = by.get(k.split("/")[0], (0.0, 0))
        by[k.split("/")[0]] = (ss + float(np.sum(v ** 2)), dof + len(v) - 1)
    ss, dof = (sum(x) for x in zip(*by.values()))
    if not ss > 0:
        return None
    ms = np.array([a / b for a, b in by.values()])
    noise = float(np.mean([2.0 / (3.0 * b) for _, b in by.values()]))     # of a log mean square, by chance
    scatter = math.sqrt(max(float(np.var(np.log(ms), ddof=1)) - noise, 0.0)) if len(ms) > 1 else 0.0
    every = np.concatenate(list(sockets.values()))
    return Accuracy(rms=math.sqrt(ss / dof), mean=float(every.mean()), n=int(dof), source=SEATINGS,
                    p95=float(np.percentile(every, 95)), max=float(every.max()), sets=len(by), scatter=scatter)


def _float(v) -> float | None:
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) else None


def _positive(v) -> bool:
    f = _float(v)
    return f is not None and f > 0


def utc_text(value=None, *, where: str = "at") -> str:
    """An instant as ISO 8601 UTC text to the second (``value`` a datetime or ISO text; None: now).
    A time without zone is taken as UTC."""
    if value is None:
        t = datetime.now(timezone.utc)
    elif isinstance(value, datetime):
        t = value
    else:
        try:
            t = datetime.fromisoformat(str(value).strip().replace("Z", "+00:00"))
        except ValueError:
            raise InputError(f"expected an ISO 8601 date and time, got {excerpt(value)}", where=where) from None
    if t.tzinfo is None:
        t = t.replace(tzinfo=timezone.utc)
    return t.astimezone(timezone.utc).isoformat(timespec="seconds")


def check_name(value, where: str) -> str:
    """A robot or type name: printable text of 1 to 200 characters."""
    if not isinstance(value, str) or not value.strip() or len(value) > MAX_NAME or not value.isprintable():
        raise InputError(f"expected a name of 1 to {MAX_NAME} printable characters, got {excerpt(value)}",
                         where=where)
    return value.strip()


@accepts(model=is_a(RobotModel))
def model_document(model: RobotModel) -> tuple[str, bytes]:
    """(SHA-256, stored bytes) of a model's file form.

    Parameters
    ----------
    {model}

    Returns
    -------
    (str, bytes)
        The SHA-256 of the model's canonical JSON and that JSON compressed.
    """
    text = json.dumps(plain(model_to_dict(model)), sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest(), zlib.compress(text.encode(), 6)


@accepts(result=is_a(CalibrationResult), robot=_name, robot_type=optional(_name), at=INSTANT,
         source=TEXT, recorded_at=INSTANT)
def stored_calibration(result: CalibrationResult, robot: str, *, robot_type: str | None = None, at=None,
                       source: str = "", recorded_at=None) -> StoredCalibration:
    """The record the store keeps of ``result`` (not yet stored).

    Parameters
    ----------
    result : CalibrationResult
        A calibration, computed or read back (``robocal.read_result``).
    robot : str
        The robot's serial or name.
    robot_type : str, optional
        The robot's type, for comparisons between robots.
    at : datetime or str, optional
        When the calibration was made (default: the result's provenance date, else now).
    source : str
        Where the result came from (a file name), for people.
    recorded_at : datetime or str, optional
        When it is recorded (default now).

    Returns
    -------
    StoredCalibration
    """
    if not isinstance(result, CalibrationResult):
        raise InputError(f"expected a CalibrationResult, got {type(result).__name__}", where="result")
    d = result_to_dict(result)
    prov = d.get("provenance") or {}
    inputs = tuple(sorted((str(k), str(v.get("sha256") or "")) for k, v in prov.items() if isinstance(v, dict)))
    fingerprint = hashlib.sha256("".join(f"{k}:{h}\n" for k, h in inputs).encode()).hexdigest()
    lim = d.get("limit") or {}
    in_use = d.get("in_use")
    accuracy = accuracy_at_calibration(d)
    return StoredCalibration(
        robot=check_name(robot, "robot"), robot_type=None if robot_type is None else check_name(robot_type, "type"),
        calibrated_at=utc_text(at if at is not None else prov.get("date"), where="at" if at is not None else
                               "provenance.date"),
        recorded_at=utc_text(recorded_at), fingerprint=fingerprint, verdict=str(d["verdict"]),
        checks=tuple((c["name"], c["status"], c["summary"]) for c in d.get("checks") or []),
        estimates=tuple(Estimate(p.name, p.unit, p.family, p.nominal, p.estimate, p.std) for p in result.parameters),
        accuracy=accuracy, in_use=plain(in_use) if isinstance(in_use, dict) else None,
        seatings_accuracy=None if accuracy is None or accuracy.source == SEATINGS else
        accuracy_at_calibration(d, seatings=True),
        limit_m=_float(lim.get("limit_m")), nominal_model=model_document(result.nominal_model)[0],
        calibrated_model=model_document(result.calibrated_model)[0], source=str(source), inputs=inputs,
        correlation=_correlation_of(result))


def _correlation_of(result: CalibrationResult) -> np.ndarray | None:
    r = np.asarray(result.correlation, dtype=float)
    k = len(result.parameters)
    return r.copy() if r.shape == (k, k) else None


def stored_verification(v: Verification, calibration: StoredCalibration, *, at=None, source: str = "",
                        fingerprint: str = "") -> StoredVerification:
    """The record the store keeps of a verification held against ``calibration``."""
    return StoredVerification(robot=calibration.robot, calibration_id=int(calibration.id or 0),
                              verified_at=utc_text(at), verdict=v.verdict, rms=v.rms, mean=v.mean, p95=v.p95,
                              max=v.max, ap_max=v.ap_max, then_rms=v.then.rms, ratio=v.ratio, threshold=v.threshold,
                              n_points=v.n_points, registered_base=v.registered_base, source=str(source),
                              fingerprint=fingerprint, sockets=v.sockets)


# -- the back-ends ----------------------------------------------------------------------------------

_TABLES = ("robocal_schema", "robocal_models", "robocal_calibrations", "robocal_verifications")
# the columns, the ones the type comparison reads first (a SQLite row's later columns may lie on
# overflow pages of their own)
_CALIBRATION_COLUMNS = ("id", "robot", "robot_type", "calibrated_at", "recorded_at", "fingerprint", "verdict",
                        "limit_m", "accuracy", "parameters", "estimates", "correlation", "nominal_model",
                        "calibrated_model", "source", "inputs", "in_use", "checks")
# the id of the latest calibration of each robot of a type
_LATEST_OF_TYPE = ("SELECT id FROM (SELECT id, ROW_NUMBER() OVER (PARTITION BY robot ORDER BY calibrated_at DESC, "
                   "id DESC) AS rn FROM robocal_calibrations WHERE robot_type = ?) latest WHERE rn = 1")
_VERIFICATION_COLUMNS = ("id", "robot", "calibration_id", "verified_at", "verdict", "document")
# the schema, step by step: step k takes a store from version k - 1 to k
_MIGRATIONS = (
    ("CREATE TABLE robocal_schema (version INTEGER NOT NULL)",
     "CREATE TABLE robocal_models (sha256 TEXT PRIMARY KEY, document {blob} NOT NULL)",
     "CREATE TABLE robocal_calibrations (id {id}, robot TEXT NOT NULL, robot_type TEXT, calibrated_at TEXT NOT NULL, "
     "recorded_at TEXT NOT NULL, fingerprint TEXT NOT NULL, verdict TEXT NOT NULL, limit_m {real}, accuracy TEXT, "
     "parameters TEXT NOT NULL, estimates {blob} NOT NULL, correlation {blob}, "
     "nominal_model TEXT NOT NULL REFERENCES robocal_models (sha256), "
     "calibrated_model TEXT NOT NULL REFERENCES robocal_models (sha256), source TEXT NOT NULL, inputs TEXT NOT NULL, "
     "in_use TEXT, checks TEXT NOT NULL, UNIQUE (robot, calibrated_at, fingerprint))",
     "CREATE INDEX robocal_calibrations_robot ON robocal_calibrations (robot, calibrated_at)",
     "CREATE INDEX robocal_calibrations_type ON robocal_calibrations (robot_type, robot, calibrated_at)",
     "INSERT INTO robocal_schema (version) VALUES (1)"),
    ("CREATE TABLE robocal_verifications (id {id}, robot TEXT NOT NULL, "
     "calibration_id BIGINT NOT NULL REFERENCES robocal_calibrations (id), verified_at TEXT NOT NULL, "
     "verdict TEXT NOT NULL, document TEXT NOT NULL)",
     "CREATE INDEX robocal_verifications_robot ON robocal_verifications (robot, verified_at)",
     "UPDATE robocal_schema SET version = 2"),
    # correlations written at double precision from here on (the rows before keep single precision,
    # told apart by their size)
    ("UPDATE robocal_schema SET version = 3",),
)


class _Backend:
    """What the two back-ends share: a connection, the errors of their database driver, the names of
    their column types; each says how it writes placeholders, transactions and locks."""

    conn: Any
    name = ""
    types: dict = {}
    errors: tuple = ()

    def __init__(self, location: str, create: bool, write: bool) -> None:
        raise NotImplementedError

    def ready(self) -> None:
        """The database is a store and will be written: what writing needs (SQLite: its log)."""

    def check(self) -> None:
        """Damage the database can find in itself, as an InputError naming the store."""

    def sql(self, text: str) -> str:
        raise NotImplementedError

    def transaction(self, write: bool) -> Any:
        raise NotImplementedError

    def lock(self, cur) -> None:
        raise NotImplementedError

    def tables(self, cur) -> set:
        raise NotImplementedError

    def insert_id(self, cur, sql: str, values) -> int:
        raise NotImplementedError

    def close(self) -> None:
        self.conn.close()


def _an_sqlite_file(path: Path, location: str) -> None:
    """InputError when the file at ``path`` (not empty: SQLite makes an empty one a database) is no
    SQLite database, naming what it is when it is one of robocal's other files (``refuse_other_form``)."""
    from .._files.text import SNIFFED_CHARS, SQLITE_MAGIC, refuse_other_form

    try:
        with open(path, "rb") as fh:
            head = fh.read(SNIFFED_CHARS)
    except OSError:         # unreadable: SQLite says so when it opens it
        return
    if not head or head.startswith(SQLITE_MAGIC):
        return
    what = "a store of calibrations (the SQLite file robocal record makes, or a postgresql:// URL)"
    refuse_other_form(head.decode("utf-8", errors="ignore"), location, what)
    raise InputError(f"not {what}", source=location)


class _SQLite(_Backend):
    name = "sqlite"
    types = {"id": "INTEGER PRIMARY KEY AUTOINCREMENT", "blob": "BLOB", "real": "REAL"}

    def __init__(self, location: str, create: bool, write: bool):
        import sqlite3

        self.errors = (sqlite3.Error,)
        self.location = location
        path = Path(location)
        if not path.exists():
            if not create:
                raise InputError("no store here (record a calibration first)", source=location)
            path.parent.mkdir(parents=True, exist_ok=True)
            # made here, with the mode the umask gives every output (SQLite's own would be 0644)
            os.close(os.open(path, os.O_WRONLY | os.O_CREAT, 0o666))
        elif not path.is_file():
            raise InputError("not a file", source=location)
        elif write and not (os.access(path, os.W_OK) and os.access(path.parent, os.W_OK)):
            # refused before SQLite opens it: a read-only store keeps no log files of a refused write
            raise InputError(f"read-only {'folder' if os.access(path, os.W_OK) else 'store'}: nothing can be "
                             "recorded here", source=location)
        _an_sqlite_file(path, location)
        self.conn = self._connect(path, write, create)
        try:
            self.conn.execute("PRAGMA foreign_keys = ON")
        except sqlite3.Error:
            self.conn.close()
            raise

    @staticmethod
    def _connect(path: Path, write: bool, create: bool):
        """A connection that writes only when asked. One that may write cleans up the write-ahead
        log's files when it closes, so reading goes through one where it may; elsewhere (a shared
        store, another user's) a read-only one, which reads the file as it is when no write-ahead
        log is beside it (a read-only connection would make the log's files and, unable to clean
        up, leave them)."""
        import sqlite3
        from urllib.parse import quote

        uri = "file:" + quote(str(path.resolve()))
        if write or (os.access(path, os.W_OK) and os.access(path.parent, os.W_OK)):
            return sqlite3.connect(uri + ("?mode=rwc" if create else "?mode=rw"), uri=True,
                                   timeout=WAIT_NOTICE if write else LOCK_WAIT, isolation_level=None,
                                   check_same_thread=False)
        if not any(Path(f"{path}-{log}").exists() for log in ("wal", "shm")):
            return sqlite3.connect(uri + "?immutable=1", uri=True, isolation_level=None, check_same_thread=False)
        conn = sqlite3.connect(uri + "?mode=ro", uri=True, timeout=LOCK_WAIT, isolation_level=None,
                               check_same_thread=False)
        try:
            conn.execute("SELECT count(*) FROM sqlite_master").fetchall()
            return conn
        except sqlite3.OperationalError:
            conn.close()
            if Path(f"{path}-wal").exists():
                raise
        return sqlite3.connect(uri + "?immutable=1", uri=True, isolation_level=None, check_same_thread=False)

    def ready(self) -> None:
        self.conn.execute("PRAGMA journal_mode = WAL")

    def check(self) -> None:
        import sqlite3

        try:
            rows = [r[0] for r in self.conn.execute("PRAGMA quick_check(5)").fetchall()]
        except sqlite3.DatabaseError as e:      # damage the check itself trips on
            rows = [str(e)]
        if rows != ["ok"]:
            raise InputError(f"damaged store: {'; '.join(map(str, rows))[:300]}; nothing recorded",
                             source=self.location)

    def sql(self, text: str) -> str:
        return text

    @contextmanager
    def transaction(self, write: bool):
        if write:
            self._begin_write()
        else:
            self.conn.execute("BEGIN")
        try:
            yield self.conn
        except BaseException:
            self.conn.execute("ROLLBACK")
            raise
        self.conn.execute("COMMIT")

    def _begin_write(self) -> None:
        """BEGIN IMMEDIATE; when another process holds the write lock, say so and wait for it."""
        import logging
        import sqlite3

        try:
            self.conn.execute("BEGIN IMMEDIATE")
            return
        except sqlite3.OperationalError as e:
            if "locked" not in str(e) and "busy" not in str(e):
                raise
        logging.getLogger("robocal").warning("%s: another process is writing the store; waiting for it (up to %d s)",
                                             self.location, LOCK_WAIT)
        self.conn.execute(f"PRAGMA busy_timeout = {int(LOCK_WAIT * 1000)}")
        try:
            self.conn.execute("BEGIN IMMEDIATE")
        finally:
            self.conn.execute(f"PRAGMA busy_timeout = {int(WAIT_NOTICE * 1000)}")

    def lock(self, cur) -> None:
        """The migration's lock: BEGIN IMMEDIATE holds the file's write lock already."""

    def tables(self, cur) -> set:
        return {r[0] for r in cur.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}

    def insert_id(self, cur, sql: str, values) -> int:
        return int(cur.execute(sql, values).lastrowid)


class _Postgres(_Backend):
    name = "postgresql"
    types = {"id": "BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY", "blob": "BYTEA", "real": "DOUBLE PRECISION"}

    def __init__(self, location: str, create: bool, write: bool):
        import psycopg

        self.errors = (psycopg.Error,)
        self.conn = psycopg.connect(location, autocommit=True, connect_timeout=20)

    def sql(self, text: str) -> str:
        return text.replace("?", "%s")

    @contextmanager
    def transaction(self, write: bool):
        with self.conn.transaction():
            yield self.conn.cursor()

    def lock(self, cur) -> None:
        cur.execute("SELECT pg_advisory_xact_lock(2029002900)")   # one migration at a time per database

    def tables(self, cur) -> set:
        cur.execute("SELECT table_name FROM information_schema.tables WHERE table_schema = current_schema()")
        return {r[0] for r in cur.fetchall()}

    def insert_id(self, cur, sql: str, values) -> int:
        cur.execute(sql + " RETURNING id", values)
        return int(cur.fetchone()[0])


class Store:
    """A store of calibrations, open: SQLite (a file path) or PostgreSQL (a ``postgresql://`` URL).

    Use as a context manager, or call ``close``. ``create``: make the store (and its tables) when
    it does not exist yet; otherwise a missing store is an InputError. ``write`` (default
    ``create``): the store will be written; without it a SQLite store is opened read-only (a store
    in a folder one cannot write is read as it is). Errors of the database (unreadable file,
    refused connection, damaged content) are InputErrors naming the store.
    """

    def __init__(self, location=None, *, create: bool = False, write: bool | None = None):
        location = store_location(None if location is None else str(location))
        _check_scheme(location)
        self.location = shown_location(location)
        backend: type[_Backend] = _Postgres if is_url(location) else _SQLite
        self._backend: _Backend | None = None
        write = create if write is None else write
        with self._errors():
            self._backend = backend(location, create, write or create)
            self.backend = self._backend.name
            try:
                self.version = self._migrate(create)
                if write or create:
                    self._backend.ready()     # only now: a database of something else is left as it was
            except BaseException:
                self._backend.close()
                self._backend = None
                raise

    def __enter__(self) -> Store:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        if self._backend is not None:
            with self._errors():
                self._backend.close()
            self._backend = None

    @property
    def _db(self) -> _Backend:
        if self._backend is None:
            raise InputError("the store is closed", source=self.location)
        return self._backend

    @contextmanager
    def _errors(self, where: str | None = None):
        """Errors of the database as InputErrors naming the store; with ``where`` (decoding a stored
        record), errors of its content too."""
        try:
            yield
        except InputError:
            raise
        except UnicodeDecodeError as e:  # the database's own text (its schema, a name) damaged
            raise InputError(f"damaged store content ({e.reason} at byte {e.start} of its text)",
                             source=self.location, where=where) from None
        except (ValueError, TypeError, KeyError, IndexError, zlib.error) as e:
            if where is None:
                raise
            raise InputError(f"damaged store content ({' '.join(str(e).split())[:200]})", source=self.location,
                             where=where) from None
        except Exception as e:
            if ((self._backend is None or not isinstance(e, self._backend.errors))
                    and type(e).__module__.split(".")[0] not in ("sqlite3", "psycopg")):
                raise
            raise InputError(f"store error: {' '.join(str(e).split())[:300] or type(e).__name__}",
                             source=self.location, where=where) from None

    def _execute(self, cur, sql: str, values=()):
        return cur.execute(self._db.sql(sql), tuple(values))

    def _migrate(self, create: bool) -> int:
        db = self._db
        with db.transaction(write=create) as cur:
            db.lock(cur)
            tables = db.tables(cur)
            if "robocal_schema" not in tables:
                if db.name == "sqlite" and tables - set(_TABLES) - {"sqlite_sequence"}:
                    raise InputError("a database of something else: not " + ("made a robocal store" if create else
                                                                             "a robocal store"), source=self.location)
                if not create:
                    raise _Unmade("not a robocal store (no robocal_schema table)", source=self.location)
                version = 0
            else:
                rows = list(self._execute(cur, "SELECT version FROM robocal_schema").fetchall())
                if len(rows) != 1 or not isinstance(rows[0][0], int):
                    raise InputError("damaged store: its schema version is not one number", source=self.location)
                version = rows[0][0]
            if version > SCHEMA_VERSION:
                raise InputError(f"store schema version {version} is newer than this robocal's "
                                 f"({SCHEMA_VERSION}): upgrade robocal", source=self.location)
            if version < SCHEMA_VERSION and not create:
                raise _Upgrade()
            for step in _MIGRATIONS[version:]:
                for statement in step:
                    self._execute(cur, statement.format(**db.types))
        return SCHEMA_VERSION

    # -- writing -----------------------------------------------------------------------------------

    def check(self) -> None:
        """Damage the database finds in itself (SQLite's quick check), as an InputError: what a
        command that records asks before it writes anything."""
        with self._errors():
            self._db.check()

    def add(self, records, models=()) -> tuple[int, ...]:
        """Store calibration records in one transaction; their ids.

        ``models``: the model documents they refer to, ``(sha256, bytes)`` pairs
        (``model_document``), stored once each. A record of the same robot, date and input
        fingerprint as one stored already is an InputError, and then nothing is stored.
        """
        with self._adding(records, models) as ids:
            return ids

    @contextmanager
    def _adding(self, records, models):
        """``add``'s transaction, open while the body runs: committed when it ends, rolled back
        when it raises."""
        records = list(records)
        columns = _CALIBRATION_COLUMNS[1:]
        insert = (f"INSERT INTO robocal_calibrations ({', '.join(columns)}) "
                  f"VALUES ({', '.join('?' * len(columns))})")
        with self._errors(), self._db.transaction(write=True) as cur:
            for sha, blob in models:
                self._execute(cur, "INSERT INTO robocal_models (sha256, document) VALUES (?, ?) "
                              "ON CONFLICT (sha256) DO NOTHING", (sha, blob))
            ids = []
            for r in records:
                found = self._execute(cur, "SELECT id FROM robocal_calibrations WHERE robot = ? AND calibrated_at = ? "
                                      "AND fingerprint = ?", (r.robot, r.calibrated_at, r.fingerprint)).fetchone()
                if found:
                    raise InputError(f"this calibration of {r.robot} ({r.calibrated_at}) is stored already, as "
                                     f"#{found[0]}", source=self.location)
                ids.append(self._db.insert_id(cur, self._db.sql(insert), _calibration_row(r)))
            yield tuple(ids)

    def record(self, result: CalibrationResult, robot: str, *, robot_type: str | None = None, at=None,
               source: str = "") -> StoredCalibration:
        """Store one calibration (see ``stored_calibration``); the stored record, with its id."""
        rec = stored_calibration(result, robot, robot_type=robot_type, at=at, source=source)
        with self.recording(result, rec) as stored:
            return stored

    @contextmanager
    def recording(self, result: CalibrationResult, rec: StoredCalibration):
        """``record`` as one outcome with the caller's own work: ``rec`` (``stored_calibration`` of
        ``result``, made before: a result that cannot be recorded is refused before any store is
        touched) is stored, with its id, when the body ends and not at all when it raises (e.g.
        writing the result's files failed)."""
        models = [model_document(result.nominal_model), model_document(result.calibrated_model)]
        with self._adding([rec], models) as (i,):
            yield replace(rec, id=i)

    def add_verification(self, v: StoredVerification) -> StoredVerification:
        """Store a verification (one transaction); the stored record, with its id."""
        doc = {k: getattr(v, k) for k in ("rms", "mean", "p95", "max", "ap_max", "then_rms", "ratio", "threshold",
                                          "n_points", "registered_base", "source", "fingerprint", "sockets")}
        sql = ("INSERT INTO robocal_verifications (robot, calibration_id, verified_at, verdict, document) "
               "VALUES (?, ?, ?, ?, ?)")
        with self._errors(), self._db.transaction(write=True) as cur:
            i = self._db.insert_id(cur, self._db.sql(sql), (v.robot, v.calibration_id, v.verified_at, v.verdict,
                                                             _json(doc)))
        return replace(v, id=i)

    # -- reading -----------------------------------------------------------------------------------

    def calibrations(self, robot: str) -> tuple[StoredCalibration, ...]:
        """A robot's calibrations, oldest first."""
        sql = (f"SELECT {', '.join(_CALIBRATION_COLUMNS)} FROM robocal_calibrations WHERE robot = ? "
               "ORDER BY calibrated_at, id")
        return self._calibrations(sql, (check_name(robot, "robot"),))

    def latest_of_type(self, robot_type: str) -> tuple[StoredCalibration, ...]:
        """The latest calibration of each robot of a type, by robot."""
        cols = ", ".join(_CALIBRATION_COLUMNS)
        sql = f"SELECT {cols} FROM robocal_calibrations WHERE id IN ({_LATEST_OF_TYPE}) ORDER BY robot"
        return self._calibrations(sql, (check_name(robot_type, "type"),))

    def latest_estimates(self, robot_type: str) -> tuple[list, list]:
        """(``Latest`` of each robot of a type, each one's ``_Estimates``): what the type comparison
        reads, without the rest of the records (the correlations decoded only where used)."""
        sql = ("SELECT robot, id, calibrated_at, verdict, accuracy, parameters, estimates, correlation "
               f"FROM robocal_calibrations WHERE id IN ({_LATEST_OF_TYPE}) ORDER BY robot")
        with self._errors(), self._db.transaction(write=False) as cur:
            rows = self._execute(cur, sql, (check_name(robot_type, "type"),)).fetchall()
        latest, estimates, layouts = [], [], {}     # the parameter layouts of this read, each decoded once
        for robot, i, at, verdict, acc, params, values, corr in rows:
            with self._errors(f"calibration #{i}"):
                a = None if acc is None else json.loads(acc)
                latest.append(Latest(_text(robot), int(i), _date(at), _text(verdict),
                                     None if a is None else _float(a["rms"]), "" if a is None else _text(a["source"])))
                if params not in layouts:
                    layouts[params] = _layout(params)
                layout, v = _estimate_rows(layouts[params], values)
                estimates.append(_Estimates(layout, v, None if corr is None else bytes(corr), f"calibration #{i}"))
        return latest, estimates

    def _calibrations(self, sql: str, values) -> tuple[StoredCalibration, ...]:
        with self._errors(), self._db.transaction(write=False) as cur:
            rows = self._execute(cur, sql, values).fetchall()
        out = []
        for row in rows:
            with self._errors(f"calibration #{row[0]}"):
                out.append(_calibration_from_row(row))
        return tuple(out)

    def verifications(self, robot: str) -> tuple[StoredVerification, ...]:
        """A robot's verifications, oldest first."""
        sql = (f"SELECT {', '.join(_VERIFICATION_COLUMNS)} FROM robocal_verifications WHERE robot = ? "
               "ORDER BY verified_at, id")
        with self._errors(), self._db.transaction(write=False) as cur:
            rows = self._execute(cur, sql, (check_name(robot, "robot"),)).fetchall()
        out = []
        for row in rows:
            with self._errors(f"verification #{row[0]}"):
                out.append(_verification_from_row(row))
        return tuple(out)

    def robots(self) -> tuple[tuple[str, str | None, int], ...]:
        """(robot, type of its latest calibration, number of calibrations) of every robot stored."""
        sql = ("SELECT robot, robot_type, n FROM (SELECT robot, robot_type, COUNT(*) OVER (PARTITION BY robot) AS n, "
               "ROW_NUMBER() OVER (PARTITION BY robot ORDER BY calibrated_at DESC, id DESC) AS rn "
               "FROM robocal_calibrations) latest WHERE rn = 1 ORDER BY robot")
        with self._errors(), self._db.transaction(write=False) as cur:
            return tuple((str(r), t, int(n)) for r, t, n in self._execute(cur, sql).fetchall())

    def model(self, sha256: str) -> RobotModel:
        """A stored model by the SHA-256 of its file form (``StoredCalibration.nominal_model`` and
        ``calibrated_model``)."""
        with self._errors(), self._db.transaction(write=False) as cur:
            row = self._execute(cur, "SELECT document FROM robocal_models WHERE sha256 = ?", (sha256,)).fetchone()
        if row is None:
            raise InputError(f"no model {excerpt(sha256)} in the store", source=self.location)
        with self._errors(f"model {sha256[:12]}"):
            d = json.loads(zlib.decompress(bytes(row[0])).decode())
            return model_from_dict(d, source=f"{self.location}: model {sha256[:12]}")


class _Unmade(InputError):
    """A database with no store in it yet, which recording makes one (SQLite: none of another
    application's tables in it)."""


def check_recordable(location: str, robot: str) -> None:
    """What recording a calibration of ``robot`` in the store at ``location`` refuses for the store
    itself, found without writing, so that a command refuses it before its work: another file or a
    database of something else, a damaged or read-only store, one of a newer schema, the robot's
    earlier records unreadable. A store not made yet, or of an older schema, passes: recording makes
    or upgrades it."""
    location = store_location(location)
    if not is_url(location) and not Path(location).exists():
        _check_scheme(location)
        return
    try:
        with Store(location, write=True) as store:
            store.check()
            store.calibrations(robot), store.verifications(robot)
    except (_Unmade, _Upgrade):
        pass


class _Upgrade(InputError):
    """A store of an older schema opened for reading: it is upgraded first (a write)."""

    def __init__(self):
        super().__init__("the store needs an upgrade")


@accepts(location=optional(PATH), create=FLAG, write=optional(FLAG))
def open_store(location=None, *, create: bool = False, write: bool | None = None) -> Store:
    """Open a store: a SQLite file path or a ``postgresql://`` URL (default: ``store_location()``).

    Parameters
    ----------
    location : str or path, optional
        The store; None: ``$ROBOCAL_STORE``, else ``default_store_path()``.
    create : bool
        Make the store when it does not exist (else an InputError).
    write : bool, optional
        The store will be written (default ``create``); else it is opened read-only.

    Returns
    -------
    Store
        Open; an older schema is upgraded in place first.
    """
    try:
        return Store(location, create=create, write=write)
    except _Upgrade:
        return Store(location, create=True)


def _json(obj) -> str:
    return json.dumps(plain(obj), separators=(",", ":"), allow_nan=False)


_ACCURACY_FIELDS = ("rms", "mean", "n", "source", "p95", "max", "sets", "scatter")


def _calibration_row(r: StoredCalibration) -> tuple:
    acc = None if r.accuracy is None else {k: getattr(r.accuracy, k) for k in _ACCURACY_FIELDS}
    if acc is not None and r.seatings_accuracy is not None:     # beside the points': read by older robocal as before
        acc["seatings"] = {k: getattr(r.seatings_accuracy, k) for k in _ACCURACY_FIELDS}
    return (r.robot, r.robot_type, r.calibrated_at, r.recorded_at, r.fingerprint, r.verdict, r.limit_m,
            None if acc is None else _json(acc), _json([[e.name, e.unit, e.family] for e in r.estimates]),
            np.array([e[3:] for e in r.estimates], dtype="<f8").reshape(-1).tobytes(), _packed(r.correlation),
            r.nominal_model, r.calibrated_model, r.source, _json(dict(r.inputs)),
            None if r.in_use is None else _json(r.in_use), _json([list(c) for c in r.checks]))


def _nan(v) -> float:
    if v is None:
        return math.nan
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ValueError(f"expected a number, got {excerpt(v)}")
    return float(v)


def _text(v) -> str:
    if not isinstance(v, str):
        raise ValueError(f"expected text, got {excerpt(v)}")
    return v


def _date(v) -> str:
    """A stored date: ISO 8601 UTC text as the store writes it."""
    try:
        ok = utc_text(_text(v)) == v
    except InputError:
        ok = False
    if not ok:
        raise ValueError(f"expected an ISO 8601 UTC date, got {excerpt(v)}")
    return v


def _packed(r: np.ndarray | None) -> bytes | None:
    """A correlation matrix as its upper triangle, little-endian float64 (single precision before
    schema version 3 lost the directions that strongly correlated parameters are told apart by)."""
    return None if r is None else np.asarray(r, dtype="<f8")[np.triu_indices(r.shape[0])].tobytes()


def _unpacked(blob, k: int) -> np.ndarray | None:
    """A stored correlation matrix, at the precision it was kept at (float64, or float32 as written
    before schema version 3)."""
    if blob is None:
        return None
    raw = bytes(blob)
    n = k * (k + 1) // 2
    if len(raw) not in (4 * n, 8 * n):
        raise ValueError(f"{len(raw)} bytes of correlations for {k} parameters")
    v = np.frombuffer(raw, dtype="<f8" if len(raw) == 8 * n and n else "<f4")
    if not (np.all(np.isfinite(v)) and np.all(np.abs(v) <= 1.0 + 1e-6)):
        raise ValueError("correlations that are not numbers between -1 and 1")
    r = np.zeros((k, k), dtype=v.dtype.newbyteorder("="))
    r[np.triu_indices(k)] = v
    if not np.allclose(np.diag(r), 1.0, rtol=0, atol=1e-6):
        raise ValueError("a correlation matrix whose diagonal is not 1")
    return r + np.triu(r, 1).T


def _layout(text) -> list:
    """The (name, unit, family) of each stored estimate."""
    rows = json.loads(text)
    if not isinstance(rows, list) or not all(isinstance(r, list) and len(r) == 3 and all(isinstance(x, str) for x in r)
                                             for r in rows):
        raise ValueError("the parameters are not rows of name, unit and family")
    return [tuple(r) for r in rows]


def _estimate_rows(layout: list, values) -> tuple[list, np.ndarray]:
    """(layout, (n, 3) nominal, estimate and std) of one calibration's stored estimates."""
    v = np.frombuffer(bytes(values), dtype="<f8")
    if v.size != 3 * len(layout):
        raise ValueError(f"{v.size} stored values for {len(layout)} parameters")
    return layout, v.reshape(-1, 3)


def _calibration_from_row(row) -> StoredCalibration:
    (i, robot, rtype, cal_at, rec_at, fp, verdict, limit_m, acc, params, values, corr, nominal, calibrated, source,
     inputs, in_use, checks) = row
    a = None if acc is None else json.loads(acc)
    accuracy = None if a is None else _accuracy_from(a)
    seated = None if a is None or a.get("seatings") is None else _accuracy_from(a["seatings"])
    ests = tuple(Estimate(*head, *map(float, v)) for head, v in zip(*_estimate_rows(_layout(params), values)))
    use = None if in_use is None else json.loads(in_use)
    if use is not None and not isinstance(use, dict):
        raise ValueError("in_use is not a mapping")
    inp = json.loads(inputs)
    if not isinstance(inp, dict):
        raise ValueError("inputs is not a mapping")
    return StoredCalibration(
        robot=_text(robot), robot_type=None if rtype is None else _text(rtype), calibrated_at=_date(cal_at),
        recorded_at=_date(rec_at), fingerprint=_text(fp), verdict=_text(verdict),
        checks=tuple((_text(n), _text(s), _text(t)) for n, s, t in json.loads(checks)), estimates=ests,
        accuracy=accuracy, in_use=use, limit_m=None if limit_m is None else _nan(limit_m),
        nominal_model=_text(nominal), calibrated_model=_text(calibrated), source=_text(source),
        inputs=tuple((_text(k), _text(v)) for k, v in inp.items()), id=int(i), correlation=_unpacked(corr, len(ests)),
        seatings_accuracy=seated)


def _accuracy_from(a) -> Accuracy:
    """A stored accuracy at calibration."""
    if not isinstance(a, dict):
        raise ValueError("an accuracy that is not a mapping")
    return Accuracy(rms=_nan(a["rms"]), mean=_float(a.get("mean")), n=int(a["n"]), source=_text(a["source"]),
                    p95=_float(a.get("p95")), max=_float(a.get("max")), sets=int(a.get("sets") or 0),
                    scatter=_float(a.get("scatter")) or 0.0)


def _verification_from_row(row) -> StoredVerification:
    i, robot, cal, at, verdict, document = row
    d = json.loads(document)
    return StoredVerification(robot=_text(robot), calibration_id=int(cal), verified_at=_date(at),
                              verdict=_text(verdict), **{k: _nan(d[k]) for k in ("rms", "mean", "p95", "max", "ap_max",
                                                                                 "then_rms", "ratio", "threshold")},
                              n_points=int(d["n_points"]), registered_base=bool(d["registered_base"]),
                              source=_text(d["source"]), fingerprint=_text(d["fingerprint"]), id=int(i),
                              sockets=int(d.get("sockets") or 0))


# -- what the commands ask --------------------------------------------------------------------------

@accepts(store=is_a(Store), robot=_name, **_JUDGED)
def history(store: Store, robot: str, *, alpha: float = DEFAULT_ALPHA, families=JUDGED_FAMILIES) -> History:
    """A robot's history: its calibrations, verifications and judged changes.

    Parameters
    ----------
    {store, robot}
    alpha : float
        The chance of naming any change in the history of a robot that did not change.
    families : tuple of str
        The parameter families judged.

    Returns
    -------
    History
        InputError when the store holds no calibration of ``robot``.
    """
    cals = store.calibrations(robot)
    if not cals:
        raise InputError(f"no calibration of {excerpt(robot)} in the store", source=store.location)
    with store._errors("the changes between its calibrations"):    # numbers no calibration gives
        comparisons, threshold = judge_changes(cals, alpha=alpha, families=families)
        overall = judge_overall(cals, alpha=alpha, families=families)
    return History(robot, cals, store.verifications(robot), comparisons, threshold, alpha, tuple(families), overall)


@accepts(store=is_a(Store), robot_type=_name, **_JUDGED)
def type_comparison(store: Store, robot_type: str, *, alpha: float = DEFAULT_ALPHA,
                    families=JUDGED_FAMILIES) -> TypeComparison:
    """The robots of one type side by side (``compare_type`` on their latest calibrations).

    Parameters
    ----------
    {store}
    robot_type : str
        The type.
    alpha : float
        The chance of naming any robot in a fleet of alike robots.
    families : tuple of str
        The parameter families compared.

    Returns
    -------
    TypeComparison
        InputError when the store holds no robot of the type.
    """
    latest, estimates = store.latest_estimates(robot_type)
    if not latest:
        raise InputError(f"no robot of type {excerpt(robot_type)} in the store", source=store.location)
    with store._errors("estimates"):
        return _type_compared(robot_type, latest, estimates, alpha, families)


@accepts(store=is_a(Store), robot=_name)
def latest_usable(store: Store, robot: str) -> StoredCalibration:
    """A robot's latest calibration that did not fail its checks (what a verification holds the
    robot against); InputError when there is none.

    Parameters
    ----------
    {store, robot}

    Returns
    -------
    StoredCalibration
        Its latest calibration whose verdict is not "fail".
    """
    cals = store.calibrations(robot)
    if not cals:
        raise InputError(f"no calibration of {excerpt(robot)} in the store", source=store.location)
    usable = [c for c in cals if c.verdict != "fail"]
    if not usable:
        raise InputError(f"every calibration of {robot} in the store failed its checks: nothing to verify against",
                         source=store.location)
    return usable[-1]


@accepts(store=is_a(Store), robot=_name, data=is_a(Measurements, Contacts), register=FLAG,
         alpha=in_range(0.0, 0.5, low_open=True, high_open=True), save=FLAG, at=INSTANT)
def verify_robot(store: Store, robot: str, data: Measurements | Contacts, *, register: bool = False,
                 alpha: float = VERIFY_ALPHA, save: bool = True, at=None) -> tuple[Verification, StoredVerification]:
    """Verify a robot against its latest stored calibration that did not fail its checks and
    (``save``) record the verification.

    Parameters
    ----------
    {store, robot}
    data : Measurements or Contacts
        The verification campaign (10 to 30 poses), or ball seatings in sockets for a robot
        calibrated from seatings.
    register : bool
        Re-register the base on these poses first (always, for measured points, when nothing the
        calibration fitted fixes the instrument's frame: ``StoredCalibration.frame_unfixed``).
    alpha : float
        The share of verifications of an unchanged robot that say "recalibrate".
    save : bool
        Store the verification.
    at : datetime or str, optional
        When it was measured (default now).

    Returns
    -------
    (Verification, StoredVerification)
    """
    latest = latest_usable(store, robot)
    then = latest.accuracy_for(data)
    if then is None:
        raise InputError(f"the latest calibration of {robot} (#{latest.id}) has no accuracy at calibration to "
                         "verify against (neither measured points nor held-out socket seatings): calibrate again "
                         "and read the changes in history", source=store.location)
    register = register or (isinstance(data, Measurements) and latest.frame_unfixed)
    v = verify(store.model(latest.calibrated_model), data, then, register=register, alpha=alpha)
    rec = stored_verification(v, latest, at=at, source=data.source, fingerprint=data.sha256)
    return v, (store.add_verification(rec) if save else rec)
