"""The calibration report: one self-contained HTML file drawn from a calibration result.

``render_report`` returns the HTML text of a ``CalibrationResult`` (computed, or read back from
result.json), ``write_report`` writes it atomically. Plots are matplotlib figures embedded as
inline SVG; the page needs no network and no JavaScript. Units are shown as ``units.DISPLAY_UNITS``
says.
"""

from __future__ import annotations

import html
import io
import math
import re
from datetime import datetime

from .._calibration import CalibrationResult
from .._errors import InputError, RobocalError
from .._files.result import result_to_dict
from .._files.text import write_texts
from .._parameters import FRAME_KINDS, GEOMETRIC_KINDS, parameter_layout, parameter_vector
from .units import UNITS_SENTENCE, absorption_text, display_unit as _display, finite as _num, fmt, symbol

# residual arrows drawn at most (large campaigns: an evenly spaced subset, so the report stays quick)
MAX_ARROWS = 500
PLOTS = ("errors-per-pose", "histograms", "correlation", "residuals")
STAT_SETS = (("fit_before", "fitted poses", "before"), ("fit_after", "fitted poses", "after"),
             ("validation_before", "held-out poses", "before"), ("validation_after", "held-out poses", "after"))
STAT_FIELDS = ("mean", "std", "rms", "max")
ALWAYS_SHOWN = GEOMETRIC_KINDS[2:]  # the paper's columns; gamma and b only for frames of a tree
WORST_POSES = 10
MISSING_VALIDATION = "No held-out poses were given: the errors shown are on the fitted poses only."
MISSING_LIMIT = ("No limit of absolute accuracy was given: run <code>robocal limit</code> on the model (repeatability, "
                 "encoder resolution, parameter round-off) and pass its value to the calibration "
                 "(<code>--limit-mm</code>, or <code>limit=</code> in Python) to judge the result against it.")
# colours: before orange, after blue, the limit dark red
BEFORE, AFTER, LIMIT, GRID = "#e0812f", "#2266b0", "#a3262a", "#d9dde3"
CORRELATED = 0.9  # |r| from which a pair is listed below the correlation map


# -- values and formatting -------------------------------------------------------------------------

def _ratio(v, spec: str) -> str:
    v = _num(v)
    return "–" if v is None else format(v, spec)


def _e(text) -> str:
    return html.escape(str(text), quote=True)


def _cell(value, unit, key, *, sign=False) -> str:
    return (f'<td class="num" data-key="{_e(key)}" data-unit="{_e(_display(unit)[0])}">'
            f"{fmt(value, unit, sign=sign)}</td>")


def _mm(v) -> float | None:
    v = _num(v)
    return None if v is None else v * 1e3


def _flat_mm(a) -> list[float]:
    """Finite entries of a nested list (metres) in mm, in order."""
    out = []

    def walk(x):
        if isinstance(x, (list, tuple)):
            for y in x:
                walk(y)
        else:
            v = _mm(x)
            if v is not None:
                out.append(v)
    walk(a if a is not None else [])
    return out


def _per_pose_mm(a) -> list[list[float]]:
    """(n_poses, n_markers) nested list in metres -> per pose, the finite errors in mm."""
    return [_flat_mm(row) for row in (a or [])]


