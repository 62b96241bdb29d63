"""Calibration without a tracker: sockets, planes, ball bars and known distances, alone or mixed with
tracker points. Every Jacobian column against central differences, recovery of a simulated 7-joint
arm within the reported uncertainty, the analysis naming what the data cannot reach, the kit's
figures on a held-out placement, and bad input refused. Heavier statistics (10 campaigns) are in
examples/arm7/contacts_campaigns.py."""

import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import z_scores
from robots import arm6r

import robocal as rc
from robocal.identification import Problem, contact_errors, contact_identifiability
from robocal.sim import bar_campaign, plan_sockets, plane_campaign, socket_campaign

ARM7 = Path(__file__).resolve().parents[1] / "examples" / "arm7" / "model.yaml"
TH8 = rc.read_model(Path(__file__).resolve().parents[1] / "examples" / "th8" / "model.yaml")
ENCODER = 2e-5      # rad: encoder-level joint noise


@pytest.fixture(scope="module")
def arm7():
    return rc.read_model(ARM7)


def _mixed_contacts(m, n=40, seed=1):
    """Every kind on random readings (residuals need not be small for a Jacobian test), every marker
    of the model seated in turn."""
    rng = np.random.default_rng(seed)
    q = rc.random_configurations(m, n, rng)
    kind = ["socket"] * 16 + ["plane"] * 12 + ["bar"] * 4 + ["plane"] * 8
    target = ["A"] * 8 + ["B"] * 8 + ["table"] * 12 + ["bar"] * 4 + ["wall"] * 8
    placement = ["P1"] * 28 + ["pair1"] * 2 + ["pair2"] * 2 + [""] * 8
    return rc.Contacts(q=q, marker=tuple(m.marker_names[i % len(m.markers)] for i in range(n)), kind=tuple(kind),
                       target=tuple(target),
                       placement=tuple(placement), sigma=rng.uniform(1e-5, 3e-5, n),
                       distances=(rc.KnownDistance("A", "B", 0.2, 2e-6),),
                       planes=(rc.KnownPlane("wall", (0.0, 0.6, 0.8), 0.1),), bars={"bar": (0.3, 2e-6)})


def _worst_column_error(prob, p):
    """The largest column error (max over rows) relative to the column's largest entry; near zero
    absolute, as in the kinematics test (1e-3 m per unit, here in the rows' standard deviations)."""
    J = prob.jacobian(p)
    x0 = p[prob.free_idx]
    floor = 1e-3 / np.median(prob.contacts.contacts.sigma)
    worst = 0.0
    for j in range(len(x0)):
        h = 1e-6 * max(1.0, abs(x0[j]))
        xp, xm = x0.copy(), x0.copy()
        xp[j] += h
        xm[j] -= h
        fd = (prob.residuals(prob.full(xp, p)) - prob.residuals(prob.full(xm, p))) / (2 * h)
        worst = max(worst, np.abs(fd - J[:, j]).max() / max(np.abs(fd).max(), floor))
    return worst


@pytest.mark.parametrize("case", ["arm7 geometric with tracker points", "arm7 with two markers seated",
                                  "arm6r compliance", "th8 backlash"])
def test_every_contact_jacobian_column_agrees_with_central_differences(arm7, case):
    if case == "arm7 with two markers seated":
        m = arm7.replace(markers=arm7.markers + (replace(arm7.markers[0], name="ball2", frame=5,
                                                         position=(0.02, -0.03, 0.05)),))
        families, compliance, data = ("geometric",), False, None
    elif case.startswith("arm7"):
        m, families, compliance = arm7, ("geometric",), False
        data = rc.simulate(m, 10, seed=3)[1]
    elif case.startswith("th8"):      # joints resting in their lost motion, with compliance
        m, families, compliance, data = TH8, ("geometric", "compliance", "backlash"), True, None
    else:
        m, families, compliance, data = arm6r(masses=True), ("geometric", "compliance"), True, None
    names = rc.candidate_parameters(m, families)
    prob = Problem(m, names, contacts=_mixed_contacts(m), compliance=compliance, data=data)
    rng = np.random.default_rng(2)
    p = prob.start_vector()
    p[prob.n_robot:] += rng.normal(0.0, 1e-2, prob.n_nuisance)      # off the starting planes and points
    lay = rc.parameter_names(m)
    for k, n in zip(prob.robot_idx, names):
        p[k] += 3e-4 if "k_" not in n else 1e-5                        # compliances deflect: corrections on
    assert set(np.unique(prob.row_kinds())) >= {2, 3, 4, 5} and len(lay) == prob.n_robot
    assert _worst_column_error(prob, p) < 1e-6
    J = prob.jacobian(p)
    lost = [i for i, n in enumerate(names) if ".backlash_" in n]
    assert len(lost) == (6 if case.startswith("th8") else 0)
    assert all(np.abs(J[:, i]).max() > 1e-3 for i in lost)      # the contacts see each joint's lost motion


