"""Mistakes of the nominal model (docs/diagnosis.md): a value with the wrong sign, a robot of another
size, a marker on another frame, and the values the data say where the calibration took up a
mistake of the model file (a link 100 mm off, every length scaled, a sign flipped, an axis
reversed): named as the model's, with the value the data give."""

from __future__ import annotations

from dataclasses import replace
from functools import partial
from typing import cast

import numpy as np

from .._identification.checks import tolerances
from .._identification.result import Finding
from .._model.kinematics import evaluate
from .._model.parameters import model_from_vector, parameter_layout
from .facts import NOTED_SCORE
from .reference import Candidate, Reference, Repair
from .rigid import gross, per_point, predicted, screen_data, screen_positions, screened_model
from .values import model_scaled

# a common scale of the frames' lengths the data give this far from 1 is another robot's size
SIZE_OFF = 0.03
# lengths within this share of one common scale are scaled alike
SCALE_SPREAD = 0.02
# an estimate within this share of the nominal's opposite is the nominal with its sign flipped
SIGN_SHARE = 0.1


def untestable_signs(ref: Reference) -> list[str]:
    """The nominal frame values whose sign these data cannot tell: those the calibration eliminated
    because identified ones (the base's, another frame's) absorb them."""
    p = ref.nominal_vector
    lay = parameter_layout(ref.model)
    out = []
    for a in ref.result.identifiability.eliminated:
        if a.name in lay.names and lay[a.name].family == "frames" and p[lay[a.name].index] != 0.0 and a.absorbers:
            by = ", ".join(n for n, _ in a.absorbers[:3])
            verb = "absorbs" if len(a.absorbers) == 1 else "absorb"
            out.append(f"the sign of the model's {a.name}: these data cannot tell it, {by} {verb} it")
    return out


def model_sign(ref: Reference) -> list[Candidate]:
    """A nominal value with the wrong sign in the model file: each non-zero length or angle of the
    frames the data can tell (not eliminated) flipped in turn, the flip the nominal robot then
    matches best refitted."""
    if not gross(ref):
        return []
    lay = parameter_layout(ref.model)
    p_nom = ref.nominal_vector
    eliminated = {a.name for a in ref.result.identifiability.eliminated}
    names = [par.name for par in lay.parameters if par.family == "frames" and p_nom[par.index] != 0.0
             and par.name not in eliminated]
    if not names:
        return []

    def flipped(name):
        p = p_nom.copy()
        p[lay[name].index] *= -1.0
        return model_from_vector(ref.model, p)

    misfits = [screened_model(ref, flipped(n)) for n in names]
    k = int(np.argmin(misfits))
    best = names[k]
    return [Candidate("model sign", f"the model's {best} has the wrong sign", "with its sign flipped",
                      f"correct the sign of {best} in the model file", (best,), predicted(ref, misfits[k]),
                      np.log2(len(names)), lambda: Repair(ref.data, model=flipped(best)), model_file=True,
                      absorbed=True)]


def robot_size(ref: Reference) -> list[Candidate]:
    """The data come from a robot of another size (another robot's file): the model with every length of
    its frames scaled by the factor the nominal robot then matches best."""
    if not gross(ref):
        return []
    coarse = np.exp(np.linspace(np.log(0.5), np.log(2.0), 15))
    s = float(coarse[int(np.argmin([screened_model(ref, model_scaled(ref.model, f, markers=False)) for f in coarse]))])
    fine = s * np.linspace(0.96, 1.04, 5)
    misfits = [screened_model(ref, model_scaled(ref.model, f, markers=False)) for f in fine]
    s = float(fine[int(np.argmin(misfits))])
    if abs(s - 1.0) < SIZE_OFF:
        return []
    return [Candidate("robot size", f"the data come from a robot about {s:.3g} times this model's size (another "
                      "robot's file or model)", "with every length scaled", "check that the measurement file and "
                      "the model file are of the same robot", (), predicted(ref, min(misfits)), 2.0,
                      lambda: Repair(ref.data, model=model_scaled(ref.model, s, markers=False)), model_file=True,
                      absorbed=True)]


