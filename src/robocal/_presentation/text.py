"""Text summaries of results, as the command line prints them: pure functions returning lines."""

from __future__ import annotations

import math

import numpy as np

from .._base.arguments import (
    FLAG,
    NAMES,
    TEXT,
    accepts,
    each_a,
    is_a,
)
from .._identification.checks import Check, error_where_used
from .._identification.contact_figures import ContactErrors
from .._identification.estimates import ErrorStats
from .._identification.holdout import REGISTERED_ON_IT, within_noise
from .._identification.identifiability import IdentifiabilityResult
from .._identification.result import CalibrationResult, Comparison
from .._model.parameters import BACKLASH_KINDS, BASE_KINDS, FRAME_KINDS, MARKER_KINDS, parameter_layout
from .._model.robot import TRANSMISSION_KINDS, RobotModel
from .units import MM, absorption_text, display_unit, with_unit

# the paper's table shows these kinds; gamma and b join them where a tree uses them
PAPER_KINDS = tuple(k for k in FRAME_KINDS[2:] if k not in BACKLASH_KINDS + TRANSMISSION_KINDS)


def registered_before(stats, poses: str) -> bool:
    """Whether "before" on the ``poses`` ("fit", "validation") had base and markers registered on
    them, away from the nominal model as given (``ErrorSummary.fit_nominal``; not known: False)."""
    raw, before = getattr(stats, f"{poses}_nominal"), getattr(stats, f"{poses}_before")
    return raw is not None and raw.n > 0 and not all(
        math.isclose(getattr(raw, f) or 0.0, getattr(before, f) or 0.0, rel_tol=1e-9, abs_tol=1e-9)
        for f in ("mean", "max"))


def stat_labels(stats, poses: str) -> list[tuple[str, str]]:
    """(when: "nominal", "before" or "after", what it is) of the error table's rows on the ``poses``
    ("fit", "validation"): the nominal model as given beside "before" where base and markers were
    registered for "before" (what the nominal missed as measured; ``stats`` None: not known)."""
    registered = stats is not None and registered_before(stats, poses)
    return ([("nominal", "nominal as given")] if registered else []) + [
        ("before", "before, registered" if registered else "before"), ("after", "after")]


def stat_rows(stats) -> list[tuple[str, str, ErrorStats]]:
    """(key of ``ErrorSummary``, what it is, statistics) of each row of the error table shown that
    holds points, on the fitted poses then the held-out ones (``stat_labels``)."""
    return [(f"{poses}_{when}", label, s) for poses in ("fit", "validation")
            for when, label in stat_labels(stats, poses)
            if (s := getattr(stats, f"{poses}_{when}")) is not None and s.n]


def stats_lines(stats, indent: str = "  ", *, unit: str = "m", in_use=None) -> list[str]:
    """The error table before and after, on fitted and held-out poses, as the instrument measured
    them (its noise in: the accuracy in use is the robot's, without it), in display units; the
    nominal model as given beside "before" where that registered base and markers (``stat_rows``);
    the held-out rows say when base and tool were registered on them (``in_use``'s method)."""
    shown, k, _ = display_unit(unit)
    head = f"{'position' if unit == 'm' else 'rotation'} error as measured ({shown})"
    held = "validation, registered on it" if in_use is not None and in_use.method == REGISTERED_ON_IT \
        else "validation"
    rows = [(f"{key.split('_')[0].replace('validation', held)}, {label}", s) for key, label, s in stat_rows(stats)]
    texts = {(key, f): "-" if getattr(s, f) is None else f"{getattr(s, f) * k:.3f}"
             for key, s in rows for f in ("mean", "std", "rms", "max")}
    # columns at least one space apart however large the errors (1234.567 mm)
    w = max([7] + [len(t) for t in texts.values()]) + 1
    lab = max([len(head)] + [len(key) for key, _ in rows]) + 1
    lines = [f"{indent}{head:<{lab}}{'n':>5}{'mean':>{w}}{'std':>{w}}{'RMS':>{w}}{'max':>{w}}"]
    for key, s in rows:
        lines.append(f"{indent}{key:<{lab}}{s.n:>5}"
                     + "".join(f"{texts[(key, f)]:>{w}}" for f in ("mean", "std", "rms", "max")))
    return lines


