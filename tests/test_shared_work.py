"""What a calibration computes once and hands on (benchmarks/README.md, issue 43): the cross-validation
steps from the solver's last Jacobian, the normal equations of a campaign evaluated in chunks from its
Gram matrix and from the analysis' factor, the marker positions such a campaign keeps, and the
diagnosis on the calibration's own residuals and Jacobian. Each is held against the same figure
computed from scratch."""

import warnings

import numpy as np
import pytest
from robots import arm6r

import robocal as rc
from robocal.identification import Points, Problem, diagnose, solve


def _campaign(n=300, seed=2):
    m = arm6r()
    _, data = rc.simulate(m, n, seed=seed)
    return m, data


def test_fold_steps_from_the_solvers_last_jacobian_are_the_least_squares_fits_without_each_fold():
    """Each fold's step, from the Jacobian the solver took a tolerance away from its solution and
    summed group by group, is the Gauss-Newton fit on the other folds' rows, solved directly."""
    from robocal._identification.holdout import Holdout, fold_steps

    m, data = _campaign()
    names = rc.identifiability(m, data).identified
    prob = Problem(m, names, data=data, compliance=False)
    sol = solve(prob, rc.parameter_vector(m))
    assert sol.jacobian_at is not None and not np.array_equal(sol.jacobian_at, sol.p)
    labels = np.random.default_rng(0).permutation(data.n_poses) % 4
    steps = fold_steps(prob, sol.p, Holdout(labels, 4, "4 folds", labels, 4), at=sol.jacobian_at)
    J, r = np.array(prob.jacobian(sol.p)), prob.residuals(sol.p)
    row_pose = np.repeat(np.arange(data.n_poses), 3)
    for g, step in enumerate(steps):
        rest = labels[row_pose] != g
        direct = -np.linalg.lstsq(J[rest], r[rest], rcond=None)[0]
        assert np.max(np.abs(step - direct)) <= 1e-6 * np.max(np.abs(direct))


def test_a_fold_that_alone_moves_a_joint_leaves_its_direction_where_it_was():
    """The last joint moves in the first fold's poses only (elsewhere by 1e-7 rad): without them the
    last frame's alpha and d are all but undetermined (the tool's offset carries them), and the step
    to the fit on the others is the least-norm one in unit-column scaling, as a direct least-squares
    solve of the same rank gives (a Cholesky solve of that fold's matrix would not)."""
    from robocal._identification.holdout import Holdout, fold_steps

    m = arm6r()
    q = rc.simulate(m, 160, seed=6)[1].q.copy()
    labels = np.arange(160) * 4 // 160
    q[labels > 0, 5] = 0.3 + 1e-7 * np.random.default_rng(0).normal(size=120)
    _, data = rc.simulate(m, q=q, seed=6)
    names = rc.identifiability(m, data).identified
    prob = Problem(m, names, data=data, compliance=False)
    sol = solve(prob, rc.parameter_vector(m))
    steps = fold_steps(prob, sol.p, Holdout(labels, 4, "4 blocks", labels, 4))
    J, r = np.array(prob.jacobian(sol.p)), prob.residuals(sol.p)
    col = np.linalg.norm(J, axis=0)
    rest = np.repeat(labels, 3) != 0
    U, sv, Vt = np.linalg.svd(J[rest] / col, full_matrices=False)
    keep = sv ** 2 > 1e-12 * sv[0] ** 2
    assert not keep.all()                       # the first fold alone determined a direction
    direct = -(Vt[keep].T @ ((U[:, keep].T @ r[rest]) / sv[keep])) / col
    assert np.max(np.abs(steps[0] - direct)) <= 1e-6 * np.max(np.abs(direct))


def test_a_campaign_in_chunks_solves_and_judges_as_the_whole_one():
    """Normal equations from the Gram matrix (and from the analysis' factor at the start), and the
    marker positions kept between checks, give the campaign held whole's answer."""
    m, data = _campaign(n=400)
    names = rc.identifiability(m, data).identified
    p0 = rc.parameter_vector(m)
    whole = Points(m, data, names, compliance=False, chunked=False)
    chunked = Points(m, data, names, compliance=False, chunked=True)
    R, g, cost = chunked.normal_equations(p0)
    J, r = whole.jacobian(p0), whole.residuals(p0)
    np.testing.assert_allclose(R.T @ R, J.T @ J, rtol=1e-9, atol=1e-9 * np.abs(J.T @ J).max())
    np.testing.assert_allclose(g, J.T @ r, rtol=1e-9, atol=1e-12 * np.abs(J.T @ r).max())
    assert cost == pytest.approx(float(r @ r), rel=1e-12)
    first = chunked.errors(p0)
    assert np.array_equal(first, chunked.errors(p0)) and np.array_equal(first, whole.errors(p0))
    a = solve(Problem(m, names, data=data, compliance=False, chunked=True), p0)
    b = solve(Problem(m, names, data=data, compliance=False, chunked=False), p0)
    assert np.max(np.abs(a.p - b.p)) < 1e-12