def marker_frame(ref: Reference) -> list[Candidate]:
    """A marker on another frame than the model says: for each marker the frame the nominal robot
    matches best (the marker's coordinates kept), every frame's pose from one evaluation."""
    if not gross(ref):
        return []
    model, d = ref.model, screen_data(ref)
    X = cast(np.ndarray, evaluate(model, d.q, frames=True, payload_mass=d.payload_mass).frames)
    out = []
    for j, name in enumerate(d.marker_names):
        k = model.marker_names.index(name)
        here = model.markers[k].frame % len(model.frames)
        others = [f for f in range(len(model.frames)) if f != here]
        Xo = X[:, others]
        on = Xo[..., :3, :3] @ np.asarray(model.markers[k].position) + Xo[..., :3, 3]
        misfits = [per_point(np.concatenate([P0[:, :j], on[:, [i]], P0[:, j + 1:]], axis=1), d)
                   for P0 in (screen_positions(ref),) for i in range(len(others))]
        i = int(np.argmin(misfits))
        frame = model.frames[others[i]].name
        moved = model.replace(markers=tuple(replace(mk, frame=others[i]) if n == k else mk
                                            for n, mk in enumerate(model.markers)))
        out.append(Candidate("marker frame", f"marker {name} is on frame {frame}, not {model.frames[here].name}",
                             "with it there", f"put marker {name} on frame {frame} in the model file", (name, frame),
                             predicted(ref, misfits[i]), np.log2(len(others)),
                             partial(Repair, ref.data, model=moved), model_file=True))
    return out


def _implausible(ref: Reference) -> list:
    """The calibration's estimates of frames and markers beyond their tolerances."""
    tol = tolerances(ref.model)
    out = []
    for e in ref.result.parameters:
        bound = tol.get((e.family, e.quantity))
        if e.family in ("frames", "markers") and bound is not None and abs(e.estimate - e.nominal) > bound:
            out.append(e)
    return out


def _value(e) -> str:
    return f"{np.degrees(e.estimate):.4g} deg" if e.quantity == "angle" else f"{e.estimate * 1e3:.5g} mm"


def _nominal(e) -> str:
    return f"{np.degrees(e.nominal):.4g} deg" if e.quantity == "angle" else f"{e.nominal * 1e3:.5g} mm"


def _common_scale(ref: Reference) -> float | None:
    """The common factor between the calibrated and the nominal lengths of the frames, when every
    non-zero one is scaled alike (within ``SCALE_SPREAD``) and beyond ``SIZE_OFF``; else None."""
    lengths = [e for e in ref.result.parameters if e.family == "frames" and e.quantity == "length"
               and abs(e.nominal) > 1e-3]
    if len(lengths) < 2:
        return None
    ratios = np.array([e.estimate / e.nominal for e in lengths])
    s = float(np.median(ratios))
    if abs(s - 1.0) > SIZE_OFF and np.all(np.abs(ratios - s) <= SCALE_SPREAD * abs(s)):
        return s
    return None


def model_values(ref: Reference) -> Finding | None:
    """Where the calibration took up a mistake of the nominal model (changes beyond their tolerances in
    a calibration that places the robot better in use): the model file's values named with what the
    data say, as a sign flipped, an axis reversed, every length scaled, or a value off."""
    wrong = _implausible(ref)
    better = any(c.name == "plausible changes" and c.status == "warn" for c in ref.result.checks)
    if not wrong or not better:
        return None
    s = _common_scale(ref)
    if s is not None:
        cause = f"the model file is of a robot of another size: the data say every length is {s:.4g} times the model's"
    else:
        cause = "the model file's " + "; ".join(_said(e) for e in wrong[:4]) + (" ..." if len(wrong) > 4 else "")
    items = tuple(e.name for e in wrong)
    values = ", ".join(f"{e.name} = {_value(e)} (+- {_std(e)})" for e in wrong[:6])
    return Finding("model values", cause, f"the calibration places the robot better in use with {values}: the data "
                   "fit them, and the calibrated model holds them", NOTED_SCORE, items, ref.rms, None,
                   f"correct {', '.join(items[:6])} in the model file (the calibrated model holds the values the data "
                   "say)")


def _std(e) -> str:
    return f"{np.degrees(e.std):.2g} deg" if e.quantity == "angle" else f"{e.std * 1e3:.2g} mm"


def _said(e) -> str:
    """One value of the model file against what the data say."""
    if abs(e.nominal) > 0 and abs(e.estimate + e.nominal) <= SIGN_SHARE * abs(e.nominal):
        return f"{e.name} has the wrong sign (the data say {_value(e)}, the file {_nominal(e)})"
    if e.quantity == "angle" and abs(abs(e.estimate - e.nominal) - np.pi) < np.radians(10):
        return (f"{e.name} is 180 deg off (the data say {_value(e)}, the file {_nominal(e)}): the joint's direction "
                "is reversed in the model, or its readings have the wrong sign")
    return f"{e.name} is off: the data say {_value(e)}, the file {_nominal(e)}"