def _truth_for(m, campaign, seed):
    """A true arm with errors on what ``campaign`` (a function of the robot and a generator) can
    identify, found on the nominal arm, so the truth is unambiguous; the base stays nominal."""
    names = rc.candidate_parameters(m, ("geometric",))
    prob = Problem(m, names, contacts=campaign(m, np.random.default_rng(seed + 100)), compliance=False)
    ident = contact_identifiability(prob, names)
    return rc.perturb_model(m, [n for n in ident.identified if not n.startswith("base.")], rng=seed)


@pytest.fixture(scope="module")
def socket_run(arm7):
    """Sockets on a 3-socket plate at 4 placements (the last held out), 20 poses per socket."""
    true = rc.perturb_model(arm7, rc.identifiability(arm7, parameters=("frames", "markers")).identified, rng=0)
    c = socket_campaign(true, placements=4, poses_per_socket=20, joint_noise=ENCODER, rng=0)
    fit, val = c.split_placements(["P4"])
    return true, fit, val


def test_sockets_with_known_spacing_recover_the_arm_and_the_held_out_spread(arm7, socket_run):
    true, fit, val = socket_run
    res = rc.calibrate(arm7, contacts=fit, validation=val)
    z = z_scores(res, true, arm7)
    assert np.all(np.abs(z) < 3), dict(zip([p.name for p in res.parameters], z.round(2)))
    assert res.verdict == "pass", [(c.name, c.summary) for c in res.checks if c.status != "pass"]
    ident = res.contacts.identifiability
    assert [u.name for u in ident.unreachable] == ["base"] and len(ident.unreachable[0].components) == 6
    assert not any(n.startswith("base.") for n in ident.identified)
    # the spacing alone identifies nothing, but with the sockets it fixes the scale
    assert ident.contributions["distance"] == () and ident.together
    assert len(ident.lost_without["distance"]) == 1 and ident.lost_without["socket"] == ident.identified
    noise_alone = contact_errors(true, val).mean_spread
    assert res.contacts.validation_before.mean_spread > 50 * noise_alone
    assert res.contacts.validation_after.mean_spread < 1.2 * noise_alone
    assert res.contacts.fit_after.distance_rms < 5 * fit.distances[0].sigma + 1e-5


def _by_hand(model, contacts):
    """Per socket the (mean, max) distance of each seating's ball centre from the socket's mean
    centre, and per placement and known distance the calibrated spacing minus the known one, by
    plain loops over the rows."""
    sockets = {}
    for i in range(contacts.n_rows):
        p = rc.forward_kinematics(model, contacts.q[i:i + 1]).positions[0, model.marker_names.index(contacts.marker[i])]
        sockets.setdefault((contacts.placement[i], contacts.target[i]), []).append(p)
    centre = {key: sum(ps) / len(ps) for key, ps in sockets.items()}
    consistency = {}
    for (placement, socket), ps in sockets.items():
        d = [float(np.sqrt(sum((p[k] - centre[placement, socket][k]) ** 2 for k in range(3)))) for p in ps]
        consistency[f"{placement}/{socket}"] = (sum(d) / len(d), max(d))
    spacing = {}
    for placement in dict.fromkeys(contacts.placement):
        for d in contacts.distances:
            a, b = centre[placement, d.a], centre[placement, d.b]
            spacing[f"{placement}: {d.a}-{d.b}"] = float(np.sqrt(sum((a[k] - b[k]) ** 2 for k in range(3)))) - d.length
    return consistency, spacing


def test_copied_contact_rows_are_named(arm7, socket_run):
    """A seating copied (the same readings twice, as no hand repeats them) counts as information it is
    not: the calibration says so, as it does of repeated tracker poses."""
    _, fit, _ = socket_run
    copied = fit.subset(np.r_[np.arange(fit.n_rows), [3, 7, 7]])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        notes = rc.calibrate(arm7, contacts=copied).notes
        clean = rc.calibrate(arm7, contacts=fit).notes
    assert any(n.startswith(f"3 of {fit.n_rows + 3} contact rows repeat an earlier row's joint readings exactly")
               for n in notes), notes
    assert not any("repeat an earlier row" in n for n in clean)


