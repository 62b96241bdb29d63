"""Identification piece by piece, for those who build their own workflow: the problem (one model on
a stack of observation blocks: measured points, sockets, planes, ball bars, known distances), the
identifiability analysis, the solve and the covariance that ``calibrate`` runs, the checks it
records (docs/checks.md), the kit's figures of contacts, and the diagnosis."""

from ._base import arguments as _arguments
from ._diagnosis.calibrate import calibrate, compare
from ._diagnosis.contacts import diagnose_contacts
from ._diagnosis.measured import diagnose
from ._identification.calibrate import register_base
from ._identification.checks import Check, outlier_bar, outlier_check, verdict
from ._identification.contact_figures import ContactErrors, ContactFigures, contact_errors
from ._identification.estimates import ErrorStats, ParameterEstimate, error_stats
from ._identification.identifiability import (
    Absorption,
    ContactIdentifiability,
    IdentifiabilityResult,
    Unreachable,
    analyse,
    contact_identifiability,
    identifiability,
    status_table,
    weakly_identifiable,
)
from ._identification.points import Points, design_problem
from ._identification.problem import ROW_KINDS, Problem, Solvable
from ._identification.result import (
    CalibrationResult,
    Comparison,
    Diagnosis,
    ErrorSummary,
    Finding,
    LimitJudgement,
    NestedTest,
    PoseSet,
    SolverRecord,
)
from ._identification.solve import Covariance, Solution, covariance, solve
from ._model.measurements import Noise

__all__ = ["calibrate", "compare", "register_base", "error_stats", "CalibrationResult", "Comparison",
           "ParameterEstimate", "ErrorStats", "ErrorSummary", "LimitJudgement", "SolverRecord", "PoseSet",
           "NestedTest", "Check", "verdict", "outlier_check",
           "outlier_bar", "Noise",
           "identifiability", "analyse", "weakly_identifiable", "status_table", "Absorption",
           "IdentifiabilityResult", "Problem", "Points", "Solvable", "design_problem", "solve", "Solution",
           "covariance", "Covariance", "ROW_KINDS", "contact_identifiability", "contact_errors",
           "ContactFigures", "ContactIdentifiability", "ContactErrors", "Unreachable",
           "diagnose", "Diagnosis", "Finding", "diagnose_contacts"]

# the functions users call check their arguments; robocal's own code calls them unchecked
_arguments.export_checked(globals())