MARKS = {"pass": "ok  ", "warn": "WARN", "fail": "FAIL"}


def in_use_heading(in_use) -> str:
    """What the accuracy in use's table holds (``AccuracyInUse``): how its points were held out, how
    many, and that the figures are the robot's, the instrument's noise taken out."""
    how = in_use.method + (f", {in_use.grouping}" if in_use.method == "cross-validation" else "")
    taken = f", the instrument's noise ({in_use.noise * MM:.4g} mm RMS) taken out" if in_use.noise > 0 else ""
    return f"accuracy in use ({how}), on {in_use.position_after.n} held-out point(s): the robot's error{taken}"


def in_use_rows(in_use, registered: bool = False) -> list[tuple[str, str | None, str]]:
    """(label, field of ``AccuracyInUse``, SI unit) of each row of the accuracy in use's table:
    before (``registered``: base and markers registered, as the error table says) and after, after
    as the instrument measured it when that differs (the error table's figure), and the rotations of
    6D data under a head of their own (field None)."""
    before = "before, registered" if registered else "before"
    rows: list[tuple[str, str | None, str]] = [(before, "position_before", "m"), ("after", "position_after", "m")]
    seen = in_use.measured_after
    if seen is not None and seen.n and seen.mean != in_use.position_after.mean:
        rows.append(("after, as measured", "measured_after", "m"))
    if in_use.rotation_after is not None and in_use.rotation_after.n:
        rows += [("rotation error (deg)", None, "rad"), (before, "rotation_before", "rad"),
                 ("after", "rotation_after", "rad")]
    return rows


def in_use_lines(in_use, indent: str = "  ", *, registered: bool = False) -> list[str]:
    """The accuracy in use before and after calibration (``AccuracyInUse``), mm and deg: the robot's
    figures, and beside them the held-out errors as the instrument measured them when the two differ
    (``registered``: see ``in_use_rows``). Columns keep apart at any size."""
    if in_use is None or not in_use.position_after.n:
        return []
    rows = [(label, None if key is None else getattr(in_use, key), display_unit(u)[1])
            for label, key, u in in_use_rows(in_use, registered)]
    cells = [[f"{getattr(s, f) * k:.3f}" for f in ("mean", "rms", "p95", "max")] for _, s, k in rows if s is not None]
    width = max([8] + [len(c) + 2 for row in cells for c in row])
    lines = [in_use_heading(in_use),
             f"{indent}{'position error (mm)':<24}" + "".join(f"{h:>{width}}" for h in ("mean", "RMS", "95 %", "max"))]
    noise = within_noise(in_use.position_after.rms, in_use.noise)
    for label, s, k in rows:
        lines.append(f"{indent}{label:<24}" + ("" if s is None else f"  {noise}" if s is in_use.position_after and noise
                                              else "".join(f"{getattr(s, f) * k:>{width}.3f}"
                                                           for f in ("mean", "rms", "p95", "max"))))
    return lines


@accepts(checks=each_a(Check))
def checks_lines(checks) -> list[str]:
    """Every check with its figures; the likely cause and the fix of those that did not pass.

    Parameters
    ----------
    {checks}

    Returns
    -------
    list of str
        One line per check.
    """
    lines = ["checks:"]
    for c in checks:
        lines.append(f"  {MARKS[c.status]} {c.name}: {c.summary}")
        if c.status != "pass":
            lines += [f"       likely cause: {c.cause}"] if c.cause else []
            lines += [f"       fix: {c.fix}"] if c.fix else []
    return lines