def test_socket_consistency_and_spacing_error_match_a_hand_computation(arm7, socket_run):
    """The community's figures, fitted and held out, before and after, to 1e-9 m. "Before" is the
    nominal geometry with the ball's offset registered on the contacts (as a tracker calibration's
    errors before are the nominal's with base and tool registered)."""
    _, fit, val = socket_run
    res = rc.calibrate(arm7, contacts=fit, validation=val)
    c = res.contacts
    before = rc.calibrate(arm7, contacts=fit, parameters=("markers",), weak="flag").calibrated_model
    for model, figures, contacts in ((before, c.fit_before, fit), (res.calibrated_model, c.fit_after, fit),
                                     (before, res.contacts.validation_before, val),
                                     (res.calibrated_model, res.contacts.validation_after, val)):
        consistency, spacing = _by_hand(model, contacts)
        assert figures.consistency.keys() == consistency.keys() and figures.distance.keys() == spacing.keys()
        for key, (mean, worst) in consistency.items():
            assert abs(figures.consistency[key][0] - mean) < 1e-9 and abs(figures.consistency[key][1] - worst) < 1e-9
        for key, e in spacing.items():
            assert abs(figures.distance[key] - e) < 1e-9
        every = [d for key in consistency for d in _seating_distances(model, contacts, key)]
        assert abs(figures.consistency_mean - sum(every) / len(every)) < 1e-9
        assert abs(figures.consistency_max - max(w for _, w in consistency.values())) < 1e-9
        assert abs(figures.spacing_max - max(abs(e) for e in spacing.values())) < 1e-9
        assert abs(figures.spacing_mean - sum(abs(e) for e in spacing.values()) / len(spacing)) < 1e-9
    # the calibration makes the held-out seatings consistent: far below the nominal's
    assert res.contacts.validation_after.consistency_mean < res.contacts.validation_before.consistency_mean / 20


def _seating_distances(model, contacts, key):
    placement, socket = key.split("/")
    rows = [i for i in range(contacts.n_rows) if contacts.placement[i] == placement and contacts.target[i] == socket]
    P = rc.forward_kinematics(model, contacts.q[rows]).positions[:, model.marker_names.index(contacts.marker[rows[0]])]
    c = P.mean(axis=0)
    return [float(np.linalg.norm(p - c)) for p in P]


def test_without_a_known_distance_the_scale_is_named_unreachable(arm7, socket_run):
    _, fit, _ = socket_run
    names = rc.candidate_parameters(arm7, ("geometric",))
    ident = contact_identifiability(Problem(arm7, names, contacts=replace(fit, distances=()), compliance=False), names)
    assert [u.name for u in ident.unreachable] == ["base", "scale"]
    assert "known distance" in ident.unreachable[1].reason and "rigid motion" in ident.unreachable[0].reason
    with_spacing = contact_identifiability(Problem(arm7, names, contacts=fit, compliance=False), names)
    assert len(with_spacing.identified) == len(ident.identified) + 1


@pytest.mark.parametrize("known", [False, True])
def test_plane_contacts_recover_the_arm(arm7, known):
    def campaign(robot, rng):
        return plane_campaign(robot, planes=6, poses_per_plane=25, joint_noise=ENCODER, known=known, rng=rng)

    true = _truth_for(arm7, campaign, 3)
    res = rc.calibrate(arm7, contacts=campaign(true, np.random.default_rng(3)))
    z = z_scores(res, true, arm7)
    assert np.all(np.abs(z) < 3), dict(zip([p.name for p in res.parameters], z.round(2)))
    unreachable = [u.name for u in res.contacts.identifiability.unreachable]
    # known planes fix the measurement frame and, lying off the base, the scale
    assert unreachable == ([] if known else ["base", "scale"])
    # unknown planes fix shape, not size: said, as a size error would not show in use
    ident = next(c for c in res.checks if c.name == "identifiability at these poses")
    assert (ident.status, res.verdict) == (("pass", "pass") if known else ("warn", "warn"))
    assert known or "size is out of reach" in ident.summary


def test_ball_bar_recovers_the_arm_and_its_scale(arm7):
    def campaign(robot, rng):
        return bar_campaign(robot, pairs=90, joint_noise=ENCODER, rng=rng)

    true = _truth_for(arm7, campaign, 4)
    res = rc.calibrate(arm7, contacts=campaign(true, np.random.default_rng(4)))
    z = z_scores(res, true, arm7)
    assert np.all(np.abs(z) < 3), dict(zip([p.name for p in res.parameters], z.round(2)))
    assert [u.name for u in res.contacts.identifiability.unreachable] == ["base"]
    assert res.verdict == "pass"


def _with_encoder_noise(data, rng):
    return replace(data, q=data.q + rng.normal(0.0, ENCODER, data.q.shape))


def test_tracker_and_sockets_together_beat_either_alone_on_held_out_tracker_poses(arm7):
    rng = np.random.default_rng(5)
    true = rc.perturb_model(arm7, rc.identifiability(arm7).identified, rng=rng)
    fit_t, val_t = (_with_encoder_noise(rc.measure(true, rc.random_configurations(arm7, n, rng), rng=rng), rng)
                    for n in (20, 40))
    sockets = socket_campaign(true, placements=3, poses_per_socket=20, joint_noise=ENCODER, rng=rng)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        models = [rc.calibrate(arm7, fit_t).calibrated_model, rc.calibrate(arm7, contacts=sockets).calibrated_model,
                  rc.calibrate(arm7, contacts=sockets, data=fit_t).calibrated_model]
    rms = [np.sqrt(np.mean(np.sum((rc.forward_kinematics(x, val_t.q).positions - val_t.positions) ** 2, axis=2)))
           for x in models]
    assert rms[2] < rms[0] and rms[2] < rms[1], rms


