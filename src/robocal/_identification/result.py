"""The records a calibration produces: its result, the error statistics before and after on the
fitted and held-out poses, the judgement against the limit of absolute accuracy, and a comparison
of identifications. Records are read, never changed."""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime, timezone
from typing import TYPE_CHECKING, cast

import numpy as np

from .._base.errors import InputError
from .._model.contacts import Contacts
from .._model.measurements import Measurements
from .._model.parameters import parameter_layout, parameter_vector
from .._model.robot import RobotModel
from .._version import __version__
from .checks import Check, verdict
from .estimates import ErrorStats, ParameterEstimate, error_stats
from .holdout import AccuracyInUse, Coverage
from .identifiability import IdentifiabilityResult

if TYPE_CHECKING:
    from .contact_figures import ContactFigures

# the limit is a mean-error bar; within this factor of it counts as reaching it
LIMIT_REACHED_WITHIN = 1.15


@dataclass(frozen=True)
class ErrorSummary:
    """Position error statistics before and after calibration on the fitted and held-out poses."""

    fit_before: ErrorStats
    fit_after: ErrorStats
    validation_before: ErrorStats
    validation_after: ErrorStats

    KEYS = ("fit_before", "fit_after", "validation_before", "validation_after")

    def __getitem__(self, key: str) -> ErrorStats:
        return getattr(self, key)


@dataclass(frozen=True)
class LimitJudgement:
    """The mean error in use after calibration (``compared``: "validation_after" for a validation
    set, "cross-validation" otherwise) against the limit of absolute accuracy, metres; ``reached``
    within ``LIMIT_REACHED_WITHIN`` of it."""

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
class CalibrationResult:
    """Everything a calibration produced. Fields are always present; absent data are None.

    Per measured point, on the fitted poses: ``errors_before``/``errors_after`` (n_poses, n_markers)
    position error norms in metres (NaN where not measured), ``residual_vectors`` (n_poses,
    n_markers, 3) calibrated minus measured and ``measured_positions`` likewise, metres in W,
    ``readings`` (n_poses, n_joints) the joint readings (SI), and for 6D data
    ``rotation_errors_before``/``rotation_errors_after`` (n_poses, n_markers) rotation error angles in
    radians (None for point data). The ``validation_*`` fields are the same on held-out poses, or
    None. ``stats`` summarises the position errors, ``rotation_stats`` the rotation errors (rad) or
    None. ``correlation`` is indexed like ``parameters``. ``sigma0`` is the residual standard
    deviation (m, or in stated standard deviations when the data carry them).

    A calibration that fitted contacts holds the kit's figures in ``contacts`` (``ContactFigures``:
    socket consistency and spacing error, fitted and held out, what each kind of contact reaches);
    its per-point fields are those of the tracker data fitted beside them (no rows without), and
    its ``in_use`` the socket consistency of each placement predicted by the others (or of the
    held-out placements).
    """

    nominal_model: RobotModel
    calibrated_model: RobotModel
    parameters: tuple[ParameterEstimate, ...]
    covariance: np.ndarray
    correlation: np.ndarray
    identifiability: IdentifiabilityResult
    stats: ErrorSummary
    errors_before: np.ndarray
    errors_after: np.ndarray
    residual_vectors: np.ndarray
    measured_positions: np.ndarray
    success: bool
    status: int
    message: str
    nfev: int
    sigma0: float
    families: tuple[str, ...]
    loss: str
    notes: tuple[str, ...] = ()
    limit: LimitJudgement | None = None
    provenance: dict = field(default_factory=dict)
    checks: tuple[Check, ...] = ()
    readings: np.ndarray | None = None
    validation_before: np.ndarray | None = None
    validation_after: np.ndarray | None = None
    rotation_errors_before: np.ndarray | None = None
    rotation_errors_after: np.ndarray | None = None
    rotation_stats: ErrorSummary | None = None
    validation_readings: np.ndarray | None = None
    validation_residual_vectors: np.ndarray | None = None
    validation_positions: np.ndarray | None = None
    rotation_validation_before: np.ndarray | None = None
    rotation_validation_after: np.ndarray | None = None
    in_use: AccuracyInUse | None = None
    coverage: Coverage | None = None
    contacts: ContactFigures | None = None
    residual_dof: float = 0.0

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
    """Errors before and after calibration on one set of poses: position vectors (n, m, 3) in m and,
    for 6D data, rotation vectors (n, m, 3) in rad; NaN where not measured."""

    data: Measurements
    before: np.ndarray
    after: np.ndarray
    rotation_before: np.ndarray | None
    rotation_after: np.ndarray | None

    @staticmethod
    def summary_of_none() -> ErrorSummary:
        """The statistics of a calibration that fitted no measured point (each with n = 0)."""
        return ErrorSummary(*(error_stats([]) for _ in ErrorSummary.KEYS))

    @staticmethod
    def no_poses(model: RobotModel) -> dict:
        """The per-point fields of a calibration that fitted no measured point: arrays of no rows."""
        m = len(model.marker_names)
        return {"errors_before": np.zeros((0, m)), "errors_after": np.zeros((0, m)),
                "residual_vectors": np.zeros((0, m, 3)), "measured_positions": np.zeros((0, m, 3)),
                "readings": np.zeros((0, model.n_joints))}

    def summary(self, other: PoseErrors | None, *, rotation: bool) -> ErrorSummary | None:
        """Statistics of the error norms here (fit) and on ``other`` (held out), positions or rotations."""
        if rotation and self.rotation_after is None:
            return None

        def stats(e: PoseErrors | None, when: str):
            if e is None:
                return error_stats([])
            v = getattr(e, f"rotation_{when}" if rotation else when)
            return error_stats([] if v is None else np.linalg.norm(v, axis=2))

        return ErrorSummary(stats(self, "before"), stats(self, "after"), stats(other, "before"), stats(other, "after"))

    def fields(self, which: str) -> dict:
        """The result fields of this set (``which``: "fit" or "validation")."""
        norms = {k: None if v is None else np.linalg.norm(v, axis=2)
                 for k, v in (("before", self.before), ("after", self.after),
                              ("rotation_before", self.rotation_before), ("rotation_after", self.rotation_after))}
        positions = np.where(self.data.mask[..., None], self.data.positions, np.nan)
        if which == "fit":
            return {"errors_before": norms["before"], "errors_after": norms["after"], "residual_vectors": self.after,
                    "measured_positions": positions, "readings": self.data.q,
                    "rotation_errors_before": norms["rotation_before"],
                    "rotation_errors_after": norms["rotation_after"]}
        return {"validation_before": norms["before"], "validation_after": norms["after"],
                "validation_residual_vectors": self.after, "validation_positions": positions,
                "validation_readings": self.data.q, "rotation_validation_before": norms["rotation_before"],
                "rotation_validation_after": norms["rotation_after"]}



