"""Joint and link compliance under gravity: identification, comparison with geometry alone,
and refusal of what cannot be computed."""

import numpy as np
import pytest

import robocal as rc
from robocal._design import select_poses
from robocal._model import Frame

from robots import arm6r, cylindrical

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


def _z(true, nominal, result, prefix=""):
    p = rc.parameter_vector(true, nominal)
    names = rc.parameter_names(nominal)
    return {e.name: (e.estimate - p[names.index(e.name)]) / e.std for e in result.parameters if prefix in e.name}


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
    assert cmp.geometric.stats["validation_after"]["rms"] > 2 * floor
    z = _z(true, m, cmp.combined, ".k_")
    assert len(z) >= 10 and all(abs(v) < 3 for v in z.values()), z
    assert cmp.helped and cmp.verdict.startswith("compliance helped")
    assert cmp.best is cmp.combined


def test_held_out_error_with_compliance_ends_near_the_noise_floor(design):
    # as for geometry alone, the bound holds for the mean over campaigns sharing a pose plan
    m = arm6r(masses=True)
    ratios = []
    for seed in range(8):
        true, fit, val = _campaign(m, design, seed, TRUE_K)
        res = rc.calibrate(m, fit, validation=val, parameters=BOTH)
        ratios.append(res.stats["validation_after"]["rms"] / _floor(true, val))
    assert np.mean(ratios) < 1.10, np.round(ratios, 3)


def test_zero_compliance_is_found_zero_and_reported_useless(design):
    m = arm6r(masses=True)
    zero = {n: 0.0 for n in TRUE_K}
    true, fit, val = _campaign(m, design, 3, zero)
    cmp = rc.compare(m, fit, validation=val)
    k = {e.name: e for e in cmp.combined.parameters if ".k_" in e.name}
    assert all(abs(e.estimate) < 3 * e.std for e in k.values()), {n: e.estimate / e.std for n, e in k.items()}
    assert not cmp.helped and cmp.verdict.startswith("compliance did not help")
    assert cmp.best is cmp.geometric


def test_paper_layout_table_lists_compliance():
    m = cylindrical(masses=True)
    ident = rc.identifiability(m, parameters=BOTH)
    table = {row["frame"]: row for row in ident.table(m.frame_names)}
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
