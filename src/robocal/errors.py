"""Exceptions and warnings robocal raises, for users to catch or filter.

``InputError`` (bad input, naming the file and the row, column or key), ``DegenerateDataError``
(data that cannot determine what was asked), both ``RobocalError``; warnings derive from
``RobocalWarning``.
"""

from ._base.errors import (
    CheckWarning,
    ConvergenceWarning,
    DegenerateDataError,
    IdentifiabilityWarning,
    InputError,
    MisfitWarning,
    RobocalError,
    RobocalWarning,
)

__all__ = ["RobocalError", "InputError", "DegenerateDataError", "RobocalWarning", "CheckWarning", "ConvergenceWarning",
           "MisfitWarning", "IdentifiabilityWarning"]
