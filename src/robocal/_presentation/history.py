"""A robot's history, robots of one type side by side, and a verification: the text the command
line prints and the HTML report of a robot with history (each parameter's drift with its
uncertainty band, the verifications over time). Pure functions of the store's records; matplotlib
is imported only when the report is drawn.
"""

from __future__ import annotations

import html
from datetime import datetime

import numpy as np

from .._accuracy.verification import SEATINGS, Verification
from .._base.arguments import FLAG, PATH, TEXT, accepts, is_a
from .._files.text import write_texts
from .._identification.holdout import within_noise
from .._store.store import APART_SIGMAS, Change, History, StoredCalibration, TypeComparison
from .plots import need_matplotlib, plot_svg
from .units import display_unit, fmt, with_unit

BAND = 2.0          # the drift plots' band: estimate +- BAND standard deviations
# a seatings' calibration on fewer placements leaves a verification's threshold wide (Student's t)
FEW_PLACEMENTS = 5
SHOWN_CALIBRATIONS = 6   # the text table's columns: the latest calibrations
AFTER, BAD = "#2266b0", "#a3262a"


def _day(text: str) -> str:
    """'2026-03-02' of an ISO date (other text unchanged)."""
    try:
        return datetime.fromisoformat(text).strftime("%Y-%m-%d")
    except ValueError:
        return str(text)


def _when(text: str) -> str:
    try:
        return datetime.fromisoformat(text).strftime("%Y-%m-%d %H:%M UTC")
    except ValueError:
        return str(text)


def _sigma(v: float) -> str:
    return f"{abs(v):.1f} sigma"


@accepts(c=is_a(Change))
def change_line(c) -> str:
    """'j2.theta +0.031 deg since 2026-03-02, 5.1 sigma'.

    Parameters
    ----------
    c : Change
        A parameter's change between two calibrations.

    Returns
    -------
    str
        One line.
    """
    return f"{c.name} {with_unit(c.delta, c.unit, sign=True)} since {_day(c.since)}, {_sigma(c.sigma)}"


def overall_line(o) -> str:
    """'something changed since 2026-03-02: chi-square 61.2 on 18 directions, p = 2.1e-06'."""
    return (f"something changed since {_day(o.since)}: chi-square {o.chi2:.1f} on {o.dof} directions, "
            f"p = {o.p:.2g}")


def _few(names, n: int = 4) -> str:
    return ", ".join(names[:n]) + (f" and {len(names) - n} more" if len(names) > n else "")


def apart_line(o) -> str:
    """'not compared with 2026-03-02: j2.k_theta fitted beyond 3 sigma of nominal in one calibration and
    not identified in the other, ...'."""
    return (f"not compared with {_day(o.since)}: {_few(o.apart)} fitted beyond {APART_SIGMAS:g} sigma of nominal in "
            "one calibration and not identified in the other (held at nominal, or its family not calibrated), whose "
            "estimates then carry them; to compare, identify the same parameters in both (the same --parameters, "
            "on poses that determine them)")


def _accuracy_text(c: StoredCalibration) -> str:
    """The accuracy at calibration, each kind's: a calibration from measured points and seatings keeps both."""
    if c.accuracy is None:
        return "no measured accuracy"
    return "; ".join(f"{with_unit(a.rms, 'm')} RMS ({a.source})" for a in (c.accuracy, c.seatings_accuracy) if a)


_HISTORY = is_a(History)


