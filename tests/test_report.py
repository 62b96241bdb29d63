"""The HTML report: numbers equal the result's, missing inputs are said, the page renders in Chromium."""

import importlib.util
import json
import math
import os
import re
import shutil
import subprocess
import sys
import warnings
from dataclasses import replace
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from robots import arm6r, cylindrical, humanoid

import robocal as rc
from robocal.io import result_from_dict, result_to_json
from robocal.report import PLOTS, render_report, write_report

pytest.importorskip("matplotlib")

CHROMIUM = "/usr/bin/chromium"
ROOT = Path(__file__).resolve().parent.parent
ARTIFACTS = ROOT / "test-artifacts"
# display unit (data-unit attribute) -> factor from SI; written independently of the report's table
FACTOR = {"mm": 1e3, "deg": 180 / math.pi, "deg/(kN m)": 180 / math.pi * 1e3}


def _roundtrip(result) -> dict:
    """What result.json holds: the tests compare the page with it."""
    return json.loads(result_to_json(result))


def _render(d: dict, **kw) -> str:
    """The report of the result read back from its file form ``d``."""
    return render_report(result_from_dict(d), **kw)


def _write(d: dict, path, **kw) -> None:
    write_report(result_from_dict(d), path, **kw)


@pytest.fixture(scope="module")
def simulated():
    m = arm6r()
    true, data = rc.simulate(m, 60, seed=1)
    return m, data


@pytest.fixture(scope="module")
def full(simulated):
    """A result with held-out poses and a limit, as read back from JSON."""
    m, data = simulated
    fit, val = data.subset(slice(0, 40)), data.subset(slice(40, None))
    res = rc.calibrate(m, fit, validation=val, limit=0.0001)
    return _roundtrip(res)


@pytest.fixture(scope="module")
def bare(simulated):
    """No held-out poses, no limit."""
    m, data = simulated
    return _roundtrip(rc.calibrate(m, data.subset(slice(0, 40))))


@pytest.fixture(scope="module")
def compliance():
    m = cylindrical(masses=True)
    _, data = rc.simulate(m, 48, parameters=("geometric", "compliance"), seed=2)
    return _roundtrip(rc.calibrate(m, data, parameters=("geometric", "compliance")))


class Page(HTMLParser):
    """Text of every element with a data-key (and its data-unit), the <svg data-plot> elements, links."""

    def __init__(self, text):
        super().__init__()
        self.keyed, self.units, self.plots, self.urls, self.tags = {}, {}, {}, [], []
        self._open = []  # [key or None, ...] per open element
        self._plot = None
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.tags.append(tag)
        for k in ("src", "href", "xlink:href"):
            if k in a:
                self.urls.append(a[k])
        if tag == "svg" and "data-plot" in a:
            self._plot = a["data-plot"]
            self.plots[self._plot] = {"elements": 0, "text": ""}
        elif self._plot:
            self.plots[self._plot]["elements"] += 1
        key = a.get("data-key")
        if key is not None:
            assert key not in self.keyed, f"data-key {key} twice"
            self.keyed[key] = ""
            self.units[key] = a.get("data-unit")
        if tag not in ("meta", "link", "br", "path", "use", "rect", "circle"):  # void or self-closed
            self._open.append((tag, key))

    def handle_startendtag(self, tag, attrs):
        self.handle_starttag(tag, attrs)
        if self._open and self._open[-1][0] == tag:
            self._open.pop()

    def handle_endtag(self, tag):
        while self._open:
            t, _ = self._open.pop()
            if t == tag:
                break
        if tag == "svg":
            self._plot = None

    def handle_data(self, data):
        for _, key in self._open:
            if key is not None:
                self.keyed[key] += data
        if self._plot:
            self.plots[self._plot]["text"] += data


def _page(d, tmp_path, name="report.html", **kw) -> tuple[Page, str]:
    path = tmp_path / name
    _write(d, path, **kw)
    text = path.read_text(encoding="utf-8")
    return Page(text), text


def _shown_equals(page: Page, key: str, si: float) -> None:
    """The cell's number equals the SI value in its display unit, to the printed precision."""
    text = page.keyed[key].strip()
    unit = page.units[key]
    decimals = len(text.split(".")[1]) if "." in text else 0
    expected = si * FACTOR[unit]
    assert abs(float(text) - expected) <= 0.5 * 10 ** -decimals * (1 + 1e-9) + 1e-12, (key, text, expected)
    assert decimals >= 4, (key, text)  # enough digits to be checked at all


def test_parameter_cells_equal_the_result(full, tmp_path):
    page, _ = _page(full, tmp_path)
    assert full["parameters"]
    for p in full["parameters"]:
        for field in ("nominal", "estimate", "change", "std"):
            _shown_equals(page, f"{p['name']}:{field}", p[field])
        assert page.keyed[f"{p['name']}:status"].strip() == "I"
    for a in full["identifiability"]["eliminated"]:
        assert page.keyed[f"{a['name']}:status"].strip() == "E"
        for t in a["absorbed_by"]:
            assert t["name"] in page.keyed[f"{a['name']}:absorbed_by"]
    # the paper's layout: one status cell per frame and shown kind
    for row in full["identifiability_table"]:
        for kind in ("beta", "alpha", "d", "theta", "r"):
            shown = page.keyed[f"{row['frame']}.{kind}:status"].strip()
            assert shown == {"I": "I", "E": "E", "-": "–"}[row[kind]]


def test_units_are_converted_once(full, tmp_path):
    page, _ = _page(full, tmp_path)
    p = next(p for p in full["parameters"] if p["name"] == "j2.alpha")
    assert page.units["j2.alpha:estimate"] == "deg"
    assert float(page.keyed["j2.alpha:nominal"]) == pytest.approx(-90.0)
    assert page.units["base.x:estimate"] == "mm"
    assert float(page.keyed["base.x:nominal"]) == pytest.approx(1500.0)
    assert p["unit"] == "rad"