def test_the_diagnosis_inside_a_calibration_is_the_one_from_scratch():
    """``calibrate`` diagnoses on its own residuals and Jacobian; ``diagnose`` evaluates them again: the
    same causes, strengths and misfit, on a clean campaign and on one whose tool moved partway."""
    m, data = _campaign()
    moved = data.positions.copy()
    moved[200:] += np.array([0.004, -0.002, 0.0])
    bumped = rc.Measurements(q=data.q, positions=moved, marker_names=data.marker_names, joint_names=data.joint_names)
    for d in (data, bumped):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = rc.calibrate(m, d)
            again = diagnose(m, d, result)
        inside = result.diagnosis
        assert inside.rms == pytest.approx(again.rms, rel=1e-9)
        assert [(f.cause, f.status) for f in inside.findings] == [(f.cause, f.status) for f in again.findings]
        assert inside.refitted == again.refitted
    assert result.diagnosis.findings        # the tool's move is named


# -- the diagnosis screen: the calibration's own columns and every split's sums at once ----------------------------

def _reference_of(m, data, **options):
    """The diagnosis' reference as ``calibrate`` makes it (on its own fit's residuals and Jacobian)."""
    from robocal._diagnosis import calibrate as face
    from robocal._diagnosis.reference import reference

    taken = {}
    screened = face.screened

    def keep(model, d, contacts, result, fitted, options):
        taken["ref"] = reference(model, d, result, options.noise, options.limit_m, options.folds, fitted)
        return screened(model, d, contacts, result, fitted, options)

    face.screened = keep
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            rc.calibrate(m, data, **options)
    finally:
        face.screened = screened
    return taken["ref"]


def test_a_split_from_the_sums_over_every_pose_is_the_least_squares_fit_letting_the_columns_change_there():
    """The best split along the rows and what it takes away, from the gradient and Gram matrices summed
    over the poses after each split (every set of columns with the same edge in one pass, the rows
    about the coarse grid's best pose by pose), against the least-squares fit of the calibration's
    columns with some of them (the base's, each marker's position) let change again from each split
    on, solved directly for every split: the same row (for the base, where the instrument was
    bumped), the same sum of squares. Two markers, one of them not seen on some poses: the rows are
    not in pose order and the poses hold different numbers of rows."""
    from robocal._diagnosis.campaign import SPLITS, marker_columns, split_gains
    from robocal._diagnosis.joints import joint_columns

    m = arm6r(markers=(("tool", (0.05, 0.02, 0.12)), ("side", (-0.04, 0.06, 0.08))))
    _, data = rc.simulate(m, 200, seed=2)
    bumped, mask = data.positions.copy(), data.mask.copy()
    bumped[120:] += np.array([0.0005, -0.0003, 0.0002])
    mask[::7, 1] = False
    bumped[~mask] = np.nan
    q = data.q.copy()
    q[70:, 2] += np.radians(0.1)            # a joint rehomed at pose 70
    ref = _reference_of(m, rc.Measurements(q=q, positions=bumped, mask=mask, marker_names=data.marker_names,
                                           joint_names=data.joint_names))
    pose = ref.problem.points.row_points()[0]
    assert np.any(np.diff(pose) < 0)
    before = np.linalg.lstsq(ref.J, ref.r, rcond=None)[1][0]
    rows = np.arange(10, data.n_poses - 10 + 1)
    base = ref.J[:, [i for i, n in enumerate(ref.names) if n.startswith("base.")]]
    columns = [base, marker_columns(ref, "tool"), marker_columns(ref, "side"), marker_columns(ref, "tool"),
               joint_columns(ref)]
    edges = [10, 10, 10, 14, 10]
    alone = [False, False, False, False, True]     # the joints one at a time: the best one's index
    found = split_gains(ref, columns, edges, alone)
    assert [col is not None for _, _, col in found] == alone
    for (row, gain, col), Z, edge, true_row in zip(found, columns, edges, (120, None, None, None, 70)):
        tried = [Z] if col is None else [Z[:, [c]] for c in range(Z.shape[1])]
        direct = np.array([[before - np.linalg.lstsq(np.hstack([ref.J, Zc * (pose >= s)[:, None]]), ref.r,
                                                     rcond=None)[1][0] for s in rows] for Zc in tried])
        n = data.n_poses          # the search: the best of a coarse grid, then each row about it
        coarse = np.unique(np.linspace(edge, n - edge, min(SPLITS, n - 2 * edge + 1)).round().astype(int))
        which, at = np.unravel_index(np.argmax(direct[:, coarse - 10]), (len(tried), len(coarse)))
        assert which == (col or 0) == (2 if true_row == 70 else which)
        best = coarse[at]
        step = coarse[1] - coarse[0]
        near = np.arange(max(edge, best - step), min(n - edge, best + step) + 1)
        assert row == near[np.argmax(direct[which, near - 10])] == (true_row or row)
        assert gain == pytest.approx(direct[which, row - 10], rel=1e-6)


