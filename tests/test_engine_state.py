"""State that can be seen: what the engine keeps between calls is owned by the object it belongs to
(a model, a problem), holds read-only values, and nothing a caller does to what it was handed can
change a later result. Warnings point at the caller's line."""

import gc
import subprocess
import sys
import warnings
import weakref
from dataclasses import replace

import numpy as np
import pytest
from robots import arm6r

import robocal as rc
from robocal._model.kinematics import correction_plan, layout
from robocal.identification import Problem
from robocal.kinematics import parameter_layout, parameter_vector

READ_ONLY = "read-only"


def test_a_parameter_layout_cannot_be_written_into_and_forward_kinematics_stays_put():
    m = arm6r()
    q = rc.random_configurations(m, 5, rng=0)
    before = rc.forward_kinematics(m, q).positions
    with pytest.raises(ValueError, match=READ_ONLY):
        parameter_layout(m).frame0[1] += 1
    with pytest.raises(ValueError, match=READ_ONLY):
        parameter_layout(m).marker0[0] = 0
    # an equal model made apart from it, and the same model again
    for model in (m, arm6r()):
        np.testing.assert_array_equal(rc.forward_kinematics(model, q).positions, before)


def test_a_parameter_vector_is_the_callers_own_and_the_models_values_stay_put():
    m = arm6r()
    first = parameter_vector(m)
    expected = first.copy()
    first[:] = 7.0                          # the caller's copy: the model's kept values do not change
    np.testing.assert_array_equal(parameter_vector(m), expected)
    other = m.replace(frames=(replace(m.frames[0], d=m.frames[0].d + 0.25),) + m.frames[1:])
    assert parameter_vector(other)[parameter_layout(other)["j1.d"].index] == m.frames[0].d + 0.25


def test_an_evaluation_holds_read_only_arrays_of_its_own():
    m = arm6r(masses=True)
    q = rc.random_configurations(m, 4, rng=1)
    first = rc.evaluate(m, q, jacobian=True, orientations=True, compliance=True, frames=True)
    for name in ("positions", "rotations", "jacobian", "moments", "frames"):
        with pytest.raises(ValueError, match=READ_ONLY):
            getattr(first, name)[0] += 1.0
    again = rc.evaluate(m, q, jacobian=True, orientations=True, compliance=True, frames=True)
    assert not np.shares_memory(first.positions, again.positions)


def test_the_step_layout_and_correction_plans_are_read_only():
    m = arm6r(masses=True)
    lay = layout(m)
    arrays = [v for v in vars(lay).values() if isinstance(v, np.ndarray)]
    assert len(arrays) > 20 and not any(a.flags.writeable for a in arrays)
    steps = lay.param_step[lay.param_step >= 0]
    plan = correction_plan(m, lay, steps, np.arange(len(lay.compliant_params)))
    assert plan is not None and plan is correction_plan(m, lay, steps.copy(), np.arange(len(lay.compliant_params)))
    with pytest.raises(ValueError, match=READ_ONLY):
        plan.rot[0] = 5.0


def test_layouts_live_with_their_model_not_in_a_module():
    m = arm6r()
    assert parameter_layout(m) is parameter_layout(m) and layout(m) is layout(m)
    other = arm6r()
    assert other == m and parameter_layout(other) is not parameter_layout(m)
    kept = weakref.ref(layout(other))
    del other
    gc.collect()
    assert kept() is None, "a model's layout outlived it: something else holds it"


def test_a_copied_or_pickled_model_carries_no_layout():
    import copy
    import pickle

    m = arm6r()
    layout(m)
    for twin in (copy.copy(m), copy.deepcopy(m), pickle.loads(pickle.dumps(m))):
        assert twin == m and "_derived" not in vars(twin)


def test_measurements_hold_their_own_read_only_arrays():
    m = arm6r()
    _, data = rc.simulate(m, 6, seed=1)
    q, pos = np.array(data.q), np.array(data.positions)
    d = rc.Measurements(q=q, positions=pos, marker_names=data.marker_names, sigma=np.full((6, 1), 1e-5),
                        payload_mass=np.zeros(6), extra={"series": np.arange(6)})
    for name in ("q", "positions", "mask", "sigma", "payload_mass"):
        a = getattr(d, name)
        with pytest.raises(ValueError, match=READ_ONLY):
            a[0] = 1
    with pytest.raises(ValueError, match=READ_ONLY):
        d.extra["series"][0] = 3
    q[0, 0] += 1.0                          # the caller's arrays are theirs: the record keeps its values
    pos[0, 0, 0] += 1.0
    np.testing.assert_array_equal(d.q, data.q)
    np.testing.assert_array_equal(d.positions, data.positions)
    assert not d.subset([0, 2]).q.flags.writeable