def test_stats_and_limit_equal_the_result(full, tmp_path):
    page, _ = _page(full, tmp_path)
    for key in ("fit_before", "fit_after", "validation_before", "validation_after"):
        s = full["stats"][key]
        assert int(page.keyed[f"stats.{key}.n"]) == s["n"] > 0
        for f in ("mean", "std", "rms", "max"):
            _shown_equals(page, f"stats.{key}.{f}", s[f])
    lim = full["limit"]
    _shown_equals(page, "limit.limit_m", lim["limit_m"])
    _shown_equals(page, "limit.mean_error_m", lim["mean_error_m"])
    assert float(page.keyed["limit.ratio"]) == pytest.approx(lim["ratio"], abs=5e-4)
    assert page.keyed["limit.reached"] == ("reached" if lim["reached"] else "not reached")
    _shown_equals(page, "solver.sigma0_m", full["sigma0_m"])
    assert int(page.keyed["solver.nfev"]) == full["nfev"]
    assert page.keyed["solver.message"] == full["message"]
    assert page.keyed["provenance.data.source"] == full["provenance"]["data"]["source"]


def test_the_accuracy_in_use_is_shown_apart_from_the_errors_as_measured(full, tmp_path):
    """The page showed the held-out errors as the instrument measured them (its noise in) as "Mean
    error after" and "Position errors", and the accuracy in use (the robot's, its noise taken out)
    only in a check's sentence: two figures of the same poses, nothing to tell them apart. Each now
    says which it is, and the accuracy in use has its table, headed as the summary heads it."""
    import html

    page, text = _page(full, tmp_path)
    text = html.unescape(text)
    use = full["in_use"]
    for key in ("position_before", "position_after", "measured_after"):
        for f in ("mean", "rms", "p95", "max"):
            _shown_equals(page, f"in_use.{key}.{f}", use[key][f])
    assert use["measured_after"]["mean"] == full["stats"]["validation_after"]["mean"] != use["position_after"]["mean"]
    assert "Position errors as measured (the instrument's noise in)" in text
    assert "Mean error after, as measured" in text
    assert (f"Accuracy in use (validation), on {use['position_after']['n']} held-out point(s): the robot's error, "
            f"the instrument's noise ({use['noise_m'] * 1e3:.4g} mm RMS) taken out") in text
    assert "the robot's, the instrument's noise taken out) on the held-out poses" in text      # the limit's figure


def test_the_nominal_as_given_is_shown_beside_the_registered_before(full, tmp_path):
    """"Before" is the nominal model with base and markers registered on the poses: a base far off
    the model's showed as a small "before", and the page never said what the nominal as given
    missed. Its figures (result.json's ``stats.fit_nominal``) stand beside it, named."""
    import html

    page, text = _page(full, tmp_path)
    text = html.unescape(text)
    stats = full["stats"]
    for key in ("fit_nominal", "validation_nominal"):
        assert stats[key]["mean"] > 1.5 * stats[key.replace("nominal", "before")]["mean"]
        assert int(page.keyed[f"stats.{key}.n"]) == stats[key]["n"]
        for f in ("mean", "std", "rms", "max"):
            _shown_equals(page, f"stats.{key}.{f}", stats[key][f])
    assert text.count('<span class="tag nominal">nominal as given</span>') == 2
    assert text.count('<span class="tag before">before, registered</span>') == 2
    _shown_equals(page, "headline.validation_nominal.mean", stats["validation_nominal"]["mean"])


def test_largest_errors_are_named_by_pose_label(full, tmp_path):
    page, _ = _page(full, tmp_path)
    err, prov = full["errors"], full["provenance"]
    points = []   # (after, before, label) over both sets, written independently of the report
    for key, src in (("fit", "data"), ("validation", "validation")):
        for label, rb, ra in zip(prov[src]["labels"], err[f"{key}_before"], err[f"{key}_after"]):
            points += [(a, b, label) for a, b in zip(ra, rb)]
    points.sort(reverse=True)
    # held-out poses keep the labels they had in the campaign they were split from
    assert prov["validation"]["labels"] == [f"pose {i}" for i in range(40, 60)]
    for j, (a, b, label) in enumerate(points[:10]):
        assert page.keyed[f"worst.{j}.pose"] == label
        _shown_equals(page, f"worst.{j}.after", a)
        _shown_equals(page, f"worst.{j}.before", b)
    assert "worst.10.pose" not in page.keyed


def test_every_plot_is_there_and_self_contained(full, tmp_path):
    page, text = _page(full, tmp_path)
    assert set(page.plots) == set(PLOTS)
    for name, plot in page.plots.items():
        assert plot["elements"] > 20, name
    assert "errors-per-pose" in page.plots and "pose" in page.plots["errors-per-pose"]["text"]
    assert "(mm)" in page.plots["histograms"]["text"]
    assert "j2.alpha" in page.plots["correlation"]["text"]
    # no network: every link is in-page or a data URL, no scripts, no external style sheets
    assert page.urls and all(u.startswith(("#", "data:")) for u in page.urls), page.urls
    assert "script" not in page.tags
    assert "@import" not in text and "url(http" not in text
    # ids unique across the inline SVGs
    ids = re.findall(r' id="([^"]+)"', text)
    assert len(ids) == len(set(ids))


def test_report_is_deterministic(full):
    assert _render(full) == _render(full)


def test_missing_validation_and_limit_are_said(bare, tmp_path):
    page, text = _page(bare, tmp_path)
    assert "No held-out poses were given: the errors shown are on the fitted poses only." in text
    assert "No limit of absolute accuracy was given: run <code>robocal limit</code>" in text
    assert page.keyed["stats.validation_after.n"] == "0"
    assert "limit.limit_m" not in page.keyed
    assert set(page.plots) == set(PLOTS)
    for p in bare["parameters"]:
        _shown_equals(page, f"{p['name']}:estimate", p["estimate"])


