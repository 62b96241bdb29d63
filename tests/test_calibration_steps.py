"""Each step of ``calibrate`` alone (``_calibration.py``): what it takes, what it returns, and one
behaviour of its own, on a small three-joint robot with one marker.

The steps, in ``calibrate``'s order: ``_without_copies`` (rows copied exactly counted once),
``_starting_model`` (the model the solve starts from), ``_analyse`` (an ``_Analysis``: what the data
can identify), ``_pin_down`` (a ``_Design``: what they can also pin down), ``_fit`` (a ``_Fit``: a
design solved, its outliers handled, cross-validated, under ``_Options``) and ``_choose`` (the
design the accuracy in use supports)."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest

import robocal as rc
from robocal._identification.calibrate import (
    _analyse,
    _Analysis,
    _choose,
    _Design,
    _Fit,
    _fit,
    _Options,
    _pin_down,
    _starting_model,
    _without_copies,
)
from robocal._identification.holdout import FoldProblems, fold_labels
from robocal.errors import DegenerateDataError

NOISE = rc.Noise.of("tracker", position=2e-5)
OPTIONS = _Options(loss="linear", f_scale=None, max_nfev=None, on_outliers="refit", weak="eliminate",
                   nonnegative_compliance=False, folds=5)


@functools.cache
def robot():
    """A nominal three-joint arm, its true (perturbed) self and a campaign of the true robot."""
    model = rc.serial_model("rrr", [dict(), dict(alpha=-np.pi / 2, r=0.1), dict(d=0.4)],
                            markers=[("tool", (0.3, 0.02, 0.05))])
    true, data = rc.simulate(model, 60, noise=2e-5, seed=4)
    return model, true, data


def folds(data):
    labels, k, _ = fold_labels(data, 5)
    return labels, k, FoldProblems(labels, k)


def analysis(data=None, parameters=("geometric",)):
    model, _, campaign = robot()
    return _analyse(model, campaign if data is None else data, parameters, (), 1e-6, noise=NOISE)


# -- _without_copies -------------------------------------------------------------------------------

def test_without_copies_counts_a_row_copied_exactly_once_and_says_so():
    _, _, data = robot()
    copied = data.subset(np.r_[np.arange(data.n_poses), 7])            # pose 8 twice, readings and points
    kept, notes = _without_copies(copied)
    assert kept.n_poses == data.n_poses
    assert np.array_equal(kept.q, data.q) and np.array_equal(kept.positions, data.positions)
    assert len(notes) == 1 and notes[0].startswith(f"1 of {data.n_poses + 1} rows repeat")
    same, none = _without_copies(data)                                  # nothing copied: the data as they are
    assert same is data and none == ()


# -- _starting_model -------------------------------------------------------------------------------

def test_starting_model_registers_the_base_only_when_asked():
    model, _, _ = robot()
    moved = model.replace(base_position=(0.5, -0.2, 0.1))
    data = rc.measure(moved, rc.random_configurations(model, 30, 1), noise=0.0)
    start, notes = _starting_model(model, data, "register")
    assert np.allclose(start.base_position, moved.base_position, atol=1e-9)
    assert np.allclose(start.base_rotation, np.eye(3), atol=1e-9) and len(notes) == 2
    assert _starting_model(model, data, "model") == (model, ())


# -- _analyse --------------------------------------------------------------------------------------

def test_analyse_returns_the_problem_over_the_candidates_and_what_they_identify():
    model, _, data = robot()
    a = analysis()
    assert isinstance(a, _Analysis)
    assert a.names == rc.candidate_parameters(model, ("geometric",))
    assert a.J.shape[1] == len(a.names) and a.problem.n_rows == 3 * data.n_poses
    assert set(a.identifiability.identified) < set(a.names)           # a geometric model has redundancies
    assert not a.compliance and a.lost == ()


def test_analyse_refuses_too_few_distinct_poses_and_notes_repeated_configurations():
    _, _, data = robot()
    with pytest.raises(DegenerateDataError, match="distinct poses are needed"):
        analysis(data.subset(np.arange(3)))
    repeated = data.subset(np.r_[np.arange(40), np.zeros(5, dtype=int)])
    notes = analysis(repeated).notes
    assert any(n.startswith("5 of 45 poses repeat an earlier joint configuration") for n in notes), notes


# -- _pin_down -------------------------------------------------------------------------------------

def test_pin_down_keeps_every_identifiable_parameter_when_not_eliminating():
    model, _, _ = robot()
    a = analysis()
    d = _pin_down(model, a, NOISE, None, eliminate=False)
    assert isinstance(d, _Design)
    assert d.identifiability.identified == a.identifiability.identified and d.weak_kept
    assert [rc.parameter_names(model)[i] for i in d.problem.free_idx] == list(a.identifiability.identified)
    assert np.array_equal(d.p0, rc.parameter_vector(model))


def test_pin_down_holds_back_what_a_large_scatter_cannot_pin_down_and_names_it():
    model, _, _ = robot()
    a = analysis()
    d = _pin_down(model, a, NOISE, None, eliminate=True, scatter=5e-3)      # 5 mm per axis
    held = set(a.identifiability.identified) - set(d.identifiability.identified)
    assert held and not d.weak_kept and d.judged_at == 5e-3
    assert held <= {name for name, _ in d.weak}


# -- _fit ------------------------------------------------------------------------------------------

def test_fit_solves_the_design_and_cross_validates_it():
    model, true, data = robot()
    d = _pin_down(model, analysis(), NOISE, None, eliminate=False)
    f = _fit(d, data, NOISE, OPTIONS, folds(data))
    assert isinstance(f, _Fit) and f.design is d and f.data is data
    assert f.solution.success and f.outlier_check.status == "pass" and not f.outlying.any()
    assert f.held_out.positions.shape == (data.n_poses, 1, 3)
    # the calibrated model predicts the true robot's markers to the noise's order
    q = rc.random_configurations(model, 200, 9)
    calibrated = rc.model_from_vector(model, f.solution.p)
    err = rc.forward_kinematics(calibrated, q).positions - rc.forward_kinematics(true, q).positions
    assert np.sqrt(np.mean(err ** 2)) < 1e-4
    # cross-validated errors are larger than the fitted residuals (each pose predicted without itself)
    fitted = np.linalg.norm(d.problem.errors(f.solution.p), axis=-1)
    held = np.linalg.norm(f.held_out.positions, axis=-1)
    assert np.mean(held ** 2) > np.mean(fitted ** 2)


def test_fit_sets_a_blunder_aside_and_refits_but_only_names_it_with_flag():
    model, _, data = robot()
    positions = data.positions.copy()
    positions[17, 0, 2] += 5e-3                                         # 5 mm on one point
    bad = dataclasses.replace(data, positions=positions)
    d = _pin_down(model, analysis(bad), NOISE, None, eliminate=False)
    refit = _fit(d, bad, NOISE, OPTIONS, folds(bad))
    assert not refit.data.mask[17, 0] and refit.data.mask.sum() == bad.mask.sum() - 1
    assert refit.outlier_check.status == "warn" and any("set aside" in n for n in refit.notes)
    assert refit.design is not d and refit.design.problem.n_rows == d.problem.n_rows - 3
    flagged = _fit(d, bad, NOISE, dataclasses.replace(OPTIONS, on_outliers="flag"), folds(bad))
    assert flagged.data is bad and flagged.design is d and flagged.outlying.sum() == 1
    assert flagged.outlier_check.status == "warn"


# -- _choose ---------------------------------------------------------------------------------------

def test_choose_with_weak_flag_keeps_the_first_design_and_notes_nothing():
    model, _, data = robot()
    a = analysis()
    chosen, notes = _choose(model, a, data, NOISE, None, dataclasses.replace(OPTIONS, weak="flag"), folds(data))
    assert notes == ()
    assert chosen.design.identifiability.identified == a.identifiability.identified and chosen.design.weak_kept


def test_choose_frees_what_a_stated_noise_held_back_when_that_predicts_better_in_use():
    model, _, data = robot()
    a = analysis()
    stated = rc.Noise.of("tracker", position=3e-3)          # 3 mm stated; the data scatter by 20 um
    first = _pin_down(model, a, stated, None, eliminate=True)
    assert len(first.identifiability.identified) < len(a.identifiability.identified)    # held back at 3 mm
    chosen, notes = _choose(model, a, data, stated, None, OPTIONS, folds(data))
    assert chosen.design.identifiability.identified == a.identifiability.identified
    assert chosen.design.kept_in_use
    n_first, n_all = len(first.identifiability.identified), len(a.identifiability.identified)
    assert len(notes) == 1 and notes[0].startswith("model choice by cross-validated error")
    assert f"{n_first} parameters" in notes[0] and f"kept the {n_all} parameters" in notes[0]


def test_options_are_a_frozen_record():
    with pytest.raises(dataclasses.FrozenInstanceError):
        OPTIONS.loss = "huber"   # type: ignore[misc]
