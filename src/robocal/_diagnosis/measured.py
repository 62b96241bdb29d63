"""Diagnosis of a calibration from measured points: why its data do not fit, tested against the data
themselves (docs/diagnosis.md).

It screens every calibration. Facts of the data come first (a marker's values equal to another's,
readings a whole turn off, the nominal model's own predictions in place of measurements); then each
hypothesis proposes its repair with the factor cheap statistics predict it divides the residual
variance by (rigid matches of the nominal robot, one Gauss-Newton step of added columns from the
calibration, the residuals split by row or by marker), and only the repairs predicted to matter are
refitted. A repair names a cause when it explains the data and places the robot better in use
(``reference.judge``): decisive, it decides the verdict; possible, it warns.

Large campaigns are diagnosed on at most ``MAX_POSES`` poses spread evenly along the campaign (the
rows, joints and markers a finding names still refer to the whole campaign).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .._base.arguments import accepts, both, is_a, measured_on, names_in, noise_of, number, optional, whole
from .._base.errors import InputError
from .._base.options import INSTRUMENT_NOISE
from .._base.threads import one_blas_thread
from .._identification.result import CalibrationResult, Diagnosis, Finding
from .._model.measurements import Measurements, Noise
from .._model.robot import RobotModel
from .campaign import (
    compliance_left_out,
    drift,
    joint_rehomed,
    labels_swapped,
    lost_motion,
    marker_elsewhere,
    pose_labels_offset,
    readings_lag,
    rows_shifted,
    step_change,
)
from .facts import FACTS
from .joints import joint_scale, joint_sign, joints_swapped, reading_unit
from .model_file import marker_frame, model_sign, model_values, robot_size, untestable_signs
from .reference import (
    BEYOND_SURVIVE_FACTOR,
    CLOSE_FACTOR,
    MAX_REFITS,
    SURVIVE_FACTOR,
    Reference,
    mm,
    reference,
    refitted,
)
from .values import axes_swapped, markers_swapped, mirrored_frame, payload_unit, position_unit, rotation_convention

HYPOTHESES = (rows_shifted, pose_labels_offset, mirrored_frame, axes_swapped, markers_swapped, position_unit,
              reading_unit, payload_unit, joint_scale, joint_sign, joints_swapped, model_sign, robot_size, marker_frame,
              step_change, joint_rehomed, drift, lost_motion, compliance_left_out, readings_lag, marker_elsewhere,
              labels_swapped, rotation_convention)
STATUS_RANK = {"fail": 2, "warn": 1}


def _identified(value, name, args):
    """Names (at least one) of parameters the calibration ``result`` identified."""
    names_in(lambda a: [e.name for e in a["result"].parameters], "a parameter the calibration identified")(
        value, name, args)
    if not len(value):
        raise InputError("must name at least one parameter the calibration identified (None: all)", where=name)


def _limit(value, name, _):
    """A limit of absolute accuracy: an ``AccuracyLimit`` or a positive number of metres."""
    number(getattr(value, "limit", value), name, low=0.0, low_open=True)


@accepts(model=is_a(RobotModel), data=both(is_a(Measurements), measured_on()), result=is_a(CalibrationResult),
         noise=noise_of(Noise, INSTRUMENT_NOISE), parameters=optional(_identified), limit=optional(_limit),
         folds=whole(2))
@one_blas_thread
def diagnose(model: RobotModel, data: Measurements, result: CalibrationResult, *, noise=None, parameters=None,
             limit=None, folds: int = 5) -> Diagnosis:
    """Test specific explanations of a calibration's misfit against the data, and name those that
    explain it (docs/diagnosis.md).

    Parameters
    ----------
    model : RobotModel
        The nominal model the calibration started from.
    data : Measurements
        The measurements it fitted (its fitted poses, in their campaign order).
    result : CalibrationResult
        The calibration of ``model`` on ``data``.
    noise : Noise, str or None
        The expected measurement noise (a ``Noise`` or an instrument class); default a laser tracker's.
    parameters : tuple of str, optional
        The parameters refitted; default those the calibration identified.
    limit : float, optional
        The limit of absolute accuracy the calibration was given (m): the robot's own scatter beside
        the instrument's.
    folds : int
        The folds of the cross-validation a repair is judged by.

    Returns
    -------
    Diagnosis
        The causes named, decisive first (none when nothing tested explains the misfit), the
        hypotheses tested, those these data cannot separate, and a one-line summary.
    """
    if parameters is not None:
        result = replace(result, parameters=tuple(e for e in result.parameters if e.name in set(parameters)))
    return diagnosed(reference(model, data, result, noise, _limit_m(limit), folds))


def diagnosed(ref: Reference) -> Diagnosis:
    """The diagnosis against a ``Reference``: facts, the hypotheses screened, the survivors refitted."""
    facts = _present(h(ref) for h in FACTS)
    survivors = screened(ref)
    found = _present(refitted(ref, c) for c in survivors)
    if not found and not any(f.status == "fail" for f in facts):
        facts += _present([model_values(ref)])
    tested = tuple(h.__name__.replace("_", " ") for h in FACTS + HYPOTHESES)
    return ranked(found + facts, tested, ref.rms, f"{mm(ref.rms)} RMS per axis", untestable=untestable_signs(ref),
                  refitted=tuple(dict.fromkeys(c.hypothesis for c in survivors)))


def _limit_m(limit) -> float | None:
    """The limit of absolute accuracy in metres (an ``AccuracyLimit`` or a number), or None."""
    return None if limit is None else float(getattr(limit, "limit", limit))


def _present(findings) -> list[Finding]:
    return [f for f in findings if f is not None]


def screened(ref) -> list:
    """The candidates of every hypothesis that the cheap statistics do not rule out (predicted to divide
    the residual variance by ``SURVIVE_FACTOR`` or more, ``BEYOND_SURVIVE_FACTOR`` for a cause no robot
    has of its own), the best predicted first, at most ``MAX_REFITS``."""
    candidates = sorted((c for h in HYPOTHESES for c in h(ref)), key=lambda c: -c.predicted)
    return [c for c in candidates
            if c.predicted >= (BEYOND_SURVIVE_FACTOR if c.beyond_robot else SURVIVE_FACTOR)][:MAX_REFITS]


def ranked(found: list[Finding], tested: tuple[str, ...], rms: float, misfit: str, *, untestable=(),
           refitted=()) -> Diagnosis:
    """The diagnosis of the ``found`` findings: decisive ones first, most likely first, the others of
    the same strength only within ``CLOSE_FACTOR`` of the first; when none is named, a summary saying
    so of the ``misfit`` (its words) and ``rms`` (m)."""
    order = sorted(found, key=lambda f: (-STATUS_RANK.get(f.status, 0), -f.score))
    shown: list[Finding] = []
    for f in order:
        top = next((g for g in shown if g.status == f.status), None)
        if top is None or f.score >= top.score - np.log10(CLOSE_FACTOR):
            shown.append(f)
    untested = tuple(untestable)
    if shown:
        first = shown[0]
        strength = "decisive" if first.status == "fail" else "noted" if first.noted else "possible cause"
        summary = f"{strength}: {first.cause} ({first.evidence})"
    else:
        summary = (f"nothing tested explains the misfit ({misfit}): none of the {len(tested)} explanations tested "
                   "explains the data and places the robot better in use")
    if untested:
        summary += f"; not testable here: {'; '.join(untested[:3])}"
    return Diagnosis(findings=tuple(shown), tested=tested, summary=summary, rms=rms, untestable=untested,
                     refitted=tuple(refitted))