def provenance(data: Measurements | None, validation: Measurements | None = None, contacts: Contacts | None = None,
               validation_contacts: Contacts | None = None) -> dict:
    """Software, date and the inputs (source, SHA-256, pose labels in the order of the error rows;
    contacts' rows and placements)."""
    prov: dict[str, object] = {"software": "robocal", "version": __version__,
                               "date": datetime.now(timezone.utc).isoformat(timespec="seconds")}
    for key, d in (("data", data), ("validation", validation)):
        if d is not None:
            prov[key] = {"source": d.source, "sha256": d.sha256, "n_poses": d.n_poses, "labels": list(d.labels)}
    for key, c in (("contacts", contacts), ("validation_contacts", validation_contacts)):
        if c is not None:
            prov[key] = {"source": c.source, "sha256": c.sha256, "n_rows": c.n_rows, "placements": list(c.placements())}
    return prov



@dataclass(frozen=True, eq=False)
class Comparison:
    """Geometric-only against geometric-and-compliance identification on the same data, and, when
    asked, against geometric, compliance and backlash together (the third).

    ``f_statistic``/``p_value``: the nested-model F test on the fitted residuals (does adding the
    compliance parameters reduce the residual more than their number explains?). ``helped`` is
    True when p < ``alpha`` and the RMS error in use (held-out poses, else cross-validated on the
    same folds) fell too: a model choice is checked by what it does in use.
    ``backlash``, ``backlash_f``, ``backlash_p``, ``backlash_helped``: the same test of the third
    against the second (None and False without it). ``verdict`` says both.
    """

    geometric: CalibrationResult
    combined: CalibrationResult
    f_statistic: float
    p_value: float
    helped: bool
    verdict: str
    backlash: CalibrationResult | None = None
    backlash_f: float | None = None
    backlash_p: float | None = None
    backlash_helped: bool = False

    @property
    def best(self) -> CalibrationResult:
        if self.backlash is not None and self.backlash_helped:
            return self.backlash
        return self.combined if self.helped else self.geometric

    @property
    def results(self) -> dict:
        """The identifications side by side, by what they identify."""
        out = {"geometric": self.geometric, "geometric and compliance": self.combined}
        if self.backlash is not None:
            out["geometric, compliance and backlash"] = self.backlash
        return out


