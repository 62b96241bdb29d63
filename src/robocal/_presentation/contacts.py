"""What the command line prints after a calibration from contacts: the kit's figures before and
after, what each kind of contact reached and what none did, the parameters and the checks."""

from __future__ import annotations

import numpy as np

from .text import cause_lines, checks_lines, in_use_lines, verdict_line
from .units import with_unit


def _listed(names, n: int = 6) -> str:
    return ", ".join(names[:n]) + (f", ... ({len(names) - n} more)" if len(names) > n else "")


def _mm(v) -> str:
    return "–" if v is None else with_unit(v, "m")


def _figures(label: str, before, after) -> list[str]:
    """Mean socket spread, known-distance RMS error, plane RMS and ball-bar RMS error, before -> after."""
    out = []
    if before.spread:
        out.append(f"  {label} socket spread (RMS about each socket's centre, mean over {len(before.spread)}): "
                   f"{_mm(before.mean_spread)} -> {_mm(after.mean_spread)}")
    if before.consistency:
        out.append(f"  {label} socket consistency (each seating's distance from its socket's mean centre), "
                   f"mean over seatings: {_mm(before.consistency_mean)} -> {_mm(after.consistency_mean)}; "
                   f"mean over placements: {_mm(before.consistency_by_placement)} -> "
                   f"{_mm(after.consistency_by_placement)}; "
                   f"max: {_mm(before.consistency_max)} -> {_mm(after.consistency_max)}")
    if before.distance:
        out.append(f"  {label} known distances, RMS error over {len(before.distance)}: "
                   f"{_mm(before.distance_rms)} -> {_mm(after.distance_rms)}")
        out.append(f"  {label} spacing error (calibrated minus known), mean |e|: {_mm(before.spacing_mean)} -> "
                   f"{_mm(after.spacing_mean)}; max |e|: {_mm(before.spacing_max)} -> {_mm(after.spacing_max)}")
    for name, kind in (("plane", "plane contacts, RMS distance to their plane"), ("bar", "ball-bar length error")):
        b, a = getattr(before, name), getattr(after, name)
        if b:
            rms = [float(np.sqrt(np.mean(np.square(list(d.values()))))) for d in (b, a)]
            out.append(f"  {label} {kind}, RMS over {len(b)}: {_mm(rms[0])} -> {_mm(rms[1])}")
    return out


def contact_summary(result, shown=()) -> str:
    """The text summary of a ``CalibrationResult`` that fitted contacts (its ``contacts`` figures);
    ``shown``: notes already printed as warnings."""
    c = result.contacts
    ident = c.identifiability
    rows = ", ".join(f"{n} {kind}" for kind, n in c.rows.items())
    lines = cause_lines(result) + [f"calibration of {result.nominal_model.name} from contacts ({rows}; "
                                   f"{', '.join(result.families)}, loss {result.solver.loss})",
                                   "what the kit shows (before -> after):"]
    lines += _figures("fitted", c.fit_before, c.fit_after)
    if c.validation_before is not None:
        lines += _figures("held-out", c.validation_before, c.validation_after)
    if c.held_out is not None:
        lines += _figures("each placement predicted by the others,", c.fit_before, c.held_out)
    tracker, held = result.stats.fit_after, result.stats.validation_after
    if tracker.n:
        lines.append(f"  tracker points: {_mm(result.stats.fit_before.rms)} -> {_mm(tracker.rms)} RMS over "
                     f"{tracker.n}")
    if held.n:
        lines += in_use_lines(result.in_use)
    lines.append(f"identified {len(ident.identified)} parameters; each kind alone identifies:")
    for kind, names in ident.contributions.items():
        lost = ident.lost_without.get(kind)
        lines.append(f"  {kind}: {len(names)}" + ("" if lost is None else
                     f"; without it {len(lost)} fewer" + (f" ({_listed(lost)})" if lost else "")))
    if ident.together:
        lines.append(f"  only the kinds together: {', '.join(ident.together)}")
    for u in ident.unreachable:
        lines.append(f"unreachable: {u.name} ({', '.join(u.components) if u.name == 'base' else 'every length alike'})"
                     f": {u.reason}")
    if c.weak:
        lines.append(("weakly identifiable, kept: " if c.weak_kept else "weakly identifiable, held at nominal: ")
                     + ", ".join(f"{n} (predicted std {s})" for n, s in c.weak))
    lines.append("parameters (change from nominal +- std):")
    for p in result.parameters:
        lines.append(f"  {p.name:<12} {with_unit(p.change, p.unit, sign=True)} +- {with_unit(p.std, p.unit)}")
    lines += [f"note: {n}" for n in result.notes if n not in shown]
    lines += checks_lines(result.checks)       # the same checks block and verdict line as a tracker fit
    lines.append(verdict_line(result))
    return "\n".join(lines)


def socket_plan_summary(plan) -> str:
    """What ``robocal plan-sockets`` prints: every design with its worst parameter against its bound,
    then the recommendation and the chosen design's predicted standard deviations."""
    d0 = plan.designs[0]
    lines = [f"socket plate: {len(d0.predicted_std)} parameters reachable; unreachable: "
             f"{', '.join(d0.unreachable) or 'none'}",
             "placements  seatings/socket  seatings  worst parameter (predicted std / bound)"]
    for d in plan.designs:
        lines.append(f"  {d.placements:>9}  {d.poses_per_socket:>15}  {d.n_seatings:>8}  {d.worst} {d.worst_ratio:.3g}"
                     + ("" if d.meets_bounds else "  (beyond)"))
    if plan.chosen is None:
        lines.append("no design of the grid keeps every parameter within its bound: more placements or seatings, "
                     "or looser bounds")
        return "\n".join(lines)
    c = plan.chosen
    lines.append(f"recommended: {c.placements} placements, {c.poses_per_socket} seatings per socket "
                 f"({c.n_seatings} seatings); predicted standard deviations:")
    lines += [f"  {n:<12} {with_unit(s, c.units[n])}" for n, s in c.predicted_std.items()]
    return "\n".join(lines)