def _worst_poses(d: dict, k: int = WORST_POSES) -> str:
    """The ``k`` measured points with the largest error after calibration, named by their pose labels."""
    err, prov = d["errors"], d.get("provenance") or {}
    markers = err.get("markers") or []
    rows = []
    for key, when, src in (("fit", "fitted", "data"), ("validation", "held-out", "validation")):
        before, after = err.get(f"{key}_before") or [], err.get(f"{key}_after") or []
        labels = (prov.get(src) or {}).get("labels") or []
        for i, (rb, ra) in enumerate(zip(before, after)):
            for m, (b, a) in enumerate(zip(rb, ra)):
                if a is not None and b is not None and math.isfinite(a) and math.isfinite(b):
                    name = labels[i] if i < len(labels) else f"pose {i}"
                    rows.append((a, b, name, when, markers[m] if m < len(markers) else str(m)))
    if not rows:
        return ""
    rows.sort(key=lambda r: -r[0])
    body = [f'<tr><td class="name" data-key="worst.{j}.pose">{_e(name)}</td><td>{when}</td><td>{_e(mk)}</td>'
            f'<td class="num" data-key="worst.{j}.before" data-unit="mm">{b * 1e3:.4f}</td>'
            f'<td class="num" data-key="worst.{j}.after" data-unit="mm">{a * 1e3:.4f}</td></tr>'
            for j, (a, b, name, when, mk) in enumerate(rows[:k])]
    return ("<h3>Largest errors after calibration</h3>"
            + _table(["pose", "poses", "marker", "before (mm)", "after (mm)"], body, num_from=3,
                     caption=f"The {min(k, len(rows))} measured points with the largest error after calibration, "
                             "by the pose labels of the input files."))


def _date(text) -> str:
    """An ISO date as '2026-01-31 14:05 UTC' (other text unchanged)."""
    try:
        t = datetime.fromisoformat(str(text))
    except ValueError:
        return str(text)
    zone = t.tzname() or ""
    return t.strftime("%Y-%m-%d %H:%M ") + ("UTC" if zone in ("UTC", "UTC+00:00") else zone)


# -- plots (pure functions of the result dict, SVG text) ---------------------------------------

def _matplotlib():
    try:
        import matplotlib  # lazy: the report is an optional extra
        from matplotlib.figure import Figure
    except ImportError:
        raise RobocalError("the report needs matplotlib: pip install robocal[report]") from None
    return matplotlib, Figure


def _style(name: str) -> dict:
    return {"svg.hashsalt": f"robocal-{name}", "svg.fonttype": "none", "font.family": "sans-serif",
            "font.sans-serif": ["DejaVu Sans", "Helvetica", "Arial"], "font.size": 9,
            "axes.edgecolor": "#8a9099", "axes.labelcolor": "#222", "axes.titlesize": 10,
            "axes.titleweight": "bold", "xtick.color": "#444", "ytick.color": "#444",
            "axes.grid": True, "grid.color": GRID, "grid.linewidth": 0.6, "axes.axisbelow": True,
            "legend.frameon": False, "legend.fontsize": 8}


def _svg(fig, name: str, label: str) -> str:
    """The figure as an inline <svg> tagged ``data-plot=name``, ids prefixed so plots never clash."""
    buf = io.StringIO()
    fig.savefig(buf, format="svg", metadata={"Date": None}, bbox_inches="tight", pad_inches=0.05)
    text = buf.getvalue()
    text = text[text.index("<svg"):]
    text = re.sub(r"\s*<metadata>.*?</metadata>", "", text, flags=re.S)
    text = re.sub(r'\s*<style type="text/css">.*?</style>', "", text, flags=re.S)  # global in HTML: moved to CSS
    text = text.replace(' id="', f' id="{name}-').replace('href="#', f'href="#{name}-')
    text = text.replace("url(#", f"url(#{name}-")
    return text.replace("<svg ", f'<svg data-plot="{name}" role="img" aria-label="{_e(label)}" ', 1)


def _plot(name: str, label: str, draw, *, figsize) -> str:
    matplotlib, Figure = _matplotlib()
    with matplotlib.rc_context(_style(name)):
        fig = Figure(figsize=figsize)
        draw(fig)
        return _svg(fig, name, label)


def _limit_mm(d: dict) -> float | None:
    return _mm((d.get("limit") or {}).get("limit_m"))


