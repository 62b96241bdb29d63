"""What the command line prints after a calibration from contacts: the kit's figures before and
after, what each kind of contact reached and what none did, the parameters and the checks."""

from __future__ import annotations

import numpy as np

from .text import checks_lines, verdict_line
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
                   f"mean: {_mm(before.consistency_mean)} -> {_mm(after.consistency_mean)}; "
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


def contact_summary(result) -> str:
    """The text summary of a ``ContactCalibration``."""
    ident = result.identifiability
    lines = ["calibration from contacts", "what the kit shows (before -> after):"]
    lines += _figures("fitted", result.fit_before, result.fit_after)
    if result.validation_before is not None:
        lines += _figures("held-out", result.validation_before, result.validation_after)
    if result.held_out is not None:
        lines += _figures("each placement predicted by the others,", result.fit_before, result.held_out)
    if result.tracker_after is not None:
        lines.append(f"  tracker points after: {_mm(result.tracker_after.rms)} RMS over {result.tracker_after.n}")
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
    if result.weak:
        lines.append(("weakly identifiable, kept: " if result.weak_kept else "weakly identifiable, held at nominal: ")
                     + ", ".join(f"{n} (predicted std {s})" for n, s in result.weak))
    lines.append("parameters (change from nominal +- std):")
    for p in result.parameters:
        lines.append(f"  {p.name:<12} {with_unit(p.change, p.unit, sign=True)} +- {with_unit(p.std, p.unit)}")
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