def diagnosis_lines(diagnosis, *, full: bool = False) -> list[str]:
    """The diagnosis: each cause named, decisive first, with its evidence and its fix; ``full`` adds what
    was tested, what survived the screen and was refitted, and what these data cannot tell."""
    if diagnosis is None:
        return []
    if not diagnosis.findings:
        lines = [f"diagnosis: {diagnosis.summary}"]
    else:
        lines = ["diagnosis:"]
        for k, f in enumerate(diagnosis.findings):
            strength = "or" if k else "DECISIVE" if f.status == "fail" else "noted" if f.noted else "possible cause"
            lines.append(f"  {strength}: {f.cause}: {f.evidence}")
            lines += [f"    fix: {f.fix}"] if f.fix else []
    if full:
        lines.append(f"  tested: {', '.join(diagnosis.tested)}")
        lines.append(f"  refitted: {', '.join(diagnosis.refitted) or 'none (the statistics ruled every repair out)'}")
        lines += [f"  not testable here: {u}" for u in diagnosis.untestable]
    return lines


def cause_lines(result) -> list[str]:
    """The causes a result's diagnosis names, printed before anything else (none when it names none)."""
    d = getattr(result, "diagnosis", None)
    return diagnosis_lines(d) if d is not None and d.findings else []


@accepts(result=is_a(CalibrationResult))
def verdict_line(result) -> str:
    """The last line of a summary: the verdict, with what it rests on.

    Parameters
    ----------
    result : CalibrationResult
        A calibration's result.

    Returns
    -------
    str
        The verdict line.
    """
    failed = [c.name for c in result.checks if c.status == "fail"]
    warned = [c.name for c in result.checks if c.status == "warn"]
    if failed:
        return (f"verdict: FAIL ({len(failed)} check(s) failed: {', '.join(failed)}); this calibration is not to be "
                "used as it is")
    if warned:
        return f"verdict: warn ({len(warned)} warning(s): {', '.join(warned)})"
    return f"verdict: pass (all {len(result.checks)} checks passed)"


def eliminated_lines(ident, units: dict) -> list[str]:
    """Each eliminated parameter and the combination that carries it, in display units.

    ``units`` maps parameter names to their SI units.
    """
    if not ident.eliminated:
        return []
    width = max(len(a.name) for a in ident.eliminated)
    lines = [f"eliminated parameters ({len(ident.eliminated)}): held at nominal; a change in each moves the "
             "tool as the changes shown"]
    for a in ident.eliminated:
        if a.absorbers:
            lines.append(f"  {a.name:<{width}}  {absorption_text(units.get(a.name, ''), a.absorbers, units)}")
        else:
            lines.append(f"  {a.name:<{width}} {a.reason}")
    return lines


@accepts(result=is_a(CalibrationResult), shown=NAMES, weighted=FLAG)
def calibration_summary(result, *, shown=(), weighted: bool = False) -> str:
    """What ``robocal calibrate`` prints about one result. ``shown``: notes already printed as warnings.

    Parameters
    ----------
    result : CalibrationResult
        A calibration's result.
    {shown, weighted}

    Returns
    -------
    str
        The text summary.
    """
    if result.contacts is not None:
        return contact_summary(result, shown)
    solver = result.solver
    lines = cause_lines(result) + [f"calibration of {result.nominal_model.name} on "
                                   f"{result.provenance['data']['n_poses']} poses ({families_text(result)}, "
                                   f"loss {solver.loss})"]
    lines += stats_lines(result.stats, in_use=result.in_use)
    if result.rotation_stats is not None:
        lines += stats_lines(result.rotation_stats, unit="rad", in_use=result.in_use)
    lines += in_use_lines(result.in_use, registered=registered_before(result.stats, "fit"))
    lines.append(f"identified parameters ({len(result.parameters)}): change = estimate - nominal")
    width = max([len(p.name) for p in result.parameters] + [16])
    for p in result.parameters:
        lines.append(f"  {p.name:<{width}} change {with_unit(p.change, p.unit, sign=True):>20}   "
                     f"std {with_unit(p.std, p.unit):>18}")
    lines += rotation_lines(result.parameters)
    units = {p.name: p.unit for p in result.parameters}
    units.update(_candidate_units(result))
    lines += eliminated_lines(result.identifiability, units)
    lines += held_lines(result)
    ident = result.identifiability
    lines.append(f"identified {len(ident.identified)} of {len(ident.candidates)} candidates; condition number of "
                 f"those kept {ident.condition_number:.4g}")
    lines.append(f"solver: {'converged' if solver.success else 'NOT converged'} (status {solver.status}, "
                 f"{solver.nfev} evaluations): {solver.message}")
    if weighted:
        lines.append(f"residual standard deviation: {solver.sigma0:.3g} times the expected measurement standard "
                     "deviations")
    else:
        lines.append(f"residual standard deviation: {solver.sigma0 * MM:.4f} mm")
    if result.limit:
        lim = result.limit
        lines.append(f"limit of absolute accuracy {lim.limit_m * MM:.3f} mm: mean error in use after (the robot's, "
                     f"as the accuracy in use says) {lim.mean_error_m * MM:.3f} mm, "
                     f"{'reached' if lim.reached else 'not reached'}")
    lines += [f"note: {n}" for n in result.notes if n not in shown]
    lines += checks_lines(result.checks)
    lines.append(verdict_line(result))
    return "\n".join(lines)


