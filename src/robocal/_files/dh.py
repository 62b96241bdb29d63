"""DH tables out (and, as formats are added, in): the MDH table as CSV with unit suffixes."""

from __future__ import annotations

import csv
import io

from .._conversion import mdh_table
from .._model import RobotModel
from .text import write_texts


def write_mdh_csv(model: RobotModel, path, *, units: str = "mm-deg", force: bool = False) -> None:
    """Write :func:`mdh_table` as CSV (header with unit suffixes), atomically; 15 significant digits."""
    rows = mdh_table(model, units=units)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(list(rows[0]))
    for row in rows:
        w.writerow([format(v, ".15g") if isinstance(v, float) else v for v in row.values()])
    write_texts({path: buf.getvalue()}, force=force)
