"""The calibration report: one self-contained HTML file drawn from a calibration result.

``render_report`` returns the HTML text of a ``CalibrationResult`` (computed, or read back from
result.json), ``write_report`` writes it atomically. Plots (``plots``) are inline SVG; the page
needs no network and no JavaScript. Units are shown as ``units.DISPLAY_UNITS``
says.
"""

from __future__ import annotations

import html
import re
from dataclasses import dataclass
from datetime import datetime
from typing import cast

import numpy as np

from .._base.arguments import (
    FLAG,
    MAPPING,
    PATH,
    accepts,
    is_a,
    optional,
)
from .._base.errors import InputError
from .._files.result import diagnosis_to_dict, per_pose_arrays, result_to_dict
from .._files.text import write_texts
from .._identification.contact_figures import ContactErrors, ContactFigures
from .._identification.holdout import within_noise
from .._identification.result import CalibrationResult, ErrorSummary
from .._model.kinematics import evaluate, layout, transmission_basis
from .._model.parameters import FRAME_KINDS, GEOMETRIC_KINDS, SI_UNITS, parameter_layout, parameter_vector
from .._model.robot import DEFAULT_LINK_DENSITY, RELATIVE_MASSES, mdh_transform
from .plots import (
    AFTER,
    BEFORE,
    BLOCK,
    DENSE,
    LIMIT,
    STRUCTURE,
    correlation_blocks,
    errors_array,
    need_matplotlib,
    plot_correlation,
    plot_errors_per_pose,
    plot_histograms,
    plot_residual_trends,
    plot_residuals,
    plot_transmission,
    residual_sample,
    residual_trends,
)
from .text import (
    REGISTERED_ON_IT,
    families_text,
    in_use_heading,
    in_use_rows,
    registered_before,
    rotation_lines,
    stat_labels,
)
from .units import UNITS_SENTENCE, absorption_text, fmt, symbol, with_unit
from .units import display_unit as _display
from .units import finite as _num

STAT_FIELDS = ("mean", "std", "rms", "max")
ALWAYS_SHOWN = GEOMETRIC_KINDS[2:]  # the paper's columns; gamma and b only for frames of a tree
WORST_POSES = 10
MISSING_VALIDATION = "No held-out poses were given: the errors shown are on the fitted poses only."
MISSING_LIMIT = ("No limit of absolute accuracy was given: run <code>robocal limit</code> on the model (repeatability, "
                 "encoder resolution, parameter round-off) and pass its value to the calibration "
                 "(<code>--limit-mm</code>, or <code>limit=</code> in Python) to judge the result against it.")
CORRELATED = 0.9  # |r| from which a pair is listed below the correlation map


# -- values and formatting -------------------------------------------------------------------------

def _ratio(v, spec: str) -> str:
    v = _num(v)
    return "–" if v is None else format(v, spec)


def _sentence(text: str) -> str:
    """``text`` with its first letter upper case and the rest as written (units keep their case: kN)."""
    return text[:1].upper() + text[1:]


def _e(text) -> str:
    return html.escape(str(text), quote=True)


def _cell(value, unit, key, *, sign=False) -> str:
    return (f'<td class="num" data-key="{_e(key)}" data-unit="{_e(_display(unit)[0])}">'
            f"{fmt(value, unit, sign=sign)}</td>")


def _worst_poses(d: dict, flagged=frozenset(), k: int = WORST_POSES) -> str:
    """The ``k`` measured points with the largest error after calibration, and those of the pose labels
    in ``flagged`` (named by a check), each pose's first row anchored for the checks to link to."""
    err, prov = d["errors"], d.get("provenance") or {}
    markers = err.get("markers") or []
    after_all, before_all, set_at, pose_at, marker_at, flag_at = [], [], [], [], [], []
    sets: list[tuple[str, list]] = []
    for key, when, src in (("fit", "fitted", "data"), ("validation", "held-out", "validation")):
        before, after = errors_array(d, f"{key}_before"), errors_array(d, f"{key}_after")
        if before is None or after is None:
            continue
        n, m = min(len(before), len(after)), min(before.shape[1], after.shape[1])
        b_k, a_k = before[:n, :m], after[:n, :m]
        poses, cols = np.nonzero(np.isfinite(a_k) & np.isfinite(b_k))    # pose by pose, marker by marker
        labels = (prov.get(src) or {}).get("labels") or []
        after_all.append(a_k[poses, cols])
        before_all.append(b_k[poses, cols])
        set_at.append(np.full(len(poses), len(sets)))
        sets.append((when, labels))
        pose_at.append(poses)
        marker_at.append(cols)
        if flagged:
            named = np.fromiter((_pose_name(labels, i) in flagged for i in range(n)), dtype=bool, count=n)
            flag_at.append(named[poses])
    if not sum(len(v) for v in after_all):
        return ""
    a_pts, b_pts = np.concatenate(after_all), np.concatenate(before_all)
    set_pts, pose_pts, marker_pts = (np.concatenate(v) for v in (set_at, pose_at, marker_at))
    order = np.argsort(-a_pts, kind="stable")          # largest first, ties in the order of the points
    picked = list(order[:k])
    if flagged:
        rest = order[k:]
        picked += list(rest[np.concatenate(flag_at)[rest]])
    shown = []
    for i in picked:
        when, labels = sets[int(set_pts[i])]
        m = int(marker_pts[i])
        shown.append((float(a_pts[i]), float(b_pts[i]), _pose_name(labels, int(pose_pts[i])), when,
                     markers[m] if m < len(markers) else str(m)))
    anchored, body = set(), []
    for j, (a, b, name, when, mk) in enumerate(shown):
        anchor = f' id="{_anchor("pose", name)}"' if name not in anchored else ""
        anchored.add(name)
        body.append(f'<tr{anchor}><td class="name" data-key="worst.{j}.pose">{_e(name)}</td><td>{when}</td>'
                    f'<td>{_e(mk)}</td><td class="num" data-key="worst.{j}.before" data-unit="mm">{b * 1e3:.4f}</td>'
                    f'<td class="num" data-key="worst.{j}.after" data-unit="mm">{a * 1e3:.4f}</td></tr>')
    more = f", then the {len(shown) - k} other points of poses a check named" if len(shown) > k else ""
    return ("<h3>Largest errors after calibration</h3>"
            + _table(["pose", "poses", "marker", "before (mm)", "after (mm)"], body, num_from=3,
                     caption=f"The {min(k, len(a_pts))} measured points with the largest error after calibration"
                             f"{more}, by the pose labels of the input files."))


def _pose_name(labels: list, i: int) -> str:
    """The label of pose ``i`` in the input file, or "pose i" without one."""
    return labels[i] if i < len(labels) else f"pose {i}"


def _anchor(kind: str, name: str) -> str:
    """The id of the row or cell of a parameter or pose, for the checks to link to."""
    return f"{kind}-" + re.sub(r"[^\w.-]", "_", str(name))


def _date(text) -> str:
    """An ISO date as '2026-01-31 14:05 UTC' (other text unchanged)."""
    try:
        t = datetime.fromisoformat(str(text))
    except ValueError:
        return str(text)
    zone = t.tzname() or ""
    return t.strftime("%Y-%m-%d %H:%M ") + ("UTC" if zone in ("UTC", "UTC+00:00") else zone)


# -- HTML pieces ----------------------------------------------------------------------------------

def _table(head: list[str], rows: list[str], *, cls: str = "", caption: str = "", num_from: int | None = None,
           num=()) -> str:
    """A table; header cells from index ``num_from`` on, and those in ``num``, are right-aligned over numbers."""
    cap = f"<caption>{caption}</caption>" if caption else ""
    th = "".join(f'<th class="num">{h}</th>' if (num_from is not None and i >= num_from) or i in num
                 else f"<th>{h}</th>" for i, h in enumerate(head))
    return (f'<div class="scroll"><table class="{cls}">{cap}<thead><tr>{th}</tr></thead>'
            f"<tbody>{''.join(rows)}</tbody></table></div>")