def rotation_lines(parameters) -> list[str]:
    """Each identified rotation correction as one angle about one axis (rx, ry, rz are its rotation
    vector, so this holds however large the turn)."""
    by_name = {p.name: p for p in parameters}
    lines = []
    for owner in dict.fromkeys(p.name.rsplit(".", 1)[0] for p in parameters):
        names = [f"{owner}.r{c}" for c in "xyz"]
        if all(n in by_name for n in names):
            v = np.array([by_name[n].change for n in names])
            angle = float(np.linalg.norm(v))
            if angle > 0:
                axis = ", ".join(f"{c:+.4f}" for c in v / angle)
                lines.append(f"  {owner} rotation: turned {with_unit(angle, 'rad')} about ({axis})")
    return lines


def held_lines(result) -> list[str]:
    """The non-zero values the calibrated model keeps from the nominal without considering them."""
    held = result.held_nominals
    if not held:
        return []
    lay = parameter_layout(result.nominal_model)
    width = max([len(n) for n, _ in held] + [16])
    return ([f"kept at nominal, not candidates ({len(held)} non-zero):"]
            + [f"  {n:<{width}} {with_unit(v, lay[n].unit, sign=True):>20}" for n, v in held])


def _candidate_units(result) -> dict:
    lay = parameter_layout(result.nominal_model)
    return {n: lay[n].unit for n in result.identifiability.candidates if n in lay}


@accepts(comparison=is_a(Comparison), shown=NAMES, weighted=FLAG)
def comparison_summary(comparison, *, shown=(), weighted: bool = False) -> str:
    """What ``robocal calibrate --compare`` prints: the two (or three) identifications side by side.

    Parameters
    ----------
    {comparison, shown, weighted}

    Returns
    -------
    str
        The text summary.
    """
    geo = comparison.geometric
    cols = tuple((compared_head(k), r) for k, r in comparison.results.items())
    widths = [max(24, len(name) + 2) for name, _ in cols]
    on = (f"contacts ({', '.join(f'{n} {k}' for k, n in geo.contacts.rows.items())})" if geo.contacts
          else f"{geo.provenance['data']['n_poses']} poses")

    figures = _compared_contacts(cols) + _compared_stats(cols)
    lab = max([30] + [len(label) + 1 for label, _ in figures])

    def row(label: str, cells) -> str:
        return f"  {label:<{lab}}" + "".join(f"{c:>{w}}" for c, w in zip(cells, widths))

    lines = cause_lines(comparison.best) + [f"comparison on {on}", row("", [name for name, _ in cols]),
                                            row("parameters identified", [len(r.parameters) for _, r in cols])]
    lines += [row(label, cells) for label, cells in figures]
    if weighted:
        lines.append(row("residual std (stated stds)", [f"{r.solver.sigma0:.4g}" for _, r in cols]))
    else:
        lines.append(row("residual std (mm)", [f"{r.solver.sigma0 * MM:.4f}" for _, r in cols]))
    lines.append(row("solver", ["converged" if r.solver.success else "NOT converged" for _, r in cols]))
    lines.append(row("verdict", [r.verdict for _, r in cols]))
    best = comparison.best
    lines += [comparison.verdict, f"calibrated model chosen: {next(name for name, r in cols if r is best)}"]
    lines += _compared_notes(cols, shown)
    lines += checks_lines(best.checks)
    lines.append(verdict_line(best))
    return "\n".join(lines)


