"""The store of calibrations (docs/store.md): each robot's calibrations over the years in SQLite or
PostgreSQL, its history and judged changes, quick verifications, robots of one type compared."""

from ._base import arguments as _arguments
from ._store.store import (
    JUDGED_FAMILIES,
    Change,
    Estimate,
    History,
    Latest,
    Outlier,
    Overall,
    Store,
    StoredCalibration,
    StoredVerification,
    TypeComparison,
    accuracy_at_calibration,
    compare_type,
    default_store_path,
    history,
    judge_changes,
    judge_overall,
    latest_usable,
    model_document,
    open_store,
    sidak_threshold,
    store_location,
    stored_calibration,
    type_comparison,
    verify_robot,
)

__all__ = ["Store", "open_store", "store_location", "default_store_path", "history", "type_comparison", "verify_robot",
           "latest_usable", "judge_changes", "judge_overall", "compare_type", "stored_calibration",
           "accuracy_at_calibration", "History", "Change", "Overall", "TypeComparison", "Latest", "Outlier",
           "StoredCalibration", "StoredVerification", "Estimate", "model_document", "sidak_threshold",
           "JUDGED_FAMILIES"]

# the functions users call check their arguments; robocal's own code calls them unchecked
_arguments.export_checked(globals())