def _kv(rows) -> str:
    """A two-column table of (label HTML, value HTML, data-key[, display unit])."""
    body = "".join(f'<tr><th scope="row">{r[0]}</th><td data-key="{_e(r[2])}"'
                   + (f' data-unit="{_e(r[3])}"' if len(r) > 3 else "") + f">{r[1]}</td></tr>" for r in rows)
    return f'<div class="scroll"><table class="kv"><tbody>{body}</tbody></table></div>'


def _notice(text: str, kind: str = "missing") -> str:
    return f'<p class="notice {kind}">{text}</p>'


def _figure(svg: str, caption: str) -> str:
    return f"<figure>{svg}<figcaption>{caption}</figcaption></figure>"


def _rotation_note(stats: dict, key: str) -> str:
    """'; rotation mean 0.00183 deg' for 6D results, else nothing."""
    r = (stats.get("rotation") or {}).get(key) or {}
    return f"; rotation mean {fmt(r.get('mean'), 'rad')} deg" if r.get("n") else ""


def _headline(d: dict, summary: ErrorSummary) -> str:
    """Cards at the top: mean error before and after as measured (before beside the nominal model as
    given where base and markers were registered for it: ``summary``, ``registered_before``), the
    limit, the solver."""
    stats = d["stats"]
    on = "validation" if (stats.get("validation_after") or {}).get("n") else "fit"
    where = "held-out poses" if on == "validation" else "fitted poses"
    raw = (f'; nominal as given <span data-key="headline.{on}_nominal.mean" data-unit="mm">'
           f'{fmt((stats.get(f"{on}_nominal") or {}).get("mean"))}</span> mm'
           if registered_before(summary, on) else "")
    cards = []
    for when in ("before", "after"):
        s = stats.get(f"{on}_{when}") or {}
        label = "before, registered" if raw and when == "before" else when
        cards.append(f'<div class="card {when}"><div class="label">Mean error {label}, as measured</div>'
                     f'<div class="value">{fmt(s.get("mean"))} <small>mm</small></div>'
                     f'<div class="sub">{where}, {_e(s.get("n", 0))} points; max {fmt(s.get("max"))} mm'
                     f'{_rotation_note(stats, f"{on}_{when}")}{raw if when == "before" else ""}</div></div>')
    lim = d.get("limit")
    if lim:
        ok = bool(lim.get("reached"))
        cards.append(f'<div class="card {"good" if ok else "bad"}"><div class="label">Limit of absolute accuracy</div>'
                     f'<div class="value">{fmt(lim.get("limit_m"))} <small>mm</small></div>'
                     f'<div class="sub">{"reached" if ok else "not reached"}: mean error / limit = '
                     f'{_ratio(lim.get("ratio"), ".2f")}</div></div>')
    else:
        cards.append('<div class="card neutral"><div class="label">Limit of absolute accuracy</div>'
                     '<div class="value">–</div><div class="sub">not given</div></div>')
    ok = bool(d.get("success"))
    cards.append(f'<div class="card {"good" if ok else "bad"}"><div class="label">Solver</div>'
                 f'<div class="value">{"converged" if ok else "not converged"}</div>'
                 f'<div class="sub">{_e(d.get("nfev"))} evaluations, {_e(d.get("loss"))} loss</div></div>')
    return f'<div class="cards">{"".join(cards)}</div>'


def _pose_labels(d: dict) -> set:
    prov = d.get("provenance") or {}
    return {lab for src in ("data", "validation") for lab in ((prov.get(src) or {}).get("labels") or [])}


def _flagged_poses(d: dict) -> set:
    """Pose labels a check that did not pass names (items read 'label: ...')."""
    labels = _pose_labels(d)
    return {_item_head(item) for c in d.get("checks") or [] if c.get("status") != "pass"
            for item in c.get("items") or []} & labels


def _item_head(item) -> str:
    """What a check's item names first: 'pose 12' of 'pose 12, marker tool: 3.1 mm'."""
    return re.split(r"[:,]", str(item), maxsplit=1)[0].strip()


def _item_html(item: str, params: set, poses: set) -> str:
    """A check's item with the parameters and the pose it names linked to their rows."""
    text = str(item)
    head = _item_head(text)
    if head in poses and text.startswith(head):
        return f'<a href="#{_anchor("pose", head)}">{_e(head)}</a>{_e(text[len(head):])}'
    parts = re.split(r"([\w.]+)", text)
    return "".join(f'<a href="#{_anchor("param", t)}">{_e(t)}</a>' if t in params else _e(t) for t in parts)


VERDICT_TEXT = {"pass": "every check passed", "warn": "usable, with warnings to read",
                "fail": "not to be used as it is: a check failed"}
STATUS_CLASS = {"pass": "good", "warn": "missing", "fail": "bad"}


def _checks_html(d: dict) -> str:
    """The verdict and every check, those that did not pass first, their items linked to their rows."""
    checks = d.get("checks") or []
    if not checks:
        return _notice("This result holds no checks (written by an older robocal): no verdict.")
    verdict = d.get("verdict") or "pass"
    params = set((d.get("identifiability") or {}).get("candidates") or []) | {p["name"] for p in d["parameters"]}
    poses = _flagged_poses(d)
    rows = []
    for j, c in enumerate(sorted(checks, key=lambda c: c.get("status") == "pass")):
        st = c.get("status", "")
        detail = "".join(f"<br><b>{label}:</b> {_e(c[key])}" for key, label in (("cause", "likely cause"),
                                                                                 ("fix", "fix"))
                         if st != "pass" and c.get(key))
        items = c.get("items") or []
        listed = items[:20]
        more = f" and {len(items) - 20} more" if len(items) > 20 else ""
        named = (f'<br><span class="items">{", ".join(_item_html(i, params, poses) for i in listed)}{more}</span>'
                 if items and st != "pass" else "")
        rows.append(f'<tr class="check {st}"><td><span class="status {st}" data-key="check.{j}.status">{st}</span>'
                    f'</td><td data-key="check.{j}.name">{_e(c.get("name", ""))}</td>'
                    f'<td class="wrap">{_e(c.get("summary", ""))}{detail}{named}</td></tr>')
    banner = (f'<p class="notice {STATUS_CLASS.get(verdict, "missing")} verdict">Verdict: '
              f'<b data-key="verdict">{_e(verdict)}</b> &ndash; {VERDICT_TEXT.get(verdict, "")}.</p>')
    return banner + _diagnosis_html(d.get("diagnosis")) + _table(["status", "check", "what it found"], rows,
                                                                 cls="checks")


def _diagnosis_html(diag: dict | None) -> str:
    """The diagnosis of the misfit (docs/diagnosis.md): the most likely cause first, with its evidence."""
    if not diag:
        return ""
    found = diag.get("findings") or []
    if not found:
        return f'<p class="diagnosis" data-key="diagnosis.summary"><b>Diagnosis:</b> {_e(diag.get("summary", ""))}</p>'
    items = "".join(f'<li data-key="diagnosis.{k}"><b>{_strength(f, k)}:</b> {_e(f["cause"])}'
                    f' &ndash; {_e(f["evidence"])}' + (f'<br><b>fix:</b> {_e(f["fix"])}' if f.get("fix") else "")
                    + "</li>" for k, f in enumerate(found))
    return f'<div class="diagnosis"><b>Diagnosis</b><ul>{items}</ul></div>'


def _strength(f: dict, k: int) -> str:
    """How a finding is introduced: decisive, noted (a fact the calibration carries, no refit), a
    possible cause, or another beside the first."""
    if k:
        return "Or"
    if f.get("status") == "fail":
        return "Decisive"
    return "Noted" if f.get("rms_after_m") is None else "Possible cause"


