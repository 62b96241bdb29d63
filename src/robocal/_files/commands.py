"""Corrected joint commands out (``robocal compensate``): one row per target, units in the header."""

from __future__ import annotations

import csv
import io

from .._accuracy.compensation import Compensation
from .._base.units import ANGLE_UNITS, LENGTH_UNITS, parse_units
from .._model.robot import RobotModel

# the column naming, per target, the joints whose commands lie beyond the readings the calibration measured
OUTSIDE = "beyond_calibrated_range"
# what the status column says of a target
REACHED, UNREACHED, NOT_CONVERGED, BEYOND_LIMITS = "ok", "out of reach", "not converged", "beyond joint limits"


def command_status(comp: Compensation, tol: float, tol_rot: float) -> list[str]:
    """Per target: ``ok``; ``out of reach`` or ``not converged`` (residual above the tolerances, see
    ``Compensation.out_of_reach``); ``beyond joint limits``."""
    reached, far = comp.reached(tol, tol_rot), comp.out_of_reach(tol, tol_rot)
    return [(UNREACHED if f else NOT_CONVERGED) if not r else (REACHED if inside else BEYOND_LIMITS)
            for r, f, inside in zip(reached, far, comp.within_limits)]


def commands_to_csv(model: RobotModel, labels, comp: Compensation, status, *, units: str = "mm-deg",
                    ranges_known: bool = False) -> str:
    """CSV text: pose, the corrected readings (unit suffix per joint; empty for a target out of reach
    or not converged, whose solver's last readings command no pose asked for), the residual
    position and orientation errors, the status of each target, and where the calibrated ranges are
    known (``ranges_known``) the joints whose corrected readings lie beyond them
    (``Compensation.outside``, separated by ";")."""
    lu, au = parse_units(units)
    L, A = LENGTH_UNITS[lu], ANGLE_UNITS[au]
    scale = [L if k == "length" else A for k in model.reading_quantities]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["pose"] + [f"{jn}_{lu if k == 'length' else au}"
                           for jn, k in zip(model.joint_names, model.reading_quantities)]
               + [f"residual_{lu}", f"residual_rot_{au}", "status"] + [OUTSIDE] * ranges_known)
    for i, label in enumerate(labels):
        beyond = [";".join(n for n, o in zip(model.joint_names, comp.outside[i]) if o)] * ranges_known
        missed = status[i] in (UNREACHED, NOT_CONVERGED)
        w.writerow([label] + ["" if missed else repr(float(v) / s) for v, s in zip(comp.q[i], scale)]
                   + [format(comp.residual[i] / L, ".3g"), format(comp.residual_rot[i] / A, ".3g"), status[i]] + beyond)
    return buf.getvalue()