def plot_errors_per_pose(d: dict) -> str:
    """Position error per pose before and after, fitted poses then held-out ones (SVG)."""
    from matplotlib.ticker import FormatStrFormatter

    err = d["errors"]
    sets = [("fitted", _per_pose_mm(err.get("fit_before")), _per_pose_mm(err.get("fit_after")), "o"),
            ("held-out", _per_pose_mm(err.get("validation_before")), _per_pose_mm(err.get("validation_after")), "^")]
    lim = _limit_mm(d)

    def draw(fig):
        ax = fig.subplots()
        start = 1
        values = []
        for label, before, after, marker in sets:
            if not before:
                continue
            n = len(before)
            if label == "held-out":
                ax.axvspan(start - 0.5, start + n - 0.5, color="#eef1f5", zorder=0, lw=0)
                ax.text(start - 0.3, 1.0, "held-out poses", transform=ax.get_xaxis_transform(), va="bottom",
                        ha="left", fontsize=8, color="#555")
            links = [(start + i, vb, va) for i, (b, a) in enumerate(zip(before, after)) for vb, va in zip(b, a)]
            if links:  # one collection, not an artist per pose: large campaigns stay quick
                ax.vlines(*zip(*links), color="#c5cad1", lw=0.7, zorder=1)
            hollow = label == "held-out"
            for when, per_pose, colour in (("before", before, BEFORE), ("after", after, AFTER)):
                xs = [start + i for i, e in enumerate(per_pose) for _ in e]
                ys = [v for e in per_pose for v in e]
                ax.scatter(xs, ys, marker=marker, s=22, zorder=3, label=f"{when}, {label} poses", linewidths=1.1,
                           facecolors="white" if hollow else colour, edgecolors=colour)
                values += ys
            start += n
        if lim is not None:
            ax.axhline(lim, color=LIMIT, ls="--", lw=1.2, zorder=2,
                       label=f"limit of absolute accuracy\n({lim:.3f} mm)")
            values.append(lim)
        positive = [v for v in values if v > 0]
        if positive and max(positive) / min(positive) > 30:
            ax.set_yscale("log")
            ax.yaxis.set_major_formatter(FormatStrFormatter("%g"))
            ax.set_ylabel("position error (mm, log scale)")
        else:
            ax.set_ylim(bottom=0)
            ax.set_ylabel("position error (mm)")
        ax.set_xlim(0.5, max(start - 0.5, 1.5))
        ax.set_xlabel("pose")
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    return _plot("errors-per-pose", "position error per pose, before and after calibration", draw,
                 figsize=(9.0, 3.4))


def plot_histograms(d: dict) -> str:
    """Histograms of the position errors before and after, with the limit as a vertical line (SVG)."""
    err = d["errors"]
    lim = _limit_mm(d)

    def draw(fig):
        axes = fig.subplots(1, 2)
        for ax, when, colour in zip(axes, ("before", "after"), (BEFORE, AFTER)):
            fit = _flat_mm(err.get(f"fit_{when}"))
            val = _flat_mm(err.get(f"validation_{when}"))
            top = max(fit + val + ([lim] if lim is not None else []) + [1e-9])
            bins = [top * 1.02 * i / 16 for i in range(17)]
            data, colours, labels, hatches = [fit], [colour], ["fitted poses"], [None]
            if val:
                data.append(val)
                colours.append("white")
                labels.append("held-out poses")
                hatches.append("////")
            _, _, patches = ax.hist(data, bins=bins, stacked=True, color=colours, edgecolor=colour, lw=0.8,
                                    label=labels)
            for group, hatch in zip(patches if val else [patches], hatches):
                for p in group:
                    p.set_hatch(hatch)
            if lim is not None:
                ax.axvline(lim, color=LIMIT, ls="--", lw=1.2, label=f"limit ({lim:.3f} mm)")
            ax.set_xlim(0, bins[-1])
            ax.set_title(f"{when} calibration", color=colour)
            ax.set_xlabel("position error (mm)")
            ax.set_ylabel("number of measured points")
            ax.yaxis.get_major_locator().set_params(integer=True)
            ax.set_ylim(top=ax.get_ylim()[1] * 1.3)  # room for the legend
            ax.legend(loc="upper right", fontsize=7.5)
        fig.subplots_adjust(wspace=0.25)
    return _plot("histograms", "histograms of the position errors before and after calibration", draw,
                 figsize=(10.5, 3.4))


