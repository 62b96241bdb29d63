"""The report's plots: matplotlib figures as inline SVG text, pure functions of the result dict.

Plots scale with the campaign: beyond ``DENSE`` poses the error per pose is drawn as binned
summaries of consecutive poses rather than one mark per point, residual vectors are a
representative subsample of at most ``VECTORS`` arrows, and the residual trends are binned
medians with their interquartile band. Matplotlib is imported here only, on first use.
"""

from __future__ import annotations

import html
import io
import math
import re

import numpy as np

from .._base.errors import RobocalError
from .units import DEG, MM

PLOTS = ("errors-per-pose", "histograms", "correlation", "residuals", "residual-trends")
# colours: before orange, after blue, the limit dark red
BEFORE, AFTER, LIMIT, GRID = "#e0812f", "#2266b0", "#a3262a", "#d9dde3"
DENSE = 600      # poses beyond which the error per pose is summarised in bins
VECTORS = 300    # residual arrows drawn at most
TREND_BINS = 16  # bins of a trend (equal counts of points)
TREND_POINTS = 200_000  # measured points a trend is taken over at most (whole poses, evenly spaced)


# -- the figure machinery ------------------------------------------------------------------------

def need_matplotlib():
    """(matplotlib, Figure), or a RobocalError saying how to install the extra."""
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
            "legend.frameon": False, "legend.fontsize": 8, "path.simplify": True}


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
    return text.replace("<svg ", f'<svg data-plot="{name}" role="img" aria-label="{html.escape(label)}" ', 1)


def _plot(name: str, label: str, draw, *, figsize) -> str:
    matplotlib, Figure = need_matplotlib()
    with matplotlib.rc_context(_style(name)):
        fig = Figure(figsize=figsize)
        draw(fig)
        return _svg(fig, name, label)


def plot_svg(name: str, label: str, draw, *, figsize) -> str:
    """A figure drawn by ``draw(fig)`` in the report's style, as inline SVG (for the other pages)."""
    return _plot(name, label, draw, figsize=figsize)


# -- the data, as arrays --------------------------------------------------------------------------

def errors_array(d: dict, key: str) -> np.ndarray | None:
    """``errors[key]`` of the result dict as a float array (null entries NaN), None when absent."""
    v = (d.get("errors") or {}).get(key)
    if v is None or len(v) == 0:
        return None
    return np.asarray(v, dtype=float)


def _limit_mm(d: dict) -> float | None:
    v = (d.get("limit") or {}).get("limit_m")
    return None if v is None or not math.isfinite(v) else v * MM


def _finite(a: np.ndarray | None) -> np.ndarray:
    return np.zeros(0) if a is None else a[np.isfinite(a)]


# -- errors per pose and their distribution ---------------------------------------------------------

def _per_pose(ax, start: int, before: np.ndarray, after: np.ndarray, label: str, marker: str) -> list:
    """One mark per measured point, before and after, joined by a grey line; returns the values."""
    n, m = before.shape
    x = np.repeat(np.arange(start, start + n), m)
    b, a = before.ravel(), after.ravel()
    ok = np.isfinite(b) & np.isfinite(a)
    ax.vlines(x[ok], b[ok], a[ok], color="#c5cad1", lw=0.7, zorder=1)
    hollow = label == "held-out"
    for when, v, colour in (("before", b, BEFORE), ("after", a, AFTER)):
        keep = np.isfinite(v)
        ax.scatter(x[keep], v[keep], marker=marker, s=22, zorder=3, label=f"{when}, {label} poses", linewidths=1.1,
                   facecolors="white" if hollow else colour, edgecolors=colour)
    return [b[ok], a[ok]]


def _binned(ax, start: int, before: np.ndarray, after: np.ndarray, label: str, width: int) -> list:
    """Median and 5-95 % band of the points in bins of ``width`` consecutive poses; returns the values."""
    n = len(before)
    edges = list(range(0, n, width)) + [n]
    for when, v, colour in (("before", before, BEFORE), ("after", after, AFTER)):
        centre, lo, mid, hi = [], [], [], []
        for i, j in zip(edges[:-1], edges[1:]):
            vals = _finite(v[i:j])
            if vals.size:
                centre.append(start + (i + j - 1) / 2)
                q = np.percentile(vals, [5, 50, 95])
                lo.append(q[0])
                mid.append(q[1])
                hi.append(q[2])
        ax.fill_between(centre, lo, hi, color=colour, alpha=0.22 if label == "fitted" else 0.12, lw=0, zorder=1)
        ax.plot(centre, mid, color=colour, lw=1.3, ls="-" if label == "fitted" else "--", zorder=3,
                label=f"{when}, {label} poses: median and 5-95 %")
    return [_finite(before), _finite(after)]