def test_complete_result_does_not_claim_anything_missing(full, tmp_path):
    _, text = _page(full, tmp_path)
    assert "No held-out poses" not in text and "No limit of absolute accuracy" not in text


def test_compliance_columns_in_paper_layout(compliance, tmp_path):
    page, text = _page(compliance, tmp_path)
    ks = [p for p in compliance["parameters"] if ".k_" in p["name"]]
    assert ks
    for p in ks:
        assert page.units[f"{p['name']}:estimate"] == "deg/(kN m)"
        _shown_equals(page, f"{p['name']}:estimate", p["estimate"])
        _shown_equals(page, f"{p['name']}:std", p["std"])
    assert "K<sub>&theta;</sub>" in text
    # units keep their case wherever the page names them, sentences included
    assert "deg/(kn m)" not in text
    assert "compliances in deg/(kN m)" in text


@pytest.fixture(scope="module")
def humanoid_result():
    """A humanoid-sized campaign: 19 joints, three fixed frames placed by matrices, five markers,
    geometric and compliance parameters on masses assumed from the geometry (relative compliances)."""
    m = humanoid()
    _, data = rc.simulate(m, 400, parameters=("geometric", "compliance"), seed=3)
    return rc.calibrate(m, data.subset(slice(0, 320)), validation=data.subset(slice(320, None)),
                        parameters=("geometric", "compliance"))


def test_fixed_frames_are_shown_as_the_position_and_matrix_written(humanoid_result, tmp_path):
    from robocal.kinematics import mdh_transform

    page, _ = _page(_roundtrip(humanoid_result), tmp_path)
    # as tests/robots.py writes them (mm; rows of the matrix)
    written = {"ltool": ((0, 0, 110), ((0, 0, 1), (1, 0, 0), (0, 1, 0))),
               "rtool": ((0, 0, 110), ((0, 1, 0), (0, 0, 1), (1, 0, 0))),
               "head": ((60, 0, 80), ((0, 0, 1), (0, 1, 0), (-1, 0, 0)))}
    calibrated = {f.name: f for f in humanoid_result.calibrated_model.frames}
    for name, (position, rotation) in written.items():
        shown = [float(v) for v in page.keyed[f"{name}:nominal.position"].split(",")]
        assert shown == pytest.approx(position, abs=5e-5)
        rows = re.findall(r"\[([^\[\]]+)\]", page.keyed[f"{name}:nominal.rotation"])
        assert np.abs(np.array([[float(v) for v in r.split(",")] for r in rows]) - rotation).max() < 5e-7
        X = mdh_transform(calibrated[name])
        cal = [float(v) for v in page.keyed[f"{name}:calibrated.position"].split(",")]
        assert cal == pytest.approx(X[:3, 3] * 1e3, abs=5e-5)
        # not as the converted parameters (gamma, beta... of the equivalent transform)
        assert f"{name}.beta:nominal" not in page.keyed and f"{name}.theta:nominal" not in page.keyed


def test_compliances_from_assumed_masses_are_shown_as_relative(humanoid_result, compliance, tmp_path):
    from robocal._presentation.html import RELATIVE_NOTE

    _, text = _page(_roundtrip(humanoid_result), tmp_path, name="humanoid.html")
    assert "K<sub>&theta;</sub> <small>(relative)</small>" in text and RELATIVE_NOTE in text
    assert "K<sub>&theta;</sub> <small>(deg/(kN m))</small>" not in text
    _, text = _page(compliance, tmp_path, name="masses.html")  # masses given: absolute compliances
    assert "K<sub>&theta;</sub> <small>(deg/(kN m))</small>" in text and RELATIVE_NOTE not in text


def test_a_tool_turn_is_shown_as_an_angle_about_an_axis(tmp_path):
    from scipy.spatial.transform import Rotation

    m = arm6r()
    axis = np.array([1.0, 1.0, 1.0]) / np.sqrt(3)
    turned = m.replace(markers=tuple(replace(mk, rotation=tuple(map(tuple, Rotation.from_rotvec(
        np.radians(120) * axis).as_matrix()))) for mk in m.markers))
    _, data = rc.simulate(turned, 80, orientation=True, noise_rot=2e-5, parameters=("base",), seed=8)
    page, _ = _page(_roundtrip(rc.calibrate(m, data)), tmp_path)
    said = page.keyed["turn.tool"]
    angle, shown_axis = re.search(r"turned ([\d.]+) deg about \(([^)]+)\)", said).groups()
    assert float(angle) == pytest.approx(120, abs=0.01)
    assert [float(v) for v in shown_axis.split(",")] == pytest.approx(axis, abs=1e-3)


def test_geometric_only_omits_compliance_columns(full, tmp_path):
    page, text = _page(full, tmp_path)
    assert not any(".k_" in k for k in page.keyed)
    assert "are not shown: those parameters were not among the candidates" in text


def test_residuals_drawn_at_measured_points_when_given(full, simulated):
    _, data = simulated
    # result.json carries the measured positions; an older file without them still renders
    without = dict(full, errors={k: v for k, v in full["errors"].items() if k != "fit_positions"})
    with_points = dict(full, errors=dict(full["errors"], fit_positions=data.positions[:40].tolist()))
    html_a, html_b = _render(without), _render(with_points)
    assert "common origin" in html_a and "Arrows start at the measured points" in html_b
    assert html_a != html_b


def test_extra_tables(full, tmp_path):
    extra = {"comparison": [{"label": "geometric", "mean_mm": 0.69, "std_mm": 0.34},
                            {"label": "geometric + compliance", "mean_mm": 0.58, "std_mm": 0.21}],
             "paper": {"title": "TH8 in the paper", "columns": ["quantity", "value (mm)"],
                       "rows": [["limit of absolute accuracy", 0.55], ["before", 2.82]]}}
    page, text = _page(full, tmp_path, extra=extra)
    assert page.keyed["extra.0.title"] == "comparison" and page.keyed["extra.1.title"] == "TH8 in the paper"
    assert "geometric + compliance" in text and "<td class=\"num\">0.58</td>" in text
    assert "limit of absolute accuracy</td><td class=\"num\">0.55</td>" in text
    with pytest.raises(rc.InputError, match="extra"):
        _render(full, extra={"paper": {"title": "t", "columns": ["a", "b"], "rows": [[1]]}})
    with pytest.raises(rc.InputError, match="extra"):
        _render(full, extra={"paper": 3})


