"""Joint and link compliance under gravity: identification, comparison with geometry alone,
and refusal of what cannot be computed."""

import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import z_scores
from robots import arm6r, cylindrical

import robocal as rc
from robocal import select_poses
from robocal.kinematics import Frame

NOISE = 2e-5
# rad/(N m); gravity moves the tool of arm6r(masses=True) by 0.25 mm on average, 1 mm at most
TRUE_K = {"j1.k_alpha": 1.5e-6, "j1.k_beta": 1.5e-6, "j2.k_theta": 4.5e-6, "j3.k_theta": 7.5e-6,
          "j3.k_alpha": 3.75e-6, "j4.k_theta": 7.5e-5, "j5.k_theta": 7.5e-5}
BOTH = ("geometric", "compliance")


def _deflection(m, true_k):
    p = rc.parameter_vector(m)
    names = rc.parameter_names(m)
    for n, v in true_k.items():
        p[names.index(n)] = v
    q = rc.random_configurations(m, 500, rng=0)
    d = rc.forward_kinematics(rc.model_from_vector(m, p), q).positions - rc.forward_kinematics(m, q).positions
    return np.linalg.norm(d, axis=2)


def _campaign(m, design, seed, true_k, n_val=300):
    q = np.vstack([design, rc.random_configurations(m, n_val, rng=500 + seed)])
    true, data = rc.simulate(m, q=q, parameters=BOTH, true_compliance=true_k, noise=NOISE, seed=seed)
    n = len(design)
    return true, data.subset(slice(0, n)), data.subset(slice(n, None))


def _floor(true, val):
    e = np.linalg.norm(rc.forward_kinematics(true, val.q).positions - val.positions, axis=2)
    return np.sqrt(np.mean(e ** 2))


@pytest.fixture(scope="module")
def design():
    return select_poses(arm6r(masses=True), 60, parameters=BOTH, rng=0).q


def test_test_compliance_is_of_the_stated_size():
    d = _deflection(arm6r(masses=True), TRUE_K)
    assert 0.2e-3 < d.mean() < 0.3e-3 and d.max() < 1.0e-3


def test_compliance_is_recovered_and_helps(design):
    m = arm6r(masses=True)
    true, fit, val = _campaign(m, design, 0, TRUE_K)
    cmp = rc.compare(m, fit, validation=val)
    floor = _floor(true, val)
    # geometry alone leaves a clear residual
    assert cmp.geometric.stats.validation_after.rms > 2 * floor
    z = dict(zip(cmp.combined.parameter_names, z_scores(cmp.combined, true, m)))
    z = {n: v for n, v in z.items() if cmp.combined.estimate(n).family == "compliance"}
    assert len(z) >= 10 and all(abs(v) < 3 for v in z.values()), z
    assert cmp.compliance_test.helped and cmp.verdict.startswith("compliance helped")
    assert cmp.best is cmp.combined


def test_held_out_error_with_compliance_ends_near_the_noise_floor(design):
    # as for geometry alone, the bound holds for the mean over campaigns sharing a pose plan
    m = arm6r(masses=True)
    ratios = []
    for seed in range(8):
        true, fit, val = _campaign(m, design, seed, TRUE_K)
        res = rc.calibrate(m, fit, validation=val, parameters=BOTH)
        ratios.append(res.stats.validation_after.rms / _floor(true, val))
    assert np.mean(ratios) < 1.10, np.round(ratios, 3)


def test_zero_compliance_is_found_zero_and_reported_useless(design):
    m = arm6r(masses=True)
    zero = {n: 0.0 for n in TRUE_K}
    true, fit, val = _campaign(m, design, 3, zero)
    cmp = rc.compare(m, fit, validation=val)
    k = {e.name: e for e in cmp.combined.parameters if ".k_" in e.name}
    assert all(abs(e.estimate) < 3 * e.std for e in k.values()), {n: e.estimate / e.std for n, e in k.items()}
    assert not cmp.compliance_test.helped and cmp.verdict.startswith("compliance did not help")
    assert cmp.best is cmp.geometric