def _error_sets(d: dict, part: str, k: float) -> list:
    """(label, before, after, marker) of fitted then held-out poses, errors in display units."""
    sets = [(label, errors_array(d, f"{key}_{part}before"), errors_array(d, f"{key}_{part}after"), marker)
            for label, key, marker in (("fitted", "fit", "o"), ("held-out", "validation", "^"))]
    return [(label, b * k, a * k, mk) for label, b, a, mk in sets if b is not None and a is not None]


def _errors_panel(ax, sets: list, total: int, width: int, what: str, unit: str, lim: float | None) -> None:
    """One quantity's errors per pose (or per bin of poses) on ``ax``, with the limit when given."""
    from matplotlib.ticker import FormatStrFormatter

    start, values = 1, []
    for label, before, after, marker in sets:
        n = len(before)
        if label == "held-out":
            ax.axvspan(start - 0.5, start + n - 0.5, color="#eef1f5", zorder=0, lw=0)
            ax.text(start - 0.3, 1.0, "held-out poses", transform=ax.get_xaxis_transform(), va="bottom",
                    ha="left", fontsize=8, color="#555")
        if total > DENSE:
            values += _binned(ax, start, before, after, label, width)
        else:
            values += _per_pose(ax, start, before, after, label, marker)
        start += n
    if lim is not None:
        ax.axhline(lim, color=LIMIT, ls="--", lw=1.2, zorder=2, label=f"limit of absolute accuracy\n({lim:.3f} mm)")
        values.append(np.array([lim]))
    v = np.concatenate(values) if values else np.zeros(0)
    v = v[v > 0]
    if v.size and v.max() / v.min() > 30:
        ax.set_yscale("log")
        ax.yaxis.set_major_formatter(FormatStrFormatter("%g"))
        ax.set_ylabel(f"{what} error ({unit}, log scale)")
    else:
        ax.set_ylim(bottom=0)
        ax.set_ylabel(f"{what} error ({unit})")
    ax.set_xlim(0.5, max(start - 0.5, 1.5))
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)


def plot_errors_per_pose(d: dict) -> str:
    """Position error per pose before and after, fitted poses then held-out ones, and the rotation
    error below it for 6D data (SVG); binned summaries of consecutive poses beyond ``DENSE`` poses."""
    panels = [("position", "mm", _error_sets(d, "", MM), _limit_mm(d))]
    if errors_array(d, "fit_rotation_after") is not None:
        panels.append(("rotation", "deg", _error_sets(d, "rotation_", DEG), None))
    total = sum(len(b) for _, b, _, _ in panels[0][2])
    width = max(1, math.ceil(total / 150))

    def draw(fig):
        axes = fig.subplots(len(panels), 1, squeeze=False)[:, 0]
        for ax, (what, unit, sets, lim) in zip(axes, panels):
            _errors_panel(ax, sets, total, width, what, unit, lim)
        axes[-1].set_xlabel("pose" if total <= DENSE else f"pose (bins of {width} consecutive poses)")
        fig.subplots_adjust(hspace=0.3)
    return _plot("errors-per-pose", "position (and rotation) error per pose, before and after calibration", draw,
                 figsize=(9.0, 3.4 * len(panels)))


def histogram_panels(d: dict) -> list[dict]:
    """What the histograms draw, one dict per panel: {"what", "when", "unit", "fit", "validation"
    (errors in display units), "limit" (display units, or None), "top"}: the x axis ends at ``top``,
    the panel's own largest error (after calibration the errors are far smaller than before), or at
    the limit when that lies within three times the largest error; a farther limit is only named."""
    lim = _limit_mm(d)
    kinds = [("position", "", MM, "mm", lim)]
    if errors_array(d, "fit_rotation_after") is not None:
        kinds.append(("rotation", "rotation_", DEG, "deg", None))
    panels = []
    for what, part, k, unit, line in kinds:
        for when in ("before", "after"):
            fit, val = (_finite(errors_array(d, f"{s}_{part}{when}")) * k for s in ("fit", "validation"))
            top = max([float(v.max()) for v in (fit, val) if v.size] + [1e-9])
            if line is not None and line <= 3 * top:
                top = max(top, line)
            panels.append({"what": what, "when": when, "unit": unit, "fit": fit, "validation": val, "limit": line,
                           "top": top})
    return panels


