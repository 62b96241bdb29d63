"""One calibration path for contacts: a calibration from contacts is a ``CalibrationResult`` like
any other (result.json, the report, the store, compensation take it), and every option of
``calibrate`` works with contacts, each tested here on simulated socket campaigns."""

import json
import re
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_one_line_error

import robocal as rc
from robocal.io import write_contacts
from robocal.sim import socket_campaign

ROOT = Path(__file__).resolve().parents[1]
ARM7 = ROOT / "examples" / "arm7" / "model.yaml"
ENCODER = 2e-5      # rad: encoder-level joint noise
ARCMIN = np.pi / 180 / 60


@pytest.fixture(scope="module")
def arm7():
    return rc.read_model(ARM7)


@pytest.fixture(scope="module")
def kit(arm7, tmp_path_factory):
    """A simulated kit session: a true arm with errors, 4 placements of 10 seatings per socket, as a
    contact file; and 15 tracker points of the same arm."""
    true = rc.perturb_model(arm7, rc.identifiability(arm7, parameters=("frames", "markers")).identified, rng=7)
    c = socket_campaign(true, placements=4, poses_per_socket=10, joint_noise=ENCODER, rng=7)
    folder = tmp_path_factory.mktemp("kit")
    write_contacts(c, folder / "sockets.csv", arm7)
    tracker = rc.measure(true, rc.random_configurations(arm7, 15, 1), rng=1)
    rc.write_measurements(tracker, folder / "tracker.csv", model=arm7)
    return true, c, folder


def _quiet(fn, *a, **k):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*a, **k)


# -- one record ------------------------------------------------------------------------------------

def test_a_contact_calibration_is_a_calibration_result_that_reads_back_whole(arm7, kit, tmp_path):
    _, c, _ = kit
    res = _quiet(rc.calibrate, arm7, contacts=c)
    assert isinstance(res, rc.CalibrationResult) and res.contacts is not None
    assert res.fit.errors_before.shape == (0, 1) and res.stats.fit_after.n == 0    # no measured point fitted
    # its accuracy in use: the socket consistency of each placement predicted by the others
    assert res.in_use.grouping == "each placement predicted by the others" and res.in_use.folds == 4
    assert res.in_use.position_after.mean == pytest.approx(res.contacts.held_out.consistency_mean, rel=1e-12)
    assert res.in_use.position_before.mean > 20 * res.in_use.position_after.mean
    # and its "before": the nominal model predicting the same seatings (its ball registered on the other
    # placements), not the fitted figures copied
    before = res.contacts.held_out_before
    assert res.in_use.position_before.mean == pytest.approx(before.consistency_mean, rel=1e-12)
    assert np.mean(res.in_use.spacing_before) == pytest.approx(before.spacing_mean, rel=1e-12)
    assert abs(before.consistency_mean - res.contacts.fit_before.consistency_mean) > 1e-3 * before.consistency_mean
    rc.write_result(res, tmp_path / "result.json")
    back = rc.read_result(tmp_path / "result.json")
    assert [(p.name, p.estimate, p.std) for p in back.parameters] == [(p.name, p.estimate, p.std)
                                                                      for p in res.parameters]
    a, b = res.contacts, back.contacts
    for key in ("fit_before", "fit_after", "held_out_before", "held_out"):
        x, y = getattr(a, key), getattr(b, key)
        assert x.consistency == y.consistency and x.distance == y.distance and x.spread == y.spread
        assert x.seatings.keys() == y.seatings.keys()
        assert all(np.array_equal(x.seatings[k], y.seatings[k]) for k in x.seatings)
        assert x.consistency_mean == y.consistency_mean and x.spacing_max == y.spacing_max
    assert a.validation_after is None and b.validation_after is None
    assert b.identifiability.contributions == a.identifiability.contributions
    assert [u.name for u in b.identifiability.unreachable] == ["base"]
    assert [u.name for u in a.identifiability.unreachable] == ["base"]
    assert b.nuisance == a.nuisance and b.weak == a.weak and b.rows == a.rows == {"socket": 120, "distance": 12}
    assert back.solver.residual_dof == res.solver.residual_dof > 0
    assert back.in_use.position_after.mean == res.in_use.position_after.mean and back.verdict == res.verdict
    from robocal.report import render_report

    assert render_report(back) == render_report(res)    # the page is the same from the file as from memory
    # under its title, as a tracker calibration's page says: what was identified, when, by what
    meta = re.search(r'<p class="meta">([^<]*)</p>', render_report(res)).group(1).split(" &middot; ")
    assert meta[0] == ", ".join(res.families) + " identification from contacts"
    assert meta[1].endswith(" UTC") and meta[2] == f"robocal {rc.__version__}"
    # a file written before the nominal model's prediction was kept: its "before" is said to be missing
    d = json.loads((tmp_path / "result.json").read_text())
    del d["contacts"]["held_out_by_placement_before"]
    (tmp_path / "result.json").write_text(json.dumps(d))
    old = rc.read_result(tmp_path / "result.json")
    assert old.contacts.held_out_before is None
    assert "predicted by the others, socket consistency (each seating's distance from its socket's mean centre), " \
           "mean over seatings: – -> " in rc.report.calibration_summary(old)
    assert 'data-key="held_out_before.' not in render_report(old)


