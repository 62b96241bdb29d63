"""Backlash (lost motion): the forward kinematics at q + b s, every Jacobian column against
central finite differences under both side models, the simulator's lost motion recovered."""

from dataclasses import replace

import numpy as np
import pytest
from robots import arm6r, cylindrical
from scipy.spatial.transform import Rotation
from test_kinematics import _random_tree_model

import robocal as rc
from robocal.kinematics import evaluate, model_from_vector, parameter_layout, parameter_vector

ARCMIN = np.pi / 180 / 60


def _with_backlash(model, rng, *, side="gravity", width=1.0, friction=0.0):
    """``model`` with a backlash of 0.5 to 3 arcmin (0.02 to 0.05 mm on slides) on every joint."""
    frames = tuple(replace(f, backlash_theta=rng.uniform(0.5, 3) * ARCMIN / 2 if f.joint == "revolute" else 0.0,
                           backlash_r=rng.uniform(0.02, 0.05) * 1e-3 / 2 if f.joint == "prismatic" else 0.0,
                           backlash_width=width, backlash_friction=friction) for f in model.frames)
    return model.replace(frames=frames, backlash_side=side)


def _fd(model, q, p, approach, h):
    cols = []
    for k in range(len(p)):
        dp = np.zeros_like(p)
        dp[k] = h
        e1, e0 = (evaluate(model, q, p + s * dp, orientations=True, compliance=True, backlash=True, approach=approach)
                  for s in (1, -1))
        dpos = (e1.positions - e0.positions) / (2 * h)
        dR = e1.rotations @ np.swapaxes(e0.rotations, -1, -2)
        drot = Rotation.from_matrix(dR.reshape(-1, 3, 3)).as_rotvec().reshape(dpos.shape) / (2 * h)
        cols.append(np.concatenate([dpos, drot], axis=-1))
    return np.stack(cols, axis=-1)


def _column_errors(model, q, approach=None, h=1e-6):
    p = parameter_vector(model)
    J = evaluate(model, q, jacobian=True, compliance=True, backlash=True, approach=approach).jacobian
    F = _fd(model, q, p, approach, h)
    scale = np.maximum(np.abs(F).max(axis=(0, 1, 2)), 1e-3)   # relative per column, absolute near zero
    err = np.abs(J - F).max(axis=(0, 1, 2)) / scale
    names = parameter_layout(model).names
    return {names[k]: err[k] for k in np.nonzero(err > 1e-6)[0]}


@pytest.mark.parametrize("side, width, friction", [("gravity", 1e-3, 0.0), ("gravity", 20.0, 0.0),
                                                   ("gravity", 3.0, 2.0), ("approach", 1.0, 0.0)])
def test_every_column_matches_finite_differences_on_random_trees(side, width, friction):
    # width 1e-3: every load far from the transition; 20: every pose within it (the chain-rule
    # terms through the load matter); friction: the approach shifts the transition
    rng = np.random.default_rng(5)
    m = _with_backlash(_random_tree_model(4), rng, side=side, width=width, friction=friction)
    q = rng.uniform(-1, 1, (6, 6))
    approach = rng.choice([-1.0, 1.0], (6, 6))
    assert not _column_errors(m, q, approach)


@pytest.mark.parametrize("make", [arm6r, cylindrical])
def test_columns_match_on_serial_arms_near_the_transition(make):
    rng = np.random.default_rng(2)
    m = _with_backlash(make(masses=True), rng, width=30.0)
    q = rc.random_configurations(m, 6, rng=1)
    assert not _column_errors(m, q)
    lay = parameter_layout(m)
    p = parameter_vector(m)
    p[[prm.index for prm in lay.parameters if prm.family == "compliance"]] = 1e-5
    assert not _column_errors(model_from_vector(m, p), q)