def _stats_table(d: dict, summary: ErrorSummary | None, *, rotation: bool = False) -> str:
    """Position errors before and after, on fitted and held-out poses, as measured; the nominal model
    as given beside "before" where that registered base and markers (``summary``, the record's
    ``ErrorSummary``: ``registered_before``); the rotation errors with ``rotation``."""
    stats, unit, prefix = (d["stats"]["rotation"], "rad", "stats.rotation") if rotation else (d["stats"], "m", "stats")
    shown = _display(unit)[0]
    rows = []
    on_it = (d.get("in_use") or {}).get("method") == REGISTERED_ON_IT
    for which, poses in (("fit", "fitted poses"), ("validation", "held-out poses")):
        poses = f"{poses}, base and tool registered on them" if on_it and which == "validation" else poses
        for cls, label in stat_labels(summary, which):
            k = f"{which}_{cls}"
            s = stats.get(k) or {}
            lead = f'<tr class="{cls}"><td>{poses}</td><td><span class="tag {cls}">{label}</span></td>'
            if not s.get("n"):
                rows.append(lead + f'<td class="num" data-key="{prefix}.{k}.n">0</td>'
                            f'<td colspan="4" class="muted">not given</td></tr>')
                continue
            cells = "".join(_cell(s.get(f), unit, f"{prefix}.{k}.{f}") for f in STAT_FIELDS)
            rows.append(lead + f'<td class="num" data-key="{prefix}.{k}.n">{_e(s["n"])}</td>{cells}</tr>')
    what = "rotation" if rotation else "position"
    return _table(["poses", "calibration", "points"] + [f"{f} ({shown})" for f in ("mean", "std", "RMS", "max")],
                  rows, cls="stats", num_from=2, caption=f"{what.capitalize()} errors as measured (the instrument's "
                  "noise in)")


def _limit_text(d: dict) -> str:
    lim = d.get("limit")
    if not lim:
        return ""  # said at the top of the page
    compared = {"validation_after": "held-out poses", "fit_after": "fitted poses"}.get(lim.get("compared"),
                                                                                          lim.get("compared"))
    ok = bool(lim.get("reached"))
    return (f'<p class="notice {"good" if ok else "bad"}">Limit of absolute accuracy '
            f'<b data-key="limit.limit_m" data-unit="mm">{fmt(lim.get("limit_m"))}</b> mm; mean error in use after '
            f"calibration (the robot's, the instrument's noise taken out) on the {_e(compared)} "
            f'<b data-key="limit.mean_error_m" data-unit="mm">'
            f'{fmt(lim.get("mean_error_m"))}</b> mm, ratio <b data-key="limit.ratio">{_ratio(lim.get("ratio"), ".3f")}'
            f'</b>: the limit is <b data-key="limit.reached">{"reached" if ok else "not reached"}</b> '
            "(within 15 % of it counts as reached).</p>")


def _nominal_values(result: CalibrationResult) -> tuple[dict, dict]:
    """Nominal values (SI) and SI units of every parameter of the nominal model."""
    lay = parameter_layout(result.nominal_model)
    values = parameter_vector(result.nominal_model)
    return ({p.name: float(values[p.index]) for p in lay.parameters}, {p.name: p.unit for p in lay.parameters})


def _placement_text(frame, key: str) -> str:
    """A fixed frame's placement in its parent as users write it: position (mm) and rotation matrix."""
    X = mdh_transform(frame)
    position = ", ".join(f"{v * 1e3:.4f}" for v in X[:3, 3])
    rows = "; ".join("[" + ", ".join(f"{v:.6f}".replace("-0.000000", "0.000000") for v in row) + "]"
                     for row in X[:3, :3])
    return (f'position (<span data-key="{_e(key)}.position" data-unit="mm">{position}</span>) mm, rotation '
            f'<span data-key="{_e(key)}.rotation">[{rows}]</span>')


@dataclass(frozen=True)
class _Values:
    """What the parameter tables show of each parameter: its estimate (file form), its status (I
    identified, E eliminated, - not a candidate) and its nominal value (SI)."""

    est: dict
    status: dict
    nominal: dict

    def cells(self, name: str, unit: str) -> list[str]:
        """nominal, identified, change, std dev"""
        p = self.est.get(name)
        if p is not None:
            return [_cell(p["nominal"], unit, f"{name}:nominal"), _cell(p["estimate"], unit, f"{name}:estimate"),
                    _cell(p["change"], unit, f"{name}:change", sign=True), _cell(p["std"], unit, f"{name}:std")]
        st = self.status.get(name, "-")
        nom = self.nominal.get(name) if st != "-" or self.nominal.get(name) else None
        held = '<td class="num muted">held</td>' if st == "E" else "<td></td>"
        return [f'<td class="num muted">{fmt(nom, unit) if nom is not None else ""}</td>', held,
                "<td></td>", "<td></td>"]

    def status_cell(self, name: str) -> str:
        st = self.status.get(name, "-")
        text = {"I": '<span class="badge si">I</span>', "E": '<span class="badge se">E</span>', "-": "–"}[st]
        return f'<td class="status" id="{_anchor("param", name)}" data-key="{_e(name)}:status">{text}</td>'


def _statuses(ident: dict) -> dict:
    """Each candidate's status: I identified, E eliminated, - neither."""
    status = {n: "-" for n in ident.get("candidates", [])}
    status.update({n: "I" for n in ident.get("identified", [])})
    status.update({a["name"]: "E" for a in ident.get("eliminated", [])})
    return status


def _parameter_tables(d: dict, nominal: dict, units: dict, result: CalibrationResult | None = None,
                      relative: bool = False) -> tuple[str, str, str]:
    """The per-frame table (the paper's layout), the base and marker table, a note on omitted columns.

    Fixed frames (placements, often written as a matrix) show their placement as position and
    rotation matrix, nominal and calibrated, beside the corrections the fit made. With ``relative``
    the compliances are headed as relative (masses assumed without a total mass)."""
    values = _Values({p["name"]: p for p in d["parameters"]}, _statuses(d["identifiability"]), nominal)
    fixed = {} if result is None else {f.name: (f, g) for f, g in zip(result.nominal_model.frames,
                                                                      result.calibrated_model.frames)
                                       if f.joint == "fixed"}
    table = d.get("identifiability_table") or []
    frames = [row["frame"] for row in table]
    shown = _shown_kinds(table, nominal)
    omitted = [k for k in FRAME_KINDS if k not in shown and k not in ("gamma", "b")]
    body = [row for f in frames for row in _frame_rows(f, shown, units, values, fixed.get(f))]
    head = ["frame", ""] + [_kind_head(k, frames, units, relative) for k in shown]
    note = ""
    if omitted:
        note = ("Columns " + ", ".join(symbol(k) for k in omitted)
                + " are not shown: those parameters were not among the candidates.")
    frame_table = _table(head, body, cls="params", num_from=2)
    return frame_table, _other_table(d["identifiability"], values, frames, units), note


def _shown_kinds(table: list[dict], nominal: dict) -> list[str]:
    """The kinds the per-frame table shows: those always shown, those that were a candidate, and
    those the model holds a non-zero value of (a fixed mount's gamma and b): nothing the calibrated
    file keeps is hidden."""
    return [k for k in FRAME_KINDS
            if k in ALWAYS_SHOWN or any(row.get(k, "-") != "-" or nominal.get(f"{row['frame']}.{k}") for row in table)]


def _kind_head(kind: str, frames: list, units: dict, relative: bool) -> str:
    """The head of a kind's column, with its display unit ("relative" for relative compliances)."""
    if not frames:
        return symbol(kind)
    unit = "relative" if relative and kind.startswith("k_") else _e(_display(units[f"{frames[0]}.{kind}"])[0])
    return f"{symbol(kind)} <small>({unit})</small>"