def test_refuses_to_overwrite_and_writes_atomically(full, tmp_path):
    path = tmp_path / "report.html"
    path.write_text("keep me")
    with pytest.raises(rc.InputError) as err:
        _write(full, path)
    assert err.value.source == str(path) and path.read_text() == "keep me"
    _write(full, path, force=True)
    assert path.read_text(encoding="utf-8").startswith("<!DOCTYPE html>")
    assert [p.name for p in tmp_path.iterdir()] == ["report.html"]  # no temporary file left


def test_not_a_result_is_an_input_error(full):
    with pytest.raises(rc.InputError, match="result: must be a CalibrationResult, got a dict"):
        render_report(full)
    with pytest.raises(rc.InputError, match="nominal_model: missing key"):
        result_from_dict({"schema": "robocal.result/1"})


def test_needs_matplotlib_only_when_drawing(full, monkeypatch):
    code = "import sys, robocal, robocal._presentation.html; assert 'matplotlib' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True)
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    with pytest.raises(rc.RobocalError, match=r"pip install robocal\[report\]"):
        _render(full)


def test_nan_entries_are_not_drawn_or_printed(full):
    d = json.loads(json.dumps(full))
    d["errors"]["fit_after"][0] = [None]
    d["errors"]["fit_residual_vectors"][0] = [[None, None, None]]
    d["stats"]["validation_after"] = {"n": 0, "mean": None, "std": None, "rms": None, "max": None}
    text = _render(d)
    assert re.search(r"\bnan\b", text, re.I) is None
    assert "validation_after" in d["stats"] and "stats.validation_after.mean" not in Page(text).keyed


# -- the browser ---------------------------------------------------------------------------------

def _browser_or_skip():
    """Chromium and Playwright, or a skip outside CI (under CI a missing browser is a failure)."""
    ci = os.environ.get("CI", "").lower() not in ("", "0", "false", "no")
    missing = [what for what, ok in (("chromium", Path(CHROMIUM).exists() or shutil.which("chromium")),)
               if not ok]
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        missing.append("playwright (pip install playwright)")
    if missing:
        msg = f"headless browser test needs {', '.join(missing)}"
        if ci:
            pytest.fail(msg + " (CI is set)")
        pytest.skip(msg)


@pytest.fixture(scope="module")
def chromium():
    """One headless Chromium for the module's page tests (Playwright driving the system's browser)."""
    _browser_or_skip()
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = p.chromium.launch(
            executable_path=CHROMIUM if Path(CHROMIUM).exists() else shutil.which("chromium"),
            args=["--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update",
                  "--disable-sync", "--no-first-run"])
        try:
            yield browser
        finally:
            browser.close()


# In the page as laid out: every text's rendered size (CSS px; SVG text scaled by its transforms and
# the picture's own scaling to the page) and every pair of texts of a plot whose boxes overlap by
# more than a pixel each way.
MEASURE_TEXT = """
() => {
  const out = {small: [], overlaps: [], texts: 0};
  const walker = document.createTreeWalker(document.body, NodeFilter.SHOW_TEXT);
  while (walker.nextNode()) {
    const t = walker.currentNode;
    if (!t.textContent.trim()) continue;
    const el = t.parentElement;
    if (el.closest('svg')) continue;
    out.texts++;
    const fs = parseFloat(getComputedStyle(el).fontSize);
    if (fs < 9) out.small.push({where: el.tagName, text: t.textContent.trim().slice(0, 40), size: fs});
  }
  for (const svg of document.querySelectorAll('svg[data-plot]')) {
    const boxes = [];
    for (const t of svg.querySelectorAll('text')) {
      if (!t.textContent.trim()) continue;
      out.texts++;
      const m = t.getScreenCTM();
      const scale = Math.sqrt(Math.abs(m.a * m.d - m.b * m.c));
      const fs = parseFloat(getComputedStyle(t).fontSize) * scale;
      if (fs < 9) out.small.push({where: svg.dataset.plot, text: t.textContent.trim().slice(0, 40), size: fs});
      const r = t.getBoundingClientRect();
      boxes.push({l: r.left, r: r.right, t: r.top, b: r.bottom, text: t.textContent.trim().slice(0, 40)});
    }
    for (let i = 0; i < boxes.length; i++) for (let j = i + 1; j < boxes.length; j++) {
      const a = boxes[i], b = boxes[j];
      const w = Math.min(a.r, b.r) - Math.max(a.l, b.l), h = Math.min(a.b, b.b) - Math.max(a.t, b.t);
      if (w > 1 && h > 1) out.overlaps.push({where: svg.dataset.plot, a: a.text, b: b.text, w: w, h: h});
    }
  }
  return out;
}
"""
SMALLEST_TEXT_PX = 9