def test_model_file_keeps_backlash_and_its_side(tmp_path):
    m = _with_backlash(cylindrical(masses=True), np.random.default_rng(0), side="approach", width=0.5, friction=2.0)
    rc.write_model(m, tmp_path / "m.yaml")
    back = rc.read_model(tmp_path / "m.yaml")
    assert back.backlash_side == "approach"
    np.testing.assert_allclose(parameter_vector(back), parameter_vector(m), atol=1e-12)
    assert [f.backlash_width for f in back.frames] == [0.5] * 6
    assert [f.backlash_friction for f in back.frames] == [2.0] * 6
    text = (tmp_path / "m.yaml").read_text().replace("side: approach", "side: sideways")
    (tmp_path / "bad.yaml").write_text(text)
    with pytest.raises(rc.InputError, match="backlash.side"):
        rc.read_model(tmp_path / "bad.yaml")


def test_approach_columns_are_read_written_and_kept_by_a_split(tmp_path):
    m = cylindrical(masses=True)
    q = rc.random_configurations(m, 8, rng=0)
    data = rc.measure(m, q, rng=1)
    # written only where the row order does not give them
    rc.write_measurements(data, tmp_path / "order.csv", model=m)
    assert "approach_" not in (tmp_path / "order.csv").read_text()
    flipped = -data.extra["approach"]
    data2 = rc.Measurements(q=data.q, positions=data.positions, marker_names=data.marker_names,
                            joint_names=data.joint_names, extra={"approach": flipped})
    rc.write_measurements(data2, tmp_path / "a.csv", model=m)
    back = rc.read_measurements(tmp_path / "a.csv", m)
    np.testing.assert_array_equal(back.extra["approach"], flipped)
    fit, val = back.split(3, rng=0)
    both = np.vstack([fit.extra["approach"], val.extra["approach"]])
    assert sorted(map(tuple, both)) == sorted(map(tuple, flipped))
    text = (tmp_path / "a.csv").read_text().splitlines()
    text[1] = text[1][:-2] + "+2"
    (tmp_path / "bad.csv").write_text("\n".join(text) + "\n")
    with pytest.raises(rc.InputError, match="approach"):
        rc.read_measurements(tmp_path / "bad.csv", m)


# --- recovery from the campaign simulator's lost motion (an implementation of its own) -------------

NOISE = 2e-5
N_FIT, N_VAL, CAMPAIGNS = 60, 60, 10
BOTH_SIDES = ("geometric", "backlash")
# the transmission's friction (N m, N): where gravity's load beats it the joint rests on the side
# gravity pushes it to, else behind its last move; the identification model says the same
FRICTION = {"revolute": 1.0, "prismatic": 10.0}


def _robot(make, side):
    nom = make(masses=True)
    frames = tuple(replace(f, backlash_width=0.01, backlash_friction=FRICTION[f.joint] if side == "gravity" else 0.0)
                   for f in nom.frames)
    return nom.replace(frames=frames, backlash_side=side)


@pytest.fixture(scope="module")
def plans():
    """Per robot and side, 60 poses chosen for geometry and backlash, as a motion program: under
    the approach-sided model each pose is reached past an overshoot from the chosen direction."""
    out = {}
    for make in (arm6r, cylindrical):
        for side in ("gravity", "approach"):
            sel = rc.select_poses(_robot(make, side), N_FIT, parameters=BOTH_SIDES, n_candidates=400, sweeps=1, rng=0)
            assert not sel.one_sided
            if sel.approach is None:
                out[make.__name__, side] = (sel.q, np.arange(N_FIT))
            else:
                program = np.empty((2 * N_FIT, sel.q.shape[1]))
                program[0::2], program[1::2] = sel.q - 0.05 * sel.approach, sel.q
                out[make.__name__, side] = (program, np.arange(1, 2 * N_FIT, 2))
    return out


