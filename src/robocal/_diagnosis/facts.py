"""Causes the data show without a refit (docs/diagnosis.md): a marker's values equal to another's,
joint readings a whole turn off, measurements equal to the nominal model's own predictions, a joint
that never moves, blunders the calibration set aside. Each is a fact of the data or of the result,
cheap to see, and a finding when it holds."""

from __future__ import annotations

from itertools import combinations

import numpy as np

from .._identification.checks import whole_turns as whole_turns_of
from .._identification.identifiability import DEFAULT_TOL, theoretical_identifiability
from .._identification.result import Finding
from .reference import NAMED_FACTOR, Reference, mm

# a fact decisive of itself outranks what refits find; one only noted is at the naming bar
DECISIVE_SCORE = 3.0
NOTED_SCORE = float(np.log10(NAMED_FACTOR))
# the nominal model's predictions fit measured values to this share of the instrument's noise only
# when they are those predictions: no robot is within a tenth of its instrument's noise of its model
NOMINAL_SHARE = 0.1


def marker_copied(ref: Reference) -> Finding | None:
    """One marker's values equal to another's (a column filled from the wrong marker), where the model
    sets them apart: the measured separation against the nominal one. A fit with the marker's
    position free passes, so this one needs no misfit: the calibrated marker is where the other is."""
    d = ref.data
    if len(d.marker_names) < 2:
        return None
    P = ref.positions0
    best = None
    floor = np.sqrt(2.0) * ref.noise.position
    for a, b in combinations(range(len(d.marker_names)), 2):
        both = d.mask[:, a] & d.mask[:, b]
        if both.sum() < 3:
            continue
        gap = float(np.sqrt(np.mean((d.positions[both, a] - d.positions[both, b]) ** 2)))
        apart = float(np.sqrt(np.mean((P[both, a] - P[both, b]) ** 2)))
        if gap <= 3.0 * floor and apart > 10.0 * max(gap, floor) and (best is None or apart / gap > best[0]):
            best = (apart / max(gap, floor), (d.marker_names[a], d.marker_names[b]), gap, apart)
    if best is None:
        return None
    _, names, gap, apart = best
    return Finding("marker copied", f"marker {names[1]}'s values equal marker {names[0]}'s",
                   f"the two differ by {mm(gap)} RMS per axis where the model sets them {mm(apart)} apart: the "
                   f"calibrated marker {names[1]} sits where {names[0]} is", DECISIVE_SCORE, names, ref.rms, None,
                   f"fill marker {names[1]}'s columns with its own measurements (or drop them)", "fail")


def whole_turns(ref: Reference) -> Finding | None:
    """Revolute joint readings beyond the model's limits that fall within them a whole number of turns
    away (``checks.whole_turns``): a reading counted from another turn (a multi-turn encoder, an
    unwrapped log). The kinematics cannot tell a turn; the limits can."""
    q = ref.campaign.q
    turns = whole_turns_of(ref.model, q)
    if not turns.any():
        return None
    lo, hi = ref.model.lower_limits, ref.model.upper_limits
    named, first = [], q.shape[0]
    for j in np.nonzero(turns)[0]:
        beyond = np.nonzero((q[:, j] < lo[j]) | (q[:, j] > hi[j]))[0]
        k = int(turns[j])
        named.append(f"{ref.model.joint_names[j]} ({k:+d} turn{'s' if abs(k) > 1 else ''} on {len(beyond)} row(s))")
        first = min(first, int(beyond[0]))
    return Finding("whole turns", f"the readings of joint(s) {', '.join(named)} are a whole number of turns off "
                   "the model's range", f"each lies beyond the joint limits by whole turns and within them without "
                   f"(first at {ref.campaign.labels[first]}); a turn changes nothing the instrument sees",
                   DECISIVE_SCORE, tuple(ref.model.joint_names[j] for j in np.nonzero(turns)[0]), ref.rms, None,
                   "take the whole turns off those readings (the controller's turn count), or give the model the "
                   "joint's real limits", "fail")


def nominal_predictions(ref: Reference) -> Finding | None:
    """Measured values equal to the nominal model's own predictions (the targets exported in place of
    the measurements): the nominal geometry, its base and markers registered, fits them to a fraction
    of the instrument's noise that no real robot reaches."""
    before = ref.result.stats.fit_before
    n = int(before.n)
    if n < 10 or before.rms is None:
        return None
    per_axis = float(before.rms) / np.sqrt(3.0)
    if per_axis > NOMINAL_SHARE * ref.noise.position:
        return None
    return Finding("nominal predictions", "the measured values are the nominal model's own predictions (the "
                   "targets, not the measurements)", f"the nominal model fits them to {mm(per_axis)} RMS per axis, "
                   f"{per_axis / ref.noise.position:.2g} times the instrument's noise, over {n} points: no robot is "
                   "that close to its model, and no instrument that precise", DECISIVE_SCORE, (), ref.rms, None,
                   "export the measured positions (not the targets) and calibrate again", "fail")


def joint_still(ref: Reference) -> Finding | None:
    """A joint that never moves in the campaign: the parameters it alone would show are lost."""
    q = ref.campaign.q
    still = [j for j in range(q.shape[1]) if np.ptp(q[:, j]) <= 1e-9 * (1.0 + np.max(np.abs(q[:, j])))]
    if not still:
        return None
    names = tuple(ref.model.joint_names[j] for j in still)
    ident = ref.result.identifiability
    # those the robot's structure allows (not those every campaign leaves to the base or the tool)
    allowed = set(theoretical_identifiability(ref.model, tuple(ident.candidates), (), ref.campaign.has_orientation,
                                              DEFAULT_TOL, ref.campaign.marker_names).identified)
    lost = tuple(a.name for a in ident.eliminated if a.name in allowed)
    said = f"; the parameters the data cannot separate: {', '.join(lost[:6])}" if lost else ""
    return Finding("joint still", f"joint(s) {', '.join(names)} never move in this campaign",
                   f"every reading of {', '.join(names)} is the same{said}", NOTED_SCORE, names, ref.rms, None,
                   "move every joint over its range (robocal plan) and measure again")


def blunders_aside(ref: Reference) -> Finding | None:
    """Measured points the calibration set aside as blunders (docs/checks.md, "outliers"): named as a
    cause the calibration already carries (its model is the one their deletion gives)."""
    aside = ref.result.fit.set_aside
    if aside is None or not aside.any():
        return None
    rows, cols = np.nonzero(aside)
    source = ref.result.provenance.get("data")
    labels = source.get("labels", ()) if isinstance(source, dict) else ()
    names = ref.campaign.marker_names
    items = tuple(f"{labels[r] if r < len(labels) else f'pose {r}'}, marker {names[c]}" for r, c in zip(rows, cols))
    return Finding("blunders", f"{len(items)} measured point(s) are blunders", "they stand far beyond the outlier bar, "
                   "and setting them aside lowered the cross-validated error; the calibration is the one their "
                   "deletion gives", NOTED_SCORE, items, ref.rms, None, "check or remove those measurements")


FACTS = (marker_copied, whole_turns, nominal_predictions, joint_still, blunders_aside)