def test_contacts_hold_their_own_read_only_arrays():
    q = np.zeros((2, 6))
    c = rc.Contacts(q=q, marker=("tool",) * 2, kind=("socket",) * 2, target=("s1",) * 2, placement=("p",) * 2,
                    sigma=np.full(2, 1e-5))
    q[0, 0] = 1.0
    assert c.q[0, 0] == 0.0
    for a in (c.q, c.sigma, c.groups()[0].rows):
        with pytest.raises(ValueError, match=READ_ONLY):
            a[0] = 1


def _problem(model, n=30, seed=1):
    _, data = rc.simulate(model, n, seed=seed)
    names = rc.candidate_parameters(model, ("geometric",) if not model.has_masses else ("geometric", "compliance"))
    return Problem(model, names, data=data, compliance=model.has_masses)


@pytest.mark.parametrize("masses", [False, True])
def test_a_problem_serves_no_stale_evaluation_when_the_caller_changes_their_vector(masses):
    m = arm6r(masses=masses)
    prob = _problem(m)
    p = parameter_vector(m)
    prob.residuals(p)
    prob.jacobian(p)
    p[prob.lay.frame0[2] + 4] += 1e-3         # a chain parameter (d of the third frame), changed in place
    fresh = _problem(m)
    np.testing.assert_array_equal(prob.residuals(p), fresh.residuals(p.copy()))
    np.testing.assert_array_equal(prob.jacobian(p), fresh.jacobian(p.copy()))


@pytest.mark.parametrize("masses", [False, True])
def test_what_a_problem_keeps_cannot_be_changed_through_what_it_returned(masses):
    m = arm6r(masses=masses)
    prob = _problem(m)
    p = parameter_vector(m)
    J, R = prob.jacobian(p), prob.jacobian_factor(p)
    keep = J.copy(), R.copy()
    for a in (J, R):
        with pytest.raises(ValueError, match=READ_ONLY):
            a[0, 0] = 1.0
    moments = prob.compliance_moments(p)
    first = {name: v.copy() for name, v in moments.items()}
    for v in moments.values():
        v += 1.0                                  # copies: the caller's to change
    np.testing.assert_array_equal(prob.jacobian(p), keep[0])
    np.testing.assert_array_equal(prob.jacobian_factor(p), keep[1])
    for name, v in prob.compliance_moments(p).items():
        np.testing.assert_array_equal(v, first[name])
    assert bool(moments) == masses


def test_a_kept_identifiability_result_cannot_be_changed_by_a_caller():
    from robocal._identification.identifiability import theoretical_identifiability

    m = arm6r()
    first = theoretical_identifiability(m, ("geometric",), (), False, 1e-6)
    with pytest.raises(TypeError):
        first.observability["O1"] = -1.0        # type: ignore[index]
    with pytest.raises(AttributeError):
        first.column_scale.clear()              # type: ignore[attr-defined]
    again = theoretical_identifiability(m, ("geometric",), (), False, 1e-6)
    assert again.observability["O1"] > 0 and again.column_scale


def test_calibrate_warns_at_the_callers_line():
    m = arm6r()
    _, data = rc.simulate(m, 40, noise=2e-5, seed=8)
    pos = np.array(data.positions)
    pos[::10, 0] += 0.005
    bad = rc.Measurements(q=data.q, positions=pos, marker_names=data.marker_names)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        rc.calibrate(m, bad, on_outliers="flag")
    ours = [w for w in seen if issubclass(w.category, rc.RobocalWarning)]
    assert ours and {w.filename for w in ours} == {__file__}, {(w.filename, w.lineno) for w in ours}