def plot_correlation(d: dict) -> str:
    """The correlation matrix of the identified parameters as a labelled heatmap (SVG)."""
    names = [p["name"] for p in d["parameters"]]
    corr = [[_num(v) if _num(v) is not None else float("nan") for v in row] for row in d["correlation"]]
    n = len(names)
    size = min(max(3.5, 0.2 * n + 1.6), 10.0)

    def draw(fig):
        ax = fig.subplots()
        im = ax.imshow(corr, cmap="RdBu_r", vmin=-1, vmax=1, interpolation="nearest")
        ax.set_xticks(range(n), names, rotation=90, fontsize=7)
        ax.set_yticks(range(n), names, fontsize=7)
        ax.grid(False)
        ax.set_xticks([i - 0.5 for i in range(1, n)], minor=True)
        ax.set_yticks([i - 0.5 for i in range(1, n)], minor=True)
        ax.grid(which="minor", color="white", lw=0.5)
        ax.tick_params(which="minor", length=0)
        cb = fig.colorbar(im, ax=ax, fraction=0.035, pad=0.02, shrink=0.8)
        cb.set_label("correlation coefficient")
    return _plot("correlation", "correlation map of the identified parameters", draw, figsize=(size + 0.9, size))


def _nice(x: float) -> float:
    """A round length (1, 2 or 5 times a power of ten) at most ``x`` > 0."""
    p = 10 ** math.floor(math.log10(x))
    return next(m * p for m in (5, 2, 1) if m * p <= x)


def _finite3(v) -> bool:
    return isinstance(v, (list, tuple)) and len(v) == 3 and all(_num(c) is not None for c in v)