def _frame_rows(f: str, shown: list, units: dict, values: _Values, fixed) -> list[str]:
    """The rows of frame ``f`` in the per-frame table: statuses, then nominal, identified, change and
    std dev of each kind shown; a fixed frame's placement (``fixed``: nominal and calibrated frame)
    as written in place of its nominal and identified rows."""
    cols = [values.cells(f"{f}.{k}", units[f"{f}.{k}"]) for k in shown]
    rows = [(label, "".join(c[i] for c in cols)) for i, label in enumerate(("nominal", "identified", "change",
                                                                             "std dev"))]
    if fixed is not None:  # a placement: shown as written, the fit's corrections below it
        nom, cal = fixed
        rows = [("placement", f'<td colspan="{len(shown)}" class="placement">{_placement_text(nom, f"{f}:nominal")}'
                              "</td>"),
                ("calibrated", f'<td colspan="{len(shown)}" class="placement">'
                               f'{_placement_text(cal, f"{f}:calibrated")}</td>')] + rows[2:]
    first = (f'<tr class="frame-start"><th rowspan="{1 + len(rows)}" class="frame">{_e(f)}'
             + ('<br><small>fixed</small>' if fixed is not None else "") + '</th><td class="what">I / E</td>'
             + "".join(values.status_cell(f"{f}.{k}") for k in shown) + "</tr>")
    return [first] + [f'<tr><td class="what">{label}</td>{cells}</tr>' for label, cells in rows]


def _other_table(ident: dict, values: _Values, frames: list, units: dict) -> str:
    """The base and marker parameters (those of no frame): candidates, then the other estimates."""
    other = [n for n in ident.get("candidates", []) if n.split(".", 1)[0] not in frames]
    other += [n for n in values.est if n not in other and n.split(".", 1)[0] not in frames]
    rows = []
    for n in other:
        unit = units.get(n, values.est[n]["unit"] if n in values.est else "")
        rows.append(f'<tr><td class="name">{_e(n)}</td><td>{_e(_display(unit)[0])}</td>'
                    + "".join(values.cells(n, unit)) + values.status_cell(n) + "</tr>")
    if not rows:
        return "<p>No base or marker parameters were considered.</p>"
    return _table(["parameter", "unit", "nominal", "identified", "change", "std dev", "I / E"], rows,
                  cls="params", num_from=2)


RELATIVE_NOTE = ("Compliances (K) are relative: the link masses were assumed from the geometry at a density of "
                 f"{DEFAULT_LINK_DENSITY:g} kg per metre with no total mass given, so only their ratios hold; give "
                 f"the arm's mass (<code>--total-mass KG</code>) for compliances in {_display('rad/(N m)')[0]}.")


def _relative_compliance(d: dict) -> bool:
    """Whether the result's compliances rest on masses assumed without a total mass (a note says so)."""
    return any(RELATIVE_MASSES in str(n) for n in d.get("notes") or []) and any(
        p.get("family") == "compliance" for p in d["parameters"])


def _eliminated_table(d: dict, units: dict) -> str:
    elim = (d.get("identifiability") or {}).get("eliminated") or []
    if not elim:
        return "<p>Every candidate parameter was identified: none was eliminated.</p>"
    rows = []
    for a in elim:
        name = a["name"]
        terms = [(t["name"], t["coefficient"]) for t in a.get("absorbed_by", [])]
        expr = (_e(absorption_text(units.get(name, ""), terms, units)) if terms
                else '<span class="muted">nothing (no effect)</span>')
        rows.append(f'<tr><td class="name">{_e(name)}</td><td>{_e(a.get("reason", ""))}</td>'
                    f'<td class="expr" data-key="{_e(name)}:absorbed_by">{expr}</td>'
                    f'<td class="num">{_ratio(a.get("residual"), ".1e") if terms else "–"}</td></tr>')
    return _table(["eliminated", "why", "a change of it moves the tool as", "fit residual"], rows,
                  cls="elim", num_from=3)


def _correlated_pairs(d: dict, k: int = 12) -> str:
    """The ``k`` most strongly correlated pairs, named in full, those beyond ``CORRELATED`` marked."""
    names = [p["name"] for p in d["parameters"]]
    pairs = []
    for i, row in enumerate(d["correlation"]):
        for j in range(i + 1, len(row)):
            r = _num(row[j])
            if r is not None:
                pairs.append((-abs(r), names[i], names[j], r))
    if not pairs:
        return ""
    pairs.sort()
    strong = sum(1 for p in pairs if -p[0] >= CORRELATED)
    rows = [f'<tr{" class=strong" if abs(r) >= CORRELATED else ""}><td class="name">{_e(a)}</td>'
            f'<td class="name">{_e(b)}</td><td class="num">{r:+.3f}</td></tr>' for _, a, b, r in pairs[:k]]
    return _table(["parameter", "parameter", "r"], rows, num_from=2, cls="pairs",
                  caption=f"The {min(k, len(pairs))} strongest of {len(pairs)} pairs; {strong} with |r| &ge; "
                          f"{CORRELATED} (in bold)")


def _correlation_section(d: dict) -> str:
    """The strongest pairs first (they name what a map of many parameters cannot), then the map:
    whole for a few parameters, in per-family blocks for many, in a scrollable panel."""
    blocks = correlation_blocks(d)
    how = ("Correlation coefficients from the covariance of the estimates (red positive, blue negative)"
           + ("." if len(blocks) == 1 else f", within each family in {len(blocks)} blocks of at most {BLOCK} "
              "parameters; pairs across blocks are in the table above."))
    k = 12 if len(d["parameters"]) <= 30 else 25
    return (_correlated_pairs(d, k)
            + f'<div class="panel">{_figure(plot_correlation(d), how)}</div>')


def _solver_table(d: dict) -> str:
    ident = d.get("identifiability") or {}
    return _kv([
        ("success", "yes" if d.get("success") else "no", "solver.success"),
        ("status", _e(d.get("status")), "solver.status"),
        ("message", _e(d.get("message")), "solver.message"),
        ("function evaluations", _e(d.get("nfev")), "solver.nfev"),
        # 6D fits weigh positions and rotations by the instrument's deviations: sigma0 is then a ratio
        (("&sigma;<sub>0</sub>, residual standard deviation (times the expected measurement deviations)",
          _ratio(d.get("sigma0_m"), ".4g"), "solver.sigma0") if (d["stats"].get("rotation") is not None) else
         ("&sigma;<sub>0</sub>, residual standard deviation (mm)", fmt(d.get("sigma0_m")), "solver.sigma0_m", "mm")),
        ("loss", _e(d.get("loss")), "solver.loss"),
        ("parameter families", _e(", ".join(d.get("families") or [])), "solver.families"),
        ("identified / candidates", f"{len(ident.get('identified', []))} / {len(ident.get('candidates', []))}",
         "identifiability.count"),
        ("rank of the scaled Jacobian", _e(ident.get("rank")), "identifiability.rank"),
        ("condition number", _ratio(ident.get("condition_number"), ".4g"), "identifiability.condition_number"),
        ("identifiability tolerance", _e(ident.get("tol")), "identifiability.tol"),
        ("equations (rows of the Jacobian)", _e(ident.get("n_rows")), "identifiability.n_rows"),
    ])


def _provenance(d: dict) -> str:
    prov = d.get("provenance") or {}
    scalars = [(k, v) for k, v in prov.items() if not isinstance(v, dict)]
    if "version" not in prov:
        scalars.append(("version", "not recorded"))
    kv = _kv([(_e(k), _e(_date(v) if k == "date" else v), f"provenance.{k}") for k, v in scalars]
             + [("result schema", _e(d.get("schema", "")), "schema")])
    rows = []
    for k, v in prov.items():
        if isinstance(v, dict):
            sha = v.get("sha256") or ""
            rows.append(f'<tr><td>{_e(k)}</td><td class="name" data-key="provenance.{_e(k)}.source">'
                        f'{_e(v.get("source") or "")}</td><td class="hash" data-key="provenance.{_e(k)}.sha256">'
                        f'{_e(sha) if sha else "<span class=muted>not read from a file</span>"}</td>'
                        f'<td class="num">{_e(v.get("n_poses", ""))}</td></tr>')
    return kv + (_table(["input", "source", "SHA-256", "poses"], rows, num_from=3) if rows else "")