def test_a_broken_contacts_part_of_a_result_file_is_named(arm7, kit, tmp_path):
    _, c, _ = kit
    rc.write_result(_quiet(rc.calibrate, arm7, contacts=c), tmp_path / "result.json")
    d = json.loads((tmp_path / "result.json").read_text())
    for edit, where in ((lambda x: x["contacts"]["fit_after"]["seatings_m"].update({"P1/A": [-1.0]}),
                         "contacts.fit_after.seatings_m.P1/A"),
                        (lambda x: x["contacts"].pop("nuisance"), "contacts.nuisance"),
                        (lambda x: x["contacts"]["rows"].update(socket="many"), "contacts.rows.socket"),
                        (lambda x: x["contacts"]["unreachable"].append(3), "contacts.unreachable[1]")):
        broken = json.loads(json.dumps(d))
        edit(broken)
        (tmp_path / "broken.json").write_text(json.dumps(broken))
        with pytest.raises(rc.InputError) as e:
            rc.read_result(tmp_path / "broken.json")
        assert e.value.where == where and "broken.json" in str(e.value)


def test_report_record_history_and_compensate_take_a_contact_calibration(cli, arm7, kit, tmp_path):
    _, _, folder = kit
    store = tmp_path / "cal.sqlite"
    code, out, err = cli("calibrate", ARM7, "--contacts", folder / "sockets.csv", "--out", tmp_path / "run",
                         "--record", "arm7-sn1", "--store", store)
    assert code == 0, err
    assert "recorded calibration #1 of arm7-sn1" in out
    saved = json.loads((tmp_path / "run" / "result.json").read_text())
    assert saved["contacts"]["held_out_by_placement"]["consistency_mean_m"] > 0
    code, out, err = cli("report", tmp_path / "run" / "result.json", "--out", tmp_path / "page.html")
    assert code == 0, err
    page = (tmp_path / "page.html").read_text()
    from robocal._presentation.units import fmt

    held = saved["contacts"]["held_out_by_placement"]["consistency_mean_m"]
    assert f'data-key="held_out.consistency_mean">{fmt(held, "m")}<' in page
    code, _, err = cli("record", tmp_path / "run" / "result.json", "--robot", "arm7-sn1", "--store", store)
    assert code == 2 and "stored already" in err          # the same calibration is not stored twice
    code, out, err = cli("record", tmp_path / "run" / "result.json", "--robot", "arm7-sn1", "--store", store,
                         "--at", "2030-01-01T00:00:00Z")
    assert code == 0, err
    assert "recorded calibration #2 of arm7-sn1" in out and "changes since the previous calibration" in out
    code, out, err = cli("history", "arm7-sn1", "--store", store)
    assert code == 0 and out.count("pass") >= 2, (out, err)
    # compensation takes the calibrated model the contacts gave
    q = rc.random_configurations(arm7, 5, 3)
    targets = tmp_path / "targets.csv"
    targets.write_text(",".join(f"{j}_deg" for j in arm7.joint_names) + "\n"
                       + "".join(",".join(f"{np.degrees(v):.6f}" for v in row) + "\n" for row in q))
    code, out, err = cli("compensate", ARM7, tmp_path / "run" / "calibrated.yaml", targets,
                         "--out", tmp_path / "commands.csv")
    assert code == 0, err
    assert "compensated 5 targets" in out and "5 reached, 0 flagged" in out


# -- every option ------------------------------------------------------------------------------------

