"""Identification piece by piece, for those who build their own workflow: the problem (residuals
and Jacobian of a model on a set of poses), the identifiability analysis, the solve and the
covariance that ``calibrate`` runs, and the checks it records (docs/checks.md); the same for
joint-only contacts (sockets, planes, ball bars, known distances), alone or with a tracker."""

from ._diagnosis.contacts import diagnose_contacts
from ._identification.calibrate import (
    CalibrationResult,
    Comparison,
    ErrorStats,
    ErrorSummary,
    LimitJudgement,
    ParameterEstimate,
    calibrate,
    calibrate_contacts,
    compare,
    error_stats,
    register_base,
)
from ._identification.checks import Check, outlier_bar, outlier_check, verdict
from ._identification.contact_blocks import ROW_KINDS, ContactProblem
from ._identification.contact_figures import (
    ContactErrors,
    ContactFigures,
    ContactIdentifiability,
    Unreachable,
    contact_errors,
    contact_identifiability,
)
from ._identification.identifiability import (
    Absorption,
    IdentifiabilityResult,
    analyse,
    identifiability,
    status_table,
    weakly_identifiable,
)
from ._identification.problem import Problem, design_problem
from ._identification.solve import Covariance, Solution, covariance, solve
from ._model.measurements import Noise

__all__ = ["calibrate", "compare", "register_base", "error_stats", "CalibrationResult", "Comparison",
           "ParameterEstimate", "ErrorStats", "ErrorSummary", "LimitJudgement", "Check", "verdict", "outlier_check",
           "outlier_bar", "Noise",
           "identifiability", "analyse", "weakly_identifiable", "status_table", "Absorption",
           "IdentifiabilityResult", "Problem", "design_problem", "solve", "Solution", "covariance", "Covariance",
           "ContactProblem", "ROW_KINDS", "calibrate_contacts", "contact_identifiability", "contact_errors",
           "ContactFigures", "ContactIdentifiability", "ContactErrors", "Unreachable",
           "diagnose_contacts"]