def test_the_identification_module_loads_on_first_use():
    out = subprocess.run([sys.executable, "-c", "import robocal as rc; print(rc.identification.calibrate.__name__)"],
                         capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "calibrate"


def test_a_models_workspace_keeps_what_owners_give_back_within_its_bound():
    """Buffers go back by their owner's word, never by counting references: the workspace keeps what
    it is given (within ``WORKSPACE_BYTES``) and hands a spare out once."""
    from robocal._model.kinematics import WORKSPACE_BYTES, workspace

    m = arm6r()
    ws = workspace(m)
    assert ws is workspace(m) and ws is not workspace(arm6r())
    shape = (2, 3, 5)
    a, b = ws.take(shape), ws.take(shape)
    ws.give([a, b])
    assert {id(x) for x in ws._spare} == {id(a), id(b)}
    assert id(ws.take(shape)) in (id(a), id(b)) and len(ws._spare) == 1
    big = [np.empty(WORKSPACE_BYTES // 8 // 2 + 1) for _ in range(3)]
    ws.give(big)
    assert sum(x.nbytes for x in ws._spare) <= WORKSPACE_BYTES


def test_a_problem_gives_back_only_evaluations_nothing_of_it_reads():
    """An evaluation moved rigidly from a dropped one reads the dropped one's buffers: those go back
    only when the moved one goes too; the problem's outputs are copies, never views of a buffer."""
    from robocal._identification import points
    from robocal._model.kinematics import workspace

    m = arm6r()
    _, data = rc.simulate(m, 20, seed=3)
    prob = points.Points(m, data, rc.candidate_parameters(m), compliance=False)
    p = parameter_vector(m)
    out = prob.predicted(p)[0]
    assert not any(np.shares_memory(out, st.ps.vec) for st in prob._kept.states.values())
    moved = p.copy()
    moved[:3] += 1e-3                                   # base only: an evaluation moved from the first
    prob.residuals(moved)
    source = next(iter(prob._kept.states.values()))
    prob._kept.drop_oldest()                            # the first goes, but the moved one reads it
    assert prob._kept.read and prob._kept.read[0] is source
    assert not any(b is source.ps.vec for b in workspace(m)._spare)
    prob._kept.drop_oldest()                            # the moved one goes: both give their buffers back
    assert not prob._kept.read and any(b is source.ps.vec for b in workspace(m)._spare)


@pytest.mark.parametrize("compliance", [False, True])
def test_problems_reusing_a_models_buffers_give_the_same_results(compliance):
    m = arm6r(masses=compliance)
    _, data = rc.simulate(m, 30, seed=2)
    names = rc.candidate_parameters(m, ("geometric", "compliance") if compliance else ("geometric",))
    p = parameter_vector(m)
    p[layout(m).compliant_params] = 2e-4              # deflecting: a pass of the undeformed chain, then one deflected
    rng = np.random.default_rng(0)
    steps = [p + 1e-4 * rng.standard_normal(len(p)) * (np.abs(p) > 0) for _ in range(12)]
    for k in range(1, 12, 3):                          # base and markers alone: a pass moved rigidly
        steps[k] = steps[k - 1].copy()
        steps[k][:3] += 1e-3
    first = Problem(m, names, data=data, compliance=compliance)
    want = [(first.residuals(q), np.array(first.jacobian(q))) for q in steps]
    del first
    gc.collect()
    spares = workspace_spares(m)
    assert spares > 0
    again = Problem(m, names, data=data, compliance=compliance)
    for q, (r, J) in zip(steps, want):
        np.testing.assert_array_equal(again.residuals(q), r)
        np.testing.assert_array_equal(again.jacobian(q), J)
    assert workspace_spares(m) < spares, "the second problem drew nothing from the workspace"


def workspace_spares(model) -> int:
    from robocal._model.kinematics import workspace

    return len(workspace(model)._spare)


def test_evaluations_of_one_model_reuse_its_buffers_and_agree():
    m = arm6r()
    qs = [rc.random_configurations(m, 7, rng=k) for k in range(3)]
    first = [rc.forward_kinematics(m, q).positions for q in qs]
    assert workspace_spares(m) == 1                   # each call's pass went back, and the next took it
    for q, want in zip(qs, first):
        np.testing.assert_array_equal(rc.forward_kinematics(m, q).positions, want)
        np.testing.assert_array_equal(rc.forward_kinematics(arm6r(), q).positions, want)