def _compared_notes(cols, shown) -> list[str]:
    """The identifications' notes not ``shown`` already: one every identification has (the data read,
    masses assumed) once, the others each under its identification's name."""
    common = [n for n in cols[0][1].notes if n not in shown and all(n in r.notes for _, r in cols)]
    return [f"note: {n}" for n in common] + [f"note ({name}): {n}" for name, r in cols for n in r.notes
                                              if n not in shown and n not in common]


def compared_head(name: str) -> str:
    """A comparison's column head, by what its identification identifies: "geometric+compliance",
    "geometric+transmission"."""
    return name.replace(", ", "+").replace(" and ", "+")


def _compared_contacts(cols) -> list[tuple[str, list[str]]]:
    """The socket consistency of each identification, fitted and in use (with contacts; mm)."""
    if cols[0][1].contacts is None:
        return []
    lines = []
    for label, pick in (("socket consistency, fitted", lambda r: r.contacts.fit_after.consistency_mean),
                        ("socket consistency, in use", lambda r: r.in_use and r.in_use.position_after.mean)):
        values = [pick(r) for _, r in cols]
        if all(v is not None for v in values):
            lines.append((label + " (mm)", [f"{v * MM:.4f}" for v in values]))
    return lines


def _compared_stats(cols) -> list[tuple[str, list[str]]]:
    """The position error statistics of each identification, on the sets and rows the first one's
    summary shows (``stat_rows``: the nominal as given where "before" registered base and markers),
    and the RMS error in use over the range of use (the check "where the model holds") the choice
    weighs (mm)."""
    lines = []
    for key, label, _ in stat_rows(cols[0][1].stats):
        for q in ("mean", "std", "rms", "max"):
            lines.append((f"{key.split('_')[0]}, {label} {q} (mm)",
                          [f"{getattr(getattr(r.stats, key), q) * MM:.3f}" for _, r in cols]))
    if all(r.in_use is not None and r.coverage is not None for _, r in cols):
        lines.append(("in use, range of use rms (mm)",
                      [f"{error_where_used(r.coverage, r.in_use.position_after.rms) * MM:.3f}" for _, r in cols]))
    return lines


@accepts(model=is_a(RobotModel), res=is_a(IdentifiabilityResult), where=TEXT)
def identifiability_summary(model, res, where: str) -> str:
    """The identifiability table in the paper's layout, base and marker statuses, what absorbs what.

    Parameters
    ----------
    {model, res, where}

    Returns
    -------
    str
        The text summary.
    """
    width = max([len(f) for f in model.frame_names] + [len(m) for m in model.marker_names] + [12])
    lines = [f"identifiability of {model.name} at {where}, tolerance {res.tol:g}",
             "I identified, E eliminated, - not considered"]
    kinds = [k for k in ("gamma", "b") if any(res.status(f"{f}.{k}") != "-" for f in model.frame_names)]
    kinds += list(PAPER_KINDS)
    # backlash and transmission where considered
    kinds += [k for k in BACKLASH_KINDS + TRANSMISSION_KINDS
              if any(res.status(f"{f}.{k}") != "-" for f in model.frame_names)]
    cols = [max(9, len(k) + 2) for k in kinds]  # long kind names (backlash_theta) widen their column
    lines.append(f"  {'frame':<{width}}" + "".join(f"{k:>{w}}" for k, w in zip(kinds, cols)))
    for f in model.frame_names:
        lines.append(f"  {f:<{width}}" + "".join(f"{res.status(f'{f}.{k}'):>{w}}" for k, w in zip(kinds, cols)))
    for owner, owner_kinds in [("base", BASE_KINDS)] + [(m, MARKER_KINDS) for m in model.marker_names]:
        lines.append(f"  {owner:<{width}} " + " ".join(f"{k}:{res.status(f'{owner}.{k}'):<3}" for k in owner_kinds))
    lines.append(f"identified {len(res.identified)} of {len(res.candidates)} candidates (rank {res.rank}, "
                 f"{res.n_rows} equations)")
    lay = parameter_layout(model)
    lines += eliminated_lines(res, {n: lay[n].unit for n in res.candidates if n in lay})
    lines.append(f"condition number: {res.condition_number:.4g}")
    lines.append("observability: " + ", ".join(f"{k} {v:.4g}" for k, v in res.observability.items()))
    return "\n".join(lines)