def test_each_kind_is_checked_on_its_own(arm7, socket_run):
    _, fit, _ = socket_run
    q = fit.q.copy()
    q[5, 1] += 1e-3                                # one socket row read while the arm still moved
    flagged = rc.calibrate(arm7, contacts=replace(fit, q=q), on_outliers="flag")
    check = next(c for c in flagged.checks if c.name == "outliers among the socket contacts")
    assert check.status == "warn" and fit.labels[5] in check.summary
    refit = rc.calibrate(arm7, contacts=replace(fit, q=q))       # the row is set aside and the fit made again
    check = next(c for c in refit.checks if c.name == "outliers among the socket contacts")
    assert check.status == "warn" and "set aside" in check.summary and refit.verdict == "warn"
    clean = rc.calibrate(arm7, contacts=fit)
    moved = [abs(a.estimate - b.estimate) / b.std for a, b in zip(refit.parameters, clean.parameters)]
    assert max(moved) < 1.0
    # a spacing misread by 0.1 mm (50 of its standard deviations): the distances' fit warns (a fit's
    # size alone never fails), the sockets still fit
    wrong = replace(fit, distances=tuple(replace(d, length=d.length + 1e-4) if d.a == "A" and d.b == "B" else d
                                         for d in fit.distances))
    status = {c.name: c.status for c in rc.calibrate(arm7, contacts=wrong).checks}
    assert status["fit of the distance contacts"] == "warn" and status["fit of the socket contacts"] == "pass"


@pytest.mark.parametrize("edit, words", [
    (dict(kind=("socket",) * 3 + ("ball",)), ["kind 'ball'"]),
    (dict(kind=("socket",) * 3 + ("bar",), target=("A",) * 3 + ("bar",)), ["ball bar", "1 rows"]),
    (dict(sigma=np.array([1e-5, 1e-5, 0.0, 1e-5])), ["sigma", "row 2"]),
    (dict(kind=("socket", "socket", "plane", "socket")), ["mixes kinds"]),
])
def test_contacts_refuse_bad_input(edit, words):
    base = dict(q=np.zeros((4, 6)), marker=("tool",) * 4, kind=("socket",) * 4, target=("A",) * 4,
                placement=("P1",) * 4, sigma=np.full(4, 1e-5), bars={"bar": (0.2, 1e-6)})
    with pytest.raises(rc.InputError) as e:
        rc.Contacts(**{**base, **edit})
    for w in words:
        assert w in str(e.value)


# -- the contact file and the command line ----------------------------------------------------------

@pytest.fixture(scope="module")
def small_session(arm7, tmp_path_factory):
    """A simulated kit session written as a contact file: 4 placements, 10 poses per socket."""
    from robocal.io import write_contacts

    true = rc.perturb_model(arm7, rc.identifiability(arm7, parameters=("frames", "markers")).identified, rng=7)
    c = socket_campaign(true, placements=4, poses_per_socket=10, joint_noise=ENCODER, rng=7)
    path = tmp_path_factory.mktemp("kit") / "sockets.csv"
    write_contacts(c, path, arm7)
    return true, c, path


def test_the_contact_file_reads_back_what_was_written(arm7, small_session):
    _, c, path = small_session
    back = rc.io.read_contacts(path, arm7)
    np.testing.assert_allclose(back.q, c.q, atol=1e-10)
    np.testing.assert_allclose(back.sigma, c.sigma, rtol=1e-5)
    assert back.target == c.target and back.placement == c.placement and back.kind == c.kind
    assert [(d.a, d.b) for d in back.distances] == [(d.a, d.b) for d in c.distances]
    np.testing.assert_allclose([d.length for d in back.distances], [d.length for d in c.distances], rtol=1e-9)


def test_a_comment_of_its_own_is_not_taken_for_a_directive(arm7, small_session, tmp_path):
    _, c, path = small_session
    noted = tmp_path / "noted.csv"
    noted.write_text(path.read_text().replace("# units:", "# plate: printed PLA\n# operator: J. Doe\n# units:", 1))
    back = rc.io.read_contacts(noted, arm7)
    np.testing.assert_allclose(back.q, c.q, atol=1e-10)
    assert len(back.distances) == len(c.distances)


@pytest.mark.parametrize("edit, words", [
    (lambda t: t.replace("# units: length=mm angle=deg\n", ""), ["units directive"]),
    (lambda t: t.replace("angle=deg", "angle=mm"), ["unknown angle unit 'mm'"]),
    (lambda t: t.replace("P1,A,socket", "P1,A,sockett", 1), ["line 7", "kind 'sockett'"]),
    (lambda t: t.replace("# distance: A B", "# distance: A Z", 1), ["socket 'Z'"]),
    (lambda t: t.replace(",j3,", ",j33,"), ["column 'j3' is missing", "is 'j33' it?"]),
    (lambda t: t.replace(",sigma", ",sigmas"), ["unknown column 'sigmas'; did you mean 'sigma'?"]),
    # a misspelt directive would leave the robot's size unknown without a word
    (lambda t: t.replace("# distance:", "# distnce:"),
     ["line 3", "unknown directive 'distnce'; did you mean 'distance'?"]),
    (lambda t: t.replace("# distance:", "# spacing:"), ["line 3", "did you mean 'distance'?"]),
    (lambda t: t.replace("angle=deg\n", "angle=deg\n# units: length=m angle=rad\n"),
     ["line 3", "a second units directive"]),
    (lambda t: t.replace("# distance: A B 200.000000", "# distance: A B -200", 1),
     ["line 3", "length must be positive"]),
])
def test_bad_contact_files_are_refused_in_one_line(cli, arm7, small_session, tmp_path, edit, words):
    from conftest import assert_one_line_error

    _, _, path = small_session
    bad = tmp_path / "bad.csv"
    bad.write_text(edit(path.read_text()))
    code, _, err = cli("calibrate", ARM7, "--contacts", bad, "--out", tmp_path / "run")
    assert_one_line_error(code, err, [str(bad)] + words, tmp_path / "run")


