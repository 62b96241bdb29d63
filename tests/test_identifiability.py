"""Identifiability: what the robot's structure and the poses let the data separate, and what absorbs the rest."""

import numpy as np
import pytest
from robots import arm6r, cylindrical

import robocal as rc

NOISE = 2e-5


def test_errors_on_eliminated_parameters_are_absorbed_exactly():
    # the true robot has errors on every geometric parameter, even those that cannot be identified:
    # the identified set still reproduces it exactly (the dependencies are global, not first order)
    m = arm6r()
    names = rc.candidate_parameters(m, ("geometric",))
    true = rc.perturb_model(m, names, rng=5)
    data = rc.measure(true, rc.random_configurations(m, 60, rng=6), noise=0.0)
    res = rc.calibrate(m, data)
    assert res.stats.fit_after.max < 1e-10


def test_eliminated_parameters_are_those_theory_predicts():
    ident = rc.identifiability(arm6r())
    elim = {a.name: dict(a.absorbers) for a in ident.eliminated}
    # frame 1 is absorbed by the base (its transform precedes joint 1 or commutes with it)
    for k in ("beta", "alpha", "d", "theta", "r"):
        assert f"j1.{k}" in elim
    assert elim["j1.theta"] == pytest.approx({"base.rz": 1.0})
    assert elim["j1.r"] == pytest.approx({"base.z": 1.0})
    # joints 2 and 3 are parallel: r3 lies along r2; beta3 takes its place
    assert elim["j3.r"] == pytest.approx({"j2.r": 1.0})
    assert "j3.beta" in ident.identified
    # the point marker absorbs the last joint's offset along and about its axis
    assert "j6.r" in elim and "j6.theta" in elim
    assert len(ident.identified) == 27
    table = {row["frame"]: row for row in rc.status_table(ident, arm6r().frame_names)}
    assert table["j3"]["beta"] == "I" and table["j3"]["r"] == "E" and table["j2"]["beta"] == "-"


def test_cylindrical_eliminations():
    ident = rc.identifiability(cylindrical())
    elim = {a.name for a in ident.eliminated}
    # the vertical prismatic joint is parallel to the base joint: its r and theta offsets are the base's
    assert {"j2.r", "j2.theta"} <= elim
    # the wrist roll axis is parallel to the radial axis and on the same line
    assert {"j4.r", "j4.theta"} <= elim
    assert "j4.beta" in ident.identified and "j2.beta" in ident.identified


def test_held_fixed_base_makes_frame1_visible():
    ident = rc.identifiability(arm6r(), known=("base",))
    assert "j1.theta" in ident.identified and "j1.alpha" in ident.identified
    assert not any(n.startswith("base.") for n in ident.candidates)


def test_tolerance_is_stated_and_settable():
    m = arm6r()
    assert rc.identifiability(m).tol == 1e-6
    loose = rc.identifiability(m, tol=0.5)
    assert len(loose.identified) < 27 and loose.tol == 0.5
    assert loose.condition_number >= 1 and set(loose.observability) == {"O1", "O2", "O3", "O4", "O5"}


def test_rank_deficient_design_is_explained():
    # joint 5 never moves: the wrist parameters it would reveal cannot be separated
    m = arm6r()
    q = rc.random_configurations(m, 60, rng=3)
    q[:, 4] = 0.3
    true = rc.perturb_model(m, rc.identifiability(m).identified, rng=1)
    data = rc.measure(true, q, noise=NOISE, rng=4)
    with pytest.warns(rc.IdentifiabilityWarning, match="cannot separate"):
        res = rc.calibrate(m, data)
    check = next(c for c in res.checks if c.name == "identifiability at these poses")
    assert check.status == "warn" and "j5.alpha" in check.items and res.verdict != "pass"
    assert len(res.parameters) < 27


def _weak_by_brute_force(J, names, quantities, sigma, bounds):
    """The weak test as stated, one trial at a time: each column joins the kept ones unless the
    trial's (A^T A)^-1, by a full SVD, leaves one of them beyond its bound."""
    norms = np.linalg.norm(J, axis=0)
    limit = np.array([bounds.get(q, np.inf) for q in quantities])
    kept, out = [], []
    for k in range(len(names)):
        trial = kept + [k]
        A = J[:, trial] / norms[trial]
        _, s, vt = np.linalg.svd(A, full_matrices=False)
        effect = sigma * np.sqrt(np.sum((vt / s[:, None]) ** 2, axis=0)) / norms[trial]
        ratio = effect / limit[trial]
        if ratio.max() > 1.0:
            worst = int(np.argmax(ratio))
            out.append((names[k], names[trial[worst]], effect[worst], limit[trial[worst]]))
        else:
            kept.append(k)
    return out


def test_a_floor_of_parameters_is_kept_and_the_others_judged_beside_it():
    """An identification nested on another keeps the other's parameters (``floor``) whatever their
    spread, and judges what it adds beside them (the floor first, whatever the order given): a
    column close to a kept one goes."""
    from robocal.identification import weakly_identifiable

    rng = np.random.default_rng(7)
    x, y, z = rng.standard_normal((3, 200))
    J = np.column_stack([x, x + 1e-3 * y, rng.standard_normal(200), x + 1e-3 * z])
    names, quantities, bounds = ["a", "b", "c", "d"], ["length"] * 4, {"length": 1e-3}
    assert [w[:2] for w in weakly_identifiable(J, names, quantities, 3e-5, bounds=bounds)] == [("b", "a"),
                                                                                                ("d", "a")]
    assert [w[:2] for w in weakly_identifiable(J, names, quantities, 3e-5, bounds=bounds, floor=("a", "b"))] == [
        ("d", "d")]
    # the floor comes first, whatever the order given: what is close to it goes, the rest stays
    assert [w[:2] for w in weakly_identifiable(J, names, quantities, 3e-5, bounds=bounds, floor=("d",))] == [
        ("a", "a"), ("b", "b")]


@pytest.mark.parametrize("seed", range(6))
def test_weak_parameters_match_the_one_at_a_time_test(seed):
    """The prefix shortcut and the one-column updates give what trial-by-trial SVDs give, whether
    the first weak column comes early, late or not at all."""
    from robocal.identification import weakly_identifiable

    rng = np.random.default_rng(seed)
    n, k = 400, 12
    J = rng.standard_normal((n, k)) * rng.uniform(0.1, 10.0, k)
    # nearly dependent pairs: column b close to column a, closer for later seeds
    for a, b in rng.choice(k, size=(2, 2), replace=False):
        J[:, b] = J[:, a] * rng.uniform(0.5, 2.0) + 10.0 ** -rng.uniform(2, 5) * rng.standard_normal(n)
    names = [f"p{i}" for i in range(k)]
    quantities = ["length" if i % 3 else "angle" for i in range(k)]
    bounds = {"length": 1e-3, "angle": 1e-3}
    for sigma in (1e-6, 1e-4, 1e-2):
        got = weakly_identifiable(J, names, quantities, sigma, bounds=bounds)
        want = _weak_by_brute_force(J, names, quantities, sigma, bounds)
        assert [g[:2] for g in got] == [w[:2] for w in want]
        assert np.allclose([g[2] for g in got], [w[2] for w in want], rtol=1e-6)