@accepts(h=_HISTORY)
def history_summary(h: History) -> str:
    """What ``robocal history ROBOT`` prints.

    Parameters
    ----------
    {h}

    Returns
    -------
    str
        Its calibrations, verifications and named changes, as text.
    """
    lines = [f"robot {h.robot}: {len(h.calibrations)} calibration(s), {len(h.verifications)} verification(s)"]
    for c in h.calibrations:
        lim = f", limit {with_unit(c.limit_m, 'm')}" if c.limit_m is not None else ""
        kind = f" [{c.robot_type}]" if c.robot_type else ""
        use = _in_use_rms(c)
        use_text = "" if use is None else f", in use {_in_use_noise(c) or with_unit(use, 'm') + ' RMS'}"
        lines.append(f"  #{c.id} {_when(c.calibrated_at)}{kind}: {c.verdict}, {_accuracy_text(c)}{use_text}"
                     f"{lim}, inputs {c.fingerprint[:12]}")
    lines += _estimates_table(h) + _changes_lines(h)
    if h.verifications:
        lines.append("verifications:")
        seated = _by_seatings(h)
        lines += [f"  {_when(v.verified_at)} against #{v.calibration_id}: {v.verdict}, {with_unit(v.rms, 'm')} RMS "
                  f"now against {with_unit(v.then_rms, 'm')} (ratio {v.ratio:.2f}, recalibrate beyond "
                  f"{v.threshold:.2f}), {'worst socket spread' if v.id in seated else 'ISO 9283 AP'} "
                  f"{with_unit(v.ap_max, 'm')}" for v in h.verifications]
    return "\n".join(lines)


def _by_seatings(h: History) -> set:
    """The ids of the verifications by socket seatings (held against a calibration's held-out seatings;
    one stored before they kept their sockets: held against a calibration from seatings alone)."""
    seatings = {c.id for c in h.calibrations if c.accuracy is not None and c.accuracy.source == SEATINGS}
    return {v.id for v in h.verifications if v.sockets or v.calibration_id in seatings}


def _compared_families(h: History) -> str:
    """The judged families of the parameters the history compared, as a list in words."""
    family = {e.name: e.family for c in h.calibrations for e in c.estimates}
    compared = {family.get(c.name) for c in h.comparisons}
    return ", ".join(f for f in h.families if f in compared)


def _changes_lines(h: History) -> list[str]:
    """The changes named between consecutive calibrations, the pairs not compared and why, and the
    largest movements within the uncertainty."""
    families = _compared_families(h)
    of = f" of {families} parameters" if families else ""
    if not h.comparisons:
        return [f"changes between consecutive calibrations: nothing compared ({_why_none(h)})"] + \
            [f"  {apart_line(o)}" for o in h.overall if not o.compared]
    lines = [f"changes between consecutive calibrations, judged at {h.threshold:.2f} sigma of their combined "
             f"uncertainty ({len(h.comparisons)} comparisons{of}; {h.alpha:.0%} chance of naming one in an "
             "unchanged robot):"]
    named = [change_line(c) for c in h.changes] + [overall_line(o) for o in h.overall if o.named]
    apart = [apart_line(o) for o in h.overall if not o.compared]
    lines += [f"  {line}" for line in named] or [f"  none{' among the calibrations compared' if apart else ''}"]
    lines += [f"  {line}" for line in apart]
    rest = sorted((c for c in h.comparisons if not c.named and c.sigma), key=lambda c: -abs(c.sigma))[:3]
    if rest:
        lines.append("  largest movements within the uncertainty: " + "; ".join(change_line(c) for c in rest))
    return lines


def _why_none(h: History) -> str:
    """Why a history compared no parameter between calibrations."""
    if len(h.calibrations) < 2:
        return "one calibration: a change is between two"
    if all(not o.compared for o in h.overall):
        return "each pair of consecutive calibrations apart, below"
    return f"consecutive calibrations identify no {' or '.join(h.families)} parameter in common"


def _estimates_table(h: History) -> list[str]:
    """Each parameter's estimate +- std at the latest calibrations (display units)."""
    cals = h.calibrations[-SHOWN_CALIBRATIONS:]
    more = f" (the latest {len(cals)})" if len(h.calibrations) > len(cals) else ""
    head = ["parameter", "unit"] + [f"#{c.id} {_day(c.calibrated_at)}" for c in cals]
    rows = []
    for name in h.parameter_names:
        unit = next(e.unit for c in h.calibrations if (e := c.estimate(name)))
        cells = []
        for c in cals:
            e = c.estimate(name)
            cells.append("–" if e is None else f"{fmt(e.estimate, unit)} ± {fmt(e.std, unit)}")
        rows.append([name, display_unit(unit)[0]] + cells)
    widths = [max(len(r[i]) for r in [head] + rows) for i in range(len(head))]
    out = [f"estimates ± standard deviation{more}:"]
    out += ["  " + "  ".join(cell.ljust(w) if i < 2 else cell.rjust(w) for i, (cell, w) in enumerate(zip(r, widths)))
            for r in [head] + rows]
    return out