def test_the_command_line_calibrates_from_contacts_alone_and_next_to_a_tracker_file(cli, arm7, small_session,
                                                                                      tmp_path):
    true, _, path = small_session
    code, out, err = cli("calibrate", ARM7, "--contacts", path, "--out", tmp_path / "a", "--holdout-placement", "P4")
    assert code == 0, err
    assert "held-out socket spread" in out and "unreachable: base" in out and "verdict: pass" in out
    written = rc.read_model(tmp_path / "a" / "calibrated.yaml")
    assert rc.parameter_vector(written).shape == rc.parameter_vector(arm7).shape
    # calibrated, from what: not the nominal model's own description
    assert written.description.startswith("calibrated model") and str(path) in written.description
    assert arm7.name in written.description and written.description != arm7.description
    result = __import__("json").loads((tmp_path / "a" / "result.json").read_text())
    assert [u["name"] for u in result["contacts"]["unreachable"]] == ["base"] and result["verdict"] == "pass"
    assert "held-out socket consistency" in out and "held-out spacing error" in out
    held = result["contacts"]["validation_after"]
    assert held["consistency_mean_m"] > 0 and held["consistency_max_m"] >= held["consistency_mean_m"]
    assert set(held["consistency_m"]) == {f"P4/{s}" for s in "ABC"} and held["spacing_error_max_m"] is not None
    tracker = rc.measure(true, rc.random_configurations(arm7, 15, 1), rng=1)
    rc.write_measurements(tracker, tmp_path / "tracker.csv", model=arm7)
    code, out, err = cli("calibrate", ARM7, tmp_path / "tracker.csv", "--contacts", path, "--out", tmp_path / "b")
    assert code == 0, err
    assert "tracker points:" in out and "unreachable" not in out
    code, _, err = cli("calibrate", ARM7, "--contacts", path, "--out", tmp_path / "c", "--holdout-placement", "P9")
    assert code == 2 and "no placement 'P9'" in err


def test_a_socket_plan_predicts_the_standard_deviations_the_calibration_reports(arm7):
    """The plan's predicted standard deviations against those a calibration of the same design
    (seatings drawn with the same seed, on a true arm with errors) reports: within 20 % on average."""
    ratios = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for seed in (1, 2):
            design = plan_sockets(arm7, placements=(3,), poses_per_socket=(20,), joint_noise=ENCODER,
                                  seed=seed).designs[0]
            true = _truth_for(arm7, lambda robot, r: socket_campaign(robot, placements=3, poses_per_socket=20,
                                                                     joint_noise=ENCODER, rng=r), seed)
            c = socket_campaign(true, placements=3, poses_per_socket=20, joint_noise=ENCODER,
                                rng=np.random.default_rng(seed))
            res = rc.calibrate(arm7, contacts=c)
            ratios += [p.std / design.predicted_std[p.name] for p in res.parameters]
            assert design.unreachable == ("base",)
    assert np.all(np.abs(np.array(ratios) - 1.0) < 0.2), (min(ratios), max(ratios))    # each parameter


def test_more_placements_or_seatings_never_predict_a_worse_parameter(arm7):
    plan = plan_sockets(arm7, placements=(1, 2, 3), poses_per_socket=(6, 12), joint_noise=ENCODER)
    by = {(d.placements, d.poses_per_socket): d.predicted_std for d in plan.designs}
    for small, big in [((1, 6), (2, 6)), ((2, 6), (3, 6)), ((1, 12), (2, 12)), ((2, 12), (3, 12)), ((3, 6), (3, 12))]:
        assert set(by[small]) == set(by[big])
        assert all(by[big][n] <= by[small][n] * (1 + 1e-9) for n in by[small]), (small, big)
    assert by[(3, 12)]["j7.d"] < by[(1, 6)]["j7.d"] / 1.5       # and it gains