def test_the_load_columns_on_the_nominals_massless_copy_are_those_of_the_calibrated_models():
    """The load columns, evaluated on the nominal's massless copy kept with it (the fit's rotation
    corrections, relative to the nominal's stored rotations), against those of a massless copy of the
    calibrated model at its own values (its stored rotations holding those corrections): the same to
    rounding, from the calibration's own fit and from a diagnosis made from scratch."""
    from dataclasses import replace

    from robocal._diagnosis.campaign import load_columns
    from robocal._diagnosis.reference import reference

    m = arm6r(masses=True)
    _, data = rc.simulate(m, 120, seed=3, parameters=("geometric", "compliance"))
    ref = _reference_of(m, data, parameters=("geometric", "compliance"))
    start = ref.start
    assert not np.allclose(start.base_rotation, m.base_rotation)
    bare = start.replace(frames=tuple(replace(f, mass=0.0) for f in start.frames), payload=rc.Payload(mass=1.0),
                         other_payloads=())
    names = tuple(n for n in rc.candidate_parameters(m, ("compliance",)) if n.endswith(".k_theta"))
    loaded = replace(ref.data.with_approach(), payload_mass=np.ones(ref.data.n_poses))
    scratch = np.array(Problem(bare, names, data=loaded, compliance=True, noise=ref.noise).jacobian(
        rc.parameter_vector(bare)))
    kept = load_columns(m, ref.problem.model, ref.p, ref.data, ref.noise)
    assert ref.problem.model is not start             # the fit's vector: corrections of the nominal's rotations
    assert np.max(np.abs(kept - scratch)) <= 1e-12 * np.max(np.abs(scratch))
    again = reference(m, data, ref.result, ref.noise)  # from scratch: the calibrated model's own vector
    assert again.problem.model is start
    from_scratch = load_columns(m, again.problem.model, again.p, again.data, again.noise)
    assert np.max(np.abs(from_scratch - scratch)) <= 1e-12 * np.max(np.abs(scratch))


def test_the_projection_from_the_solvers_factor_is_the_one_from_the_columns():
    """The diagnosis projects out of the calibration's columns with the Gram matrix of the solver's R
    factor (well conditioned here); the projection, the Gram inverse and the products of projected
    columns against those made from the columns themselves; columns (nearly) in their span are
    projected whole, as from scratch."""
    from robocal._diagnosis.reference import projected_products

    m, data = _campaign()
    ref = _reference_of(m, data)
    assert ref.factor is not None and ref.projector[0] is None
    col = np.linalg.norm(ref.J, axis=0)
    Js = ref.J / col
    inverse = np.linalg.pinv(Js.T @ Js, hermitian=True)
    rng = np.random.default_rng(5)
    Z = rng.normal(size=(len(ref.r), 4)) * ref.J[:, :1]
    Zp = Z - Js @ (inverse @ (Js.T @ Z))
    assert np.max(np.abs(ref.project(Z) - Zp)) <= 1e-10 * np.max(np.abs(Zp))
    assert np.max(np.abs(ref.gram_inverse * np.outer(col, col) - inverse)) <= 1e-10 * np.max(np.abs(inverse))
    settled = ref.r - Js @ (inverse @ (Js.T @ ref.r))
    M, b = projected_products(ref, Z)
    assert np.max(np.abs(M - Zp.T @ Zp)) <= 1e-10 * np.max(np.abs(M))
    assert np.max(np.abs(b - Zp.T @ settled)) <= 1e-8 * np.max(np.abs(b))
    inside = np.hstack([ref.J[:, :2] + 1e-9 * Z[:, :2], Z[:, 2:]])
    M, b = projected_products(ref, inside)
    whole = ref.project(inside)
    assert np.array_equal(M, whole.T @ whole) and np.array_equal(b, whole.T @ ref.settled)


def test_the_markers_columns_the_diagnosis_takes_from_the_calibration_are_those_evaluated_at_its_solution():
    """A marker's columns in the calibration's Jacobian (taken a solver's tolerance from its solution)
    against the columns of its position evaluated at the solution."""
    from robocal._diagnosis.campaign import marker_columns

    m, data = _campaign()
    ref = _reference_of(m, data)
    evaluated = np.array(ref.problem.over(("tool.x", "tool.y", "tool.z")).jacobian(ref.p))
    assert np.max(np.abs(marker_columns(ref, "tool") - evaluated)) <= 1e-6 * np.max(np.abs(evaluated))


# -- the evidence: cross-validation, accuracy in use, reach, coverage --------------------------------

def _placed(m, names):
    lay = rc.kinematics.parameter_layout(m)
    return tuple(n for n in names if lay[n].family in ("base", "markers"))


@pytest.mark.parametrize("masses", [False, True])
def test_the_nominals_fold_models_moved_rigidly_are_the_ones_evaluated_from_scratch(masses):
    """The nominal's fold models differ from it in the base and markers only: its held-out errors
    are its one evaluation moved rigidly, and equal each fold model evaluated on its own poses (with
    compliance evaluated at zero compliance too, and stated deviations weighing the loss)."""
    from robocal._identification.holdout import cross_validate, evaluated, fold_steps, holdout_of

    m = arm6r(markers=(("tool", (0.05, 0.02, 0.12)), ("side", (0.1, -0.05, 0.08))), masses=masses)
    _, data = rc.simulate(m, 240, seed=3)
    sigma = np.full(data.mask.shape, 2e-5) * (1 + np.arange(data.n_poses) % 3)[:, None]
    data = rc.Measurements(q=data.q, positions=data.positions, marker_names=data.marker_names,
                           joint_names=data.joint_names, sigma=sigma)
    names = rc.identifiability(m, data).identified
    placed = Problem(m, _placed(m, names), data=data, compliance=masses)
    before = solve(placed, rc.parameter_vector(m)).p
    holdout = holdout_of(placed)
    shared = cross_validate(placed, before, holdout)
    steps = fold_steps(placed, before, holdout)
    for g in range(holdout.point_folds):
        index = np.nonzero(holdout.pose_labels == g)[0]
        pg = before.copy()
        pg[placed.free_idx] += steps[g]
        alone = evaluated(Points(m, data.subset(index), _placed(m, names), compliance=masses), pg)
        np.testing.assert_allclose(shared.positions[index], alone.positions, rtol=0, atol=1e-13)
        np.testing.assert_allclose(shared.loss[index], alone.loss, rtol=1e-10)
    assert np.isfinite(shared.positions).all() and shared.loss.min() > 0