def _extra_tables(extra) -> list[dict]:
    """``extra`` as a list of {"title", "columns", "rows", "note"} tables.

    ``extra`` maps a key to a titled table ``{"title", "columns", "rows"}``, a list of them, or a
    list of records (dicts; the table is titled by the key, one column per record key).
    """
    if extra is None:
        return []
    if not isinstance(extra, dict):
        raise InputError(f"expected a dict, got {type(extra).__name__}", where="extra")
    return [t for key, value in extra.items() for t in _extra_entry(key, value)]


def _extra_entry(key, value) -> list[dict]:
    """The tables of one entry of ``extra``: titled tables, or one table of records titled ``key``."""
    items = value if isinstance(value, list) else [value]
    if items and all(isinstance(t, dict) and "rows" in t for t in items):
        return [_titled_table(key, t) for t in items]
    if items and all(isinstance(r, dict) for r in items):
        cols = list(dict.fromkeys(k for r in items for k in r))
        return [{"title": str(key), "columns": cols, "note": "", "rows": [[r.get(c, "") for c in cols] for r in items]}]
    raise InputError("expected a table {'title', 'columns', 'rows'}, a list of them, or a list of records",
                     where=f"extra[{key!r}]")


def _titled_table(key, t: dict) -> dict:
    """A table ``{"title", "columns", "rows"[, "note"]}`` of ``extra[key]``, every row checked."""
    cols, rows = list(t.get("columns") or []), t["rows"]
    if not all(isinstance(r, (list, tuple)) and len(r) == len(cols) for r in rows):
        raise InputError(f"each row of table {t.get('title', key)!r} needs {len(cols)} cells", where=f"extra[{key!r}]")
    return {"title": str(t.get("title", key)), "columns": cols, "rows": rows, "note": t.get("note", "")}


def _extra_cell(v) -> str:
    if isinstance(v, float):
        return f'<td class="num">{_ratio(v, ".4g")}</td>'
    if isinstance(v, int) and not isinstance(v, bool):
        return f'<td class="num">{v}</td>'
    return f"<td>{_e('' if v is None else v)}</td>"


def _extra_html(tables: list[dict]) -> str:
    out = []
    for i, t in enumerate(tables):
        rows = [f"<tr>{''.join(_extra_cell(v) for v in r)}</tr>" for r in t["rows"]]
        note = f'<p class="muted">{_e(t["note"])}</p>' if t["note"] else ""
        num = {j for j in range(len(t["columns"]))
               if t["rows"] and all(isinstance(r[j], (int, float)) and not isinstance(r[j], bool) for r in t["rows"])}
        out.append(f'<h3 data-key="extra.{i}.title">{_e(t["title"])}</h3>'
                   + _table([_e(c) for c in t["columns"]], rows, num=num) + note)
    return "".join(out)


# -- the page -----------------------------------------------------------------------------------

_CSS = """
:root{--before:%(before)s;--after:%(after)s;--limit:%(limit)s;--ink:#1d232b;--muted:#6b7480;--line:#dde1e6;
--soft:#f5f7f9;--mono:ui-monospace,"SFMono-Regular",Menlo,Consolas,"DejaVu Sans Mono",monospace}
*{box-sizing:border-box}
body{margin:0;background:#eef1f4;color:var(--ink);font:14px/1.5 system-ui,-apple-system,"Segoe UI",Roboto,
"Helvetica Neue",Arial,sans-serif}
main{max-width:1120px;margin:0 auto;padding:28px 36px 40px;background:#fff;min-height:100vh}
header{border-bottom:3px solid var(--after);padding-bottom:10px;margin-bottom:18px}
h1{font-size:26px;margin:0 0 2px;font-weight:650}
h1 .robot{color:var(--after)}
h2{font-size:19px;margin:34px 0 10px;padding-bottom:4px;border-bottom:1px solid var(--line);font-weight:620}
h3{font-size:15px;margin:22px 0 6px;font-weight:620}
p{margin:8px 0}
.meta,.muted,caption,figcaption{color:var(--muted)}
nav ol{columns:3;margin:8px 0 0;padding-left:20px;font-size:13px}
nav a{color:var(--after);text-decoration:none}
code{font:12.5px var(--mono);background:var(--soft);padding:1px 4px;border-radius:3px}
.cards{display:grid;grid-template-columns:repeat(4,1fr);gap:12px;margin:14px 0}
.card{border:1px solid var(--line);border-left:5px solid var(--muted);border-radius:6px;padding:10px 12px}
.card .label{font-size:12px;text-transform:uppercase;letter-spacing:.04em;color:var(--muted)}
.card .value{font-size:24px;font-weight:650;font-variant-numeric:tabular-nums;white-space:nowrap}
.card .value small{font-size:14px;font-weight:400;color:var(--muted)}
.card .sub{font-size:12.5px;color:var(--muted)}
.card.before{border-left-color:var(--before)}.card.before .value{color:var(--before)}
.card.after{border-left-color:var(--after)}.card.after .value{color:var(--after)}
.card.good{border-left-color:#2e8540}.card.bad{border-left-color:var(--limit)}
.notice{border-radius:5px;padding:8px 12px;border:1px solid}
.notice.missing{background:#fff8e6;border-color:#f0d48a}
.notice.good{background:#eef8f0;border-color:#b7dcc0}
.notice.bad{background:#fcefef;border-color:#eab8b9}
.scroll{overflow-x:auto;margin:8px 0}
table{border-collapse:collapse;font-size:13px;font-variant-numeric:tabular-nums}
caption{caption-side:top;text-align:left;font-size:12.5px;padding:2px 0 6px}
th,td{padding:4px 10px;border-bottom:1px solid var(--line);text-align:left;vertical-align:top}
thead th{background:var(--soft);border-bottom:2px solid #c9ced5;font-weight:600;white-space:nowrap}
thead th small{font-weight:400;color:var(--muted)}
th.num,td.num{text-align:right;white-space:nowrap}
td.name,td.expr{font-family:var(--mono);font-size:12.5px}
td.name{white-space:nowrap}
td.hash{font-family:var(--mono);font-size:11.5px;word-break:break-all}
.tag{display:inline-block;padding:0 8px;border-radius:9px;font-size:12px;color:#fff}
.tag.before{background:var(--before)}.tag.after{background:var(--after)}.tag.nominal{background:var(--muted)}
table.stats tr.after td{background:#f3f7fc}
table.params th.frame{background:var(--soft);font-family:var(--mono);vertical-align:middle;
border-right:1px solid var(--line)}
table.params td.what{color:var(--muted);font-size:12px;white-space:nowrap}
table.params td{border-bottom:1px solid #f0f2f4}
table.params tr.frame-start td,table.params tr.frame-start th{border-top:2px solid #c9ced5}
td.status{text-align:right;color:#b0b6be}
.badge{display:inline-block;min-width:20px;text-align:center;border-radius:4px;font-size:11.5px;font-weight:700;
padding:0 4px;line-height:17px}
.badge.si{background:#e3f2e6;color:#1d6b2f}.badge.se{background:#fbe5e5;color:var(--limit)}
table.kv{min-width:540px}
table.kv th{font-weight:500;color:var(--muted);white-space:nowrap}
figure{margin:16px 0 6px}
figcaption{font-size:12.5px;margin-top:2px}
svg[data-plot]{max-width:100%%;height:auto;display:block}
svg[data-plot] *{stroke-linejoin:round;stroke-linecap:butt}
ul.notes li{margin:4px 0}
span.status{display:inline-block;padding:0 6px;border-radius:4px;font-weight:700;font-size:11.5px;
text-transform:uppercase}
span.status.pass{background:#e3f2e6;color:#1d6b2f}span.status.warn{background:#fff0c2;color:#7a5600}
span.status.fail{background:#fbe5e5;color:var(--limit)}
table.checks{width:100%%}table.checks td.wrap{overflow-wrap:anywhere}
.verdict{font-size:16px}:target{outline:2px solid var(--after);background:#eaf2fb}
footer{margin-top:36px;padding-top:8px;border-top:1px solid var(--line);font-size:12px;color:var(--muted)}
table.pairs tr.strong td{font-weight:650}
td.placement{font-family:var(--mono);font-size:12px;white-space:normal}
.panel{max-height:1100px;overflow:auto;border:1px solid var(--line);border-radius:6px;padding:0 8px}
table.params{font-size:12.5px}table.params td,table.params th{padding:3px 7px}
@page{size:A4;margin:12mm}
@media print{body{background:#fff;font-size:11px}main{padding:0;max-width:none;min-height:0}
.scroll{overflow:visible}table{font-size:10px}th,td{padding:2px 5px}table.params{font-size:9px}
table.params td,table.params th{padding:1px 3px}td.name{white-space:normal;overflow-wrap:anywhere}
.panel{max-height:none;overflow:visible;border:0}h2{break-after:avoid}figure,tr,.card,.notice{break-inside:avoid}
nav ol{columns:4}:target{outline:none;background:none}}
@media (max-width:800px){.cards{grid-template-columns:1fr 1fr}nav ol{columns:1}}
""" % {"before": BEFORE, "after": AFTER, "limit": LIMIT}  # noqa: UP031 - the CSS is full of braces