def test_a_socket_plan_recommends_the_smallest_design_within_the_bounds(arm7):
    tight = {"length": 2e-5, "angle": np.deg2rad(0.002)}     # 0.02 mm, 0.002 deg
    plan = plan_sockets(arm7, placements=(3, 6), poses_per_socket=(20, 30), joint_noise=ENCODER, bounds=tight)
    by = {(d.placements, d.poses_per_socket): d for d in plan.designs}
    assert by[(6, 20)].worst_ratio < by[(3, 20)].worst_ratio and by[(6, 30)].worst_ratio < by[(3, 30)].worst_ratio
    good = [d for d in plan.designs if d.meets_bounds]
    assert good and plan.chosen == min(good, key=lambda d: d.n_seatings)
    assert not by[(3, 20)].meets_bounds      # the bounds decide: the smallest design is not enough
    assert plan.campaign.q.shape[0] == plan.chosen.n_seatings
    nothing = plan_sockets(arm7, placements=(3,), poses_per_socket=(20,), bounds={"length": 1e-9, "angle": 1e-12})
    assert nothing.chosen is None and nothing.held == ()
    # bounds no design meets for some parameters: those are held at nominal, as the calibration
    # holds them, and the design is chosen on the others
    lengths = plan_sockets(arm7, placements=(3,), poses_per_socket=(20,), bounds={"length": 1e-9})
    assert lengths.chosen is not None and lengths.held
    assert not set(lengths.held) & set(lengths.chosen.predicted_std)
    assert all(n.split(".")[1] in ("d", "r", "x", "y", "z") for n in lengths.held)


def test_a_design_too_small_to_identify_what_the_plate_reaches_is_never_recommended(arm7, cli, tmp_path):
    """One placement of two seatings per socket identifies only part of what the plate reaches: what
    it reaches is the largest design's, the small design loses the rest, is not recommended, and the
    summary names what it loses."""
    plan = plan_sockets(arm7, placements=(1, 3), poses_per_socket=(2, 20), joint_noise=ENCODER)
    by = {(d.placements, d.poses_per_socket): d for d in plan.designs}
    names = rc.candidate_parameters(arm7, ("geometric",))
    largest = socket_campaign(arm7, placements=3, poses_per_socket=20, rng=0)
    reach = contact_identifiability(Problem(arm7, names, contacts=largest, compliance=False), names).identified
    assert set(by[(3, 20)].predicted_std) == set(reach) and not by[(3, 20)].lost
    tiny = by[(1, 2)]
    assert tiny.lost and set(tiny.lost) | set(tiny.predicted_std) == set(reach)
    assert not tiny.meets_bounds and tiny.worst in tiny.lost
    assert plan.chosen is not None and plan.chosen != tiny and set(plan.chosen.predicted_std) == set(reach)
    code, out, err = cli("plan-sockets", ARM7, "--placements", "1,3", "--poses-per-socket", "2,20")
    assert code == 0, err
    assert f"socket plate: {len(reach)} parameters reachable" in out
    assert f"cannot identify {len(tiny.lost)} of the {len(reach)}: {', '.join(tiny.lost)}" in out
    assert "recommended: 1 placements, 2 seatings" not in out


def test_the_only_spacing_row_is_kept_and_named(arm7):
    """One placement, one known distance stated 5 mm wrong, and a socket row read while the arm moved
    (set aside and refitted): the distance alone fixes the scale, so it is kept in full (the stated
    spacing is met) and a check says that nothing else checks it. With three placements no
    distance row carries the scale alone and no such check appears."""
    from robocal._identification.solve import carried_alone

    true = rc.perturb_model(arm7, rc.identifiability(arm7, parameters=("frames", "markers")).identified, rng=0)
    runs = {}
    for placements in (1, 3):
        c = socket_campaign(true, placements=placements, poses_per_socket=25, joint_noise=ENCODER, rng=1)
        q = c.q.copy()
        q[5, 1] += 1e-3
        wrong = replace(c, q=q, distances=(replace(c.distances[0], length=c.distances[0].length + 5e-3),))
        names = rc.candidate_parameters(arm7, ("geometric",))
        prob = Problem(arm7, names, contacts=wrong, compliance=False)
        design = prob.over(contact_identifiability(prob, names).identified)
        alone = carried_alone(design.jacobian(design.start_vector()))
        kinds = [rc.identification.ROW_KINDS[k] for k in design.row_kinds()[alone]]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            runs[placements] = (kinds, rc.calibrate(arm7, contacts=wrong))
    kinds, res = runs[1]
    assert kinds == ["distance"]
    check = next(c for c in res.checks if c.name == "rows carried alone")
    assert check.status == "warn" and "P1: A-B" in check.summary and "the scale" in check.summary
    assert abs(res.contacts.fit_after.distance["P1: A-B"]) < 5 * 2e-6            # the stated spacing is met
    assert any(c.name.startswith("outliers") and "set aside" in c.summary for c in res.checks)
    kinds, res = runs[3]
    assert kinds == [] and not any(c.name == "rows carried alone" for c in res.checks)