def test_marker_positions_moved_rigidly_are_a_pass_at_the_moved_vector():
    """Bases turned and shifted and markers moved in their frames, one vector for some poses and
    another for the others: the evaluation at the start moved is the pass at each moved vector."""
    m = arm6r(markers=(("tool", (0.05, 0.02, 0.12)), ("side", (0.1, -0.05, 0.08))))
    _, data = rc.simulate(m, 60, seed=5)
    names = rc.parameter_names(m)
    free = tuple(n for n in names if n.startswith(("base.", "tool.", "side.")))
    p = rc.parameter_vector(m)
    moved = np.repeat(p[None], 2, axis=0)
    moved[:, [names.index(n) for n in free]] += np.random.default_rng(2).normal(scale=0.05, size=(2, len(free)))
    which = np.arange(60) % 3 // 2
    shared = Points(m, data, free, compliance=False).moved_positions(p, moved, which)
    for g in range(2):
        direct = Points(m, data, free, compliance=False).predicted(moved[g])[0]
        np.testing.assert_allclose(shared[which == g], direct[which == g], rtol=0, atol=1e-14)


def test_a_chain_that_moves_is_not_moved_rigidly():
    """Compliance at work, or a step of the chain, is evaluated again: no rigid move stands for it."""
    m = arm6r(masses=True)
    _, data = rc.simulate(m, 50, seed=1)
    pts = Points(m, data, ("base.x",), compliance=True)
    at = {n: i for i, n in enumerate(rc.parameter_names(m))}
    p = rc.parameter_vector(m)
    shifted = p.copy()
    shifted[at["base.x"]] += 1e-3
    which = np.zeros(50, dtype=int)
    assert pts.moved_positions(p, [shifted], which) is not None
    bent, bent_shifted = p.copy(), shifted.copy()
    bent[at["j2.k_theta"]] = bent_shifted[at["j2.k_theta"]] = 1e-6
    assert pts.moved_positions(bent, [bent_shifted], which) is None
    chain = p.copy()
    chain[at["j2.alpha"]] += 1e-4
    assert pts.moved_positions(p, [shifted, chain], which) is None


def test_the_uncertainty_over_the_workspace_is_the_covariance_carried_pose_by_pose():
    """The coverage's uncertainty over the workspace (one matrix product over every row) is the
    RMS over poses and markers of sqrt(trace(J C J^T)) taken one pose and marker at a time."""
    from robocal._identification.holdout import coverage, design_like, workspace_readings

    m = arm6r(markers=(("tool", (0.05, 0.02, 0.12)), ("side", (0.1, -0.05, 0.08))))
    _, data = rc.simulate(m, 120, seed=4)
    names = rc.identifiability(m, data).identified
    pts = Points(m, data, names, compliance=False)
    p = rc.parameter_vector(m)
    A = np.random.default_rng(1).normal(size=(len(names), len(names)))
    cov = 1e-8 * (A @ A.T + np.eye(len(names)))
    at = design_like(pts, workspace_readings(m, 30, data.q))
    cover = coverage(pts, p, cov, at.predicted(p)[0], workspace=at)
    blocks = at.pose_blocks(p)
    var = [np.trace(blocks[i, 3 * j:3 * j + 3] @ cov @ blocks[i, 3 * j:3 * j + 3].T)
           for i in range(len(blocks)) for j in range(2)]
    assert cover.uncertainty_workspace == pytest.approx(np.sqrt(np.mean(var)), rel=1e-12)


# -- points measured at every pose: their residuals and errors without masks or weights -------------

def test_points_measured_at_every_pose_give_the_residuals_and_errors_of_the_general_path():
    """A marker measured at every pose, unweighted, takes its positions as they are (no selection, no
    weight of 1, no blanking): the same numbers as the general path, which weighs the rows by stated
    deviations of 1 m and blanks the points set aside."""
    from dataclasses import replace

    m, data = _campaign(n=50)
    names = rc.identifiability(m, data).identified
    p = rc.parameter_vector(m) + np.random.default_rng(3).normal(0.0, 1e-4, len(rc.parameter_vector(m)))
    every = Points(m, data, names, compliance=False)
    weighted = Points(m, replace(data, sigma=np.ones(data.mask.shape)), names, compliance=False)
    assert not every.weighted and weighted.weighted
    assert np.array_equal(every.residuals(p), weighted.residuals(p))
    aside = np.zeros(data.mask.shape, dtype=bool)
    aside[7, 0] = True
    blanked = every.without(aside).errors(p)
    full = every.errors(p)
    assert full.flags.c_contiguous and np.isnan(blanked[7, 0]).all() and not np.isnan(full).any()
    assert np.array_equal(np.where(aside[..., None], np.nan, full), blanked, equal_nan=True)