def test_f_scale_sets_where_a_robust_loss_bends_on_contact_rows(arm7, kit):
    """One seating read 20 mrad off on a joint: with soft_l1 bending at 1 stated deviation the fit
    keeps close to the clean one; bending at 1e4 the loss is linear in effect and the row pulls."""
    _, c, _ = kit
    clean = _quiet(rc.calibrate, arm7, contacts=c)
    q = c.q.copy()
    q[5, 2] += 0.02
    bad = replace(c, q=q)
    runs = {f: _quiet(rc.calibrate, arm7, contacts=bad, loss="soft_l1", f_scale=f) for f in (1.0, 1e4)}
    std = np.array([p.std for p in clean.parameters])

    def off(r):
        assert [p.name for p in r.parameters] == [p.name for p in clean.parameters]
        return float(np.max(np.abs(np.array([p.estimate - e.estimate for p, e in zip(r.parameters, clean.parameters)])
                                   / std)))

    assert runs[1.0].solver.loss == runs[1e4].solver.loss == "soft_l1"
    assert off(runs[1.0]) < 3 and off(runs[1e4]) > 10 * off(runs[1.0]), (off(runs[1.0]), off(runs[1e4]))


def test_holdout_takes_a_fraction_of_the_placements(cli, kit, tmp_path):
    _, _, folder = kit
    code, out, err = cli("calibrate", ARM7, "--contacts", folder / "sockets.csv", "--out", tmp_path / "h",
                         "--holdout", "0.25", "--seed", "3")
    assert code == 0, err
    held = out.splitlines()[0]
    assert held.startswith("held out placement(s) P") and "of 4" in held
    name = held.split("placement(s) ")[1].split(" ")[0]
    saved = json.loads((tmp_path / "h" / "result.json").read_text())["contacts"]
    assert {k.split("/")[0] for k in saved["validation_after"]["consistency_m"]} == {name}
    assert name not in {k.split("/")[0] for k in saved["fit_after"]["consistency_m"]}
    # the held-out placement judges the calibration: no cross-validation of the others beside it
    assert saved["held_out_by_placement"] is None and saved["held_out_by_placement_before"] is None
    assert "held-out socket consistency" in out and "predicted by the others," not in out


def _figure(out: str, line: str, figure: str) -> tuple[float, float]:
    """The before and after (mm) of ``figure`` ("mean over seatings", "mean |e|") on the summary's line
    starting with ``line``."""
    text = next(t for t in out.splitlines() if t.strip().startswith(line))
    found = re.search(re.escape(figure) + r": ([0-9.]+) mm -> ([0-9.]+) mm", text)
    assert found, text
    return float(found[1]), float(found[2])


def test_each_figure_of_a_contact_summary_is_the_same_wherever_it_is_shown(cli, kit, tmp_path):
    """Each placement predicted by the others: the kit's lines and the checks "accuracy in use" and
    "spacing in use" give the same figures before and after (the "before" was the fitted one copied:
    2.6044 mm beside 2.632 mm on the real Panda)."""
    _, _, folder = kit
    code, out, err = cli("calibrate", ARM7, "--contacts", folder / "sockets.csv", "--out", tmp_path / "run")
    assert code == 0, err
    use = json.loads((tmp_path / "run" / "result.json").read_text())["in_use"]
    label = "each placement predicted by the others, "
    consistency = _figure(out, label + "socket consistency", "mean over seatings")
    spacing = _figure(out, label + "spacing error", "mean |e|")
    assert consistency == pytest.approx((use["position_before"]["mean"] * 1e3, use["position_after"]["mean"] * 1e3),
                                        abs=6e-5)
    assert spacing == pytest.approx((np.mean(use["spacing_before_m"]) * 1e3, np.mean(use["spacing_after_m"]) * 1e3),
                                    abs=6e-5)
    fitted = _figure(out, "fitted socket consistency", "mean over seatings")
    assert abs(consistency[0] - fitted[0]) > 1e-3