def plan_summary(model, selection, prediction, *, n_candidates: int, source: str) -> str:
    """What ``robocal plan`` prints: the chosen poses against random ones, and what a campaign at
    them will give (predicted standard deviations and errors) before anything is measured."""
    sel, pre = selection, prediction
    lines = [f"plan for {model.name}: {len(sel.q)} poses chosen from {n_candidates} {source} ({sel.criterion}-optimal)",
             f"  average prediction variance over the workspace: {sel.prediction_selected:.4g} chosen, "
             f"{sel.prediction_random:.4g} for as many random poses (lower is better)",
             f"  condition number: {sel.condition_selected:.4g} chosen, {sel.condition_random:.4g} random",
             f"predicted at measurement noise {with_unit(pre.noise, 'm')} per axis:",
             f"  position error after calibration over {pre.n_workspace} configurations (RMS): "
             f"{with_unit(pre.error_rms, 'm')} from the parameters' uncertainty; "
             f"{with_unit(pre.held_out_rms, 'm')} as measured on held-out poses (with the instrument's noise)",
             f"parameters identified ({len(pre.parameters)}) and their predicted standard deviations:"]
    lay = parameter_layout(model)
    width = max([len(n) for n in pre.parameters] + [16])
    for name, std in zip(pre.parameters, pre.std):
        lines.append(f"  {name:<{width}} std {with_unit(std, lay[name].unit):>18}")
    if pre.held:
        lines.append("weakly identifiable at these poses, held at nominal as the calibration holds them (the figures "
                     "above are with them held): " + ", ".join(f"{n} (predicted std {s})" for n, s in pre.held))
    if pre.lost:
        lines.append(f"warning: these poses cannot separate {_listed(pre.lost)}, which the robot's structure allows "
                     "(a joint that hardly moves among them): held at nominal, their errors are in none of the "
                     "figures above; add poses that move every joint")
    lines += eliminated_lines(pre.identifiability, {n: lay[n].unit for n in pre.identifiability.candidates if n in lay})
    return "\n".join(lines)


# -- calibrations from contacts, and socket-plate plans ------------------------------------------

def _listed(names, n: int = 6) -> str:
    return ", ".join(names[:n]) + (f", ... ({len(names) - n} more)" if len(names) > n else "")


def _mm(v) -> str:
    return "–" if v is None else with_unit(v, "m")


def _rms(values) -> float | None:
    return float(np.sqrt(np.mean(np.square(list(values))))) if values else None


