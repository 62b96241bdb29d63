"""The records a calibration produces: its result, the error statistics before and after on the
fitted and held-out poses, the judgement against the limit of absolute accuracy, and a comparison
of identifications. Records are read, never changed."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from datetime import datetime, timezone
from types import MappingProxyType
from typing import TYPE_CHECKING, cast

import numpy as np

from .._base.arguments import accepts, is_a
from .._base.arrays import frozen, frozen_mapping, vector_norms
from .._base.errors import InputError
from .._model.contacts import Contacts
from .._model.measurements import Measurements
from .._model.parameters import parameter_layout, parameter_vector
from .._model.robot import RobotModel
from .._version import __version__
from .checks import LIMIT_REACHED_WITHIN, STATUSES, Check, verdict
from .estimates import ErrorStats, ParameterEstimate, error_stats
from .holdout import AccuracyInUse, Coverage
from .identifiability import IdentifiabilityResult

if TYPE_CHECKING:
    from .contact_figures import ContactFigures


@dataclass(frozen=True)
class ErrorSummary:
    """Error statistics before and after calibration on the fitted and held-out poses (position
    error norms in m, or rotation error angles in rad).

    Attributes
    ----------
    fit_before : ErrorStats
        The nominal model on the fitted poses.
    fit_after : ErrorStats
        The calibrated model on the fitted poses.
    validation_before : ErrorStats
        The nominal model on the held-out poses (n = 0 without them).
    validation_after : ErrorStats
        The calibrated model on the held-out poses (n = 0 without them).
    fit_nominal : ErrorStats or None
        The nominal model as given (the model's base and markers, nothing registered: what it
        missed as measured) on the fitted poses, where "before" has base and markers registered;
        None when not known (a result written before it, nothing measured fitted).
    validation_nominal : ErrorStats or None
        The same on the held-out poses; None without them, or when they were registered on.
    """

    fit_before: ErrorStats
    fit_after: ErrorStats
    validation_before: ErrorStats
    validation_after: ErrorStats
    fit_nominal: ErrorStats | None = None
    validation_nominal: ErrorStats | None = None

    KEYS = ("fit_before", "fit_after", "validation_before", "validation_after")


@dataclass(frozen=True)
class LimitJudgement:
    """The mean error in use after calibration against the limit of absolute accuracy.

    Attributes
    ----------
    limit_m : float
        The limit of absolute accuracy, m.
    compared : str
        What was held against it: "validation_after" for a validation set, "cross-validation"
        otherwise.
    mean_error_m : float
        The mean position error in use after calibration, m.
    ratio : float
        ``mean_error_m / limit_m``.
    reached : bool
        Whether the ratio is within ``LIMIT_REACHED_WITHIN`` of 1 or below.
    """

    limit_m: float
    compared: str
    mean_error_m: float
    ratio: float
    reached: bool


def judge_against_limit(limit, in_use: AccuracyInUse) -> LimitJudgement:
    """The mean error in use after calibration against the limit of absolute accuracy (an
    AccuracyLimit or metres)."""
    value = float(getattr(limit, "limit", limit))
    key = "cross-validation" if in_use.method == "cross-validation" else "validation_after"
    mean = float(cast(float, in_use.position_after.mean))
    ratio = mean / value
    return LimitJudgement(limit_m=value, compared=key, mean_error_m=mean, ratio=ratio,
                          reached=bool(ratio <= LIMIT_REACHED_WITHIN))


@dataclass(frozen=True, eq=False)
class SolverRecord:
    """How the least-squares solve of a calibration went.

    Attributes
    ----------
    success : bool
        Whether the solver converged.
    status : int
        The solver's termination status (scipy's ``least_squares``).
    message : str
        The solver's termination message.
    nfev : int
        The evaluations of the residuals it took.
    loss : str
        The least-squares loss: "linear" or a robust one of scipy's.
    sigma0 : float
        The residual standard deviation: m, or in stated standard deviations when the data state
        them (contacts, 6D data, a sigma column).
    residual_dof : float
        The residual degrees of freedom: the rows less what the fit takes from them (what
        ``compare``'s F test counts).
    """

    success: bool
    status: int
    message: str
    nfev: int
    loss: str
    sigma0: float
    residual_dof: float


@dataclass(frozen=True, eq=False)
class PoseSet:
    """The errors before and after calibration on one set of poses (the fitted ones, or those held
    out), pose by pose and marker by marker; every array is read-only, and NaN where a marker was
    not measured.

    Attributes
    ----------
    readings : numpy.ndarray or None
        (n_poses, n_joints) the joint readings, SI (rad, m); None in a result file that does not
        hold them.
    measured_positions : numpy.ndarray or None
        (n_poses, n_markers, 3) the measured marker positions, m, in the measurement frame W; NaN
        throughout on the fitted poses of a result file that does not hold them (None on held-out
        ones).
    errors_before : numpy.ndarray
        (n_poses, n_markers) the position error norms of the nominal geometry (the base and
        marker parameters the calibration identifies fitted to the data first), m.
    errors_after : numpy.ndarray
        (n_poses, n_markers) the position error norms of the calibrated model, m.
    residual_vectors : numpy.ndarray or None
        (n_poses, n_markers, 3) calibrated minus measured positions, m, in W; None on held-out
        poses of a result file that does not hold them.
    rotation_errors_before : numpy.ndarray or None
        (n_poses, n_markers) the rotation error angles of the nominal model, rad; None for point
        data.
    rotation_errors_after : numpy.ndarray or None
        (n_poses, n_markers) the rotation error angles of the calibrated model, rad; None for
        point data.
    set_aside : numpy.ndarray or None
        (n_poses, n_markers) the measured points the calibration set aside as blunders (docs/checks.md,
        "outliers"); None where not known (held-out poses, a result file).
    """

    readings: np.ndarray | None
    measured_positions: np.ndarray | None
    errors_before: np.ndarray
    errors_after: np.ndarray
    residual_vectors: np.ndarray | None
    rotation_errors_before: np.ndarray | None = None
    rotation_errors_after: np.ndarray | None = None
    set_aside: np.ndarray | None = None

    def __post_init__(self) -> None:
        for f in fields(self):
            a = getattr(self, f.name)
            if a is not None:
                object.__setattr__(self, f.name, frozen(a, bool if f.name == "set_aside" else float))

    @staticmethod
    def empty(model: RobotModel) -> PoseSet:
        """The fitted poses of a calibration that fitted no measured point: arrays of no rows."""
        m = len(model.marker_names)
        return PoseSet(readings=np.zeros((0, model.n_joints)), measured_positions=np.zeros((0, m, 3)),
                       errors_before=np.zeros((0, m)), errors_after=np.zeros((0, m)),
                       residual_vectors=np.zeros((0, m, 3)))


@dataclass(frozen=True)
class Finding:
    """A cause the diagnosis names (docs/diagnosis.md).

    Attributes
    ----------
    hypothesis : str
        The hypothesis tested ("rows shifted", "joint scale", ...).
    cause : str
        The cause in words.
    evidence : str
        What shows it: the refit with the cause repaired against the calibration, or the fact found.
    score : float
        log10 of the factor by which the repair divides the residual variance (its own freedom
        counted): comparable across hypotheses, most likely first.
    items : tuple of str
        The rows, joints, markers or parameters it names.
    rms_before : float or None
        The calibration's residual RMS per axis (m) on the poses diagnosed.
    rms_after : float or None
        The repaired refit's (m); None when the cause needs no refit.
    fix : str
        How to act on it.
    status : str
        "fail": decisive (the repair explains the data and places the robot better in use: the
        calibration is wrong as it is); "warn": a possible cause with weaker evidence, or one the
        calibration already carries (a mistake of the nominal model, blunders set aside).
    """

    hypothesis: str
    cause: str
    evidence: str
    score: float
    items: tuple[str, ...] = ()
    rms_before: float | None = None
    rms_after: float | None = None
    fix: str = ""
    status: str = "warn"

    def __post_init__(self) -> None:
        object.__setattr__(self, "items", tuple(self.items))

    @property
    def noted(self) -> bool:
        """A fact the calibration already carries, noted rather than suspected: not decisive and
        needing no refit (blunders it set aside, a joint that never moves, model-file values it took up)."""
        return self.status == "warn" and self.rms_after is None


@dataclass(frozen=True)
class Diagnosis:
    """Why a calibration's data do not fit, tested against them (docs/diagnosis.md).

    Attributes
    ----------
    findings : tuple of Finding
        The causes named, decisive first, then most likely first (others only when close to it).
    tested : tuple of str
        The hypotheses tested.
    summary : str
        One line: the most likely cause, or that nothing tested explains the misfit.
    rms : float
        The calibration's residual RMS per axis on the poses diagnosed (m; contacts: their errors).
    untestable : tuple of str
        Hypotheses these data cannot separate, each with the reason (never named as likely).
    refitted : tuple of str
        The hypotheses the cheap statistics did not rule out, refitted.
    """

    findings: tuple[Finding, ...]
    tested: tuple[str, ...]
    summary: str
    rms: float
    untestable: tuple[str, ...] = ()
    refitted: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        for name in ("findings", "tested", "untestable", "refitted"):
            object.__setattr__(self, name, tuple(getattr(self, name)))

    @property
    def cause(self) -> Finding | None:
        """The most likely cause, or None."""
        return self.findings[0] if self.findings else None

    @property
    def status(self) -> str:
        """"fail" when a cause is decisive, "warn" when one is possible, else "pass"."""
        return max((f.status for f in self.findings), key=STATUSES.index, default="pass")


@dataclass(frozen=True, eq=False, kw_only=True)
class CalibrationResult:
    """Everything a calibration produced, grouped by what it describes. Read, never changed: every
    array is read-only, every mapping a read-only view; absent data are None.

    A calibration that fitted contacts holds the kit's figures in ``contacts``; its ``fit`` poses
    are those of the tracker data fitted beside them (no rows without), and its ``in_use`` the
    socket consistency of each placement predicted by the others (or of the held-out placements).

    Attributes
    ----------
    nominal_model : RobotModel
        The model the calibration started from.
    calibrated_model : RobotModel
        The model with the identified parameters (SI).
    parameters : tuple of ParameterEstimate
        Each identified parameter: nominal, estimate, change and standard deviation (SI units).
    covariance : numpy.ndarray
        (n_parameters, n_parameters) the covariance of the estimates, indexed like ``parameters``
        (SI units squared).
    correlation : numpy.ndarray
        (n_parameters, n_parameters) their correlation coefficients, indexed likewise.
    identifiability : IdentifiabilityResult
        Which candidates were identified and which eliminated, and what absorbs them.
    solver : SolverRecord
        How the solve went: convergence, loss, the residual standard deviation.
    families : tuple of str
        What was asked to be identified: families, names or patterns.
    fit : PoseSet
        The errors before and after on the fitted poses.
    validation : PoseSet or None
        The same on the held-out poses (a validation set); None without them.
    stats : ErrorSummary
        Statistics of the position error norms (m) before and after, fitted and held out (with
        held-out measured points and no fitted ones, theirs in the fitted rows).
    rotation_stats : ErrorSummary or None
        The same of the rotation error angles (rad) for 6D data; None for point data.
    in_use : AccuracyInUse or None
        The accuracy in use before and after, from observations not fitted; None when nothing
        was held out.
    coverage : Coverage or None
        Where the measured points were taken against the workspace; None without them.
    limit : LimitJudgement or None
        The accuracy in use against the limit of absolute accuracy; None when none was given.
    contacts : ContactFigures or None
        The kit's figures (socket consistency and spacing error, fitted and held out, what each
        kind of contact reaches); None without contacts.
    checks : tuple of Check
        Every check, its status and what it found (``verdict`` the worst).
    notes : tuple of str
        What the calibration decided on the user's behalf.
    provenance : Mapping
        Software, version, date (ISO 8601 UTC) and the inputs: for measured points ``data`` (and
        ``validation``) {source, sha256, n_poses, labels}, labels in the order of the pose rows;
        for contacts ``contacts`` (and ``validation_contacts``) {source, sha256, n_rows,
        placements}.
    diagnosis : Diagnosis or None
        The mistakes tested against the data and the causes named (docs/diagnosis.md); its verdict
        is the check "diagnosis". None for a result not screened (the identification alone).
    """

    nominal_model: RobotModel
    calibrated_model: RobotModel
    parameters: tuple[ParameterEstimate, ...]
    covariance: np.ndarray
    correlation: np.ndarray
    identifiability: IdentifiabilityResult
    solver: SolverRecord
    families: tuple[str, ...]
    fit: PoseSet
    validation: PoseSet | None = None
    stats: ErrorSummary
    rotation_stats: ErrorSummary | None = None
    in_use: AccuracyInUse | None = None
    coverage: Coverage | None = None
    limit: LimitJudgement | None = None
    contacts: ContactFigures | None = None
    checks: tuple[Check, ...] = ()
    notes: tuple[str, ...] = ()
    provenance: Mapping[str, object] = field(default_factory=dict)
    diagnosis: Diagnosis | None = None

    def __post_init__(self) -> None:
        for name in ("parameters", "families", "checks", "notes"):
            object.__setattr__(self, name, tuple(getattr(self, name)))
        object.__setattr__(self, "covariance", frozen(self.covariance))
        object.__setattr__(self, "correlation", frozen(self.correlation))
        object.__setattr__(self, "provenance", frozen_mapping(self.provenance))

    @property
    def verdict(self) -> str:
        """"pass", "warn" or "fail": the worst of the checks."""
        return verdict(self.checks)

    def estimate(self, name: str) -> ParameterEstimate:
        """The estimate of the identified parameter ``name``."""
        found = next((p for p in self.parameters if p.name == name), None)
        if found is None:
            raise InputError(f"{name!r} is not an identified parameter (identified: "
                             f"{', '.join(self.parameter_names) or 'none'})", where="name")
        return found

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    @property
    def held_nominals(self) -> tuple[tuple[str, float], ...]:
        """``(name, SI value)`` of every non-zero parameter the calibrated model keeps that was not a
        candidate (a fixed mount's gamma and b, a known marker): the report shows them beside the
        identified ones, so nothing the calibrated file holds is hidden."""
        lay = parameter_layout(self.calibrated_model)
        values = parameter_vector(self.calibrated_model)
        considered = set(self.identifiability.candidates) | set(self.parameter_names)
        return tuple((p.name, float(values[p.index])) for p in lay.parameters
                     if p.name not in considered and values[p.index] != 0.0)


@dataclass(frozen=True, eq=False)
class PoseErrors:
    """Errors before and after calibration on one set of poses, as computed: position vectors (n, m,
    3) in m and, for 6D data, rotation vectors (n, m, 3) in rad; NaN where not measured."""

    data: Measurements
    before: np.ndarray
    after: np.ndarray
    rotation_before: np.ndarray | None
    rotation_after: np.ndarray | None
    set_aside: np.ndarray | None = None
    nominal: np.ndarray | None = None
    rotation_nominal: np.ndarray | None = None

    @staticmethod
    def summary_of_none() -> ErrorSummary:
        """The statistics of a calibration that fitted no measured point (each with n = 0)."""
        return ErrorSummary(*(error_stats([]) for _ in ErrorSummary.KEYS))

    def summary(self, other: PoseErrors | None, *, rotation: bool) -> ErrorSummary | None:
        """Statistics of the error norms here (fit) and on ``other`` (held out), positions or rotations."""
        if rotation and self.rotation_after is None:
            return None

        def stats(e: PoseErrors | None, when: str):
            if e is None:
                return error_stats([])
            v = getattr(e, f"rotation_{when}" if rotation else when)
            return error_stats([] if v is None else vector_norms(v))

        def nominal(e: PoseErrors | None):
            return None if e is None or e.nominal is None else stats(e, "nominal")

        return ErrorSummary(stats(self, "before"), stats(self, "after"), stats(other, "before"), stats(other, "after"),
                            nominal(self), nominal(other))

    def pose_set(self) -> PoseSet:
        """The record of this set: error norms, residual vectors, measured positions, readings."""
        def norms(v):
            return None if v is None else vector_norms(v)

        return PoseSet(readings=self.data.q,
                       measured_positions=np.where(self.data.mask[..., None], self.data.positions, np.nan),
                       errors_before=norms(self.before), errors_after=norms(self.after), residual_vectors=self.after,
                       rotation_errors_before=norms(self.rotation_before),
                       rotation_errors_after=norms(self.rotation_after), set_aside=self.set_aside)


def provenance(data: Measurements | None, validation: Measurements | None = None, contacts: Contacts | None = None,
               validation_contacts: Contacts | None = None) -> dict:
    """Software, date and the inputs (source, SHA-256, pose labels in the order of the error rows;
    contacts' rows and placements)."""
    prov: dict[str, object] = {"software": "robocal", "version": __version__,
                               "date": datetime.now(timezone.utc).isoformat(timespec="seconds")}
    for key, d in (("data", data), ("validation", validation)):
        if d is not None:
            prov[key] = {"source": d.source, "sha256": d.sha256, "n_poses": d.n_poses, "labels": d.labels}
    for key, c in (("contacts", contacts), ("validation_contacts", validation_contacts)):
        if c is not None:
            prov[key] = {"source": c.source, "sha256": c.sha256, "n_rows": c.n_rows, "placements": list(c.placements())}
    return prov



@dataclass(frozen=True, eq=False)
class NestedTest:
    """One identification against a simpler one nested in it, on the same data.

    Attributes
    ----------
    f_statistic : float
        The nested-model F statistic on the fitted residuals: does adding the parameters reduce
        the residual more than their number explains?
    p_value : float
        Its p-value.
    helped : bool
        True when p < ``alpha``, the RMS error in use (held-out poses, else cross-validated on
        the same folds) fell too, and the error in use over the range of use (the check "where the
        model holds") did not grow: a model choice is checked by what it does in use.
    summary : str
        What the test found, in one sentence.
    """

    f_statistic: float
    p_value: float
    helped: bool
    summary: str


@dataclass(frozen=True, eq=False)
class Comparison:
    """Geometric-only against geometric-and-compliance identification on the same data, and, when
    asked, backlash added to the one kept (the third) and transmission terms added to the one kept
    then; each larger one keeps the parameters of the one it adds to. What the model cannot support
    (compliance without link masses, a larger model than the poses determine) is skipped and said.

    Attributes
    ----------
    geometric : CalibrationResult
        The geometric identification.
    combined : CalibrationResult or None
        The geometric and compliance identification; None when skipped.
    compliance_test : NestedTest or None
        ``combined`` against ``geometric``: did the compliances help? None when skipped.
    backlash : CalibrationResult or None
        Backlash added to the identification kept before it (geometric and compliance when
        compliance helped, else geometric); None unless asked.
    backlash_test : NestedTest or None
        ``backlash`` against the identification it adds to; None unless asked.
    transmission : CalibrationResult or None
        Transmission terms added to the identification kept before them, the level that did best
        in use over the range of use; None unless asked.
    transmission_test : NestedTest or None
        ``transmission`` against the identification it adds to; None unless asked.
    skipped : tuple of str
        The identifications not compared, and why.
    """

    geometric: CalibrationResult
    combined: CalibrationResult | None = None
    compliance_test: NestedTest | None = None
    backlash: CalibrationResult | None = None
    backlash_test: NestedTest | None = None
    transmission: CalibrationResult | None = None
    transmission_test: NestedTest | None = None
    skipped: tuple[str, ...] = ()

    @property
    def verdict(self) -> str:
        """What the tests found, one line each, then what was skipped."""
        tests = (self.compliance_test, self.backlash_test, self.transmission_test)
        return "\n".join([t.summary for t in tests if t is not None] + list(self.skipped))

    @property
    def best(self) -> CalibrationResult:
        """The identification chosen: the largest that helped in use."""
        if self.transmission is not None and self.transmission_test is not None and self.transmission_test.helped:
            return self.transmission
        if self.backlash is not None and self.backlash_test is not None and self.backlash_test.helped:
            return self.backlash
        if self.combined is not None and self.compliance_test is not None and self.compliance_test.helped:
            return self.combined
        return self.geometric

    @property
    def results(self) -> Mapping[str, CalibrationResult]:
        """The identifications side by side, by what they identify (a read-only mapping)."""
        out = {"geometric": self.geometric}
        for r in (self.combined, self.backlash, self.transmission):
            if r is not None:
                out[compared_name(r.families)] = r
        return MappingProxyType(out)


def compared_name(families) -> str:
    """An identification of a comparison by the families it identifies: "geometric and compliance",
    "geometric, compliance and backlash", "geometric and transmission" (terms named one by one
    count as their family)."""
    named = []
    for f in families:
        fam = "transmission" if "." in f else f
        if fam not in named:
            named.append(fam)
    return named[0] if len(named) == 1 else f"{', '.join(named[:-1])} and {named[-1]}"


@accepts(result=is_a(CalibrationResult))
def calibration_record(result) -> dict:
    """What a calibrated model file says of its own calibration: the verdict, the date, the checks
    that did not pass, and ``joint_ranges``: each joint's lowest and highest reading over the fitted
    poses (``coverage.joint_ranges``, SI; absent without measured points), where the model was
    calibrated.

    Parameters
    ----------
    {result}

    Returns
    -------
    dict
        The calibration record a model file stores (verdict, checks, date, joint ranges).
    """
    out = {"verdict": result.verdict, "date": result.provenance.get("date", "")}
    data = result.provenance.get("data") or {}
    sources = [str(d["source"]) for d in (result.provenance.get("contacts") or {}, data) if d.get("source")]
    if sources:
        out["data"] = " and ".join(sources)
    if data.get("n_poses"):
        out["poses"] = int(data["n_poses"])
    out["families"] = list(result.families)
    out["nominal"] = result.nominal_model.name
    for status, key in (("fail", "failed"), ("warn", "warned")):
        names = [c.name for c in result.checks if c.status == status]
        if names:
            out[key] = names
    if result.coverage is not None:
        names = result.coverage.joint_names or result.nominal_model.joint_names
        out["joint_ranges"] = {n: [float(lo), float(hi)] for n, (lo, hi) in zip(names, result.coverage.joint_ranges)}
    return out


def calibrated_description(calibration: dict) -> str:
    """What a calibrated model file says it is, from its ``calibration`` record: calibrated, from
    which nominal model and data, when, with which verdict (never the nominal model's own words).

    >>> calibrated_description({"verdict": "pass", "date": "2026-01-31", "nominal": "th8",
    ...                         "families": ["geometric"], "data": "m.csv", "poses": 36})[37:]
    'geometric parameters identified from 36 poses of m.csv, on 2026-01-31 (verdict: pass)'
    """
    what = ", ".join(calibration.get("families") or []) or "its"
    data = calibration.get("data")
    poses = calibration.get("poses")
    source = (f" from {poses} poses of {data}" if poses and data else f" from {data}" if data
              else f" from {poses} poses" if poses else "")
    nominal = f"nominal model {calibration['nominal']}, " if calibration.get("nominal") else ""
    when = f", on {str(calibration['date'])[:10]}" if calibration.get("date") else ""  # the day; the time below
    return (f"calibrated model: {nominal}{what} parameters identified{source}{when} "
            f"(verdict: {calibration.get('verdict', 'not recorded')})")