def test_measured_points_judge_a_contact_calibration_in_use(cli, arm7, kit, tmp_path):
    """Sockets to calibrate, tracker points to judge: the frame the contacts leave free is registered
    on the points (for the nominal and the calibrated model alike) and the points judge the result."""
    true, _, folder = kit
    moved = rc.measure(true.replace(base_position=(1.0, 2.0, 0.5)), rc.random_configurations(arm7, 30, 2), rng=2)
    rc.write_measurements(moved, tmp_path / "val.csv", model=arm7)
    code, out, err = cli("calibrate", ARM7, "--contacts", folder / "sockets.csv", "--out", tmp_path / "v",
                         "--validation", tmp_path / "val.csv")
    assert code == 0, err
    assert "registered on the validation points" in out and "verdict: pass" in out
    back = rc.read_result(tmp_path / "v" / "result.json")
    use = back.in_use
    assert use.method == "validation, base and tool registered on it" and use.position_after.n == 30
    assert use.position_after.mean < use.position_before.mean / 20
    assert back.validation.errors_after.shape == (30, 1) and back.stats.validation_after.n == 30
    assert "accuracy in use" in {c.name for c in back.checks}
    from robocal._presentation.units import fmt
    from robocal.report import render_report

    page = render_report(back)
    # noise-free points, base and tool registered on them: nothing of the robot's is left once the
    # instrument's noise is taken out, and the page says so rather than a bare 0 (a perfect robot)
    assert use.position_after.rms == 0 and use.noise > 0 and "0 mm after" not in out
    assert (f'data-key="in_use.mean">{fmt(use.position_before.mean, "m")} &rarr; within the instrument&#x27;s noise of '
            f'{use.noise * 1e3:.4g} mm RMS<') in page
    code, _, err = cli("calibrate", ARM7, "--contacts", folder / "sockets.csv", "--out", tmp_path / "w",
                       "--validation", tmp_path / "val.csv", "--holdout-placement", "P2")
    assert_one_line_error(code, err, ["--validation", "--holdout-placement"], tmp_path / "w")


def test_register_base_needs_measured_points_beside_the_contacts(cli, kit, tmp_path):
    _, _, folder = kit
    code, out, err = cli("calibrate", ARM7, folder / "tracker.csv", "--contacts", folder / "sockets.csv",
                         "--out", tmp_path / "r", "--register-base")
    assert code == 0, err
    assert "closed-form registration" in out and "tracker points:" in out
    plain = json.loads((tmp_path / "r" / "result.json").read_text())
    assert any("closed-form registration" in n for n in plain["notes"])
    code, _, err = cli("calibrate", ARM7, "--contacts", folder / "sockets.csv", "--out", tmp_path / "alone",
                       "--register-base")
    assert_one_line_error(code, err, ["initial_base", "no frame"], tmp_path / "alone")
    code, out, err = cli("calibrate", ARM7, "--contacts", folder / "sockets.csv", "--out", tmp_path / "rv",
                         "--holdout-placement", "P2", "--register-validation")
    assert code == 0, err
    assert "nothing to register" in out


def test_noise_deg_weighs_the_rotations_of_a_tracker_fitted_beside_contacts(cli, arm7, kit, tmp_path):
    """6D tracker poses without stated deviations beside the sockets: --noise-deg is their rotations'
    weight. Rotations read 5 mrad off on every pose (a mounting mistake of the tool's frame): trusted
    at 0.001 deg they pull the geometry; at 10 deg they hardly count, and the fit is the position-only one."""
    true, _, folder = kit
    q = rc.random_configurations(arm7, 20, 4)
    six = rc.measure(true, q, orientation=True, noise_rot=1e-5, rng=4)
    from scipy.spatial.transform import Rotation

    tilt = Rotation.from_rotvec([0.005, 0.0, 0.0]).as_matrix()
    six = replace(six, rotations=six.rotations @ tilt)
    rc.write_measurements(six, tmp_path / "six.csv", model=arm7)
    rc.write_measurements(replace(six, rotations=None, rot_mask=None), tmp_path / "three.csv", model=arm7)
    est = {}
    for name, data, extra in (("tight", "six.csv", ["--noise-deg", "0.001"]),
                              ("loose", "six.csv", ["--noise-deg", "10"]), ("points", "three.csv", [])):
        code, _, err = cli("calibrate", ARM7, tmp_path / data, "--contacts", folder / "sockets.csv",
                           "--out", tmp_path / name, *extra)
        assert code in (0, 3), err
        est[name] = {p["name"]: p["estimate"] for p in
                     json.loads((tmp_path / name / "result.json").read_text())["parameters"]}
    common = sorted(set(est["points"]) & set(est["loose"]) & set(est["tight"]))

    def gap(a, b):
        return max(abs(est[a][n] - est[b][n]) for n in common)

    assert len(common) > 20 and gap("loose", "points") < gap("tight", "points") / 10