@accepts(t=is_a(TypeComparison))
def type_summary(t: TypeComparison) -> str:
    """What ``robocal history --type TYPE`` prints.

    Parameters
    ----------
    t : TypeComparison
        Robots of one type side by side (``robocal.type_comparison``).

    Returns
    -------
    str
        The robots standing out and each robot's latest calibration, as text.
    """
    head = f"type {t.robot_type}: {len(t.latest)} robot(s), latest calibration of each; {len(t.names)} parameter(s)"
    if not t.compared:      # no threshold, no robot held to it: nothing of how robots are compared applies
        lines = [f"{head}; nothing compared: a parameter is compared with the type's median over three robots or "
                 "more that identify it" + (f", and the type has {len(t.latest)}" if len(t.latest) < 3 else
                                             ", and no parameter has them"), "robots:"]
        lines += [f"  {_latest_line(c)}" for c in t.latest[:200]]
    else:
        lines = [f"{head}, each robot against the type's median in robust standard deviations (widened for a robot "
                 f"calibrated less precisely than most), named beyond {t.threshold:.2f} ({t.compared} comparisons; "
                 f"{t.alpha:.0%} chance of naming one among alike robots)", "standing out:"]
        lines += [f"  {o.robot} {o.name} {with_unit(o.value - o.median, o.unit, sign=True)} from the type's median, "
                  f"{_sigma(o.z)}" for o in t.outliers[:40]] or ["  none"]
        if len(t.outliers) > 40:
            lines.append(f"  ... and {len(t.outliers) - 40} more")
        lines.append("robots:")
        lines += [f"  {_latest_line(c)}{_compared_as(t, c.robot, row)}" for c, row in zip(t.latest[:200], t.z)]
    if len(t.latest) > 200:
        lines.append(f"  ... and {len(t.latest) - 200} more")
    return "\n".join(lines)


def _latest_line(c) -> str:
    """'R1: #3 2026-01-01, pass, 0.0462 mm RMS' of a robot's latest calibration."""
    acc = "no measured accuracy" if c.accuracy_rms is None else f"{with_unit(c.accuracy_rms, 'm')} RMS" + (
        f" ({c.accuracy_source})" if c.accuracy_source == SEATINGS else "")
    return f"{c.robot}: #{c.id} {_day(c.calibrated_at)}, {c.verdict}, {acc}"


def _compared_as(t: TypeComparison, robot: str, z) -> str:
    """How a robot (``z`` its row) was compared with its type: its parameters standing out, those held
    at nominal and why, or why it was not compared."""
    flag = ""
    standing = sum(o.robot == robot for o in t.outliers)
    if standing:
        flag += f", {standing} parameter(s) standing out"
    held, apart, conditioned = dict(t.held).get(robot), dict(t.apart).get(robot), dict(t.conditioned).get(robot)
    if held:
        flag += f"; compared with {_few(held)} held at nominal (not identified by most of the type's calibrations)"
    if conditioned:
        none = set(dict(t.uncalibrated).get(robot, ()))
        weak = [n for n in conditioned if n not in none]
        why = [f"{_few(weak)} (weak for its poses)"] * bool(weak) + \
            [f"{_few(sorted(none))} (their family not calibrated)"] * bool(none)
        flag += (f"; holds {' and '.join(why)} at nominal, which most of the type's calibrations identify: compared "
                 "with those that identify what it does, as they would be with them held too")
    if apart:
        flag += (f"; not compared: {_few(apart)} fitted beyond {APART_SIGMAS:g} sigma of nominal, not identified "
                 "by most of the type's calibrations, and no stored correlations to hold them with")
    elif not np.isfinite(z).any():
        flag += "; not compared: fewer than three of the type's calibrations identify what it does"
    return flag