def _lost_campaign(m, plan, seed, scale=1.0):
    """A true robot near ``m`` with lost motion of 0.5 to 3 arcmin (0.02 to 0.05 mm on slides),
    measured by the campaign simulator: (true half lost motions, fit, held-out, noise floor)."""
    from robocal.sim import RobotImperfections, measure_campaign
    rng = np.random.default_rng(seed)
    true, _ = rc.simulate(m, 2, parameters=("geometric",), seed=seed)
    lost = np.array([rng.uniform(0.5, 3) * ARCMIN if f.joint == "revolute" else rng.uniform(0.02, 0.05) * 1e-3
                     for f in m.frames]) * scale
    imp = RobotImperfections(encoder_resolution=(0.0,) * 6, repeatability_sigma=NOISE, instrument_noise_per_m=0.0,
                             backlash=tuple(lost), backlash_friction=tuple(f.backlash_friction for f in m.frames)
                             if m.backlash_side == "gravity" else ())
    program, measured = plan
    q = np.vstack([program, rc.random_configurations(m, N_VAL, rng=rng)])
    data = measure_campaign(true, q, imp, rng=seed)
    exact = measure_campaign(true, q, replace(imp, repeatability_sigma=0.0), rng=seed)
    n = len(program)
    floor = np.sqrt(np.mean(np.sum((data.positions - exact.positions)[n:] ** 2, axis=-1)))
    return dict(zip(m.frame_names, lost / 2)), data.subset(measured), data.subset(slice(n, None)), floor