def test_backlash_side_says_where_the_contacts_joints_rest(cli, arm7, tmp_path):
    """A true arm whose joints rest on the side gravity pushes them to (lost motion of 1-3 arcmin):
    calibrated with backlash, the gravity side recovers each joint's lost motion within its reported
    uncertainty and predicts the held-out placements; the wrong side (behind the last move) does not."""
    from robocal._model.robot import default_masses

    nom = default_masses(arm7)
    nom = nom.replace(frames=tuple(replace(f, backlash_width=0.01, backlash_friction=0.0) for f in nom.frames),
                      backlash_side="gravity")
    rng = np.random.default_rng(1)
    true = rc.perturb_model(nom, [n for n in rc.candidate_parameters(nom, ("geometric",))
                                  if not n.startswith("base.")], rng=1)
    true = true.replace(frames=tuple(replace(f, backlash_theta=rng.uniform(1, 3) * ARCMIN) for f in true.frames))
    rc.write_model(nom, tmp_path / "model.yaml")
    write_contacts(socket_campaign(true, placements=4, poses_per_socket=20, rng=2), tmp_path / "c.csv", nom)
    out = {}
    for side in ("gravity", "approach"):
        code, text, err = cli("calibrate", tmp_path / "model.yaml", "--contacts", tmp_path / "c.csv",
                              "--out", tmp_path / side, "--parameters", "geometric,backlash", "--backlash-side", side)
        assert code in (0, 3), err
        out[side] = json.loads((tmp_path / side / "result.json").read_text())
    truth = {f"{f.name}.backlash_theta": f.backlash_theta for f in true.frames}
    z = [(p["estimate"] - truth[p["name"]]) / p["std"] for p in out["gravity"]["parameters"]
         if ".backlash_" in p["name"]]
    assert len(z) >= 5 and max(abs(v) for v in z) < 3, z
    held = {s: out[s]["in_use"]["position_after"]["mean"] for s in out}
    assert held["gravity"] < held["approach"] / 3
    assert out["approach"]["nominal_model"]["backlash"]["side"] == "approach"       # the option reached the model


def test_compare_with_contacts_keeps_compliance_only_where_the_held_out_placements_gain(cli, arm7, tmp_path):
    """A rigid arm: compliance does not help in use and the geometric model is chosen; the same arm
    bending under its own weight: it helps, and geometric+compliance is chosen."""
    from robocal._model.robot import default_masses

    nom = default_masses(arm7)
    names = rc.candidate_parameters(nom, ("geometric",))
    rigid = rc.perturb_model(nom, [n for n in names if not n.startswith("base.")], rng=5)
    k = [n for n in rc.candidate_parameters(nom, ("compliance",)) if n.endswith(".k_theta")]
    from robocal.kinematics import model_from_vector, parameter_layout

    p = rc.parameter_vector(rigid)
    p[parameter_layout(nom).indices(k)] = 2e-5      # rad per N m: a few hundredths of a degree at the shoulder
    bending = model_from_vector(rigid, p)
    rc.write_model(nom, tmp_path / "model.yaml")
    chosen = {}
    for name, true in (("rigid", rigid), ("bending", bending)):
        write_contacts(socket_campaign(true, placements=4, poses_per_socket=20, rng=6), tmp_path / f"{name}.csv", nom)
        code, out, err = cli("calibrate", tmp_path / "model.yaml", "--contacts", tmp_path / f"{name}.csv",
                             "--out", tmp_path / name, "--compare")
        assert code in (0, 3), err
        assert out.startswith("comparison on contacts") and "socket consistency, in use" in out
        chosen[name] = out.split("calibrated model chosen: ")[1].split("\n")[0]
        files = {f.name for f in (tmp_path / name).iterdir()}
        assert {"result-geometric.json", "result-compliance.json", "result.json"} <= files
    assert chosen == {"rigid": "geometric", "bending": "geometric+compliance"}


def test_diagnose_names_the_mistake_of_a_contact_campaign(cli, arm7, kit, tmp_path):
    """Joint j4's readings written with the wrong sign: the calibration fails on implausible changes
    and the diagnosis (run on every calibration) names the joint; its finding is in result.json and on the
    page. A clean campaign with --diagnose: nothing is named."""
    _, c, folder = kit
    q = c.q.copy()
    q[:, 3] *= -1
    write_contacts(replace(c, q=q), tmp_path / "sign.csv", arm7)
    code, out, err = cli("calibrate", ARM7, "--contacts", tmp_path / "sign.csv", "--out", tmp_path / "sign", "--report")
    assert code == 3, err
    assert "possible cause: joint j4's readings have the wrong sign" in out
    saved = json.loads((tmp_path / "sign" / "result.json").read_text())
    first = saved["diagnosis"]["findings"][0]
    assert first["hypothesis"] == "joint sign" and first["items"] == ["j4"]
    assert "joint j4" in (tmp_path / "sign" / "report.html").read_text()
    code, out, err = cli("calibrate", ARM7, "--contacts", folder / "sockets.csv", "--out", tmp_path / "clean",
                         "--diagnose")
    assert code == 0, err
    assert "diagnosis: nothing tested explains the misfit" in out
    assert json.loads((tmp_path / "clean" / "result.json").read_text())["diagnosis"]["findings"] == []