@accepts(v=is_a(Verification), robot=TEXT, calibration=is_a(StoredCalibration))
def verification_summary(v: Verification, robot: str, calibration) -> str:
    """What ``robocal verify`` prints.

    Parameters
    ----------
    v : Verification
        The verification (``robocal.verify``).
    robot : str
        The robot verified.
    calibration : StoredCalibration
        The stored calibration it was held against.

    Returns
    -------
    str
        The errors now and then, the ratio and the verdict, as text.
    """
    reg = ", base re-registered on them" if v.registered_base else ""
    worst = int(np.nanargmax(v.ap)) if v.ap.size else 0
    what = (f"{v.n_points} seatings in {v.sockets} sockets, each from its socket's mean predicted centre" if v.sockets
            else f"{v.n_poses} poses, {v.n_points} measured points{reg}")
    return "\n".join([
        f"verification of {robot} against calibration #{calibration.id} ({_day(calibration.calibrated_at)}): {what}",
        *(f"  left out: {why}" for why in v.left_out),
        f"  now:            RMS {with_unit(v.rms, 'm')}, mean {with_unit(v.mean, 'm')}, p95 {with_unit(v.p95, 'm')}, "
        f"max {with_unit(v.max, 'm')}",
        f"  at calibration: RMS {with_unit(v.then.rms, 'm')} ({v.then.source})",
        (f"  socket spread (RMS about its centre; worst socket, {v.poses[worst]}): " if v.sockets else
         f"  ISO 9283 positional accuracy AP (worst pose, {v.poses[worst] if v.poses else '-'}): ")
        + with_unit(v.ap_max, 'm'),
        f"  ratio now / at calibration {v.ratio:.2f}"
        + (" (each over the degrees of freedom the sockets' centres leave)" if v.sockets else "")
        + f"; recalibrate beyond {v.threshold:.2f} (an unchanged robot "
        f"exceeds it in {v.alpha:.0%} of verifications)", *_if_registered(v), *_few_placements(v),
        f"verdict: {v.verdict}"])


def _few_placements(v: Verification) -> list[str]:
    """Seatings held against a calibration on few placements: why its threshold is wide."""
    if not v.sockets or not 2 <= v.then.sets < FEW_PLACEMENTS:
        return []
    return [f"  the calibration's {v.then.sets} placements tell how much placements differ poorly, so the threshold is "
            "wide: a calibration on more placements verifies sharper"]


def _if_registered(v: Verification) -> list[str]:
    """What re-registering the base would say, when the verdict is recalibrate without it."""
    if v.if_registered is None:
        return []
    ratio, threshold = v.if_registered
    if ratio <= threshold:
        return [f"  with the base re-registered on these poses the ratio is {ratio:.2f} (within {threshold:.2f}): "
                "if the instrument was set up again since the calibration, verify with --register-base"]
    return [f"  with the base re-registered on these poses the ratio is still {ratio:.2f} (beyond {threshold:.2f}): "
            "not a new set-up of the instrument alone"]


# -- the HTML report ----------------------------------------------------------------------------------

_CSS = """
body{font-family:system-ui,sans-serif;margin:0;color:#222;background:#fafbfc}
main{max-width:1100px;margin:0 auto;padding:1em 1.5em}
table{border-collapse:collapse;margin:.5em 0;font-size:.9em}
th,td{padding:.25em .6em;border-bottom:1px solid #e3e6ea;text-align:left}
td.num{text-align:right;font-variant-numeric:tabular-nums}
.bad{color:#a3262a;font-weight:bold}.ok{color:#2d7a3a}.warn{color:#9a6200}
figure{margin:1em 0}figcaption{font-size:.85em;color:#555}
svg{max-width:100%;height:auto}
"""


def _e(text) -> str:
    return html.escape(str(text), quote=True)


def _judged_names(h: History) -> list[str]:
    return [n for n in h.parameter_names
            if any((e := c.estimate(n)) is not None and e.family in h.families for c in h.calibrations)]