def _render_in_chromium(browser, path: Path, shot_name: str):
    """Load ``path`` as a user opens it and print it to PDF: console messages, requests, plots, title,
    screenshot, how far the page is wider than the window, the PDF's outline."""
    url = path.as_uri()
    console, requests = [], []
    page = browser.new_page(viewport={"width": 1200, "height": 900})
    try:
        page.on("console", lambda m: console.append((m.type, m.text)))
        page.on("pageerror", lambda e: console.append(("pageerror", str(e))))
        page.on("request", lambda r: requests.append(r.url))
        page.goto(url, wait_until="load")
        plots = page.eval_on_selector_all(
            "svg[data-plot]", "els => els.map(e => ({name: e.dataset.plot, width: e.getBoundingClientRect().width,"
            " height: e.getBoundingClientRect().height, n: e.querySelectorAll('path, use, text').length}))")
        overflow = page.evaluate("Math.max(document.documentElement.scrollWidth, document.body.scrollWidth)"
                                 " - document.documentElement.clientWidth")
        title = page.title()
        text = page.evaluate(MEASURE_TEXT)
        ARTIFACTS.mkdir(exist_ok=True)
        shot = ARTIFACTS / shot_name
        page.screenshot(path=str(shot), full_page=True)
        pdf = page.pdf(path=str(shot.with_suffix(".pdf")), format="A4", outline=True, tagged=True,
                       print_background=True)
    finally:
        page.close()
    outline = [t.decode("latin-1") for t in re.findall(rb"/Title\s*\(([^)]*)\)", pdf)]
    return {"console": console, "requests": requests, "plots": plots, "title": title, "shot": shot, "url": url,
            "overflow": overflow, "outline": outline, "text": text}


def _assert_rendered(r: dict, html: str, plots=PLOTS):
    assert [m for m in r["console"] if m[0] in ("error", "pageerror")] == []
    assert r["requests"] == [r["url"]]  # nothing fetched but the page itself
    assert r["title"].startswith("Calibration report")
    assert sorted(pl["name"] for pl in r["plots"]) == sorted(plots)
    for pl in r["plots"]:
        assert pl["width"] > 300 and pl["height"] > 150 and pl["n"] > 20, pl
    assert r["shot"].stat().st_size > 50_000
    assert r["overflow"] <= 0, f"the page is {r['overflow']} px wider than the window"
    # readable: no text smaller than 9 px as laid out, no two labels of a plot on top of each other
    assert r["text"]["texts"] > 100
    assert r["text"]["small"] == [], r["text"]["small"][:10]
    assert r["text"]["overlaps"] == [], r["text"]["overlaps"][:10]
    # the printed PDF holds every section: each section heading is in its outline
    sections = re.findall(r'<section id="[^"]+"><h2>([^<]+)</h2>', html)
    assert len(sections) >= 10 and set(sections) <= set(r["outline"]), (sections, r["outline"])