def test_the_remaining_options_of_calibrate_work_with_contacts(cli, arm7, kit, tmp_path):
    """--known, --tol, --out-units, --force, --write-failed, --type (with --record), --instrument and
    --noise-mm (tracker points beside the contacts), --folds (the placements are the folds) and
    --compare --backlash, each doing with contacts what it does with measured points."""
    true, c, folder = kit
    sockets = folder / "sockets.csv"

    def run(name, *extra, data=()):
        code, out, err = cli("calibrate", ARM7, *data, "--contacts", sockets, "--out", tmp_path / name, *extra)
        assert code in (0, 3), err
        return code, out, json.loads((tmp_path / name / "result.json").read_text())

    _, _, plain = run("plain")
    names = {p["name"] for p in plain["parameters"]}
    # --known holds a family at nominal; --tol is the identifiability tolerance
    _, _, known = run("known", "--known", "markers")
    assert not any(n.startswith("ball.") for n in {p["name"] for p in known["parameters"]}) and \
        any(n.startswith("ball.") for n in names)
    assert run("tol", "--tol", "0.5")[2]["identifiability"]["tol"] == 0.5
    # --out-units: the calibrated model in metres and radians
    run("units", "--out-units", "m-rad")
    np.testing.assert_allclose(rc.parameter_vector(rc.read_model(tmp_path / "units" / "calibrated.yaml")),
                               rc.parameter_vector(rc.read_model(tmp_path / "plain" / "calibrated.yaml")),
                               rtol=1e-12, atol=1e-15)
    assert "units: {length: m, angle: rad}" in (tmp_path / "units" / "calibrated.yaml").read_text().replace("'", "")
    # --force overwrites, without it nothing is overwritten
    code, _, err = cli("calibrate", ARM7, "--contacts", sockets, "--out", tmp_path / "plain")
    assert code == 2 and "--force" in err
    assert run("plain", "--force")[0] == 0
    # --folds gives way to the placements: the same calibration
    assert run("folds", "--folds", "3")[2]["parameters"] == plain["parameters"]
    # --write-failed writes the failed calibration's model, marked
    q = c.q.copy()
    q[:, 3] *= -1
    write_contacts(replace(c, q=q), tmp_path / "sign.csv", arm7)
    for name, extra in (("failed", []), ("written", ["--write-failed"])):
        code, _, err = cli("calibrate", ARM7, "--contacts", tmp_path / "sign.csv", "--out", tmp_path / name, *extra)
        assert code == 3, err
    assert not (tmp_path / "failed" / "calibrated.yaml").exists()
    assert "verdict: fail" in (tmp_path / "written" / "calibrated.yaml").read_text()
    # --type is stored with --record
    code, out, err = cli("calibrate", ARM7, "--contacts", sockets, "--out", tmp_path / "rec", "--record", "sn9",
                         "--type", "arm7", "--store", tmp_path / "s.sqlite")
    assert code == 0, err
    code, out, err = cli("history", "--type", "arm7", "--store", tmp_path / "s.sqlite")
    assert code == 0 and "sn9" in out, (out, err)
    # the instrument's noise weighs tracker points that state none against the contacts
    tracker = [folder / "tracker.csv"]
    ratios = {name: run(name, *extra, data=tracker)[2]["contacts"]["noise_ratio"]["tracker"]
              for name, extra in (("tracker", []), ("cmm", ["--instrument", "cmm"]), ("mm", ["--noise-mm", "0.2"]))}
    # in the instrument's deviations: 0.2 mm ten times the tracker's 0.02, the CMM's 0.005 a quarter
    assert ratios["tracker"] / 12 < ratios["mm"] < ratios["tracker"] / 8
    assert ratios["cmm"] > 3 * ratios["tracker"]
    # --compare --backlash: a third identification with backlash beside the contacts
    code, out, _ = run("three", "--compare", "--backlash", "--assume-masses")
    assert "+backlash" in out and (tmp_path / "three" / "result-backlash.json").exists()