def test_an_identification_not_nested_in_the_other_is_said_beside_its_f_test(design):
    """The F test takes the larger identification to hold every parameter of the smaller; one that
    holds some at nominal is said, by name. ``compare`` keeps them (its nested fits add to the
    smaller's parameters)."""
    from robocal._identification.calibrate import nested_test

    m = arm6r(masses=True)
    _, fit, val = _campaign(m, design, 0, TRUE_K)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cmp = rc.compare(m, fit, validation=val)
        held = rc.calibrate(m, fit, validation=val, parameters=BOTH, known=("j2.alpha",))
    assert set(cmp.geometric.parameter_names) <= set(cmp.combined.parameter_names)
    assert "not nested" not in cmp.compliance_test.summary
    said = nested_test(cmp.geometric, held, val, 0.01, "compliance").summary
    assert "j2.alpha" in cmp.geometric.parameter_names and said.endswith(
        "; not nested: the larger holds j2.alpha at nominal, which the smaller identifies (the F test compares fits "
        "that are not nested)")


def test_paper_layout_table_lists_compliance():
    m = cylindrical(masses=True)
    ident = rc.identifiability(m, parameters=BOTH)
    table = {row["frame"]: row for row in rc.status_table(ident, m.frame_names)}
    # gravity has no moment about the vertical base axis: its torsion cannot show
    assert table["j1"]["k_theta"] == "E"
    assert ident.absorption("j1.k_theta").reason == "has no effect on the measurements"
    assert any(table[f]["k_theta"] == "I" for f in ("j4", "j5"))


def test_compliance_without_masses_is_refused():
    with pytest.raises(rc.InputError, match="need link masses"):
        rc.calibrate(arm6r(), rc.simulate(arm6r(), 60, seed=0)[1], parameters=BOTH)


def test_negative_mass_is_refused():
    with pytest.raises(rc.InputError, match="mass must be a non-negative"):
        Frame(name="x", mass=-1.0, coupling=((0, 1.0),)) and rc.serial_model("bad", [dict(mass=-1.0)])


def test_payload_per_pose_enters_the_moments():
    m = arm6r(masses=True)
    k = dict(TRUE_K)
    q = rc.random_configurations(m, 5, rng=1)
    p = rc.parameter_vector(m)
    names = rc.parameter_names(m)
    for n, v in k.items():
        p[names.index(n)] = v
    mk = rc.model_from_vector(m, p)
    light = rc.forward_kinematics(mk, q, payload_mass=np.zeros(5)).positions
    heavy = rc.forward_kinematics(mk, q, payload_mass=np.full(5, 10.0)).positions
    assert np.linalg.norm(heavy - light, axis=2).min() > 1e-6


# ------------------------------------------------------------------------------------------------
# gravity loads on the joints (what decides the side of a loaded joint's backlash)

def _potential_gradient(m, q, payload_mass=None, h=1e-6):
    """d/dq of sum_k m_k g . c_k by central differences: the generalised gravity force."""
    def work(qq):
        X = rc.forward_kinematics(m, qq, frames=True).frames
        g = np.asarray(m.gravity)
        total = np.zeros(len(qq))
        bodies = [(f.mass, i, f.com) for i, f in enumerate(m.frames)]
        pm = m.payload.mass if payload_mass is None else payload_mass
        bodies.append((pm, m.payload.frame if m.payload.frame >= 0 else m.n_frames - 1, m.payload.com))
        for mass, i, com in bodies:
            c = X[:, i, :3, :3] @ np.asarray(com, float) + X[:, i, :3, 3]
            total += mass * (c @ g)
        return total
    out = np.zeros(q.shape)
    for j in range(q.shape[1]):
        dq = np.zeros(q.shape[1])
        dq[j] = h
        out[:, j] = (work(q + dq) - work(q - dq)) / (2 * h)
    return out