def _in_use_table(result: CalibrationResult) -> str:
    """The accuracy in use: the robot's error at the held-out points before and after, the
    instrument's noise taken out, as ``robocal calibrate`` prints it (``in_use_rows``)."""
    use = result.in_use
    if use is None or not use.position_after.n:
        return ""
    within = within_noise(use.position_after.rms, use.noise)
    body = []
    for label, key, unit in in_use_rows(use, registered_before(result.stats, "fit")):
        if key is None:
            body.append(f'<tr><th colspan="5">{_e(label)}</th></tr>')
            continue
        cells = (f'<td colspan="4" data-key="in_use.{key}">{_e(within)}</td>' if key == "position_after" and within
                 else "".join(_cell(getattr(getattr(use, key), f), unit, f"in_use.{key}.{f}")
                              for f in ("mean", "rms", "p95", "max")))
        body.append(f"<tr><td>{_e(label)}</td>{cells}</tr>")
    return _table(["", "mean (mm)", "RMS (mm)", "95 % (mm)", "max (mm)"], body, cls="stats", num_from=1,
                  caption=_e(_sentence(in_use_heading(use))))


def _errors_section(d: dict, has_val: bool, result: CalibrationResult) -> str:
    lim = d.get("limit")
    n = sum(len(v) for v in (errors_array(d, k) for k in ("fit_before", "validation_before")) if v is not None)
    how = ("Position error of each measured point before (orange) and after (blue) calibration. Filled circles: "
           "fitted poses; open triangles on grey: held-out poses" if n <= DENSE else
           f"Position errors of the {n} poses before (orange) and after (blue) calibration, summarised in bins of "
           "consecutive poses: the line is the median of a bin, the band holds 90 % of its points; dashed lines "
           "and the grey band: held-out poses")
    rotation = d["stats"].get("rotation")
    return (_stats_table(d, result.stats) + (_stats_table(d, result.rotation_stats, rotation=True) if rotation else "")
            + _in_use_table(result)
            + _limit_text(d)
            + _figure(plot_errors_per_pose(d), how + ("" if has_val else " (none given)")
                      + ". Dashed red line: the limit of absolute accuracy" + ("" if lim else " (not given)") + ".")
            + _figure(plot_histograms(d), "Distribution of the errors. Solid bars: fitted poses; hatched: held-out "
                      "poses." + (" Dashed line: the limit of absolute accuracy." if lim else ""))
            + _worst_poses(d, _flagged_poses(d)))


def _residuals_section(d: dict) -> str:
    shown, at_points, n = residual_sample(d)
    where = ("Arrows start at the measured points and are scaled up; the bar gives their scale."
             if at_points is not None else
             "The measured positions are not stored in the result, so every arrow starts at a common origin; "
             "the bar gives the scale.")
    count = (f" {len(shown)} of the {n} measured points are drawn, evenly spaced through the campaign."
             if len(shown) < n else "")
    return _figure(plot_residuals(d), "Fit residuals (calibrated minus measured) of the fitted poses, projected on "
                   "three planes. " + where + count)


def _trends_section(d: dict, result: CalibrationResult) -> str:
    model = result.nominal_model
    trends = residual_trends(d, model.joint_names, [SI_UNITS[q] for q in model.reading_quantities],
                             result.calibrated_model.X_WB)
    if trends is None:
        return "<p>The result holds no measured points and joint readings: no trends to draw.</p>"
    joints = [c for c, _ in trends["columns"][2:]]
    drawn = [c for c in joints if c in trends["structured"]]
    flat = [c.removesuffix(" reading") for c in joints if c not in drawn]
    said = (f" Against {_list(flat)} the medians stay within the noise (within {STRUCTURE:g} standard errors of a "
            "bin's median): not drawn." if flat else "")
    which = (f"all {trends['points']}" if trends["points"] == trends["of"] else
             f"{trends['points']} (whole poses evenly spaced through the campaign) of the {trends['of']}")
    return ("<p>Where a model term is missing (backlash, compliance, a wrong encoder ratio, a thermal drift), the "
            "residuals follow the robot's posture: a trend here against one joint's reading and not against the "
            "others points at that joint. Reach and height are always drawn; a joint's reading only where the "
            "residuals show structure against it.</p>"
            + _figure(plot_residual_trends(trends, ["reach", "height"] + drawn),
                      f"Residual components after calibration (calibrated minus measured, world axes) of {which} "
                      "measured points, fitted and held-out, against the distance from the "
                      "calibrated base's vertical axis (reach), the height above the calibrated base and the "
                      "readings of the joints that show structure. Line: median in bins of equal counts of points; "
                      f"band: the middle half.{said}"))


def _list(items: list[str]) -> str:
    """'a, b and c'."""
    items = [_e(i) for i in items]
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


@accepts(result=is_a(CalibrationResult), extra=optional(MAPPING))
def render_report(result: CalibrationResult, *, extra: dict | None = None) -> str:
    """The HTML text of the report of ``result`` (a CalibrationResult, computed or read back), its
    diagnosis in the verdict section.

    ``extra``: optional tables for a comparison section (see ``_extra_tables``).
    Raises RobocalError when matplotlib is missing, InputError when ``result`` is not a result.

    Parameters
    ----------
    {result, extra}

    Returns
    -------
    str
        The HTML page.
    """
    if not isinstance(result, CalibrationResult):
        raise InputError(f"expected a CalibrationResult, got {type(result).__name__}", where="result")
    if result.contacts is not None:
        return render_contact_report(result)
    d = result_to_dict(result, per_pose=False)
    d["errors"].update(per_pose_arrays(result))    # arrays as they are: a million poses are no lists
    tables = _extra_tables(extra)
    need_matplotlib()  # fail early and clearly without the extra
    has_val = bool((d["stats"].get("validation_after") or {}).get("n"))
    robot = (d.get("nominal_model") or {}).get("name", "robot")
    return _page(f"Calibration report: {_e(robot)}", robot, _meta(families_text(result), d.get("provenance") or {}),
                 _report_sections(d, result, has_val, tables),
                 _headline(d, result.stats) + "".join(_notices(d, has_val)))