def test_observations_of_each_kind_are_those_listed_with_it():
    """The observations of a kind (made once for the problem) are those whose kind is listed as it,
    measured points and contacts together, in the order the kinds first appear."""
    from pathlib import Path

    from robocal.sim import socket_campaign

    arm7 = rc.read_model(Path(__file__).parent.parent / "examples" / "arm7" / "model.yaml")
    true, data = rc.simulate(arm7, 20, noise=2e-5, seed=2)
    sockets = socket_campaign(true, placements=3, poses_per_socket=6, joint_noise=2e-5, rng=3)
    obs = Problem(arm7, (), data=data, contacts=sockets, compliance=False).observations()
    assert len(obs.kinds()) > 2 and obs.kinds() == tuple(dict.fromkeys(obs.kind))
    for kind in obs.kinds():
        assert np.array_equal(obs.of(kind), np.array([k == kind for k in obs.kind]))
    assert not obs.of("no such kind").any() and len(obs.of("no such kind")) == len(obs)


# -- the model choice: a design freeing more solved from where the first fit ended ------------------

def _choice_start(noise_m=3e-3, n=120):
    """The steps of a calibration up to the first fit, under a stated noise large enough that some
    parameters are held back (so that the model choice has other designs to fit)."""
    from robocal._identification.holdout import FoldProblems, holdout_of
    from robocal._identification.registration import rigid_base
    from robocal._identification.steps import Options, analyse, fit, pin_down, prepare

    m, data = _campaign(n=n, seed=5)
    noise = rc.Noise.of("tracker", position=noise_m)
    options = Options(parameters=("geometric",), known=(), noise=noise, tol=1e-6, loss="linear", f_scale=None,
                      max_nfev=None, on_outliers="refit", weak="eliminate", nonnegative_compliance=False, folds=5,
                      limit_m=None, initial_base="model", register_validation=False)
    a = analyse(prepare(m, data, None, None, options, rigid_base), options)
    holdout = holdout_of(a.problem, 5)
    folds = FoldProblems(holdout)
    first = fit(pin_down(a, noise, None, eliminate=True), options, holdout, folds)
    return a, options, holdout, folds, first


def test_a_jacobian_over_more_parameters_takes_the_columns_kept_and_builds_the_others():
    """Asked for more parameters at a point where fewer were built, the Jacobian keeps those columns
    and builds the others: the Jacobian built whole, to the last bit."""
    m, data = _campaign(n=60)
    names = rc.identifiability(m, data).identified
    p = rc.parameter_vector(m) + np.random.default_rng(4).normal(0.0, 1e-4, len(rc.parameter_vector(m)))
    grown = Points(m, data, names[3:-4], compliance=False)
    part = grown.jacobian(p)
    whole = grown.over(names).jacobian(p)
    assert np.array_equal(whole, Points(m, data, names, compliance=False).jacobian(p))
    assert np.array_equal(whole[:, 3:-4], part)


def test_a_design_freeing_more_solved_from_the_first_fit_ends_where_it_ends_from_the_nominal():
    """Every identifiable parameter free, more than the first fit: solved from where the first fit
    took its last Jacobian (``warm_start``) it ends where it ends from the nominal, within 1e-3 of
    each estimate's standard deviation and with the same held-out errors (1e-6), in no more
    evaluations; a design freeing fewer starts from the nominal."""
    from dataclasses import replace

    from robocal._identification.steps import fit, pin_down, warm_start

    a, options, holdout, folds, first = _choice_start()
    flag = replace(options, on_outliers="flag")
    more = pin_down(a, options.noise, None, eliminate=False, problem=first.problem)
    assert len(first.design.identifiability.identified) < len(more.identifiability.identified)
    start = warm_start(first, more)
    assert first.solution.jacobian_at is not None and np.array_equal(start, first.solution.jacobian_at)
    warm = fit(more, flag, holdout, folds, outliers=first, start=start)
    cold = fit(more, flag, holdout, folds, outliers=first)
    std = rc.identification.covariance(cold.solution).std
    free = more.problem.free_idx
    assert np.all(np.abs(warm.solution.p[free] - cold.solution.p[free]) <= 1e-3 * std)
    mask = first.problem.point_mask
    np.testing.assert_allclose(warm.held_out.observation_norms(mask), cold.held_out.observation_norms(mask),
                               rtol=1e-6)
    assert warm.solution.nfev <= cold.solution.nfev
    fewer = pin_down(a, options.noise, None, eliminate=True, scatter=6e-3, problem=first.problem)
    assert warm_start(first, fewer) is fewer.p0
    assert warm_start(replace(first, solution=replace(first.solution, loss="soft_l1")), more) is more.p0


def test_the_95th_percentile_from_one_partition_is_numpys_bit_for_bit():
    """The accuracy in use's 95th percentile, from one partition, equals np.percentile exactly: every
    size from one value to a few hundred, ties, and a campaign's size."""
    from robocal._identification.holdout import percentile_95

    rng = np.random.default_rng(3)
    for n in [*range(1, 300), 1000, 10001]:
        for v in (rng.lognormal(-8, 1, n), np.round(rng.lognormal(-8, 1, n), 5), np.full(n, 2e-4)):
            assert percentile_95(v) == float(np.percentile(v, 95))