def test_th8_demo_report_renders_in_headless_chromium(chromium, tmp_path):
    # the report `make demo` writes, rendered as a user opens it
    spec = importlib.util.spec_from_file_location("th8_reproduce", ROOT / "examples" / "th8" / "reproduce.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert mod.main(["--out", str(tmp_path)]) == 0
    html = (tmp_path / "report.html").read_text()
    # the report of the model kept (geometric, compliance and backlash: no gear terms to draw)
    _assert_rendered(_render_in_chromium(chromium, tmp_path / "report.html", "th8-report.png"), html)
    d = json.loads((tmp_path / "result.json").read_text())
    # the demo's own numbers are the ones on the page, and so is the paper's table
    mean_mm = d["stats"]["validation_after"]["mean"] * 1e3
    assert f"{mean_mm:.4f}" in html
    assert "figures beside ours" in html


def _campaign_6d(n: int, seed: int):
    """A 6R arm measured with positions and orientations, a fifth of the poses held out."""
    m = arm6r()
    _, data = rc.simulate(m, n, orientation=True, noise_rot=2e-5, seed=seed)
    k = int(0.8 * n)
    return rc.calibrate(m, data.subset(slice(0, k)), validation=data.subset(slice(k, None)), limit=5e-5)


@pytest.fixture(scope="module")
def big_6d():
    """20,000 poses, 6D: built once for the tests that need a campaign of real size."""
    return _campaign_6d(20_000, seed=11)


def test_6d_report_renders_in_headless_chromium(chromium, tmp_path):
    path = tmp_path / "report.html"
    write_report(_campaign_6d(80, seed=5), path)
    html = path.read_text(encoding="utf-8")
    page = Page(html)
    assert "stats.rotation.validation_after.mean" in page.keyed
    assert "solver.sigma0" in page.keyed and "solver.sigma0_m" not in page.keyed  # a ratio for weighted 6D fits
    assert "rotation error" in page.plots["histograms"]["text"]
    assert "rotation error" in page.plots["residual-trends"]["text"]
    _assert_rendered(_render_in_chromium(chromium, path, "report-6d.png"), html)


def test_20000_pose_report_is_small_and_renders_in_headless_chromium(chromium, big_6d, tmp_path):
    path = tmp_path / "report.html"
    write_report(big_6d, path)
    assert path.stat().st_size < 5e6
    html = path.read_text(encoding="utf-8")
    assert "300 of the 16000 measured points are drawn" in html
    _assert_rendered(_render_in_chromium(chromium, path, "report-20000.png"), html)


def test_humanoid_sized_report_is_readable_in_headless_chromium(chromium, humanoid_result, tmp_path):
    # a model of 100+ parameters and 19 joints: every label at 9 px or more, none overlapping
    assert len(humanoid_result.parameters) >= 117 and humanoid_result.nominal_model.n_joints >= 19
    path = tmp_path / "report.html"
    write_report(humanoid_result, path)
    assert path.stat().st_size < 5e6
    html = path.read_text(encoding="utf-8")
    page = Page(html)
    assert all(p.name in page.plots["correlation"]["text"] for p in humanoid_result.parameters)
    _assert_rendered(_render_in_chromium(chromium, path, "report-humanoid.png"), html)


def test_history_page_is_readable_in_headless_chromium(chromium, tmp_path):
    # a robot calibrated four times and verified three times: the drift and verification plots' date
    # labels rendered at 8 px (32a3abb); every text at 9 px or more, none overlapping
    th8 = ROOT / "examples" / "th8"
    nominal = rc.read_model(th8 / "model.yaml")
    fit, val = rc.split_sets(rc.read_measurements(th8 / "measurements.csv", nominal))
    result = rc.calibrate(nominal, fit, validation=val, known=("markers",))
    check = rc.read_measurements(th8 / "verification.csv", nominal)
    with rc.open_store(tmp_path / "s.sqlite", create=True) as store:
        for k, at in enumerate(("2026-01-05", "2026-04-12", "2026-08-30", "2027-01-17")):
            store.record(result, "TH8-01", robot_type="th8", at=at)
            if k:
                rc.verify_robot(store, "TH8-01", check, at=f"{at[:8]}20")
        h = rc.history(store, "TH8-01")
    path = tmp_path / "history.html"
    rc.write_history(h, path)
    r = _render_in_chromium(chromium, path, "history.png")
    assert [m for m in r["console"] if m[0] in ("error", "pageerror")] == []
    assert sorted(p["name"] for p in r["plots"]) == ["drift", "verifications"]
    assert r["text"]["texts"] > 50
    assert r["text"]["small"] == [], r["text"]["small"][:10]
    assert r["text"]["overlaps"] == [], r["text"]["overlaps"][:10]
    assert r["overflow"] <= 0


# -- absorptions in display units, against the Jacobian -------------------------------------------

TERM = re.compile(r"([+-]\d[\d.]*(?:e[+-]?\d+)?) (mm|deg|deg/\(kN m\)) (\S+)")


def _absorptions(text: str) -> dict:
    """'name  1 deg = +2.865 mm tool.y ...' lines (summary) or cells (report) -> {name: (unit, terms)}."""
    out = {}
    for name, unit, rhs in re.findall(r"([\w.]+)\s+1 (mm|deg|deg/\(kN m\)) = (.*)", text):
        out[name] = (unit, [(float(c), u, n) for c, u, n in TERM.findall(rhs)])
    return out


def _agrees_with_finite_differences(model, q, name, unit, terms) -> None:
    """A change of ``name`` moves the markers as the shown combination does (central differences)."""
    from robocal.kinematics import forward_kinematics, model_from_vector, parameter_layout, parameter_vector

    lay, p0 = parameter_layout(model), parameter_vector(model)
    h = 1e-3  # display units

    def moved(step: dict, sign: float):
        p = p0.copy()
        for n, (v, u) in step.items():
            p[lay[n].index] += sign * v / FACTOR[u]
        return forward_kinematics(model_from_vector(model, p), q).positions

    def central(step):
        return (moved(step, 1) - moved(step, -1)) / (2 * h)

    direct = central({name: (h, unit)})
    combination = central({n: (c * h, u) for c, u, n in terms})
    assert np.abs(direct - combination).max() <= 2e-3 * np.abs(direct).max(), (name, terms)


@pytest.fixture(scope="module")
def length_by_angle():
    """A slide whose marker's sideways offset is absorbed by the base rotation: a length by an angle."""
    m = rc.serial_model("slide", [dict(joint="prismatic"), dict(joint="revolute", r=0.2)],
                        markers=[("tool", (0.8, 0.0, 0.1))], joint_limits=[(0.0, 0.5), (-0.3, 0.3)])
    _, data = rc.simulate(m, 30, parameters=["base.rz", "tool.y"], seed=3)
    return _roundtrip(rc.calibrate(m, data, parameters=["base.rz", "tool.y"]))


def test_absorptions_in_display_units_agree_with_the_jacobian(full, length_by_angle, tmp_path):
    from robocal.report import calibration_summary

    quantity = {"mm": "length", "deg": "angle"}
    pairs = set()
    for d in (full, length_by_angle):
        result = result_from_dict(d)
        q = np.asarray(d["errors"]["fit_readings"])
        page, _ = _page(d, tmp_path, name=f"{result.nominal_model.name}.html")
        cells = {a["name"]: page.keyed[f"{a['name']}:absorbed_by"] for a in d["identifiability"]["eliminated"]}
        shown = _absorptions("\n".join(f"{n} {c}" for n, c in cells.items()))
        summary = _absorptions(calibration_summary(result))
        assert shown == summary and len(shown) == len(cells) > 0
        for name, (unit, terms) in shown.items():
            _agrees_with_finite_differences(result.nominal_model, q, name, unit, terms)
            pairs |= {(quantity[unit], quantity[u]) for _, u, _ in terms}
    assert pairs == {("length", "length"), ("length", "angle"), ("angle", "length"), ("angle", "angle")}


# -- the verdict and the checks --------------------------------------------------------------------

def test_verdict_and_every_check_at_the_top_with_items_linked(full, tmp_path):
    d = json.loads(json.dumps(full))
    label = d["provenance"]["data"]["labels"][7]  # a pose far from the largest errors, named by a failed check
    d["checks"].append({"name": "outliers", "status": "fail", "summary": f"1 point: {label}",
                        "cause": "a blunder", "fix": "remove it", "items": [f"{label}, marker tool: 3.1 mm, 9 sd"]})
    d["checks"].append({"name": "plausible changes", "status": "warn", "summary": "j2.alpha moved far",
                        "cause": "", "fix": "", "items": ["j2.alpha: 1.2 deg (tolerance 0.5 deg)"]})
    d["verdict"] = "fail"
    page, text = _page(d, tmp_path)
    assert page.keyed["verdict"] == "fail"
    # every check shown, failed first, before any other section
    shown = [(page.keyed[f"check.{j}.status"], page.keyed[f"check.{j}.name"]) for j in range(len(d["checks"]))]
    assert sorted(shown) == sorted((c["status"], c["name"]) for c in d["checks"])
    assert shown[0] == ("fail", "outliers") and shown[1][0] == "warn"
    assert text.index('id="checks"') < text.index('id="errors"') < text.index('id="parameters"')
    # the named pose and parameter link to rows that exist
    pose_id = "pose-" + re.sub(r"[^\w.-]", "_", label)
    assert f'href="#{pose_id}"' in text and f'id="{pose_id}"' in text
    assert 'href="#param-j2.alpha"' in text and 'id="param-j2.alpha"' in text
    assert "left no notes" not in text


def test_a_passing_result_says_so(full, tmp_path):
    page, _ = _page(full, tmp_path)
    assert page.keyed["verdict"] == full["verdict"]
    assert {page.keyed[f"check.{j}.name"] for j in range(len(full["checks"]))} == {c["name"] for c in full["checks"]}


# -- residual trends -----------------------------------------------------------------------------

def test_an_unmodelled_joint_error_shows_as_a_trend_against_that_joint_only():
    from dataclasses import replace

    from robocal._presentation.plots import residual_trends

    m = arm6r()
    _, data = rc.simulate(m, 2000, seed=4)
    # an error the model cannot absorb: 0.3 mm along world z, three periods over joint 2's reading
    bump = 3e-4 * np.sin(3 * data.q[:, 1])
    data = replace(data, positions=data.positions + bump[:, None, None] * np.array([0.0, 0.0, 1.0]))
    result = rc.calibrate(m, data)
    d = _roundtrip(result)
    trends = residual_trends(d, m.joint_names, ["rad"] * 6, result.calibrated_model.X_WB)
    spread = {x: np.ptp(trends["trends"][("dz", x)]["median"]) for x, _ in trends["columns"]}
    joint2 = f"{m.joint_names[1]} reading"
    # reach and height follow joint 2 too (it lifts the arm); the other joints do not
    others = max(v for x, v in spread.items() if x.endswith("reading") and x != joint2)
    assert spread[joint2] > 0.35  # mm: most of the 0.6 mm peak to peak survives the fit
    assert spread[joint2] > 3 * others, spread
    # the trend follows the error's shape: residuals are calibrated minus measured, so minus the bump
    t = trends["trends"][("dz", joint2)]
    shape = -0.3 * np.sin(3 * np.radians(t["x"]))
    assert np.corrcoef(t["median"], shape)[0, 1] > 0.9


def test_trends_are_drawn_only_against_joints_that_show_structure():
    from dataclasses import replace

    from robocal._presentation.plots import STRUCTURE, residual_trends, structure

    m = arm6r()
    _, data = rc.simulate(m, 2000, seed=4)
    clean = rc.calibrate(m, data)
    bumped = replace(data, positions=data.positions + 3e-4 * np.sin(3 * data.q[:, 1])[:, None, None]
                     * np.array([0.0, 0.0, 1.0]))
    joint2 = f"{m.joint_names[1]} reading"
    shown = {}
    for name, result in (("clean", clean), ("bumped", rc.calibrate(m, bumped))):
        trends = residual_trends(_roundtrip(result), m.joint_names, ["rad"] * 6, result.calibrated_model.X_WB)
        shown[name] = [c for c in trends["structured"] if c.endswith("reading")]
        # what "structured" says is what the measure says, row by row
        for c, _ in trends["columns"]:
            assert (c in trends["structured"]) == any(structure(trends["trends"][(r, c)]) >= STRUCTURE
                                                      for r, _ in trends["rows"])
    assert shown["clean"] == []  # noise alone shows no trend
    assert joint2 in shown["bumped"] and len(shown["bumped"]) < 6
    html = _render(_roundtrip(rc.calibrate(m, bumped)))
    trends_svg = html[html.index('data-plot="residual-trends"'):]
    trends_svg = trends_svg[:trends_svg.index("</svg>")]
    assert f"{joint2} (deg)" in trends_svg and f"{m.joint_names[0]} reading" not in trends_svg


def test_reach_and_height_are_measured_from_the_calibrated_base():
    from robocal._presentation.plots import residual_trends

    true, data = rc.simulate(arm6r(), 400, parameters=("base",), seed=6)
    at_tracker = true.replace(base_position=(0.0, 0.0, 0.0),  # the base unknown
                              base_rotation=((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)))
    result = rc.calibrate(at_tracker, data)
    trends = residual_trends(_roundtrip(result), true.joint_names, ["rad"] * 6, result.calibrated_model.X_WB)
    # the marker's distance from the true base's vertical axis, and its height above the base
    rel = (data.positions[:, 0] - np.asarray(true.base_position)) @ np.asarray(true.base_rotation)
    reach, height = np.hypot(rel[:, 0], rel[:, 1]) * 1e3, rel[:, 2] * 1e3
    for label, truth in (("reach", reach), ("height", height)):
        x = trends["trends"][("dx", label)]["x"]
        assert truth.min() - 1 <= x.min() and x.max() <= truth.max() + 1, (label, x, truth.min(), truth.max())
    assert np.hypot(*true.base_position[:2]) * 1e3 > reach.max() + 500  # the tracker's distance would differ


def test_each_histogram_has_its_own_axis(full):
    from robocal._presentation.plots import histogram_panels

    d = json.loads(json.dumps(full))
    d["limit"] = dict(d["limit"], limit_m=1e-2)  # a limit far beyond the errors after calibration
    panels = {p["when"]: p for p in histogram_panels(d)}
    after = max(panels["after"]["fit"].max(), panels["after"]["validation"].max())
    before = max(panels["before"]["fit"].max(), panels["before"]["validation"].max())
    assert before > 10 * after
    assert panels["after"]["top"] == pytest.approx(after) and panels["before"]["top"] == pytest.approx(before)
    d["limit"] = dict(d["limit"], limit_m=2 * after * 1e-3)  # a limit within reach is on the axis
    assert [p["top"] for p in histogram_panels(d) if p["when"] == "after"] == [pytest.approx(2 * after)]


def test_terminal_tables_align_for_long_names():
    from robocal.report import calibration_summary, identifiability_summary

    m = arm6r(markers=(("spherically_mounted_retroreflector_2", (0.05, 0.02, 0.12)),))
    lines = identifiability_summary(m, rc.identifiability(m, n_random=30), "random poses").splitlines()
    header = next(i for i, line in enumerate(lines) if line.lstrip().startswith("frame"))
    assert {len(line) for line in lines[header:header + 1 + m.n_frames]} == {len(lines[header])}
    owners = [line for line in lines if line.lstrip().startswith(("base ", "spherically"))]
    assert len(owners) == 2 and owners[0].index(" x:") == owners[1].index(" x:")
    _, data = rc.simulate(m, 30, seed=1)
    rows = [line for line in calibration_summary(rc.calibrate(m, data)).splitlines()
            if " change " in line and " std " in line]
    assert len(rows) > 20
    assert len({line.index(" change ") for line in rows}) == 1 and len({line.index(" std ") for line in rows}) == 1


def test_summary_error_columns_stay_apart_past_999_mm():
    from robocal._identification.estimates import ErrorStats
    from robocal._presentation.text import stats_lines

    big = rc.ErrorSummary(fit_before=ErrorStats(36, 3.252, 1.06, 3.4, 12.5),
                          fit_after=ErrorStats(36, 4e-4, 2e-4, 5e-4, 1e-3),
                          validation_before=ErrorStats(12, 1.0004, 0.998, 1.5, 2.75),
                          validation_after=ErrorStats(0, None, None, None, None))
    lines = stats_lines(big)
    head = lines[0]
    for line, key in zip(lines[1:], ("fit_before", "fit_after", "validation_before")):
        s = getattr(big, key)
        cells = line[24:].split()  # after the row label: n and four numbers, each its own word
        assert [int(cells[0])] + [float(c) for c in cells[1:]] == pytest.approx(
            [s.n] + [v * 1e3 for v in (s.mean, s.std, s.rms, s.max)], abs=5e-4)
        # each number ends under its column's name
        for name, cell in zip(("mean", "std", "RMS", "max"), cells[1:]):
            assert head.index(name) + len(name) == line.index(cell) + len(cell)
    assert len(lines) == 4


def test_a_contact_report_shows_the_held_out_placements_sockets_and_spacings(tmp_path):
    """With placements held out, the page's per-socket and spacing tables hold their sockets with their
    figures, nominal and calibrated, as result.json does (they were left out: only the fitted
    placements' sockets had rows, their "held out" cells all "–"); no placement is then shown as
    predicted by the others."""
    from robocal._presentation.units import fmt
    from robocal.sim import socket_campaign

    arm7 = rc.read_model(ROOT / "examples" / "arm7" / "model.yaml")
    true = rc.perturb_model(arm7, rc.identifiability(arm7, parameters=("frames", "markers")).identified, rng=3)
    fit, held = socket_campaign(true, placements=3, poses_per_socket=10, joint_noise=2e-5, rng=3).split_placements(
        ["P2"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        saved = _roundtrip(rc.calibrate(arm7, contacts=fit, validation=held))
    html = _render(saved)
    c = saved["contacts"]
    for key in ("validation_before", "validation_after"):
        sockets, spacings = c[key]["consistency_m"], c[key]["distance_error_m"]
        assert {s.split("/")[0] for s in sockets} == {"P2"} and len(sockets) == 3 and len(spacings) == 3
        for socket, figures in sockets.items():
            for which in ("mean", "max"):
                assert f'data-key="{key}.consistency.{socket}.{which}">{fmt(figures[which], "m")}<' in html
        for pair, value in spacings.items():
            assert f'data-key="{key}.spacing.{pair}">{fmt(value, "m")}<' in html
    assert "Socket consistency, held-out placements" in html
    assert c["held_out_by_placement"] is None and "predicted by the others" not in html


def test_a_contact_calibration_report_renders_in_headless_chromium(chromium, cli, tmp_path):
    """``calibrate --contacts --report``: the verdict, the kit's figures (socket consistency and
    spacing error, fitted and each placement predicted by the others) as in result.json,
    readable in a browser and printable."""
    from robocal.io import write_contacts
    from robocal.sim import socket_campaign

    arm7 = rc.read_model(ROOT / "examples" / "arm7" / "model.yaml")
    true = rc.perturb_model(arm7, rc.identifiability(arm7, parameters=("frames", "markers")).identified, rng=3)
    write_contacts(socket_campaign(true, placements=3, poses_per_socket=10, joint_noise=2e-5, rng=3),
                   tmp_path / "sockets.csv", arm7)
    code, _, err = cli("calibrate", ROOT / "examples" / "arm7" / "model.yaml", "--contacts", tmp_path / "sockets.csv",
                       "--out", tmp_path / "out", "--report")
    assert code == 0, err
    path = tmp_path / "out" / "report.html"
    html = path.read_text()
    saved = json.loads((tmp_path / "out" / "result.json").read_text())["contacts"]
    from robocal._presentation.units import fmt

    for key, figure, saved_as in (("fit_after", "consistency_mean", "consistency_mean_m"),
                                  ("held_out", "consistency_mean", "consistency_mean_m"),
                                  ("held_out_before", "consistency_mean", "consistency_mean_m"),
                                  ("held_out", "spacing_max", "spacing_error_max_m")):
        value = saved[{"held_out": "held_out_by_placement",
                       "held_out_before": "held_out_by_placement_before"}.get(key, key)][saved_as]
        assert f'data-key="{key}.{figure}">{fmt(value, "m")}<' in html
    for key in ("held_out_by_placement", "held_out_by_placement_before"):
        for socket, figures in saved[key]["consistency_m"].items():
            cell = key.replace("_by_placement", "")
            assert f'data-key="{cell}.consistency.{socket}.max">{fmt(figures["max"], "m")}<' in html
    r = _render_in_chromium(chromium, path, "report-contacts.png")
    assert [m for m in r["console"] if m[0] in ("error", "pageerror")] == []
    assert r["requests"] == [r["url"]] and r["title"].startswith("Calibration report")
    assert r["overflow"] <= 0, f"the page is {r['overflow']} px wider than the window"
    assert r["text"]["texts"] > 100 and r["text"]["small"] == [], r["text"]["small"][:10]
    sections = re.findall(r'<section id="[^"]+"><h2>([^<]+)</h2>', html)
    assert len(sections) == 6 and set(sections) <= set(r["outline"]), (sections, r["outline"])