@pytest.mark.parametrize("loss", ["soft_l1", "huber", "cauchy", "arctan"])
def test_a_partly_robust_loss_is_the_loss_with_the_kept_rows_linear(loss):
    from robocal._identification.solve import partly_robust, robust_weights

    z = np.array([0.0, 0.3, 0.9, 1.5, 4.0, 30.0, 0.3, 30.0])
    keep = np.array([False] * 6 + [True, True])
    rho = partly_robust(loss, keep)
    out, up, down = rho(z), rho(z * (1 + 1e-7) + 1e-9), rho(z * (1 - 1e-7) - 1e-9)
    h = (z * (1 + 1e-7) + 1e-9) - (z * (1 - 1e-7) - 1e-9)
    assert np.allclose(out[1], (up[0] - down[0]) / h, rtol=1e-5, atol=1e-7)        # rho' of rho
    assert np.allclose(out[2], (up[1] - down[1]) / h, rtol=1e-4, atol=1e-6)        # rho'' of rho'
    assert np.allclose(out[1, ~keep], robust_weights(np.sqrt(z[~keep]), loss, 1.0))
    assert np.array_equal(out[:, keep], np.vstack([z[keep], np.ones(2), np.zeros(2)]))


@pytest.fixture(scope="module")
def narrow_run(arm7):
    """One placement with the last joint held within 0.06 rad: the seatings barely turn it, and four
    pairs of parameters become interchangeable (r = -1.0000); the same readings as tracker data."""
    limits = list(arm7.joint_limits)
    limits[6] = (0.57, 0.63)
    narrow = arm7.replace(joint_limits=tuple(limits))
    true = rc.perturb_model(narrow, rc.identifiability(arm7, parameters=("frames", "markers")).identified, rng=0)
    sockets = socket_campaign(true, placements=1, poses_per_socket=20, joint_noise=ENCODER, rng=1)
    return narrow, sockets, rc.measure(true, sockets.q, rng=1)


@pytest.mark.parametrize("weak", ["eliminate", "flag"])
def test_interchangeable_parameters_are_held_back_or_flagged_as_on_tracker_data(narrow_run, weak):
    narrow, sockets, tracker = narrow_run
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        by_contacts = rc.calibrate(narrow, contacts=sockets, weak=weak)
        by_tracker = rc.calibrate(narrow, tracker, weak=weak)
    checks = [{c.name: c for c in r.checks}["identifiability at these poses"] for r in (by_contacts, by_tracker)]
    if weak == "eliminate":
        assert [n for n, _ in by_contacts.contacts.weak] == ["j7.alpha", "j7.d"]
        assert not {"j7.alpha", "j7.d"} & set(by_tracker.parameter_names)
        assert not {"j7.alpha", "j7.d"} & {p.name for p in by_contacts.parameters}
        assert [c.status for c in checks] == ["pass", "pass"]
        assert all("held at their nominal values" in c.summary for c in checks)
        assert max(abs(p.change) for p in by_contacts.parameters if p.quantity == "length") < 2e-3
    else:
        pairs = [{i for i in c.items if "~" in i} for c in checks]
        assert [c.status for c in checks] == ["warn", "warn"] and pairs[0] == pairs[1] and len(pairs[0]) == 4
        assert "ball.z ~ j7.alpha (r = -1.0000)" in pairs[0]


def test_calibrate_takes_contacts_and_holds_out_each_placement_in_turn(arm7, socket_run):
    _, fit, _ = socket_run
    res = rc.calibrate(arm7, contacts=fit)
    alias = rc.calibrate(arm7, contacts=fit)
    assert [p.estimate for p in res.parameters] == [p.estimate for p in alias.parameters]
    held, fitted, before = res.contacts.held_out, res.contacts.fit_after, res.contacts.fit_before
    assert set(held.consistency) == set(fitted.consistency) and set(held.distance) == set(fitted.distance)
    # each placement predicted by the others: worse than fitted, far better than the nominal
    assert fitted.consistency_mean < held.consistency_mean < before.consistency_mean / 20
    # contacts alone fix no frame: registering the base needs measured points beside them
    with pytest.raises(rc.InputError, match="no frame") as e:
        rc.calibrate(arm7, contacts=fit, initial_base="register")
    assert e.value.where == "initial_base"
    with pytest.raises(rc.InputError) as e:
        rc.calibrate(arm7)
    assert e.value.where == "data"


def _result(tmp_path, name):
    """The result file's parameters and its contacts' part, as one mapping."""
    d = __import__("json").loads((tmp_path / name / "result.json").read_text())
    return {"parameters": d["parameters"], **d["contacts"]}