def plot_residuals(d: dict) -> str:
    """Fit residual vectors (predicted - measured) on the XY, XZ and YZ planes, with a scale bar (SVG).

    With ``errors.fit_positions`` (measured points in metres, shaped like the residual vectors) the
    arrows start at the points, scaled up; without it they start at a common origin.
    """
    from matplotlib.ticker import MaxNLocator

    err = d["errors"]
    vec = [v for pose in (err.get("fit_residual_vectors") or []) for v in pose]
    pos = [p for pose in (err.get("fit_positions") or []) for p in pose]
    at_points = len(pos) == len(vec) > 0 and any(_finite3(p) for p in pos)
    keep = [k for k, v in enumerate(vec) if _finite3(v) and (not at_points or _finite3(pos[k]))]
    keep = keep[::-(-len(keep) // MAX_ARROWS)] if keep else keep  # an arrow costs ~5 ms: evenly spaced subset
    res = [[c * 1e3 for c in vec[k]] for k in keep]
    length = max((math.sqrt(sum(c * c for c in v)) for v in res), default=0.0) or 1e-3
    bar = _nice(length * 0.5)
    if at_points:
        pts = [[c * 1e3 for c in pos[k]] for k in keep]
        span = max(max(p[i] for p in pts) - min(p[i] for p in pts) for i in range(3)) or 1.0
        gain = _nice(0.08 * span / length)
    else:
        pts = [[0.0, 0.0, 0.0] for _ in res]
        gain = 1.0

    def draw(fig):
        axes = fig.subplots(1, 3)
        for ax, (a, b, i, j) in zip(axes, (("X", "Y", 0, 1), ("X", "Z", 0, 2), ("Y", "Z", 1, 2))):
            for p, v in zip(pts, res):
                ax.annotate("", xy=(p[i] + gain * v[i], p[j] + gain * v[j]), xytext=(p[i], p[j]),
                            arrowprops=dict(arrowstyle="-|>", color=AFTER, lw=0.8, mutation_scale=7,
                                            shrinkA=0, shrinkB=0))
            if at_points:
                ax.scatter([p[i] for p in pts], [p[j] for p in pts], s=6, color="#555", zorder=3)
                xs = [p[i] for p in pts] + [p[i] + gain * v[i] for p, v in zip(pts, res)]
                ys = [p[j] for p in pts] + [p[j] + gain * v[j] for p, v in zip(pts, res)]
                pad = 0.08 * max(max(xs) - min(xs), max(ys) - min(ys), 1e-9)
                ax.set_xlim(min(xs) - pad, max(xs) + pad)
                ax.set_ylim(min(ys) - pad, max(ys) + pad)
                ax.set_xlabel(f"{a} (mm)")
                ax.set_ylabel(f"{b} (mm)")
            else:
                r = 1.15 * length
                ax.set_xlim(-r, r)
                ax.set_ylim(-r, r)
                ax.axhline(0, color="#999", lw=0.6)
                ax.axvline(0, color="#999", lw=0.6)
                ax.set_xlabel(f"residual {a} (mm)")
                ax.set_ylabel(f"residual {b} (mm)")
            ax.set_aspect("equal", adjustable="box")
            ax.set_title(f"{a}{b} plane")
            for axis in (ax.xaxis, ax.yaxis):
                axis.set_major_locator(MaxNLocator(4, symmetric=not at_points))
            ax.tick_params(labelsize=8)
            # scale bar: ``bar`` mm of residual, drawn at the arrows' scale
            x0, x1 = ax.get_xlim()
            y0, y1 = ax.get_ylim()
            bx, by = x0 + 0.06 * (x1 - x0), y0 + 0.07 * (y1 - y0)
            ax.plot([bx, bx + gain * bar], [by, by], color="#222", lw=2.2, solid_capstyle="butt")
            ax.text(bx + gain * bar / 2, by + 0.025 * (y1 - y0), f"{bar:g} mm", ha="center", va="bottom",
                    fontsize=8)
        fig.subplots_adjust(wspace=0.35)
    return _plot("residuals", "fit residual vectors projected on the XY, XZ and YZ planes", draw,
                 figsize=(11.0, 4.0))


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


def _headline(d: dict) -> str:
    """Cards at the top: mean error before and after, the limit, the solver."""
    stats = d["stats"]
    on = "validation" if (stats.get("validation_after") or {}).get("n") else "fit"
    where = "held-out poses" if on == "validation" else "fitted poses"
    cards = []
    for when in ("before", "after"):
        s = stats.get(f"{on}_{when}") or {}
        cards.append(f'<div class="card {when}"><div class="label">Mean error {when}</div>'
                     f'<div class="value">{fmt(s.get("mean"))} <small>mm</small></div>'
                     f'<div class="sub">{where}, {_e(s.get("n", 0))} points; max {fmt(s.get("max"))} mm</div></div>')
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


def _stats_table(d: dict) -> str:
    rows = []
    for key, poses, when in STAT_SETS:
        s = d["stats"].get(key) or {}
        lead = f'<tr class="{when}"><td>{poses}</td><td><span class="tag {when}">{when}</span></td>'
        if not s.get("n"):
            rows.append(lead + f'<td class="num" data-key="stats.{key}.n">0</td>'
                        f'<td colspan="4" class="muted">not given</td></tr>')
            continue
        cells = "".join(_cell(s.get(f), "m", f"stats.{key}.{f}") for f in STAT_FIELDS)
        rows.append(lead + f'<td class="num" data-key="stats.{key}.n">{_e(s["n"])}</td>{cells}</tr>')
    return _table(["poses", "calibration", "points", "mean (mm)", "std (mm)", "RMS (mm)", "max (mm)"], rows,
                  cls="stats", num_from=2)


def _limit_text(d: dict) -> str:
    lim = d.get("limit")
    if not lim:
        return ""  # said at the top of the page
    compared = {"validation_after": "held-out poses", "fit_after": "fitted poses"}.get(lim.get("compared"),
                                                                                          lim.get("compared"))
    ok = bool(lim.get("reached"))
    return (f'<p class="notice {"good" if ok else "bad"}">Limit of absolute accuracy '
            f'<b data-key="limit.limit_m" data-unit="mm">{fmt(lim.get("limit_m"))}</b> mm; mean error after '
            f'calibration on the {_e(compared)} <b data-key="limit.mean_error_m" data-unit="mm">'
            f'{fmt(lim.get("mean_error_m"))}</b> mm, ratio <b data-key="limit.ratio">{_ratio(lim.get("ratio"), ".3f")}'
            f'</b>: the limit is <b data-key="limit.reached">{"reached" if ok else "not reached"}</b> '
            "(within 15 % of it counts as reached).</p>")


def _nominal_values(result: CalibrationResult) -> tuple[dict, dict]:
    """Nominal values (SI) and SI units of every parameter of the nominal model."""
    lay = parameter_layout(result.nominal_model)
    values = parameter_vector(result.nominal_model)
    return ({p.name: float(values[p.index]) for p in lay.parameters}, {p.name: p.unit for p in lay.parameters})


def _parameter_tables(d: dict, nominal: dict, units: dict) -> tuple[str, str, str]:
    """The per-frame table (the paper's layout), the base and marker table, a note on omitted columns."""
    est = {p["name"]: p for p in d["parameters"]}
    ident = d["identifiability"]
    status = {n: "-" for n in ident.get("candidates", [])}
    status.update({n: "I" for n in ident.get("identified", [])})
    status.update({a["name"]: "E" for a in ident.get("eliminated", [])})
    table = d.get("identifiability_table") or []
    frames = [row["frame"] for row in table]
    shown = [k for k in FRAME_KINDS if k in ALWAYS_SHOWN or any(row.get(k, "-") != "-" for row in table)]
    omitted = [k for k in FRAME_KINDS if k not in shown and k not in ("gamma", "b")]

    def value_cells(name, unit):
        """nominal, identified, change, std dev"""
        p = est.get(name)
        if p is not None:
            return [_cell(p["nominal"], unit, f"{name}:nominal"), _cell(p["estimate"], unit, f"{name}:estimate"),
                    _cell(p["change"], unit, f"{name}:change", sign=True), _cell(p["std"], unit, f"{name}:std")]
        st = status.get(name, "-")
        nom = nominal.get(name) if st != "-" else None
        held = '<td class="num muted">held</td>' if st == "E" else "<td></td>"
        return [f'<td class="num muted">{fmt(nom, unit) if nom is not None else ""}</td>', held,
                "<td></td>", "<td></td>"]

    def status_cell(name):
        st = status.get(name, "-")
        text = {"I": '<span class="badge si">I</span>', "E": '<span class="badge se">E</span>', "-": "–"}[st]
        return f'<td class="status" data-key="{_e(name)}:status">{text}</td>'

    body = []
    for f in frames:
        cols = [value_cells(f"{f}.{k}", units[f"{f}.{k}"]) for k in shown]
        body.append(f'<tr class="frame-start"><th rowspan="5" class="frame">{_e(f)}</th><td class="what">I / E</td>'
                    + "".join(status_cell(f"{f}.{k}") for k in shown) + "</tr>")
        for i, label in enumerate(("nominal", "identified", "change", "std dev")):
            body.append(f'<tr><td class="what">{label}</td>' + "".join(c[i] for c in cols) + "</tr>")
    head = ["frame", ""] + [f"{symbol(k)} <small>({_e(_display(units[f'{frames[0]}.{k}'])[0])})</small>"
                            if frames else symbol(k) for k in shown]
    note = ""
    if omitted:
        note = ("Columns " + ", ".join(symbol(k) for k in omitted)
                + " are not shown: those parameters were not among the candidates.")
    frame_table = _table(head, body, cls="params", num_from=2)

    other = [n for n in ident.get("candidates", []) if n.split(".", 1)[0] not in frames]
    other += [n for n in est if n not in other and n.split(".", 1)[0] not in frames]
    rows = []
    for n in other:
        unit = units.get(n, est[n]["unit"] if n in est else "")
        rows.append(f'<tr><td class="name">{_e(n)}</td><td>{_e(_display(unit)[0])}</td>'
                    + "".join(value_cells(n, unit)) + status_cell(n) + "</tr>")
    other_table = (_table(["parameter", "unit", "nominal", "identified", "change", "std dev", "I / E"], rows,
                          cls="params", num_from=2)
                   if rows else "<p>No base or marker parameters were considered.</p>")
    return frame_table, other_table, note


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


def _correlated_pairs(d: dict) -> str:
    names = [p["name"] for p in d["parameters"]]
    pairs = []
    for i, row in enumerate(d["correlation"]):
        for j in range(i + 1, len(row)):
            r = _num(row[j])
            if r is not None and abs(r) >= CORRELATED:
                pairs.append((-abs(r), names[i], names[j], r))
    if not pairs:
        return f"<p>No two identified parameters correlate beyond |r| = {CORRELATED}.</p>"
    rows = [f'<tr><td class="name">{_e(a)}</td><td class="name">{_e(b)}</td><td class="num">{r:+.3f}</td></tr>'
            for _, a, b, r in sorted(pairs)[:15]]
    more = f" ({len(pairs) - 15} more not listed)" if len(pairs) > 15 else ""
    return _table(["parameter", "parameter", "r"], rows, num_from=2,
                  caption=f"Pairs with |r| &ge; {CORRELATED}{more}")


def _solver_table(d: dict) -> str:
    ident = d.get("identifiability") or {}
    return _kv([
        ("success", "yes" if d.get("success") else "no", "solver.success"),
        ("status", _e(d.get("status")), "solver.status"),
        ("message", _e(d.get("message")), "solver.message"),
        ("function evaluations", _e(d.get("nfev")), "solver.nfev"),
        ("&sigma;<sub>0</sub>, residual standard deviation (mm)", fmt(d.get("sigma0_m")), "solver.sigma0_m", "mm"),
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
    tables = []
    for key, value in extra.items():
        items = value if isinstance(value, list) else [value]
        if items and all(isinstance(t, dict) and "rows" in t for t in items):
            for t in items:
                cols, rows = list(t.get("columns") or []), t["rows"]
                if not all(isinstance(r, (list, tuple)) and len(r) == len(cols) for r in rows):
                    raise InputError(f"each row of table {t.get('title', key)!r} needs {len(cols)} cells",
                                     where=f"extra[{key!r}]")
                tables.append({"title": str(t.get("title", key)), "columns": cols, "rows": rows,
                               "note": t.get("note", "")})
        elif items and all(isinstance(r, dict) for r in items):
            cols = list(dict.fromkeys(k for r in items for k in r))
            tables.append({"title": str(key), "columns": cols, "note": "",
                           "rows": [[r.get(c, "") for c in cols] for r in items]})
        else:
            raise InputError("expected a table {'title', 'columns', 'rows'}, a list of them, or a list of records",
                             where=f"extra[{key!r}]")
    return tables


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
.tag.before{background:var(--before)}.tag.after{background:var(--after)}
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
footer{margin-top:36px;padding-top:8px;border-top:1px solid var(--line);font-size:12px;color:var(--muted)}
@media print{body{background:#fff}main{padding:0}figure,table{break-inside:avoid}}
@media (max-width:800px){.cards{grid-template-columns:1fr 1fr}nav ol{columns:1}}
""" % {"before": BEFORE, "after": AFTER, "limit": LIMIT}


def render_report(result: CalibrationResult, *, extra: dict | None = None) -> str:
    """The HTML text of the report of ``result`` (a CalibrationResult, computed or read back).

    ``extra``: optional tables for a comparison section (see ``_extra_tables``).
    Raises RobocalError when matplotlib is missing, InputError when ``result`` is not a result.
    """
    if not isinstance(result, CalibrationResult):
        raise InputError(f"expected a CalibrationResult, got {type(result).__name__}", where="result")
    d = result_to_dict(result)
    nominal, units = _nominal_values(result)
    tables = _extra_tables(extra)
    _matplotlib()  # fail early and clearly without the extra
    robot = (d.get("nominal_model") or {}).get("name", "robot")
    has_val = bool((d["stats"].get("validation_after") or {}).get("n"))
    prov = d.get("provenance") or {}
    lim = d.get("limit")

    notices = [] if has_val else [_notice(MISSING_VALIDATION)]
    if not lim:
        notices.append(_notice(MISSING_LIMIT))
    if not d.get("success"):
        notices.append(_notice(f"The solver did not converge: {_e(d.get('message'))}", "bad"))

    sections = [("errors", "Position errors", _stats_table(d) + _limit_text(d) + _figure(
        plot_errors_per_pose(d),
        "Position error of each measured point before (orange) and after (blue) calibration. Filled circles: "
        "fitted poses; open triangles on grey: held-out poses" + ("" if has_val else " (none given)")
        + ". Dashed line: the limit of absolute accuracy" + ("" if lim else " (not given)") + ".")
        + _figure(plot_histograms(d), "Distribution of the position errors. Solid bars: fitted poses; hatched: "
                  "held-out poses." + (" Dashed line: the limit of absolute accuracy." if lim else ""))
        + _worst_poses(d))]
    frame_table, other_table, note = _parameter_tables(d, nominal, units)
    sections.append(("parameters", "Parameters",
                     "<p>Per frame, in the paper's layout: I identified, E eliminated (held at its nominal value, "
                     "its effect carried by identified parameters), &ndash; not a candidate. "
                     f"{_e(UNITS_SENTENCE).capitalize()}; std dev is the standard deviation of the estimate.</p>" + frame_table + (f'<p class="muted">{note}</p>' if note else "")
                     + "<h3>Base and marker parameters</h3>" + other_table))
    sections.append(("identifiability", "Eliminated parameters and what absorbs them",
                     "<p>An eliminated parameter cannot be told apart from a combination of identified ones: a "
                     "change in it moves the tool exactly as the combination shown does.</p>" + _eliminated_table(d, units)))
    sections.append(("correlation", "Correlation of the identified parameters",
                     _figure(plot_correlation(d), "Correlation coefficients from the covariance of the estimates "
                             "(red positive, blue negative).") + _correlated_pairs(d)))
    at_points = any(_finite3(p) for pose in (d["errors"].get("fit_positions") or []) for p in pose)
    sections.append(("residuals", "Residual vectors after calibration", _figure(
        plot_residuals(d), "Fit residuals (predicted minus measured) of the fitted poses, projected on three planes. "
        + ("Arrows start at the measured points and are scaled up; the bar gives their scale." if at_points else
           "The measured positions are not stored in the result, so every arrow starts at a common origin; "
           "the bar gives the scale."))))
    if tables:
        sections.append(("comparison", "Comparison", _extra_html(tables)))
    sections.append(("solver", "Solver and identifiability", _solver_table(d)))
    notes = d.get("notes") or []
    sections.append(("notes", "Notes", '<ul class="notes">' + "".join(f"<li>{_e(n)}</li>" for n in notes) + "</ul>"
                     if notes else "<p>The calibration left no notes.</p>"))
    sections.append(("provenance", "Provenance", _provenance(d)))

    toc = "".join(f'<li><a href="#{i}">{t}</a></li>' for i, t, _ in sections)
    body = "".join(f'<section id="{i}"><h2>{t}</h2>{b}</section>\n' for i, t, b in sections)
    meta = [", ".join(d.get("families") or []) + " identification", _date(prov.get("date", "date not recorded")),
            f'{prov.get("software", "")} {prov.get("version", "")}'.strip()]
    return ('<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
            '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
            f'<link rel="icon" href="data:,">\n<title>Calibration report: {_e(robot)}</title>\n'
            f"<style>{_CSS}</style>\n</head>\n<body>\n<main>\n"
            f'<header><h1>Calibration report &ndash; <span class="robot">{_e(robot)}</span></h1>'
            f'<p class="meta">{" &middot; ".join(_e(m) for m in meta if m)}</p></header>\n'
            f"{_headline(d)}{''.join(notices)}<nav><ol>{toc}</ol></nav>\n{body}"
            f"<footer>{_e(UNITS_SENTENCE).capitalize()}; the result file keeps SI "
            "units. A self-contained page: no scripts, no network.</footer>\n</main>\n</body>\n</html>\n")


def write_report(result: CalibrationResult, path, *, force: bool = False, extra: dict | None = None) -> None:
    """Write the HTML report of ``result`` to ``path`` atomically (temporary file, then rename).

    An existing ``path`` is an InputError unless ``force``. See ``render_report``.
    """
    write_texts({path: render_report(result, extra=extra)}, force=force)
