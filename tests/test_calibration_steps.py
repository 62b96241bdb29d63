"""Each step of ``calibrate`` alone (``robocal/_identification/steps.py``): what it takes, what it
returns, and one behaviour of its own, on a small three-joint robot with one marker; and the one
sequence of steps for measured points, contacts and both.

The steps, in ``calibrate``'s order: ``prepare`` (rows copied exactly counted once, the start),
``analyse`` (an ``Analysis``: what the data can identify), ``pin_down`` (a ``Design``: what they can
also pin down), ``fit`` (a ``Fit``: a design solved, its outliers handled, its observations held
out) and ``choose`` (the design the accuracy in use supports); then ``judgement``."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest

import robocal as rc
from robocal._identification import judgement, steps
from robocal._identification.calibrate import run
from robocal._identification.holdout import FoldProblems, holdout_of
from robocal._identification.registration import rigid_base
from robocal._identification.steps import Analysis, Design, Fit, Options, analyse, choose, fit, pin_down, prepare
from robocal.errors import DegenerateDataError

NOISE = rc.Noise.of("tracker", position=2e-5)
OPTIONS = Options(parameters=("geometric",), known=(), noise=NOISE, tol=1e-6, loss="linear", f_scale=None,
                  max_nfev=None, on_outliers="refit", weak="eliminate", nonnegative_compliance=False, folds=5,
                  limit_m=None, initial_base="model", register_validation=False)


@functools.cache
def robot():
    """A nominal three-joint arm, its true (perturbed) self and a campaign of the true robot."""
    model = rc.serial_model("rrr", [dict(), dict(alpha=-np.pi / 2, r=0.1), dict(d=0.4)],
                            markers=[("tool", (0.3, 0.02, 0.05))])
    true, data = rc.simulate(model, 60, noise=2e-5, seed=4)
    return model, true, data


def inputs(data=None, options=OPTIONS, model=None):
    m, _, campaign = robot()
    return prepare(m if model is None else model, campaign if data is None else data, None, None, options, rigid_base)


def analysis(data=None, options=OPTIONS) -> Analysis:
    return analyse(inputs(data, options), options)


def held(a: Analysis):
    h = holdout_of(a.problem, 5)
    return h, FoldProblems(h)


# -- prepare ---------------------------------------------------------------------------------------

def test_prepare_counts_a_row_copied_exactly_once_and_says_so():
    _, _, data = robot()
    copied = data.subset(np.r_[np.arange(data.n_poses), 7])            # pose 8 twice, readings and points
    got = inputs(copied)
    assert got.data.n_poses == data.n_poses
    assert np.array_equal(got.data.q, data.q) and np.array_equal(got.data.positions, data.positions)
    assert got.notes[-1].startswith(f"1 of {data.n_poses + 1} rows repeat")
    assert inputs(data).data is data                                    # nothing copied: the data as they are


def test_prepare_registers_the_base_only_when_asked():
    model, _, _ = robot()
    moved = model.replace(base_position=(0.5, -0.2, 0.1))
    data = rc.measure(moved, rc.random_configurations(model, 30, 1), noise=0.0)
    got = inputs(data, dataclasses.replace(OPTIONS, initial_base="register"))
    assert np.allclose(got.start.base_position, moved.base_position, atol=1e-9)
    assert np.allclose(got.start.base_rotation, np.eye(3), atol=1e-9)
    assert sum("registration" in n or "registered base" in n for n in got.notes) == 2
    assert inputs(data).start is model


# -- analyse ---------------------------------------------------------------------------------------

def test_analyse_returns_the_problem_over_the_candidates_and_what_they_identify():
    model, _, data = robot()
    a = analysis()
    assert isinstance(a, Analysis)
    assert a.stack.names == rc.candidate_parameters(model, ("geometric",))
    assert a.stack.J.shape[1] == len(a.stack.names) and a.problem.n_rows == 3 * data.n_poses
    assert set(a.identifiability.identified) < set(a.stack.names)           # a geometric model has redundancies
    assert not a.compliance and a.lost == () and a.reach is None             # measured points: no kinds to tell


def test_analyse_refuses_too_few_distinct_poses_and_notes_repeated_configurations():
    _, _, data = robot()
    with pytest.raises(DegenerateDataError, match="distinct poses are needed"):
        analysis(data.subset(np.arange(3)))
    repeated = data.subset(np.r_[np.arange(40), np.zeros(5, dtype=int)])
    positions = repeated.positions.copy()
    positions[40:] += 1e-5 * np.arange(1, 6)[:, None, None]            # measured again: not copies
    labels = tuple(f"P{i}" for i in range(45))
    notes = analysis(dataclasses.replace(repeated, positions=positions, labels=labels)).notes
    note = next(n for n in notes if n.startswith("5 of 45 poses repeat an earlier joint configuration"))
    # the fifth repeat moved 5e-5 m along each axis from the first pose's point
    assert f"their points lie up to {5e-2 * np.sqrt(3):.4g} mm apart (P0 and P44)" in note, note


# -- pin_down --------------------------------------------------------------------------------------

def test_pin_down_keeps_every_identifiable_parameter_when_not_eliminating():
    model, _, _ = robot()
    a = analysis()
    d = pin_down(a, NOISE, None, eliminate=False)
    assert isinstance(d, Design)
    assert d.identifiability.identified == a.identifiability.identified and d.weak_kept
    assert [rc.parameter_names(model)[i] for i in d.problem.free_idx] == list(a.identifiability.identified)
    assert np.array_equal(d.p0, rc.parameter_vector(model))


def test_pin_down_holds_back_what_a_large_scatter_cannot_pin_down_and_names_it():
    a = analysis()
    d = pin_down(a, NOISE, None, eliminate=True, scatter=5e-3)      # 5 mm per axis
    held_back = set(a.identifiability.identified) - set(d.identifiability.identified)
    assert held_back and not d.weak_kept and d.judged_at == 5e-3
    assert held_back <= {name for name, _ in d.weak}


# -- fit -------------------------------------------------------------------------------------------

def test_fit_solves_the_design_and_holds_each_fold_out():
    model, true, data = robot()
    a = analysis()
    d = pin_down(a, NOISE, None, eliminate=False)
    f = fit(d, OPTIONS, *held(a))
    assert isinstance(f, Fit) and f.design is d and f.problem is d.problem
    assert f.solution.success and [c.status for c in f.outliers.checks] == ["pass"] and not f.outliers.out.any()
    assert f.held_out.positions.shape == (data.n_poses, 1, 3)
    # the calibrated model predicts the true robot's markers to the noise's order
    q = rc.random_configurations(model, 200, 9)
    calibrated = rc.model_from_vector(model, f.solution.p)
    err = rc.forward_kinematics(calibrated, q).positions - rc.forward_kinematics(true, q).positions
    assert np.sqrt(np.mean(err ** 2)) < 1e-4
    # held-out errors are larger than the fitted residuals (each pose predicted without itself)
    fitted = np.linalg.norm(d.problem.points.errors(f.solution.p), axis=-1)
    held_out = np.linalg.norm(f.held_out.positions, axis=-1)
    assert np.mean(held_out ** 2) > np.mean(fitted ** 2)


def test_fit_sets_a_blunder_aside_and_refits_but_only_names_it_with_flag():
    _, _, data = robot()
    positions = data.positions.copy()
    positions[17, 0, 2] += 5e-3                                         # 5 mm on one point
    bad = dataclasses.replace(data, positions=positions)
    a = analysis(bad)
    d = pin_down(a, NOISE, None, eliminate=False)
    refit = fit(d, OPTIONS, *held(a))
    assert not refit.problem.points.data.mask[17, 0] and refit.aside.sum() == 1 and refit.aside[17]
    assert refit.outliers.checks[0].status == "warn" and any("set aside" in n for n in refit.notes)
    assert refit.design is not d and refit.design.problem.n_rows == d.problem.n_rows - 3
    flagged = fit(d, dataclasses.replace(OPTIONS, on_outliers="flag"), *held(a))
    assert flagged.problem is d.problem and flagged.design is d and flagged.outliers.out.sum() == 1
    assert not flagged.aside.any() and flagged.outliers.checks[0].status == "warn"


# -- choose ----------------------------------------------------------------------------------------

def test_choose_with_weak_flag_keeps_the_first_design_and_notes_nothing():
    a = analysis()
    chosen, notes = choose(a, dataclasses.replace(OPTIONS, weak="flag"), *held(a))
    assert notes == ()
    assert chosen.design.identifiability.identified == a.identifiability.identified and chosen.design.weak_kept


def test_choose_frees_what_a_stated_noise_held_back_when_that_predicts_better_in_use():
    stated = rc.Noise.of("tracker", position=3e-3)          # 3 mm stated; the data scatter by 20 um
    options = dataclasses.replace(OPTIONS, noise=stated)
    a = analysis(options=options)
    first = pin_down(a, stated, None, eliminate=True)
    assert len(first.identifiability.identified) < len(a.identifiability.identified)    # held back at 3 mm
    chosen, notes = choose(a, options, *held(a))
    assert chosen.design.identifiability.identified == a.identifiability.identified
    assert chosen.design.kept_in_use
    n_first, n_all = len(first.identifiability.identified), len(a.identifiability.identified)
    assert len(notes) == 1 and notes[0].startswith("model choice by cross-validated error")
    assert f"{n_first} parameters" in notes[0] and f"kept the {n_all} parameters" in notes[0]


def test_a_compared_design_is_solved_loosely_and_once_chosen_on_to_the_solvers_tolerance(monkeypatch):
    """The all-free design (chosen here, as above) is compared at ``COMPARED_TOL`` and, chosen, solved on
    from there at the solver's tolerance: its estimates are those of the design solved alone from the
    nominal, within 1e-3 of their standard deviations."""
    from robocal._identification.solve import SOLVER_TOL, covariance

    stated = rc.Noise.of("tracker", position=3e-3)
    options = dataclasses.replace(OPTIONS, noise=stated)
    a = analysis(options=options)
    tols = []

    def spy(problem, start, **kw):
        tols.append((len(problem.free_idx), kw.get("tol", SOLVER_TOL)))
        return solve(problem, start, **kw)

    solve = steps.solve
    monkeypatch.setattr(steps, "solve", spy)
    chosen, _ = choose(a, options, *held(a))
    n_all = len(a.identifiability.identified)
    assert len(chosen.problem.free_idx) == n_all
    assert (n_all, steps.COMPARED_TOL) in tols and tols[-1] == (n_all, SOLVER_TOL)
    alone = fit(chosen.design, dataclasses.replace(options, on_outliers="flag"), *held(a))
    std = covariance(alone.solution).std
    free = alone.problem.free_idx
    assert np.all(np.abs(chosen.solution.p[free] - alone.solution.p[free]) <= 1e-3 * std)


def test_choose_leaves_out_a_compared_design_that_has_not_converged_within_its_budget(monkeypatch):
    stated = rc.Noise.of("tracker", position=3e-3)          # as above: the all-free design would be chosen
    options = dataclasses.replace(OPTIONS, noise=stated)
    a = analysis(options=options)
    monkeypatch.setattr(steps, "COMPARED_NFEV", 1)         # one evaluation: the start, no step
    chosen, notes = choose(a, options, *held(a))
    first = pin_down(a, stated, None, eliminate=True)
    assert chosen.design.identifiability.identified == first.identifiability.identified
    assert chosen.solution.success and not chosen.design.kept_in_use
    n_all = len(a.identifiability.identified)
    assert notes == (f"the {n_all}-parameter design did not converge within 1 evaluations of the residuals: left "
                     "out of the model choice",)


def test_options_are_a_frozen_record():
    with pytest.raises(dataclasses.FrozenInstanceError):
        OPTIONS.loss = "huber"   # type: ignore[misc]


# -- one sequence for every kind of observation ----------------------------------------------------

STEPS = [(steps, "prepare"), (steps, "analyse"), (steps, "pin_down"), (steps, "fit"), (steps, "choose"),
         (steps, "registered_nominal"), (judgement, "estimates"), (judgement, "in_use"), (judgement, "reach"),
         (judgement, "input_checks"), (judgement, "fit_checks"), (judgement, "result_checks"),
         (judgement, "use_checks"), (judgement, "warn_checks"), (judgement, "record")]


def _sequence(monkeypatch, call):
    """The step functions ``call`` runs, in the order they are first entered."""
    import robocal._identification.calibrate as face

    seen = []
    for module, name in STEPS:
        real = getattr(module, name)

        def spy(*args, __real=real, __name=name, **kwargs):
            if __name not in seen:
                seen.append(__name)
            return __real(*args, **kwargs)

        monkeypatch.setattr(module, name, spy)
        if hasattr(face, name):
            monkeypatch.setattr(face, name, spy)
    call()
    monkeypatch.undo()
    return seen


def test_measured_points_contacts_and_both_run_the_same_steps(monkeypatch):
    from pathlib import Path

    from robocal.sim import socket_campaign

    arm7 = rc.read_model(Path(__file__).parent.parent / "examples" / "arm7" / "model.yaml")
    true, data = rc.simulate(arm7, 40, noise=2e-5, seed=2)
    arm7_sockets = socket_campaign(true, placements=3, poses_per_socket=8, joint_noise=2e-5, rng=3)
    options = dataclasses.replace(OPTIONS, noise=rc.Noise.of("tracker"))
    tracker = _sequence(monkeypatch, lambda: run(arm7, data, None, None, options))
    contacts = _sequence(monkeypatch, lambda: run(arm7, None, arm7_sockets, None, options))
    both = _sequence(monkeypatch, lambda: run(arm7, data, arm7_sockets, None, options))
    assert tracker == contacts == both
    assert set(tracker) == {name for _, name in STEPS}


def test_rows_that_carry_the_scale_together_are_never_set_aside(monkeypatch):
    """Known distances carry the robot's scale together (none alone): however far one stands out, the
    refit keeps it, while a real blunder among the sockets beside it is set aside."""
    from pathlib import Path

    from robocal.sim import socket_campaign

    arm7 = rc.read_model(Path(__file__).parent.parent / "examples" / "arm7" / "model.yaml")
    true = rc.perturb_model(arm7, rc.identifiability(arm7, parameters=("frames",)).identified, rng=0)
    sockets = socket_campaign(true, placements=4, poses_per_socket=15, joint_noise=2e-5, rng=3)
    q = sockets.q.copy()
    q[5, 1] += 0.01                                                   # one seating read 10 mrad off
    sockets = dataclasses.replace(sockets, q=q)
    options = dataclasses.replace(OPTIONS, noise=rc.Noise.of("tracker"))
    real = steps.find_outliers

    def distances_standing_out(problem, solution, noise):
        found = real(problem, solution, noise)
        first = np.array([k == "distance" for k in problem.observations().kind]).cumsum() == 1
        far = found.out | (first & np.array([k == "distance" for k in problem.observations().kind]))
        return dataclasses.replace(found, out=far, gross=found.gross | far, apart=found.apart | far)

    monkeypatch.setattr(steps, "find_outliers", distances_standing_out)
    a = analyse(prepare(arm7, None, sockets, None, options, rigid_base), options)
    refit = fit(pin_down(a, options.noise, None, eliminate=False), options, *held(a))
    kind = np.array(a.problem.observations().kind)
    assert refit.aside.any() and not refit.aside[kind == "distance"].any()
    assert refit.aside[5] and kind[5] == "socket"                     # the seating read off