def _figures(label: str, before, after) -> list[str]:
    """Mean socket spread, socket consistency, known-distance RMS error and spacing error, plane RMS
    and ball-bar RMS error, before -> after; ``before`` None ("–": a result file without it)."""
    b = before if before is not None else ContactErrors({}, {}, {}, {})
    out = []
    if after.spread:
        out.append(f"  {label} socket spread (RMS about each socket's centre, mean over {len(after.spread)}): "
                   f"{_mm(b.mean_spread)} -> {_mm(after.mean_spread)}")
    if after.consistency:
        out.append(f"  {label} socket consistency (each seating's distance from its socket's mean centre), "
                   f"mean over seatings: {_mm(b.consistency_mean)} -> {_mm(after.consistency_mean)}; "
                   f"mean over placements: {_mm(b.consistency_by_placement)} -> "
                   f"{_mm(after.consistency_by_placement)}; "
                   f"max: {_mm(b.consistency_max)} -> {_mm(after.consistency_max)}")
    if after.distance:
        out.append(f"  {label} known distances, RMS error over {len(after.distance)}: "
                   f"{_mm(b.distance_rms)} -> {_mm(after.distance_rms)}")
        out.append(f"  {label} spacing error (calibrated minus known), mean |e|: {_mm(b.spacing_mean)} -> "
                   f"{_mm(after.spacing_mean)}; max |e|: {_mm(b.spacing_max)} -> {_mm(after.spacing_max)}")
    for name, kind in (("plane", "plane contacts, RMS distance to their plane"), ("bar", "ball-bar length error")):
        a = getattr(after, name)
        if a:
            out.append(f"  {label} {kind}, RMS over {len(a)}: {_mm(_rms(getattr(b, name).values()))} -> "
                       f"{_mm(_rms(a.values()))}")
    return out


def families_text(result) -> str:
    """The families a calibration identified, as a list in words; parameters it named one by one (a
    compared level's transmission terms, ``j2.alpha``) counted by their family: "geometric,
    compliance, 21 transmission parameters" rather than the 21 names."""
    lay = parameter_layout(result.nominal_model)
    named: dict[str, int] = {}
    for f in result.families:
        if "." in f:
            family = lay[f].family if f in lay else "named"
            named[family] = named.get(family, 0) + 1
    return ", ".join([f for f in result.families if "." not in f]
                     + [f"{n} {family} parameter{'s' if n > 1 else ''}" for family, n in named.items()])


def contact_summary(result, shown=()) -> str:
    """The text summary of a ``CalibrationResult`` that fitted contacts (its ``contacts`` figures);
    ``shown``: notes already printed as warnings."""
    c = result.contacts
    ident = c.identifiability
    rows = ", ".join(f"{n} {kind}" for kind, n in c.rows.items())
    lines = cause_lines(result) + [f"calibration of {result.nominal_model.name} from contacts ({rows}; "
                                   f"{families_text(result)}, loss {result.solver.loss})",
                                   "what the kit shows (before -> after):"]
    lines += _figures("fitted", c.fit_before, c.fit_after)
    if c.validation_before is not None:
        lines += _figures("held-out", c.validation_before, c.validation_after)
    if c.held_out is not None:
        lines += _figures("each placement predicted by the others,", c.held_out_before, c.held_out)
    tracker, held = result.stats.fit_after, result.stats.validation_after
    if tracker.n:
        lines.append(f"  tracker points: {_mm(result.stats.fit_before.rms)} -> {_mm(tracker.rms)} RMS over "
                     f"{tracker.n}")
    if held.n:
        lines += in_use_lines(result.in_use)
    fitted = "" if len(result.parameters) == len(ident.identified) else f", {len(result.parameters)} identified"
    lines.append(f"{len(ident.identified)} parameters identifiable{fitted}; each kind alone identifies:")
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
    top = plan.designs[-1]      # the largest: what the plate reaches
    judged = len(top.predicted_std) + len(top.lost)
    lines = [f"socket plate: {judged + len(plan.held)} parameters reachable; unreachable: "
             f"{', '.join(top.unreachable) or 'none'}"]
    if plan.held:
        lines.append(f"beyond their bound in every design of the grid, held at nominal as the calibration holds "
                     f"them: {', '.join(plan.held)}; the designs below are judged on the other {judged} parameters")
    lines.append("placements  seatings/socket  seatings  worst parameter (predicted std / bound)")
    for d in plan.designs:
        worst = (f"cannot identify {len(d.lost)} of the {judged}: {', '.join(d.lost)}" if d.lost
                 else f"{d.worst} {d.worst_ratio:.3g}")
        lines.append(f"  {d.placements:>9}  {d.poses_per_socket:>15}  {d.n_seatings:>8}  {worst}"
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