def test_the_row_wise_reductions_are_the_column_ones():
    """Norms, column extents and the points' spread, taken along long rows for speed, against numpy's
    own column-wise forms: the norms and extents bit for bit, the spread to rounding, non-finite
    points left out."""
    from robocal._base.arrays import column_extent, point_spread, vector_norms

    rng = np.random.default_rng(4)
    v = rng.normal(size=(500, 2, 3))
    assert np.array_equal(vector_norms(v), np.linalg.norm(v, axis=2))
    assert np.array_equal(vector_norms(v[..., :2]), np.linalg.norm(v[..., :2], axis=2))
    q = rng.normal(size=(700, 6))
    lo, hi = column_extent(q)
    assert np.array_equal(lo, q.min(axis=0)) and np.array_equal(hi, q.max(axis=0))
    p = rng.normal(size=(400, 3)) * [1.0, 2.0, 0.5]
    expected = np.sqrt(np.mean(np.sum((p - p.mean(axis=0)) ** 2, axis=1)))
    assert point_spread(p) == pytest.approx(expected, rel=1e-13)
    with_gaps = np.vstack([p, [[np.nan, 0.0, 0.0], [np.inf, 1.0, 1.0]]])
    assert point_spread(with_gaps) == pytest.approx(expected, rel=1e-13)
    assert point_spread(p[:1]) == 0.0


# -- what a campaign's readings give every problem made on it: the joints' turns -----------------------

def test_a_fold_takes_the_joint_turns_of_the_campaign_and_evaluates_as_one_made_from_scratch(monkeypatch):
    """The cosines and sines of the readings are made once per campaign while a problem holds them
    (``Measurements.derived``) and a fold cut from it takes its rows: its errors are those of the same
    rows in a record made from scratch, and once no problem holds them the next one makes them anew."""
    import dataclasses
    import gc

    m, data = _campaign(n=60)
    names = rc.identifiability(m, data).identified
    p = rc.parameter_vector(m)
    free = [rc.parameter_names(m).index(n) for n in names]         # geometric: the passes turn the readings
    p[free] += np.random.default_rng(4).normal(0.0, 1e-4, len(free))
    key = ("joint turns", m.coupling_matrix.shape, m.coupling_matrix.tobytes())
    whole = Points(m, data, names, compliance=False)
    whole.errors(p)
    made = data.derived(key, lambda d: pytest.fail("made again while held"), None)
    index = np.arange(60)[np.arange(60) % 5 != 2]
    fold = data.subset(index)
    scratch = rc.Measurements(**{f.name: getattr(fold, f.name) for f in dataclasses.fields(fold)})
    from_scratch = Points(m, scratch, names, compliance=False).errors(p)
    with monkeypatch.context() as patch:             # the fold's turns are the campaign's rows, not made
        patch.setattr(np, "cos", lambda *a, **k: pytest.fail("the fold's turns made anew"))
        cut = Points(m, fold, names, compliance=False)
        errors = cut.errors(p)
    assert np.array_equal(errors, from_scratch)
    taken = fold.derived(key, lambda d: pytest.fail("made although the campaign's are held"), None)
    qf = np.asarray(data.q[index]) @ m.coupling_matrix.T
    assert np.array_equal(taken[0], np.cos(qf.T)) and np.array_equal(taken[1][:, 0, 0], np.sin(qf.T))
    del whole, made, taken, cut
    gc.collect()
    fresh = data.subset(index).derived(key, lambda d: (np.zeros(1),), None)
    assert np.array_equal(fresh[0], np.zeros(1))


# -- the model choice, the fits and the analysis --------------------------------------------------

def test_a_triangular_factor_is_its_own_qr_as_lapack_makes_it():
    """The R factor of stacked rows (``reduced``) is returned as its own QR (Q the identity): what
    numpy's Householder QR gives for it, bit for bit, whatever the signs on its diagonal; any other
    matrix is factored."""
    from robocal._base.linalg import reduced
    from robocal._identification.identifiability import qr_factors

    rng = np.random.default_rng(5)
    for k in (1, 6, 35, 114):
        R = reduced(rng.normal(size=(4 * k, k)) * np.logspace(-4, 2, k))
        Q, same = qr_factors(R)
        Qn, Rn = np.linalg.qr(R)
        assert np.array_equal(Q, Qn) and np.array_equal(same, Rn)
    A = rng.normal(size=(8, 8))
    Q, R = qr_factors(A)
    assert np.allclose(Q @ R, A) and not np.array_equal(Q, np.eye(8))


def test_the_all_free_design_names_the_weak_parameters_the_first_one_found_as_from_scratch():
    """The model choice's all-free design names the weak parameters its first design found at the
    same scatter (kept with the analysis): the same names and predicted effects as an analysis that
    judges them anew."""
    from dataclasses import replace

    from robocal._identification.steps import pin_down

    a, options, _, _, first = _choice_start()
    assert first.design.weak and a.weak_at
    shared = pin_down(a, options.noise, None, eliminate=False, problem=first.problem)
    anew = pin_down(replace(a, weak_at={}), options.noise, None, eliminate=False, problem=first.problem)
    assert shared.weak == anew.weak == first.design.weak
    assert shared.identifiability.identified == anew.identifiability.identified