def _meta(families: str, provenance, how: str = "identification") -> str:
    """The line under the page's title: what was identified (``families_text``) and how, when, by which
    software."""
    items = [f"{families} {how}", _date(provenance.get("date", "date not recorded")),
             f'{provenance.get("software", "")} {provenance.get("version", "")}'.strip()]
    return " &middot; ".join(_e(m) for m in items if m)


def _notices(d: dict, has_val: bool) -> list[str]:
    """What the page says is missing (held-out poses, the limit) or went wrong (the solver)."""
    notices = [] if has_val else [_notice(MISSING_VALIDATION)]
    if not d.get("limit"):
        notices.append(_notice(MISSING_LIMIT))
    if not d.get("success"):
        notices.append(_notice(f"The solver did not converge: {_e(d.get('message'))}", "bad"))
    return notices


def _transmission_section(result: CalibrationResult) -> str:
    """Each revolute joint's identified transmission error against its reading, the data beside it."""
    curves = transmission_curves(result)
    if not curves:
        return "<p>The calibrated model's transmission terms are on joints no fitted point was measured at.</p>"
    return _figure(plot_transmission(curves),
                   "The angle each joint reaches minus its reading, as identified (the line: the gear's scale error "
                   "and its harmonics), against the reading over the fitted poses; each dot is a fitted pose's "
                   "residual turned into that joint's angle (along the joint's column) and added to the line, so the "
                   "dots scatter about the line where the terms carry what the data show.")


def transmission_curves(result: CalibrationResult) -> list[dict]:
    """Per revolute frame with transmission terms: its curve over the fitted readings' range and the
    fitted poses' residuals (first marker) as that joint's angle, all in degrees. Reference:
    docs/conventions.md (transmission)."""
    model, fit = result.calibrated_model, result.fit
    if fit.readings is None or fit.residual_vectors is None or not len(fit.readings):
        return []
    lay = layout(model)
    t = parameter_vector(model)[lay.transmission_params]
    seen = np.all(np.isfinite(fit.residual_vectors[:, 0]), axis=1)
    q, r = fit.readings[seen], fit.residual_vectors[seen, 0]
    qf = q @ model.coupling_matrix.T
    out = []
    for i, f in enumerate(model.frames):
        if f.joint != "revolute" or not np.any(t[i]) or not len(q):
            continue
        grid = np.zeros((200, model.n_frames))
        grid[:, i] = np.linspace(qf[:, i].min(), qf[:, i].max(), 200)
        J = evaluate(model, q, jacobian=True, columns=[lay.frame0[i] + FRAME_KINDS.index("theta")]).jacobian
        J = J[:, 0, :3, 0]
        # residual = predicted - measured = -J (reached - modelled): the angle the data say the joint missed
        missed = -np.einsum("nk,nk->n", J, r) / np.maximum(np.einsum("nk,nk->n", J, J), 1e-30)
        curve = transmission_basis(model, grid)[:, i] @ t[i]
        at = transmission_basis(model, qf)[:, i] @ t[i]
        out.append({"joint": f.name, "x": np.degrees(grid[:, i]), "y": np.degrees(curve),
                    "points_x": np.degrees(qf[:, i]), "points_y": np.degrees(at + missed)})
    return out


def _report_sections(d: dict, result: CalibrationResult, has_val: bool, tables: list[dict]) -> list[tuple]:
    """(id, heading, HTML) of every section of the report, in page order."""
    nominal, units = _nominal_values(result)
    title = "Position and rotation errors" if d["stats"].get("rotation") else "Position errors"
    sections = [("checks", "Verdict and checks", _checks_html(d)),
                ("errors", title, _errors_section(d, has_val, result)),
                ("parameters", "Parameters", _parameters_section(d, result, nominal, units)),
                ("identifiability", "Eliminated parameters and what absorbs them",
                 "<p>An eliminated parameter cannot be told apart from a combination of identified ones: a "
                 "change of one display unit in it moves the tool as the changes shown do.</p>"
                 + _eliminated_table(d, units)),
                ("correlation", "Correlation of the identified parameters", _correlation_section(d)),
                ("residuals", "Residual vectors after calibration", _residuals_section(d)),
                ("trends", "Residuals against reach, height and joint readings", _trends_section(d, result))]
    if result.calibrated_model.has_transmission:
        sections.append(("transmission", "Transmission errors", _transmission_section(result)))
    if tables:
        sections.append(("comparison", "Comparison", _extra_html(tables)))
    sections.append(("solver", "Solver and identifiability", _solver_table(d)))
    notes = d.get("notes") or []
    sections.append(("notes", "Notes", '<ul class="notes">' + "".join(f"<li>{_e(n)}</li>" for n in notes) + "</ul>"
                     if notes else "<p>No notes beyond the checks at the top of the page.</p>"))
    sections.append(("provenance", "Provenance", _provenance(d)))
    return sections


def _parameters_section(d: dict, result: CalibrationResult, nominal: dict, units: dict) -> str:
    """The per-frame table, the base and marker table with the rotation corrections as turns, and
    the notes on what is not shown and on relative compliances."""
    relative = _relative_compliance(d)
    frame_table, other_table, note = _parameter_tables(d, nominal, units, result, relative)
    turns = rotation_lines(result.parameters)
    if turns:
        other_table += ("<p>Rotation corrections as one turn about one axis (rx, ry, rz above are the components "
                        "of its rotation vector):</p><ul class=\"notes\">"
                        + "".join(f'<li data-key="turn.{_e(t.split(" rotation:")[0].strip())}">{_e(t.strip())}</li>'
                                  for t in turns) + "</ul>")
    if relative:
        note = ((note + " ") if note else "") + RELATIVE_NOTE
    return ("<p>Per frame, in the paper's layout: I identified, E eliminated (held at its nominal value, "
            "its effect carried by identified parameters), &ndash; not a candidate. "
            f"{_e(_sentence(UNITS_SENTENCE))}; std dev is the standard deviation of the estimate.</p>"
            + frame_table + (f'<p class="muted">{note}</p>' if note else "")
            + "<h3>Base and marker parameters</h3>" + other_table)


def _page(title: str, robot: str, meta: str, sections: list[tuple], after_first: str = "") -> str:
    """The self-contained HTML page: head, the sections with a table of contents after the first
    one (``after_first`` between them), the footer."""
    toc = "".join(f'<li><a href="#{i}">{t}</a></li>' for i, t, _ in sections)
    first, *rest = [f'<section id="{i}"><h2>{t}</h2>{b}</section>\n' for i, t, b in sections]
    return ('<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
            '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
            f'<link rel="icon" href="data:,">\n<title>{title}</title>\n'
            f"<style>{_CSS}</style>\n</head>\n<body>\n<main>\n"
            f'<header><h1>Calibration report &ndash; <span class="robot">{_e(robot)}</span></h1>'
            f'<p class="meta">{meta}</p></header>\n'
            f"{first}{after_first}<nav><ol>{toc}</ol></nav>\n{''.join(rest)}"
            f"<footer>{_e(_sentence(UNITS_SENTENCE))}; the result file keeps SI "
            "units. A self-contained page: no scripts, no network.</footer>\n</main>\n</body>\n</html>\n")


@accepts(result=is_a(CalibrationResult), path=PATH, force=FLAG, extra=optional(MAPPING))
def write_report(result: CalibrationResult, path, *, force: bool = False, extra: dict | None = None) -> None:
    """Write the HTML report of ``result`` to ``path`` atomically (temporary file, then rename).

    An existing ``path`` is an InputError unless ``force``. See ``render_report``.

    Parameters
    ----------
    {result, path, force, extra}

    Returns
    -------
    None
    """
    write_texts({path: render_report(result, extra=extra)}, force=force)


# -- the report of a calibration from contacts -----------------------------------------------------

def _contact_cell(value, key: str) -> str:
    return f'<td class="num" data-key="{_e(key)}">{_e(fmt(value, "m"))}</td>'