def plot_drift(h: History) -> str:
    """Each judged parameter's estimates over the calibrations with a band of +-2 standard deviations."""
    names = _judged_names(h)
    if not names:
        return ""
    cols = min(4, len(names))
    rows = -(-len(names) // cols)
    named = {c.name for c in h.changes}

    def draw(fig):
        axes = fig.subplots(rows, cols, squeeze=False)
        for ax, name in zip(axes.ravel(), names):
            dates, est, std = h.series(name)
            unit = next(e.unit for c in h.calibrations if (e := c.estimate(name)))
            k = display_unit(unit)[1]
            x = np.arange(len(dates))
            ax.fill_between(x, (est - BAND * std) * k, (est + BAND * std) * k, color=AFTER, alpha=0.2, lw=0)
            ax.plot(x, est * k, "o-", color=BAD if name in named else AFTER, ms=3, lw=1)
            ax.set_title(name + (" (changed)" if name in named else ""), fontsize=8)
            ax.set_ylabel(display_unit(unit)[0])
            ax.set_xticks(x, [_day(d)[2:] for d in dates], rotation=45, fontsize=7)
        for ax in axes.ravel()[len(names):]:
            ax.set_visible(False)
        fig.tight_layout()

    return plot_svg("drift", f"drift of {len(names)} parameters of {h.robot}", draw,
                    figsize=(2.6 * cols, 1.9 * rows))


def plot_verifications(h: History) -> str:
    """The RMS error of each verification against the accuracy at calibration and the threshold."""
    if not h.verifications:
        return ""
    k = display_unit("m")[1]
    vs = h.verifications
    x = np.arange(len(vs))

    def draw(fig):
        ax = fig.subplots()
        ax.plot(x, [v.then_rms * k for v in vs], "s--", color="#777", ms=3, label="RMS at calibration")
        ax.plot(x, [v.then_rms * v.threshold * k for v in vs], "v:", color=BAD, ms=4, label="recalibrate beyond")
        ax.plot(x, [v.rms * k for v in vs], "o-", color=AFTER, label="RMS now")
        ax.set_xticks(x, [_day(v.verified_at) for v in vs], rotation=30, fontsize=8)
        ax.set_ylabel("mm")
        ax.legend(fontsize=7)
        fig.tight_layout()

    return plot_svg("verifications", f"verifications of {h.robot}", draw, figsize=(7, 2.6))


_VERDICT_CLASS = {"pass": "ok", "warn": "warn", "fail": "bad"}


def _in_use_rms(c: StoredCalibration):
    """The RMS position error in use a calibration predicted (m), None when it has none."""
    use = ((c.in_use or {}).get("position_after") or {}).get("rms")
    return use if isinstance(use, (int, float)) and not isinstance(use, bool) else None


def _in_use_noise(c: StoredCalibration) -> str | None:
    """Within the instrument's noise, when the accuracy in use is nothing of the robot's once it was
    taken out (a result written before it kept its noise: without the figure); else None."""
    noise = (c.in_use or {}).get("noise_m")
    return within_noise(_in_use_rms(c), float(noise) if isinstance(noise, (int, float)) and
                        not isinstance(noise, bool) else None)


def _calibration_rows(h: History) -> str:
    return "".join(
        f'<tr><td>#{c.id}</td><td>{_e(_when(c.calibrated_at))}</td><td>{_e(c.robot_type or "")}</td>'
        f'<td class="{_VERDICT_CLASS.get(c.verdict, "")}">{_e(c.verdict)}</td>'
        f'<td class="num">{fmt(c.accuracy.rms if c.accuracy else None)}</td>'
        f'<td>{_e(c.accuracy.source if c.accuracy else "")}</td>'
        f'<td class="num">{_e(_in_use_noise(c) or fmt(_in_use_rms(c)))}</td>'
        f'<td class="num">{fmt(c.limit_m)}</td>'
        f"<td><code>{_e(c.fingerprint[:16])}</code></td><td>{_e(c.source)}</td></tr>" for c in h.calibrations)


@accepts(h=_HISTORY)
def render_history(h: History) -> str:
    """The HTML text of a robot's history report (needs matplotlib).

    Parameters
    ----------
    {h}

    Returns
    -------
    str
        A self-contained HTML page.
    """
    need_matplotlib()
    apart = [apart_line(o) for o in h.overall if not o.compared]
    families = _compared_families(h)
    changes = "".join(f"<li>{_e(change_line(c))}</li>" for c in h.changes) or \
        f"<li>none{' among the calibrations compared' if apart else ''}</li>"
    verifs = "".join(
        f'<tr><td>{_e(_when(v.verified_at))}</td><td>#{v.calibration_id}</td>'
        f'<td class="{"bad" if v.verdict != "within accuracy" else "ok"}">{_e(v.verdict)}</td>'
        f'<td class="num">{fmt(v.rms)}</td><td class="num">{fmt(v.then_rms)}</td><td class="num">{v.ratio:.2f}</td>'
        f'<td class="num">{v.threshold:.2f}</td><td class="num">{fmt(v.ap_max)}</td><td class="num">{v.n_points}</td>'
        f"</tr>" for v in h.verifications)
    drift, vplot = plot_drift(h), plot_verifications(h)
    body = [
        f"<h1>Calibration history &ndash; {_e(h.robot)}</h1>",
        f"<p>{len(h.calibrations)} calibration(s), {len(h.verifications)} verification(s). Lengths in mm.</p>",
        "<h2>Calibrations</h2><table><thead><tr><th>#</th><th>calibrated</th><th>type</th><th>verdict</th>"
        "<th>measured accuracy RMS (mm)</th><th>from</th><th>in use RMS (mm)</th><th>limit (mm)</th>"
        "<th>inputs SHA-256</th><th>source</th></tr>"
        f"</thead><tbody>{_calibration_rows(h)}</tbody></table>",
        (f"<h2>Changes</h2><p>Between consecutive calibrations, judged at {h.threshold:.2f} standard deviations of "
         f"their combined uncertainty ({len(h.comparisons)} comparisons"
         + (f" of {_e(families)} parameters" if families else "")
         + f"; a {h.alpha:.0%} chance of naming one in an unchanged robot's history, with the overall tests).</p>"
         f"<ul>{changes}</ul>" if h.comparisons else
         f"<h2>Changes</h2><p>Between consecutive calibrations: nothing compared ({_e(_why_none(h))}).</p>")
        + "".join(f"<p>{_e(overall_line(o))}</p>" for o in h.overall if o.named)
        + "".join(f"<p>{_e(line)}</p>" for line in apart),
        "<h2>Drift of each parameter</h2>" + (f"<figure>{drift}<figcaption>Estimates at each calibration with a band "
                                              f"of &plusmn;{BAND:g} standard deviations; red: a change named."
                                              "</figcaption></figure>" if drift else "<p>No parameter judged.</p>"),
        "<h2>Verifications</h2>" + (
            f"<figure>{vplot}<figcaption>RMS position error of each verification, against the calibration's and the "
            "ratio beyond which it says recalibrate.</figcaption></figure><table><thead><tr><th>verified</th>"
            "<th>against</th><th>verdict</th><th>RMS now (mm)</th><th>RMS then (mm)</th><th>ratio</th>"
            "<th>threshold</th><th>ISO 9283 AP, or worst socket spread of seatings (mm)</th><th>points</th>"
            "</tr></thead>"
            f"<tbody>{verifs}</tbody></table>" if h.verifications else "<p>No verification yet.</p>")]
    return ('<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
            f"<title>Calibration history: {_e(h.robot)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n<main>\n"
            + "\n".join(body) + "\n</main>\n</body>\n</html>\n")


@accepts(h=_HISTORY, path=PATH, force=FLAG)
def write_history(h: History, path, *, force: bool = False) -> None:
    """Write the history report of ``h`` to ``path`` atomically; an existing file is an InputError
    unless ``force``.

    Parameters
    ----------
    {h, path, force}

    Returns
    -------
    None
    """
    write_texts({path: render_history(h)}, force=force)