def test_weak_parameters_eliminated_together_are_absorbed_as_each_alone():
    """Parameters eliminated together take their absorbing combinations from one least-squares solve:
    each combination (parameter units) and what it leaves (unit columns) as a solve of that column
    alone on the parameters kept."""
    from robocal._identification.identifiability import eliminate
    from robocal._model.parameters import parameter_layout

    a, _, _, _, _ = _choice_start()
    J, names = a.stack.J, a.stack.names
    lay = parameter_layout(a.problem.model)
    kept = a.identifiability.identified
    dropped = {kept[-1]: "held", kept[-3]: "held"}
    result = eliminate(a.identifiability, J, names, [lay[n].quantity for n in names], dropped,
                       n_rows=a.problem.n_rows)
    unit = J / np.linalg.norm(J, axis=0)
    cols = [names.index(n) for n in result.identified]
    absorbed_ = [x for x in result.eliminated if x.name in dropped]
    assert len(absorbed_) == 2
    for absorbed in absorbed_:
        k = names.index(absorbed.name)
        c = np.linalg.lstsq(unit[:, cols], unit[:, k], rcond=None)[0]
        assert absorbed.residual == pytest.approx(np.linalg.norm(unit[:, cols] @ c - unit[:, k]), rel=1e-9, abs=1e-15)
        coef = dict(absorbed.absorbers)
        scale = np.linalg.norm(J, axis=0)
        for i in np.argsort(-np.abs(c))[:len(coef)]:
            assert coef[result.identified[i]] == pytest.approx(c[i] * scale[k] / scale[cols[i]], rel=1e-9)


def test_observation_errors_asked_again_are_those_made_anew_and_a_changed_problem_makes_its_own():
    """The outliers, the scatter and the checks ask a problem for its observations' errors at the
    solution in turn: the ones kept are those a problem made anew gives (read-only), another vector
    or the problem with observations set aside computes its own."""
    m, data = _campaign(n=80)
    names = rc.identifiability(m, data).identified
    prob = Problem(m, names, data=data, compliance=False)
    p = rc.parameter_vector(m) + np.random.default_rng(6).normal(0.0, 1e-4, len(rc.parameter_vector(m)))
    first = prob.observation_errors(p)
    again = prob.observation_errors(p.copy())
    fresh = Problem(m, names, data=data, compliance=False).observation_errors(p)
    assert again is first
    for e, _, index in first.values():
        assert not e.flags.writeable and not index.flags.writeable
    assert all(np.array_equal(a, b) for a, b in zip(first["tracker"], fresh["tracker"]) if a is not None)
    elsewhere = prob.observation_errors(p + 1e-5)
    assert not np.array_equal(elsewhere["tracker"][0], first["tracker"][0])
    aside = np.zeros(prob.n_points, dtype=bool)
    aside[:5] = True
    fewer = prob.without(aside).observation_errors(p)
    assert len(fewer["tracker"][0]) == prob.n_points - 5
    assert np.array_equal(fewer["tracker"][0], first["tracker"][0][5:])


def test_the_nominals_fold_steps_from_the_registrations_last_jacobian_are_those_at_its_vector():
    """The nominal's registration (errors before calibration) ends a tolerance from where its solve
    took its last Jacobian; the held-out errors of its fold models stepped from that Jacobian are those
    stepped from one evaluated at the registered vector itself (1e-6)."""
    from robocal._identification.holdout import cross_validate
    from robocal._identification.steps import placed_parameters, registered_nominal

    _, _, holdout, folds, first = _choice_start()
    before, at, _ = registered_nominal(first.design)
    assert at is not None and not np.array_equal(at, before)
    placed = first.problem.over(placed_parameters(first.design))
    shared = cross_validate(placed, before, holdout, folds=folds, at=at)
    anew = cross_validate(placed, before, holdout, folds=folds)
    mask = first.problem.point_mask
    np.testing.assert_allclose(shared.observation_norms(mask), anew.observation_norms(mask), rtol=1e-6)
    assert not np.array_equal(shared.observation_norms(mask), anew.observation_norms(mask))


def test_the_chosen_fit_keeps_its_evaluations_through_the_model_choice_and_the_registration(monkeypatch):
    """With compliance (nothing moved rigidly) the model choice's all-free design and the nominal's
    registration evaluate many vectors after the chosen fit's: its solution and the point of its last
    Jacobian are still kept when the accuracy in use and the diagnosis ask for them (no vector is
    evaluated twice on the campaign's readings)."""
    from robots import humanoid

    import robocal._identification.points as points

    m = humanoid(markers=("lhand", "rhand"))
    families = ("geometric", "compliance")
    _, data = rc.simulate(m, 100, parameters=families, seed=1)
    made = []
    real = points.evaluate_state

    def counted(model, lay, p, qf, **kwargs):
        made.append((id(qf), np.asarray(p).tobytes()))
        return real(model, lay, p, qf, **kwargs)

    monkeypatch.setattr(points, "evaluate_state", counted)
    res = rc.calibrate(m, data, parameters=families)
    assert any(n.startswith("model choice by cross-validated error") for n in res.notes)
    assert len(made) == len(set(made))


# -- the evidence: folds, workspace and coverage from what the calibration holds ----------------------

def _lost_motion(model):
    """``model`` with 2 arcmin of backlash on every joint, resting on the side of its last move."""
    from dataclasses import replace

    arcmin = np.pi / 180 / 60
    return model.replace(frames=tuple(replace(f, backlash_theta=arcmin, backlash_width=1.0) for f in model.frames),
                         backlash_side="approach")