def _hist(ax, p: dict, colour: str) -> None:
    fit, val, top, lim, unit = p["fit"], p["validation"], p["top"], p["limit"], p["unit"]
    bins = np.linspace(0, top * 1.02, 25)
    data, colours, labels = [fit], [colour], ["fitted poses"]
    if val.size:
        data, colours, labels = [fit, val], [colour, "white"], ["fitted poses", "held-out poses"]
    _, _, patches = ax.hist(data, bins=bins, stacked=True, color=colours, edgecolor=colour, lw=0.8, label=labels)
    if val.size:
        for patch in patches[1]:
            patch.set_hatch("////")
    if lim is not None and lim > bins[-1]:
        ax.plot([], [], color=LIMIT, ls="--", lw=1.2, label=f"limit ({lim:.3f} {unit}), beyond the axis")
    elif lim is not None:
        ax.axvline(lim, color=LIMIT, ls="--", lw=1.2, label=f"limit ({lim:.3f} {unit})")
    ax.set_xlim(0, bins[-1])
    ax.set_ylabel("number of measured points")
    ax.yaxis.get_major_locator().set_params(integer=True)
    ax.set_ylim(top=ax.get_ylim()[1] * 1.4)  # room for the legend
    ax.legend(loc="upper right")


def plot_histograms(d: dict) -> str:
    """Histograms of the position errors before and after, each on its own axis, with the limit as a
    vertical line, and of the rotation errors below them when the data hold orientations (SVG)."""
    panels = histogram_panels(d)
    rows = len(panels) // 2

    def draw(fig):
        axes = np.atleast_2d(fig.subplots(rows, 2)).ravel()
        for ax, p in zip(axes, panels):
            colour = BEFORE if p["when"] == "before" else AFTER
            _hist(ax, p, colour)
            ax.set_title(f"{p['what']} errors {p['when']} calibration", color=colour)
            ax.set_xlabel(f"{p['what']} error ({p['unit']})")
        fig.subplots_adjust(wspace=0.3, hspace=0.6)
    return _plot("histograms", "histograms of the position (and rotation) errors before and after calibration",
                 draw, figsize=(10.5, 3.6 * rows))


# -- correlation ------------------------------------------------------------------------------------

BLOCK = 24        # parameters in one correlation block at most (labels stay 8 pt)
WHOLE_MAP = 30    # up to this many parameters the correlation map is drawn whole


def correlation_blocks(d: dict) -> list[tuple[str, list[int]]]:
    """The blocks the correlation map is drawn in: (title, parameter indices). One block of every
    parameter up to ``WHOLE_MAP`` of them; beyond, each family (base, markers, frames, compliance,
    backlash) in blocks of at most ``BLOCK`` consecutive parameters, small families sharing one."""
    params = d["parameters"]
    n = len(params)
    if n <= WHOLE_MAP:
        return [("all identified parameters", list(range(n)))]
    by_family: dict[str, list[int]] = {}
    for i, p in enumerate(params):
        by_family.setdefault(p.get("family") or "other", []).append(i)
    blocks: list[tuple[str, list[int]]] = []
    small: list[tuple[str, list[int]]] = []
    for family, idx in by_family.items():
        if len(idx) <= BLOCK // 2:
            small.append((family, idx))
            continue
        parts = math.ceil(len(idx) / BLOCK)
        size = math.ceil(len(idx) / parts)
        for k in range(parts):
            blocks.append((family + (f" ({k + 1} of {parts})" if parts > 1 else ""), idx[k * size:(k + 1) * size]))
    while small:  # families of a few parameters share a block
        title, idx = small.pop(0)
        while small and len(idx) + len(small[0][1]) <= BLOCK:
            t, more = small.pop(0)
            title, idx = f"{title} and {t}", idx + more
        blocks.append((title, idx))
    return blocks


CELL, CORR_FONT, COLOURBAR = 13, 10, 70  # correlation cell and label size (CSS px), colour bar width


def _rdbu(r: float, cmap) -> str:
    """The colour of a correlation coefficient ``r`` (red positive, blue negative)."""
    if not math.isfinite(r):
        return "#ffffff"
    red, green, blue, _ = cmap(0.5 + 0.5 * max(-1.0, min(1.0, r)))
    return f"#{round(red * 255):02x}{round(green * 255):02x}{round(blue * 255):02x}"