@pytest.mark.parametrize("make", [arm6r, cylindrical])
@pytest.mark.parametrize("side", ["gravity", "approach"])
def test_lost_motion_is_recovered_and_the_held_out_error_reaches_the_noise_floor(make, side, plans):
    import warnings
    m = _robot(make, side)
    ratios = []
    for seed in range(CAMPAIGNS):
        half, fit, val, floor = _lost_campaign(m, plans[make.__name__, side], seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", rc.RobocalWarning)
            res = rc.calibrate(m, fit, validation=val, parameters=BOTH_SIDES)
        ratios.append(res.stats.validation_after.rms / floor)
        if seed == 0:
            est = {e.name: e for e in res.parameters if e.family == "backlash"}
            assert len(est) >= 4, sorted(est)
            z = {n: (e.estimate - half[n.split(".")[0]]) / e.std for n, e in est.items()}
            assert all(abs(v) < 3 for v in z.values()), z
    assert np.mean(ratios) < 1.10, np.round(ratios, 3)


def test_without_lost_motion_backlash_is_found_zero_and_the_comparison_says_it_did_not_help(plans):
    import warnings
    m = _robot(arm6r, "gravity")
    half, fit, val, _ = _lost_campaign(m, plans["arm6r", "gravity"], 3, scale=0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rc.RobocalWarning)
        cmp = rc.compare(m, fit, validation=val, backlash=True, transmission=False)
    est = [e for e in cmp.backlash.parameters if e.family == "backlash"]
    assert len(est) >= 4 and all(abs(e.estimate) < 3 * e.std for e in est), [(e.name, e.estimate / e.std) for e in est]
    # backlash is added to the identification kept before it
    small, name = ((cmp.combined, "geometric and compliance") if cmp.compliance_test.helped else
                   (cmp.geometric, "geometric"))
    assert set(small.parameter_names) <= set(cmp.backlash.parameter_names)
    assert not cmp.backlash_test.helped and f"backlash (on {name}) did not help" in cmp.verdict
    assert cmp.best is not cmp.backlash
    larger = "geometric, compliance and backlash" if cmp.compliance_test.helped else "geometric and backlash"
    assert list(cmp.results) == ["geometric", "geometric and compliance", larger]


def test_a_backlash_whose_side_never_changes_is_absorbed_by_its_joint_offset():
    m = _robot(cylindrical, "approach")
    q = rc.random_configurations(m, 40, rng=0)
    one_way = rc.Measurements(q=q, positions=np.zeros((40, 1, 3)), marker_names=m.marker_names,
                              extra={"approach": np.ones((40, 6))})
    ident = rc.identifiability(m, one_way, parameters=BOTH_SIDES)
    for f in m.frames:
        name = f"{f.name}.backlash_{'theta' if f.joint == 'revolute' else 'r'}"
        a = next(a for a in ident.eliminated if a.name == name)
        absorbers = dict(a.absorbers)
        # the offset of the joint's own variable carries it with the side's sign (resting behind a
        # move that always comes from +: -1), or what carries that offset where it is eliminated too
        offset = f"{f.name}.{'theta' if f.joint == 'revolute' else 'r'}"
        carriers = {offset: 1.0} if offset in ident.identified else \
            dict(next(a for a in ident.eliminated if a.name == offset).absorbers)
        assert name not in ident.identified and set(absorbers) == set(carriers), (name, absorbers, carriers)
        assert "same side of its lost motion at every pose, so the joint offset absorbs it" in a.reason
        for n, c in carriers.items():
            assert absorbers[n] == pytest.approx(-c, abs=1e-6)
    # with both sides visited (the row order of random poses) they are identified
    both = rc.identifiability(m, rc.measure(m, q, rng=0), parameters=BOTH_SIDES)
    assert sum(n.endswith(("backlash_theta", "backlash_r")) for n in both.identified) == 6


def test_backlash_checks_sign_tolerance_and_support():
    from robocal._identification.checks import (
        DEFAULT_TOLERANCES,
        backlash_sign_check,
        plausibility_check,
        support_check,
    )
    from robocal._identification.estimates import ParameterEstimate
    e = ParameterEstimate("j1.backlash_theta", "rad", 0.0, -1e-3, 1e-5, family="backlash", quantity="angle")
    assert backlash_sign_check([e]).status == "warn"
    assert backlash_sign_check([replace(e, estimate=-1e-5)]).status == "pass"
    assert plausibility_check([e], DEFAULT_TOLERANCES, {}).status == "pass"
    big = replace(e, estimate=0.02)
    assert plausibility_check([big], DEFAULT_TOLERANCES, {}).status == "fail"
    noise = replace(e, estimate=1e-5)
    # a family the data do not show is said, not warned: the accuracy in use judges the model with it
    assert support_check([noise]).status == "pass" and "no backlash" in support_check([noise]).summary
    assert support_check([e]).status == "pass"


def test_command_line_compares_three_identifications(tmp_path, cli):
    from robocal.io import write_measurements, write_model
    m = _robot(cylindrical, "approach")
    true = _with_backlash(m, np.random.default_rng(1), side="approach")
    data = rc.measure(true, rc.random_configurations(m, 60, rng=2), rng=3)
    write_model(m, tmp_path / "model.yaml")
    write_measurements(data, tmp_path / "data.csv", model=m)
    code, out, err = cli("calibrate", tmp_path / "model.yaml", tmp_path / "data.csv", "--out", tmp_path / "cmp",
                         "--compare", "--backlash", "--holdout", "0.3")
    assert code in (0, 3), err
    assert "backlash (on geometric) helped" in out and "calibrated model chosen: geometric+backlash" in out
    assert {p.name for p in (tmp_path / "cmp").iterdir()} >= {"result-geometric.json", "result-compliance.json",
                                                              "result-backlash.json", "result.json"}
    chosen = rc.read_result(tmp_path / "cmp" / "result.json")
    assert any(p.family == "backlash" for p in chosen.parameters)
    code, out, err = cli("calibrate", tmp_path / "model.yaml", tmp_path / "data.csv", "--out", tmp_path / "one",
                         "--backlash")
    assert code == 2 and "--backlash" in err and "Traceback" not in err
    # the side chosen for this campaign, over the model file's: gravity-sided needs masses the arm has
    code, out, err = cli("calibrate", tmp_path / "model.yaml", tmp_path / "data.csv", "--out", tmp_path / "grav",
                         "--parameters", "geometric,backlash", "--backlash-side", "gravity")
    assert code in (0, 3), err
    assert rc.read_result(tmp_path / "grav" / "result.json").calibrated_model.backlash_side == "gravity"