@pytest.mark.parametrize("kind", ["geometric", "compliance", "backlash"])
def test_each_folds_pass_at_its_own_readings_is_the_fold_evaluated_as_a_problem_of_its_own(kind):
    """The fit's held-out errors, each fold's model evaluated at that fold's readings alone and the
    errors and loss taken over the campaign at once, equal each fold made a problem of its own and
    evaluated: folds drawn at random (poses of a fold apart), points not measured, stated
    deviations, a payload per pose under compliance, lost motion resting by the campaign's order."""
    from robocal._identification.holdout import Holdout, cross_validate, evaluated, fold_steps

    m = arm6r(markers=(("tool", (0.05, 0.02, 0.12)), ("side", (0.1, -0.05, 0.08))), masses=kind == "compliance")
    m = _lost_motion(m) if kind == "backlash" else m
    mass = np.arange(90) % 3 * 2.0 if kind == "compliance" else None
    _, data = rc.simulate(m, 90, seed=7, payload_mass=mass)
    mask = data.mask.copy()
    mask[::7, 1] = False
    sigma = np.full(mask.shape, 2e-5) * (1 + np.arange(90) % 2)[:, None]
    data = rc.Measurements(q=data.q, positions=data.positions, marker_names=data.marker_names,
                           joint_names=data.joint_names, mask=mask, sigma=sigma, payload_mass=data.payload_mass)
    names = rc.identifiability(m, data).identified
    names += ("j2.k_theta",) if kind == "compliance" else ("j3.backlash_theta",) if kind == "backlash" else ()
    prob = Problem(m, names, data=data, compliance=kind == "compliance")
    p = rc.parameter_vector(m) + 1e-4 * np.isin(rc.parameter_names(m), names)
    labels = np.random.default_rng(1).permutation(90) % 4
    holdout = Holdout(labels[np.nonzero(mask)[0]], 4, "4 folds", labels, 4)
    shared = cross_validate(prob, p, holdout)
    steps = fold_steps(prob, p, holdout)
    whole = data.with_approach()
    for g in range(4):
        index = np.nonzero(labels == g)[0]
        pg = p.copy()
        pg[prob.free_idx] += steps[g]
        alone = evaluated(Points(m, whole.subset(index), names, compliance=kind == "compliance"), pg)
        np.testing.assert_allclose(shared.positions[index], alone.positions, rtol=0, atol=1e-14)
        np.testing.assert_allclose(shared.loss[index], alone.loss, rtol=1e-12)
    assert np.isnan(shared.positions[::7, 1]).all() and np.isfinite(shared.positions[1::7]).all()


def test_the_instruments_share_taken_out_by_a_plain_mean_is_the_nan_mean_one():
    """Norms all finite take their mean square as a plain sum (np.nanmean's figure bit for bit);
    with points not measured (NaN), an infinite norm or none at all, the NaN-aware mean as before."""
    from robocal._identification.holdout import without_instrument

    def reference(v, variance):
        ms = float(np.nanmean(v * v)) if np.isfinite(v).any() else 0.0
        return v if ms <= 0 or variance <= 0 else v * np.sqrt(max(1.0 - 3.0 * variance / ms, 0.0))

    rng = np.random.default_rng(5)
    for n in (1, 2, 7, 1000, 10001):
        v = rng.lognormal(-8, 1, n)
        gaps = np.where(np.arange(n) % 5 == 1, np.nan, v)
        for norms in (v, gaps, np.full(n, np.nan), np.r_[v, np.inf]):
            for variance in (0.0, 1e-9, float(np.mean(v * v))):
                assert np.array_equal(without_instrument(norms, variance), reference(norms, variance), equal_nan=True)
    assert without_instrument(np.zeros(0), 1e-9).size == 0


@pytest.mark.parametrize("stated", [False, True])
def test_each_points_loss_from_its_errors_is_the_sum_of_its_squared_residuals(stated):
    """A held-out point's loss taken from its errors (three weighted components squared and added)
    equals its rows' squared residuals summed row by row, bit for bit: every point measured or some
    not, stated deviations or none."""
    from robocal._identification.holdout import point_loss

    m = arm6r(markers=(("tool", (0.05, 0.02, 0.12)), ("side", (0.1, -0.05, 0.08))))
    _, data = rc.simulate(m, 80, seed=9, noise=1e-4)
    names = rc.identifiability(m, data).identified
    p = rc.parameter_vector(m)
    for mask in (data.mask, data.mask & (np.arange(80) % 6 != 4)[:, None] * [True, False] | [False, True]):
        sigma = (np.full(mask.shape, 3e-5) * (1 + np.arange(80) % 4)[:, None]) if stated else None
        d = rc.Measurements(q=data.q, positions=data.positions, marker_names=data.marker_names,
                            joint_names=data.joint_names, mask=mask, sigma=sigma)
        pts = Points(m, d, names, compliance=False)
        r = pts.residuals(p)
        poses, markers = pts.row_points()
        by_rows = np.bincount(poses * 2 + markers, weights=r * r, minlength=160).reshape(80, 2)
        assert np.array_equal(point_loss(pts, p, pts.errors(p)), by_rows)
        assert np.array_equal(point_loss(pts, p), by_rows)


def test_a_model_given_other_words_is_the_model_a_checked_replace_makes():
    """RobotModel.replace with a description alone skips the structure's checks (nothing they check
    changed): the model equals the one dataclasses.replace builds and checks; other changes are checked."""
    import dataclasses
    import pickle

    m = arm6r()
    worded = m.replace(description="calibrated on the 6R grid")
    assert worded == dataclasses.replace(m, description="calibrated on the 6R grid") and worded is not m
    assert worded.description == "calibrated on the 6R grid" and m.description != worded.description
    assert pickle.loads(pickle.dumps(worded)) == worded
    with pytest.raises(rc.InputError):
        m.replace(frames=())