def _text_width(text: str, size: float) -> float:
    """A generous width of ``text`` at font ``size`` (DejaVu Sans averages under 0.62 em a character)."""
    return 0.62 * size * len(text)


def plot_correlation(d: dict) -> str:
    """The correlation matrix of the identified parameters as heatmaps, every label in full at 10 px
    (SVG, written directly: matplotlib takes seconds over a hundred labels): whole up to ``WHOLE_MAP``
    parameters, else one block per family (``correlation_blocks``), two blocks side by side; the
    pairs across blocks are in the strongest-pairs table beside it."""
    matplotlib, _ = need_matplotlib()
    cmap = matplotlib.colormaps["RdBu_r"]
    names = [p["name"] for p in d["parameters"]]
    n = len(names)
    corr = np.asarray([[np.nan if v is None else v for v in row] for row in d["correlation"]],
                      dtype=float).reshape(n, n)
    blocks = correlation_blocks(d)
    label = max([_text_width(nm, CORR_FONT) for nm in names] + [20.0]) + 6
    sizes = [(label + len(idx) * CELL, 22 * (len(blocks) > 1) + len(idx) * CELL + label) for _, idx in blocks]
    cols = 1 if len(blocks) == 1 else 2
    col_w = max(w for w, _ in sizes) + 24
    row_h = [max(h for _, h in sizes[i:i + cols]) + 18 for i in range(0, len(blocks), cols)]
    width, height = cols * col_w + COLOURBAR, sum(row_h)
    out = [f'<svg data-plot="correlation" role="img" aria-label="correlation map of the identified parameters" '
           f'xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {width:.0f} {height:.0f}" width="{width:.0f}" '
           f'height="{height:.0f}" font-family="DejaVu Sans, Helvetica, Arial, sans-serif" font-size="{CORR_FONT}" '
           'fill="#222">']
    for b, (title, idx) in enumerate(blocks):
        x0 = (b % cols) * col_w + label
        y0 = sum(row_h[:b // cols]) + (22 if len(blocks) > 1 else 4)
        k = len(idx)
        if len(blocks) > 1:
            out.append(f'<text x="{x0 + k * CELL / 2:.1f}" y="{y0 - 8}" text-anchor="middle" font-size="11" '
                       f'font-weight="bold">{html.escape(title)}</text>')
        for a, i in enumerate(idx):
            out.append(f'<text x="{x0 - 4}" y="{y0 + a * CELL + CELL - 3}" text-anchor="end">'
                       f"{html.escape(names[i])}</text>")
            cx = x0 + a * CELL + CELL / 2 + 3.5
            out.append(f'<text transform="translate({cx:.1f} {y0 + k * CELL + 4}) rotate(-90)" text-anchor="end">'
                       f"{html.escape(names[i])}</text>")
            cells = "".join(f'<rect x="{x0 + c * CELL}" y="{y0 + a * CELL}" width="{CELL - 1}" height="{CELL - 1}" '
                            f'fill="{_rdbu(corr[i, j], cmap)}"/>' for c, j in enumerate(idx))
            out.append(cells)
    # the colour bar
    bx, by, bh = cols * col_w + 8, 24, min(240, height - 48)
    steps = 24
    out += [f'<rect x="{bx}" y="{by + bh * s_ / steps:.1f}" width="14" height="{bh / steps + 0.5:.1f}" '
            f'fill="{_rdbu(1 - 2 * (s_ + 0.5) / steps, cmap)}"/>' for s_ in range(steps)]
    out += [f'<text x="{bx + 18}" y="{by + bh * (1 - v) / 2 + 3.5:.1f}">{f"{v:+g}" if v else "0"}</text>'
            for v in (1, 0.5, 0, -0.5, -1)]
    out.append(f'<text x="{bx}" y="{by - 10}" font-size="10">r</text>')
    return "".join(out) + "</svg>"


# -- residual vectors -------------------------------------------------------------------------------

def _nice(x: float) -> float:
    """A round length (1, 2 or 5 times a power of ten) at most ``x`` > 0."""
    p = 10 ** math.floor(math.log10(x))
    return next(m * p for m in (5, 2, 1) if m * p <= x)


def residual_sample(d: dict) -> tuple[np.ndarray, np.ndarray | None, int]:
    """(vectors (k, 3) mm, their measured points (k, 3) mm or None, number of finite vectors): at most
    ``VECTORS`` fit residual vectors, evenly spaced through the campaign."""
    vec = errors_array(d, "fit_residual_vectors")
    if vec is None:
        return np.zeros((0, 3)), None, 0
    vec = vec.reshape(-1, 3) * MM
    pos = errors_array(d, "fit_positions")
    pos = pos.reshape(-1, 3) * MM if pos is not None and pos.size == vec.size else None
    ok = np.isfinite(vec).all(axis=1) & (np.isfinite(pos).all(axis=1) if pos is not None else True)
    idx = np.nonzero(ok)[0]
    n = len(idx)
    if n > VECTORS:
        idx = idx[np.linspace(0, n - 1, VECTORS).round().astype(int)]
    return vec[idx], None if pos is None or not n else pos[idx], n


def plot_residuals(d: dict) -> str:
    """Fit residual vectors (calibrated minus measured) on the XY, XZ and YZ planes, with a scale bar
    (SVG). With the measured points stored the arrows start at them, scaled up; otherwise at a
    common origin. At most ``VECTORS`` arrows, evenly spaced through the campaign."""
    res, pts, _ = residual_sample(d)
    # arrows scaled to the typical residual, not the largest: one outlier must not shrink them all
    length = float(np.percentile(np.linalg.norm(res, axis=1), 90)) if len(res) else 0.0
    length = length or 1e-3
    bar = _nice(length * 0.5)
    at_points = pts is not None
    if pts is not None:
        span = float((pts.max(axis=0) - pts.min(axis=0)).max()) or 1.0
        gain = _nice(0.08 * span / length)
    else:
        pts, gain = np.zeros_like(res), 1.0

    def draw(fig):
        axes = fig.subplots(1, 3)
        for ax, (a, b, i, j) in zip(axes, (("X", "Y", 0, 1), ("X", "Z", 0, 2), ("Y", "Z", 1, 2))):
            ax.quiver(pts[:, i], pts[:, j], gain * res[:, i], gain * res[:, j], angles="xy", scale_units="xy",
                      scale=1, color=AFTER, width=0.005, headwidth=3, headlength=3.5, headaxislength=3, zorder=2)
            if at_points:
                ax.scatter(pts[:, i], pts[:, j], s=4, color="#555", zorder=3, lw=0)
                xs = np.concatenate([pts[:, i], pts[:, i] + gain * res[:, i]])
                ys = np.concatenate([pts[:, j], pts[:, j] + gain * res[:, j]])
                pad = 0.08 * max(np.ptp(xs) if xs.size else 0, np.ptp(ys) if ys.size else 0, 1e-9)
                ax.set_xlim(xs.min() - pad if xs.size else -1, xs.max() + pad if xs.size else 1)
                ax.set_ylim(ys.min() - pad if ys.size else -1, ys.max() + pad if ys.size else 1)
                ax.set_xlabel(f"{a} (mm)")
                ax.set_ylabel(f"{b} (mm)")
            else:
                r = 1.15 * (float(np.linalg.norm(res, axis=1).max()) if len(res) else length)
                ax.set_xlim(-r, r)
                ax.set_ylim(-r, r)
                ax.axhline(0, color="#999", lw=0.6)
                ax.axvline(0, color="#999", lw=0.6)
                ax.set_xlabel(f"residual {a} (mm)")
                ax.set_ylabel(f"residual {b} (mm)")
            _scale_bar(ax, a + b, gain, bar, at_points)
        fig.subplots_adjust(wspace=0.35)
    return _plot("residuals", "fit residual vectors projected on the XY, XZ and YZ planes", draw,
                 figsize=(11.0, 4.0))


def _scale_bar(ax, plane: str, gain: float, bar: float, at_points: bool) -> None:
    from matplotlib.ticker import MaxNLocator

    ax.set_aspect("equal", adjustable="box")
    ax.set_title(f"{plane} plane")
    for axis in (ax.xaxis, ax.yaxis):
        axis.set_major_locator(MaxNLocator(4, symmetric=not at_points))
    ax.tick_params(labelsize=8)
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    bx, by = x0 + 0.06 * (x1 - x0), y0 + 0.07 * (y1 - y0)
    ax.plot([bx, bx + gain * bar], [by, by], color="#222", lw=2.2, solid_capstyle="butt")
    ax.text(bx, by + 0.025 * (y1 - y0), f"{bar:g} mm", ha="left", va="bottom", fontsize=8)


# -- residuals against where the robot was -------------------------------------------------------

def _stacked(d: dict, key: str) -> np.ndarray | None:
    """Fitted then held-out poses of ``errors.fit_<key>`` and ``errors.validation_<key>``."""
    fit, held_out = (errors_array(d, f"{s}_{key}") for s in ("fit", "validation"))
    if fit is None:
        return None
    return fit if held_out is None else np.concatenate([fit, held_out])


def binned_median(x: np.ndarray, y: np.ndarray, bins: int = TREND_BINS, *, order: np.ndarray | None = None) -> dict:
    """The trend of ``y`` against ``x``: median and quartiles of ``y`` in bins of equal counts of points.

    ``order``: ``np.argsort(x, kind="stable")`` when at hand (several ``y`` against one ``x``); it
    is used only where every ``x`` and ``y`` is finite. Returns {"x": bin centres (median x),
    "median", "q25", "q75", "n": points per bin} as arrays (empty without data).
    """
    ok = np.isfinite(x) & np.isfinite(y)
    if order is None or not ok.all():
        x, y = x[ok], y[ok]
        order = None
    bins = min(bins, len(x) // 8)
    if bins < 2:
        return {k: np.zeros(0) for k in ("x", "median", "q25", "q75", "n")}
    order = np.argsort(x, kind="stable") if order is None else order
    groups = np.array_split(order, bins)
    return {"x": np.array([np.median(x[g]) for g in groups]),
            "median": np.array([np.median(y[g]) for g in groups]),
            "q25": np.array([np.percentile(y[g], 25) for g in groups]),
            "q75": np.array([np.percentile(y[g], 75) for g in groups]),
            "n": np.array([len(g) for g in groups])}


STRUCTURE = 6.0  # a trend shows structure when its medians spread this many standard errors


def structure(t: dict) -> float:
    """How far a trend's bin medians spread, in standard errors of a bin median: the range of the
    medians over the typical standard error (1.2533 sigma / sqrt(n), sigma from the interquartile
    range). About 3 for noise over 16 bins; 0 without data."""
    if len(t["median"]) < 2:
        return 0.0
    sigma = (t["q75"] - t["q25"]) / 1.349
    se = float(np.median(1.2533 * sigma / np.sqrt(t["n"])))
    spread = float(np.ptp(t["median"]))
    return spread / se if se > 0 else (math.inf if spread > 0 else 0.0)


def residual_trends(d: dict, joint_names, joint_units, X_WB) -> dict | None:
    """What the trend plot draws: residual components after calibration against reach, height and
    each joint's reading, fitted and held-out poses together.

    ``joint_names``/``joint_units`` (SI unit per reading), ``X_WB`` (4x4, m: the calibrated base
    in the measurement frame). Reach is the distance of the measured point from the base's z axis,
    height its height along that axis above the base origin. Returns {"rows": [(label, unit)],
    "columns": [(label, unit)], "points": n, "trends": {(row label, column label): binned_median(...)},
    "structured": column labels whose trend in some row spreads beyond ``STRUCTURE`` standard errors}
    or None when the result holds no measured points. Beyond ``TREND_POINTS`` points the trends are
    taken over that many, whole poses evenly spaced through the campaign (``points``; ``of``: all).
    """
    picked = _trend_points(d)
    if picked is None:
        return None
    vec, pos, q, rot, total = picked
    n, m = vec.shape[:2]
    xs = _abscissae(pos, q, X_WB, joint_names, joint_units)
    ys = [(f"d{c}", "mm", vec[..., i] * MM) for i, c in enumerate("xyz")]
    if rot is not None and rot.shape == (n, m):
        ys.append(("rotation error", "deg", rot * DEG))
    orders = {xlab: np.argsort(x.ravel(), kind="stable") for xlab, _, x in xs}   # one sort per abscissa
    trends = {(ylab, xlab): binned_median(x.ravel(), y.ravel(), order=orders[xlab]) for ylab, _, y in ys
              for xlab, _, x in xs}
    structured = [xlab for xlab, _, _ in xs if max(structure(trends[(ylab, xlab)]) for ylab, _, _ in ys) >= STRUCTURE]
    return {"rows": [(lab, u) for lab, u, _ in ys], "columns": [(lab, u) for lab, u, _ in xs], "points": n * m,
            "of": total, "trends": trends, "structured": structured}


def _trend_points(d: dict):
    """The residual vectors, measured positions, readings and rotation errors after calibration of
    the fitted and held-out poses together, and the number of points of all; beyond
    ``TREND_POINTS`` points, whole poses evenly spaced. None without residuals, positions and
    readings of the same poses."""
    vec, pos, q = _stacked(d, "residual_vectors"), _stacked(d, "positions"), _stacked(d, "readings")
    if vec is None or pos is None or q is None or pos.shape != vec.shape or len(q) != len(vec):
        return None
    rot = _stacked(d, "rotation_after")
    n, m = vec.shape[:2]
    if n * m > TREND_POINTS:    # evenly spaced poses: 12,500 points a bin still place its median well
        keep = np.unique(np.linspace(0, n - 1, max(TREND_POINTS // m, 1)).round().astype(int))
        vec, pos, q = vec[keep], pos[keep], q[keep]
        rot = rot[keep] if rot is not None and len(rot) == n else rot
    return vec, pos, q, rot, n * m


def _abscissae(pos: np.ndarray, q: np.ndarray, X_WB, joint_names, joint_units) -> list[tuple]:
    """(label, display unit, values (n, m)) of reach and height in the base frame, and of each
    joint's reading (the same for every marker of a pose)."""
    m = pos.shape[1]
    X_WB = np.asarray(X_WB, dtype=float)
    rel = (pos - X_WB[:3, 3]) @ X_WB[:3, :3]  # in the base frame
    xs = [("reach", "mm", np.hypot(rel[..., 0], rel[..., 1]) * MM), ("height", "mm", rel[..., 2] * MM)]
    for j, (name, unit) in enumerate(zip(joint_names, joint_units)):
        shown = "deg" if unit == "rad" else "mm"
        xs.append((f"{name} reading", shown, np.repeat(q[:, j:j + 1], m, axis=1) * (DEG if unit == "rad" else MM)))
    return xs


def _ticks(lo: float, hi: float, n: int = 3) -> list[float]:
    """About ``n`` round values within [lo, hi]."""
    step = _nice((hi - lo) / max(n - 1, 1)) if hi > lo else 1.0
    first = math.ceil(lo / step) * step
    return [first + k * step for k in range(int((hi - first) / step + 1e-9) + 1)]


def _span(values: list[np.ndarray]) -> tuple[float, float]:
    v = np.concatenate([x for x in values if x.size]) if any(x.size for x in values) else np.zeros(1)
    lo, hi = float(v.min()), float(v.max())
    pad = 0.06 * (hi - lo) or 1e-3
    return lo - pad, hi + pad


# panel size, gaps and margins of the trend grid (SVG user units, CSS pixels at the page's width)
PANEL_W, PANEL_H, GAP, LEFT, BOTTOM, TOP = 140, 92, 20, 66, 44, 24
TREND_COLUMNS = 6  # panels side by side; more columns go on to a further band below


def plot_residual_trends(trends: dict, columns: list | None = None) -> str:
    """Panels of each residual component (rows) against reach, height and each joint's reading
    (``columns``: the column labels to draw, default all), the binned median as a line over the
    interquartile band, in bands of at most ``TREND_COLUMNS`` columns one below the other, every
    panel its own axis labels (SVG, written directly: dozens of panels would take matplotlib seconds;
    laid out at the page's width so that no text is scaled below its size)."""
    rows, data = trends["rows"], trends["trends"]
    cols = [(c, u) for c, u in trends["columns"] if columns is None or c in columns]
    yspan = [_span([data[(r, c)][k] for c, _ in cols for k in ("q25", "q75", "median")] + [np.zeros(1)])
             for r, _ in rows]
    bands = [cols[i:i + TREND_COLUMNS] for i in range(0, len(cols), TREND_COLUMNS)] or [[]]
    band_h = TOP + len(rows) * (PANEL_H + GAP) - GAP + BOTTOM
    width = LEFT + min(len(cols), TREND_COLUMNS) * (PANEL_W + GAP)
    height = len(bands) * band_h
    out = [f'<svg data-plot="residual-trends" role="img" aria-label="residual components against reach, height and '
           f'each joint\'s reading" xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {width} {height}" '
           f'width="{width}" height="{height}" font-family="DejaVu Sans, Helvetica, Arial, sans-serif" '
           'font-size="10" fill="#444">']
    for b, band in enumerate(bands):
        top = b * band_h + TOP
        for i, (r, runit) in enumerate(rows):
            y0 = top + i * (PANEL_H + GAP)
            lo, hi = yspan[i]

            def py(v, y0=y0, lo=lo, hi=hi):
                return y0 + PANEL_H * (hi - v) / (hi - lo)
            out.append(f'<text transform="translate(13 {y0 + PANEL_H / 2:.1f}) rotate(-90)" text-anchor="middle" '
                       f'font-size="11" fill="#222">{html.escape(r)} ({runit})</text>')
            out += [f'<text x="{LEFT - 5}" y="{py(t) + 3.5:.1f}" text-anchor="end">{t:.3g}</text>'
                    for t in _ticks(lo, hi)]
            for j, (c, _) in enumerate(band):
                x0 = LEFT + j * (PANEL_W + GAP)
                xl, xh = _span([data[(rr, c)]["x"] for rr, _ in rows])
                out.append(_trend_panel(data[(r, c)], x0, y0, (xl, xh), py))
        base = top + len(rows) * (PANEL_H + GAP) - GAP
        for j, (c, cunit) in enumerate(band):
            x0 = LEFT + j * (PANEL_W + GAP)
            xl, xh = _span([data[(rr, c)]["x"] for rr, _ in rows])
            ticks = [t for t in _ticks(xl, xh) if x0 + 14 <= x0 + PANEL_W * (t - xl) / (xh - xl) <= x0 + PANEL_W - 14]
            out += [f'<text x="{x0 + PANEL_W * (t - xl) / (xh - xl):.1f}" y="{base + 13}" text-anchor="middle">'
                    f"{t:.4g}</text>" for t in ticks]
            out.append(f'<text x="{x0 + PANEL_W / 2}" y="{base + 30}" text-anchor="middle" font-size="11" '
                       f'fill="#222">{html.escape(c)} ({cunit})</text>')
    return "".join(out) + "</svg>"


def _trend_panel(t: dict, x0: float, y0: float, xspan: tuple, py) -> str:
    """One panel: frame, zero line, interquartile band and median polyline."""
    xl, xh = xspan

    def px(v):
        return x0 + PANEL_W * (v - xl) / (xh - xl)
    parts = [f'<rect x="{x0}" y="{y0}" width="{PANEL_W}" height="{PANEL_H}" fill="#fafbfc" stroke="#8a9099" '
             'stroke-width="0.6"/>',
             f'<path d="M{x0} {py(0):.1f}H{x0 + PANEL_W}" stroke="#888" stroke-width="0.6"/>']
    if len(t["x"]):
        band = [f"{px(x):.1f} {py(v):.1f}" for x, v in zip(t["x"], t["q75"])]
        band += [f"{px(x):.1f} {py(v):.1f}" for x, v in zip(t["x"][::-1], t["q25"][::-1])]
        parts.append(f'<path d="M{"L".join(band)}Z" fill="{AFTER}" fill-opacity="0.2" stroke="none"/>')
        line = "L".join(f"{px(x):.1f} {py(v):.1f}" for x, v in zip(t["x"], t["median"]))
        parts.append(f'<path d="M{line}" fill="none" stroke="{AFTER}" stroke-width="1.4"/>')
    return "".join(parts)


# -- transmission ------------------------------------------------------------------------------------

CURVES_PER_ROW = 4


def plot_transmission(curves: list[dict]) -> str:
    """Each joint's identified transmission error against its reading (a line over the fitted
    poses' range), with each fitted pose's residual turned into that joint's angle beside it
    (``curves``: joint, x, y, points_x, points_y, in degrees) (SVG)."""
    rows = -(-len(curves) // CURVES_PER_ROW)
    cols = min(len(curves), CURVES_PER_ROW)

    def draw(fig):
        axes = np.atleast_2d(fig.subplots(rows, cols, squeeze=False)).ravel()
        for ax, c in zip(axes, curves):
            ax.plot(c["points_x"], c["points_y"], ".", color=BEFORE, ms=2.5, alpha=0.5, label="the data")
            ax.plot(c["x"], c["y"], color=AFTER, lw=1.6, label="identified")
            ax.set_title(c["joint"])
            ax.set_xlabel(f"{c['joint']} reading (deg)")
            ax.set_ylabel("error of the joint (deg)")
        for ax in axes[len(curves):]:
            ax.set_visible(False)
        axes[0].legend(loc="best")
        fig.subplots_adjust(wspace=0.45, hspace=0.6)
    return _plot("transmission", "each joint's transmission error against its reading, with the data beside it",
                 draw, figsize=(2.8 * cols + 0.6, 2.8 * rows))