def test_gravity_loads_by_hand_for_one_horizontal_axis():
    # joint axis along W's y (base turned -90 deg about x), 2 kg at 0.5 m along x: at q = 0 gravity
    # (0, 0, -9.81) pulls x towards -z, a positive turn about y: + 2 * 9.81 * 0.5 N m
    c, s = np.cos(-np.pi / 2), np.sin(-np.pi / 2)
    m = rc.serial_model("h", [dict(joint="revolute", mass=2.0, com=(0.5, 0, 0))], markers=[("t", (1.0, 0, 0))],
                        base_rotation=[[1, 0, 0], [0, c, -s], [0, s, c]])
    q = np.array([[0.0], [np.pi], [np.pi / 2], [np.pi / 3]])
    np.testing.assert_allclose(rc.gravity_loads(m, q)[:, 0],
                               9.81 * np.array([1.0, -1.0, 0.0, 0.5]), rtol=0, atol=1e-12)


@pytest.mark.parametrize("which", ["cylindrical", "torso"])
def test_gravity_loads_are_the_potential_energys_gradient(which):
    if which == "cylindrical":
        m = cylindrical(masses=True)      # prismatic joints, one vertical, one horizontal
    else:
        # a tree with a coupled joint: couplings map frame loads to joints by virtual work
        m = rc.read_model(Path(__file__).resolve().parents[1] / "examples" / "torso" / "model.yaml")
        frames = [replace(f, mass=1.0 + i, com=(0.05, -0.02 * i, 0.1)) for i, f in enumerate(m.frames)]
        m = m.replace(frames=tuple(frames), payload=rc.Payload(mass=1.5, com=(0.0, 0.0, 0.1), frame=5))
    q = rc.random_configurations(m, 7, rng=3)
    expected = _potential_gradient(m, q)
    np.testing.assert_allclose(rc.gravity_loads(m, q), expected, rtol=1e-6, atol=1e-6)
    pm = np.linspace(0.0, 4.0, len(q))
    np.testing.assert_allclose(rc.gravity_loads(m, q, payload_mass=pm),
                               _potential_gradient(m, q, payload_mass=pm), rtol=1e-6, atol=1e-6)