def test_every_option_of_calibrate_works_with_contacts(cli, arm7, small_session, narrow_run, tmp_path):
    from robocal.io import write_contacts

    _, _, path = small_session
    narrow, sockets, _ = narrow_run
    write_contacts(sockets, tmp_path / "narrow.csv", narrow)
    runs = {"held": [], "flag": ["--weak", "flag"]}
    for name, extra in runs.items():
        code, out, err = cli("calibrate", ARM7, "--contacts", tmp_path / "narrow.csv", "--out", tmp_path / name, *extra)
        assert code in (0, 3), err
    held, flagged = _result(tmp_path, "held"), _result(tmp_path, "flag")
    assert [w["name"] for w in held["weak"]] == ["j7.alpha", "j7.d"] == [w["name"] for w in flagged["weak"]]
    assert not held["weak_kept"] and flagged["weak_kept"]
    assert "j7.alpha" not in {p["name"] for p in held["parameters"]} <= {p["name"] for p in flagged["parameters"]}
    assert "j7.alpha" in {p["name"] for p in flagged["parameters"]}
    # the limit: weak parameters judged at the robot's scatter, and kept where the held-out placements gain
    for name, extra in (("plain", []), ("limit", ["--limit-mm", "2"])):
        assert cli("calibrate", ARM7, "--contacts", path, "--out", tmp_path / name, *extra)[0] == 0
    assert _result(tmp_path, "plain")["weak"] == [] and _result(tmp_path, "limit")["weak"]
    assert _result(tmp_path, "limit")["weak_kept"]
    # masses from the geometry make compliance identifiable; the bound keeps it non-negative
    compliance = ["--parameters", "geometric,compliance"]
    for name, extra in (("masses", ["--assume-masses"]), ("bounded", ["--assume-masses", "--nonnegative-compliance"])):
        code, _, err = cli("calibrate", ARM7, "--contacts", path, "--out", tmp_path / name, *compliance, *extra)
        assert code == 0, err
    k = {name: [p["estimate"] for p in _result(tmp_path, name)["parameters"] if ".k_" in p["name"]]
         for name in ("masses", "bounded")}
    assert len(k["masses"]) == len(k["bounded"]) > 5
    assert min(k["masses"]) < 0 <= min(k["bounded"])
    code, _, err = cli("calibrate", ARM7, "--contacts", path, "--out", tmp_path / "none", *compliance)
    assert code == 2 and "--assume-masses" in err and not (tmp_path / "none").exists()


def test_held_out_seatings_judge_the_calibration_in_use(arm7, socket_run):
    _, fit, val = socket_run
    res = rc.calibrate(arm7, contacts=fit, validation=val)
    check = {c.name: c for c in res.checks}["accuracy in use"]
    assert check.status == "pass" and "held-out placements" in check.summary
    by_placement = {c.name: c for c in rc.calibrate(arm7, contacts=fit).checks}["accuracy in use"]
    assert by_placement.status == "pass" and "predicted by the others" in by_placement.summary
    # half of socket A's held-out seatings labelled B: nothing the fit explains
    target = list(val.target)
    rows = [i for i, t in enumerate(target) if t == "A"]
    for i in rows[::2]:
        target[i] = "B"
    wrong = rc.calibrate(arm7, contacts=fit, validation=replace(val, target=tuple(target)))
    check = {c.name: c for c in wrong.checks}["accuracy in use"]
    assert check.status == "fail" and "beyond anything the fit explains" in check.summary


def test_total_mass_scales_the_contact_compliances_and_nothing_else(cli, small_session, tmp_path):
    """--total-mass spreads a stated mass as --assume-masses spreads relative ones: every compliance
    scales by one factor, the geometry is the same."""
    _, _, path = small_session
    estimates = {}
    for name, extra in (("relative", ["--assume-masses"]), ("absolute", ["--total-mass", "20"])):
        code, _, err = cli("calibrate", ARM7, "--contacts", path, "--out", tmp_path / name,
                           "--parameters", "geometric,compliance", *extra)
        assert code == 0, err
        estimates[name] = {p["name"]: p["estimate"] for p in _result(tmp_path, name)["parameters"]}
    rel, absolute = estimates["relative"], estimates["absolute"]
    assert rel.keys() == absolute.keys()
    ratios = np.array([rel[n] / absolute[n] for n in rel if ".k_" in n])
    assert len(ratios) > 5 and abs(ratios[0] - 1.0) > 0.1 and np.ptp(ratios) < 1e-6 * abs(ratios[0])
    assert max(abs(rel[n] - absolute[n]) for n in rel if ".k_" not in n) < 1e-12


def test_the_only_rows_of_a_plane_are_carried_alone(arm7):
    """A plane touched three times: its three rows alone fix its offset and tilt (leverage 1), so a
    robust refit must keep them; the rows of well-sampled planes carry nothing alone."""
    from robocal._identification.solve import carried_alone

    c = plane_campaign(arm7, planes=4, poses_per_plane=30, joint_noise=ENCODER, rng=2)
    last = [i for i, t in enumerate(c.target) if t == c.target[-1]]
    keep = np.setdiff1d(np.arange(c.n_rows), last[3:])
    few = c.subset(keep)
    names = rc.candidate_parameters(arm7, ("geometric",))
    prob = Problem(arm7, names, contacts=few, compliance=False)
    design = prob.over(contact_identifiability(prob, names).identified)
    alone = np.nonzero(carried_alone(design.jacobian(design.start_vector())))[0]
    labels = np.array(design.row_labels())[alone]
    assert len(alone) == 3 and all(f"({c.target[-1]})" in label for label in labels), labels
