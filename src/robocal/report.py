"""What people read: the HTML report of a calibration (needs the ``report`` extra) and the text
summaries the command line prints, all pure functions of the result records."""

from ._base import arguments as _arguments
from ._presentation.history import (
    change_line,
    history_summary,
    render_history,
    type_summary,
    verification_summary,
    write_history,
)
from ._presentation.html import render_report, write_report
from ._presentation.plots import PLOTS
from ._presentation.text import (
    calibration_summary,
    checks_lines,
    comparison_summary,
    identifiability_summary,
    verdict_line,
)
from ._presentation.units import DISPLAY_UNITS, fmt

__all__ = ["render_report", "write_report", "PLOTS", "calibration_summary", "comparison_summary",
           "identifiability_summary", "checks_lines", "verdict_line", "DISPLAY_UNITS", "fmt", "change_line",
           "history_summary", "type_summary", "verification_summary", "render_history", "write_history"]

# the functions users call check their arguments; robocal's own code calls them unchecked
_arguments.export_checked(globals())