def test_the_loads_of_other_values_on_a_models_layout_are_that_models_own():
    """The diagnosis takes a calibrated model's gravity loads on the nominal's structure, whose layout
    exists (``loads_at``): the numbers ``gravity_loads`` gives the calibrated model itself, its
    compliances left out as there."""
    from robocal._model.kinematics import layout, loads_at
    from robocal._model.parameters import candidate_parameters, model_from_vector, parameter_layout, parameter_vector

    m = arm6r(masses=True)
    p = parameter_vector(m)
    lay = parameter_layout(m)
    moved = [lay[n].index for n in candidate_parameters(m, ("geometric", "compliance"))]
    # values on the model's own layout (its stored rotations), as a calibration's are
    p[moved] += np.random.default_rng(4).uniform(1e-6, 2e-2, len(moved))
    other = model_from_vector(m, p)
    q = rc.random_configurations(m, 9, rng=5)
    pm = np.linspace(0.0, 3.0, len(q))
    expected = rc.gravity_loads(other, q, payload_mass=pm)
    assert np.abs(expected - rc.gravity_loads(m, q, payload_mass=pm)).max() > 1e-3      # the values matter
    np.testing.assert_allclose(loads_at(m, layout(m), p, q, payload_mass=pm), expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("factors", [(2.0, 0.5, 2.0, 0.5, 2.0, 0.5), (0.5, 2.0, 0.5, 2.0, 0.5, 2.0)])
def test_default_masses_give_most_of_the_compliance_benefit(factors):
    """True masses up to 2x off the default mass model: compliance identified with the default still
    brings at least 80 % of the held-out improvement (over geometry alone) that the true masses bring."""
    default = rc.default_masses(arm6r(), total_mass=50.0)
    assert default.notes[-1].startswith("masses assumed from the geometry (total 50 kg): j2 21.8 kg")
    true_masses = default.replace(frames=tuple(replace(f, mass=f.mass * k) for f, k in zip(default.frames, factors)),
                                  notes=())
    true, data = rc.simulate(true_masses, 80, true_compliance={"j2.k_theta": 3e-6, "j3.k_theta": 4e-6,
                                                               "j2.k_alpha": 1e-6}, seed=1)
    fit, val = data.split(0.3, rng=1)
    gain = {}
    for name, m in (("true", true_masses), ("default", default)):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")      # the checks' warnings on the geometric fit are expected
            geo = rc.calibrate(m, fit, validation=val, parameters=("geometric",))
            both = rc.calibrate(m, fit, validation=val, parameters=("geometric", "compliance"))
        gain[name] = geo.stats.validation_after.rms - both.stats.validation_after.rms
        assert any("masses assumed" in n for n in both.notes) == (name == "default")
    assert gain["true"] > 0 and gain["default"] >= 0.8 * gain["true"], gain



def test_assume_masses_on_the_command_line(tmp_path, cli):
    model = arm6r()
    rc.write_model(model, tmp_path / "m.yaml")
    true, data = rc.simulate(rc.default_masses(model, 50.0), 40, true_compliance={"j2.k_theta": 3e-6}, seed=3)
    rc.write_measurements(data, tmp_path / "d.csv", model=model)
    argv = ("calibrate", tmp_path / "m.yaml", tmp_path / "d.csv", "--parameters", "geometric,compliance")
    code, out, err = cli(*argv, "--out", tmp_path / "a")
    assert code == 2 and "--assume-masses" in err
    code, out, err = cli(*argv, "--out", tmp_path / "b", "--total-mass", "50")
    assert code in (0, 3), err
    assert "note: masses assumed from the geometry (total 50 kg): j2 21.8 kg" in out
    code, out, err = cli(*argv, "--out", tmp_path / "c", "--assume-masses")
    assert "kg per metre, no total mass given: compliances are relative" in out


def test_fixed_frames_get_no_compliance_candidates(tmp_path):
    # a tool flange placed by a matrix, as users write fixed frames: it has no joint to yield
    text = Path(__file__).resolve().parent.parent.joinpath("examples/th8/model.yaml").read_text()
    model = rc.read_model(Path(__file__).resolve().parent.parent / "examples/th8/model.yaml")
    last = model.frames[-1].name
    text = text.replace("markers:", f"""  - name: flange
    joint: fixed
    parent: {last}
    position: [10, 20, 80]
    rotation: {{matrix: [[0, -1, 0], [1, 0, 0], [0, 0, 1]]}}
markers:""", 1)
    path = tmp_path / "model.yaml"
    path.write_text(text)
    flanged = rc.read_model(path)
    assert flanged.frames[-1].name == "flange" and flanged.frames[-1].joint == "fixed"
    names = rc.candidate_parameters(flanged, ("compliance",))
    moving = [f.name for f in flanged.frames if f.joint != "fixed"]
    assert names == rc.candidate_parameters(model, ("compliance",))
    assert {n.split(".")[0] for n in names} == set(moving) and not any(n.startswith("flange.") for n in names)
    assert not any(n.startswith("flange.k_") for n in rc.candidate_parameters(flanged, ("*.k_*",)))


def test_data_failing_a_check_before_solving_compare_nothing():
    """Points in metres declared as millimetres (a cloud 1,000 times the robot's spread too small):
    0fb5037 compared compliance and every transmission level on them too, each crawling to its
    evaluation limit (20 s of CPU for 20 poses); the geometric calibration's failure is the answer."""
    m = cylindrical(masses=True)
    _, data = rc.simulate(m, 40, seed=3)
    wrong = replace(data, positions=data.positions * 1e-3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        comparison = rc.compare(m, wrong)
    assert comparison.geometric.verdict == "fail" and comparison.combined is None
    assert comparison.transmission is None
    assert comparison.skipped == ("nothing compared: the data fail measured points against the robot's size, "
                                  "checked before solving; correct them and compare again",)
    clean = rc.compare(m, data, transmission=False)       # the same robot's own data: compared
    assert clean.combined is not None and clean.skipped == ()