def _contact_sets(c: ContactFigures) -> list[tuple[str, str, ContactErrors]]:
    """(key, heading, ContactErrors) of every set of figures the calibration holds: the fitted
    placements' (fitted, then each predicted by the others), then the held-out placements'."""
    named = [("fit_before", "fitted, nominal", c.fit_before), ("fit_after", "fitted, calibrated", c.fit_after),
             ("held_out_before", "each placement predicted by the others, nominal", c.held_out_before),
             ("held_out", "each placement predicted by the others, calibrated", c.held_out),
             ("validation_before", "held out, nominal", c.validation_before),
             ("validation_after", "held out, calibrated", c.validation_after)]
    return [(key, label, e) for key, label, e in named if e is not None]


def _contact_figures(c: ContactFigures) -> str:
    """The kit's figures, one column per set: consistency, spacing, spread, planes and bars."""
    sets = _contact_sets(c)
    rows = []
    for name, label, pick in (
            ("consistency_mean", "socket consistency, mean distance from the socket's centre",
             lambda e: e.consistency_mean),
            ("consistency_max", "socket consistency, largest distance", lambda e: e.consistency_max),
            ("spacing_mean", "spacing error, mean |calibrated &minus; known|", lambda e: e.spacing_mean),
            ("spacing_max", "spacing error, largest", lambda e: e.spacing_max),
            ("spread", "socket spread, RMS about the centre (mean over sockets)", lambda e: e.mean_spread),
            ("plane", "plane contacts, RMS distance to their plane",
             lambda e: float(np.sqrt(np.mean(np.square(list(e.plane.values()))))) if e.plane else None),
            ("bar", "ball-bar length error, RMS",
             lambda e: float(np.sqrt(np.mean(np.square(list(e.bar.values()))))) if e.bar else None)):
        values = [pick(e) for _, _, e in sets]
        if all(v is None for v in values):
            continue
        rows.append(f"<tr><td>{label}</td>" + "".join(_contact_cell(v, f"{key}.{name}")
                                                       for (key, _, _), v in zip(sets, values)) + "</tr>")
    head = ["figure (" + _e(_display("m")[0]) + ")"] + [label for _, label, _ in sets]
    return _table(head, rows, cls="contacts", num_from=1)


def _contact_sockets(c: ContactFigures) -> str:
    """Per socket the mean and largest distance of its seatings from its centre, per known distance
    the spacing error: for the fitted placements in their sets, then for the held-out ones in theirs."""
    sets = _contact_sets(c)
    out = ""
    for group, those in (("fitted placements", [s for s in sets if not s[0].startswith("validation")]),
                         ("held-out placements", [s for s in sets if s[0].startswith("validation")])):
        if not those:
            continue
        first = those[0][2]
        rows = [f"<tr><td>{_e(s)}</td>" + "".join(
            _contact_cell((e.consistency.get(s) or (None, None))[i],
                          f"{key}.consistency.{s}.{'mean' if i == 0 else 'max'}")
            for key, _, e in those for i in (0, 1)) + "</tr>" for s in first.consistency]
        if rows:
            out += f"<h3>Socket consistency, {group}</h3>" + _table(
                ["socket"] + [f"{label}: {what}" for _, label, _ in those for what in ("mean", "max")], rows,
                cls="contacts", num_from=1)
        rows = [f"<tr><td>{_e(p)}</td>" + "".join(_contact_cell(e.distance.get(p), f"{key}.spacing.{p}")
                                                   for key, _, e in those) + "</tr>" for p in first.distance]
        if rows:
            out += f"<h3>Spacing error (calibrated minus known distance), {group}</h3>" + _table(
                ["placement: sockets"] + [label for _, label, _ in those], rows, cls="contacts", num_from=1)
    return out or "<p>No socket contacts.</p>"


def _contact_parameters(result: CalibrationResult) -> str:
    rows = [f'<tr id="{_anchor("param", p.name)}"><td>{_e(p.name)}</td>'
            f'<td class="num" data-key="param.{_e(p.name)}.change">{_e(with_unit(p.change, p.unit, sign=True))}</td>'
            f'<td class="num" data-key="param.{_e(p.name)}.std">{_e(with_unit(p.std, p.unit))}</td></tr>'
            for p in result.parameters]
    c = cast(ContactFigures, result.contacts)
    weak = "".join(f"<li>{_e(n)} (predicted std {_e(s)})</li>" for n, s in c.weak)
    said = ("kept: the placements predicted by the others are better with them, or as asked" if c.weak_kept
            else "held at their nominal values")
    return (_table(["parameter", "change from nominal", "std dev"], rows, num_from=1)
            + (f"<p>Weakly identifiable, {said}:</p><ul class=\"notes\">{weak}</ul>" if weak else ""))


def _contact_reach(c: ContactFigures) -> str:
    ident = c.identifiability
    rows = [f"<tr><td>{_e(kind)}</td><td class=\"wrap\">{_e(', '.join(names) or 'nothing alone')}</td></tr>"
            for kind, names in ident.contributions.items()]
    out = _table(["kind of contact", "identifies alone"], rows)
    if ident.together:
        out += f"<p>Only the kinds together: {_e(', '.join(ident.together))}.</p>"
    out += "".join(f'<p class="notice missing">Unreachable: {_e(u.name)} ({_e(", ".join(u.components))}): '
                   f"{_e(u.reason)}.</p>" for u in ident.unreachable)
    return out


def render_contact_report(result: CalibrationResult) -> str:
    """The HTML page of a calibration that fitted contacts (its ``contacts`` figures): the verdict
    and its checks (and its diagnosis), the kit's figures (socket consistency, spacing error, ...)
    fitted and held out, per socket and known distance, the tracker points fitted beside them, the
    parameters and what each kind of contact reaches. A self-contained page, no plots."""
    c = cast(ContactFigures, result.contacts)
    d: dict = {"checks": [{"name": k.name, "status": k.status, "summary": k.summary, "cause": k.cause, "fix": k.fix,
                           "items": list(k.items)} for k in result.checks],
               "verdict": result.verdict, "parameters": [{"name": p.name} for p in result.parameters]}
    if result.diagnosis is not None:
        d["diagnosis"] = diagnosis_to_dict(result.diagnosis)
    robot = result.nominal_model.name
    tracker, use = result.stats.fit_after, result.in_use
    points = ""
    if tracker.n:
        points += (f'<p>Tracker points fitted beside the contacts: <span data-key="tracker.rms">'
                   f'{_e(fmt(result.stats.fit_before.rms, "m"))} &rarr; {_e(fmt(tracker.rms, "m"))}</span> RMS '
                   f"over {tracker.n}.</p>")
    if result.stats.validation_after.n and use is not None:
        points += (f'<p>Measured points held out ({_e(use.method)}): mean error <span data-key="in_use.mean">'
                   f'{_e(fmt(use.position_before.mean, "m"))} &rarr; '
                   f'{_e(within_noise(use.position_after.rms, use.noise) or fmt(use.position_after.mean, "m"))}</span> '
                   f"over {use.position_after.n}, the instrument's noise taken out.</p>")
    sections = [("checks", "Verdict and checks", _checks_html(d)),
                ("figures", "What the kit shows", _contact_figures(c) + points),
                ("sockets", "Each socket and each known distance", _contact_sockets(c)),
                ("parameters", "Parameters", _contact_parameters(result)),
                ("reach", "What each kind of contact identifies", _contact_reach(c)),
                ("solver", "Solver", _kv([("converged", _e("yes" if result.solver.success else "no"), "success"),
                                          ("message", _e(result.solver.message), "message"),
                                          ("evaluations", _e(str(result.solver.nfev)), "nfev")]))]
    return _page(f"Calibration report: {_e(robot)} (contacts)", robot,
                 _meta(families_text(result), result.provenance, "identification from contacts"), sections)
