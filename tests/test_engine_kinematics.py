"""The engine's pieces, each against the reference transform ``mdh_transform`` (docs/method.md
sections 1 to 3): a pass's frames on both of its paths (constant and deflected parts), the step
axes and points the Jacobian reads, the markers, a pass moved by its base, the gravity moments."""

from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from test_kinematics import _random_tree_model

from robocal._model.kinematics import (
    FRAME_ROWS,
    N_BASE,
    N_FRAME_STEPS,
    FrameRow,
    FrameStep,
    base_rotation_of,
    compliant_vectors,
    evaluate_state,
    joint_moments,
    joint_turns,
    kinematic_pass,
    layout,
    mass_sums,
    moved_state,
)
from robocal.kinematics import GEOMETRIC_KINDS, Frame, mdh_transform, parameter_vector

TOL = 1e-13


def _reference_frames(model, qf, changes=None):
    """X_W<frame> (N, n_frames, 4, 4) by chained ``mdh_transform``; ``changes(i, n)`` a dict of values
    replacing frame i's at pose n (its deflections)."""
    N = len(qf)
    out = np.empty((N, model.n_frames, 4, 4))
    for n in range(N):
        for i, f in enumerate(model.frames):
            g = replace(f, **changes(i, n)) if changes else f
            parent = model.X_WB if f.parent < 0 else out[n, f.parent]
            out[n, i] = parent @ mdh_transform(g, qf[n, i] if f.joint != "fixed" else 0.0)
    return out


def _model_and_readings(seed, n=5):
    m = _random_tree_model(seed)
    q = np.random.default_rng(seed).uniform(-1, 1, (n, m.n_joints))
    return m, q @ m.coupling_matrix.T


def _pass_frames(ps):
    X = np.zeros((ps.N, ps.model.n_frames, 4, 4))
    X[..., :3, :3] = ps.R.transpose(1, 0, 2, 3)
    X[..., :3, 3] = ps.O.transpose(1, 0, 2)
    X[..., 3, 3] = 1.0
    return X


@pytest.mark.parametrize("seed", [0, 1])
def test_a_pass_places_every_frame_as_the_reference_transform_does(seed):
    # kinematic_pass with _constant_frame, _place and _turn_rows: every frame's constant part
    m, qf = _model_and_readings(seed)
    ps = kinematic_pass(m, layout(m), parameter_vector(m), qf)
    np.testing.assert_allclose(_pass_frames(ps), _reference_frames(m, qf), atol=TOL)


@pytest.mark.parametrize("seed", [0, 1])
def test_a_deflected_pass_places_every_frame_at_its_deflected_values(seed):
    # _deflected_frame (alpha and beta varying pose by pose) and theta's per-pose deflection
    m, qf = _model_and_readings(seed)
    rng = np.random.default_rng(seed + 10)
    defl = [tuple(rng.normal(0, 0.05, len(qf)) for _ in range(3)) for _ in m.frames]   # theta, alpha, beta
    ps = kinematic_pass(m, layout(m), parameter_vector(m), qf, defl=defl)

    def deflected(i, n):
        f, (d_th, d_al, d_be) = m.frames[i], defl[i]
        return dict(theta=f.theta + d_th[n], alpha=f.alpha + d_al[n], beta=f.beta + d_be[n])
    np.testing.assert_allclose(_pass_frames(ps), _reference_frames(m, qf, deflected), atol=TOL)


def test_the_turns_a_caller_holds_give_the_pass_it_would_make():
    m, qf = _model_and_readings(2)
    p = parameter_vector(m)
    cos_q, sin_q = joint_turns(qf)
    assert not cos_q.flags.writeable and not sin_q.flags.writeable
    held, made = (kinematic_pass(m, layout(m), p, qf, turns=turns) for turns in ((cos_q, sin_q), None))
    np.testing.assert_array_equal(_pass_frames(held), _pass_frames(made))
    np.testing.assert_array_equal(held.P, made.P)


def test_the_frame_steps_are_the_geometric_kinds_in_order():
    assert [getattr(FrameStep, k.upper()) for k in GEOMETRIC_KINDS] == list(range(N_FRAME_STEPS))
    rows = [v for k, v in vars(FrameRow).items() if k.isupper()]
    assert sorted(rows) == list(range(FRAME_ROWS))


def _partial(f: Frame, upto: int) -> np.ndarray:
    """The product of f's steps before ``upto`` (a ``FrameStep``; the others zero), by ``mdh_transform``."""
    return mdh_transform(Frame("part", joint="fixed", **{k: getattr(f, k) for k in GEOMETRIC_KINDS[:upto]}))


@pytest.mark.parametrize("seed", [0, 1])
def test_step_axes_and_points_are_those_of_the_reference_transform(seed):
    # _vector_rows and _fill_step_vectors: what every Jacobian column reads (docs/method.md section 3)
    m, qf = _model_and_readings(seed)
    lay = layout(m)
    ps = kinematic_pass(m, lay, parameter_vector(m), qf, orientations=True)
    vec = ps.vectors()
    X = _reference_frames(m, qf)
    for i, f in enumerate(m.frames):
        parent = np.broadcast_to(m.X_WB, X[:, i].shape) if f.parent < 0 else X[:, f.parent]
        at_beta = parent @ _partial(f, FrameStep.BETA)            # after gamma and b
        at_d = parent @ _partial(f, FrameStep.D)                  # after beta and alpha
        at_theta = parent @ _partial(f, FrameStep.THETA)          # after d
        r0 = lay.frame_row[i]
        expected = {"BETA_AXIS": at_beta[:, :3, 1], "BETA_POINT": at_beta[:, :3, 3], "D_AXIS": at_d[:, :3, 0],
                    "THETA_POINT": at_theta[:, :3, 3], "Z_AXIS": X[:, i, :3, 2], "ORIGIN": X[:, i, :3, 3]}
        for row, want in expected.items():
            np.testing.assert_allclose(vec[r0 + getattr(FrameRow, row)].T, want, atol=TOL, err_msg=f"{f.name} {row}")
        # the steps' own rows: each step's axis and point through the layout
        s0 = N_BASE + N_FRAME_STEPS * i
        axes, points = lay.step_rows[1]
        np.testing.assert_allclose(vec[axes[s0 + FrameStep.ALPHA]].T, at_d[:, :3, 0], atol=TOL)
        np.testing.assert_allclose(vec[points[s0 + FrameStep.THETA]].T, at_theta[:, :3, 3], atol=TOL)
        np.testing.assert_allclose(vec[axes[s0 + FrameStep.GAMMA]].T, parent[:, :3, 2], atol=TOL)


def test_markers_sit_where_the_reference_transform_puts_them():
    m, qf = _model_and_readings(3)
    ps = kinematic_pass(m, layout(m), parameter_vector(m), qf, orientations=True)
    X = _reference_frames(m, qf)
    for k, mk in enumerate(m.markers):
        np.testing.assert_allclose(ps.P[k], (X[:, mk.frame] @ np.append(mk.position, 1.0))[:, :3], atol=TOL)
        np.testing.assert_allclose(ps.RM[k], X[:, mk.frame, :3, :3] @ np.asarray(mk.rotation), atol=TOL)


def test_a_pass_moved_by_its_base_is_the_reference_chain_on_the_moved_base():
    m, qf = _model_and_readings(4)
    lay = layout(m)
    p = parameter_vector(m)
    st = evaluate_state(m, lay, p, qf, compliance=False, orientations=False)
    moved = p.copy()
    moved[:6] += (0.02, -0.01, 0.03, 0.01, -0.02, 0.015)
    ps = moved_state(st, moved).ps
    Rb = base_rotation_of(m.base_rotation, *moved[3:6])[1]
    Rref = np.asarray(m.base_rotation)
    np.testing.assert_allclose(Rb, Rref @ Rotation.from_rotvec(moved[3:6]).as_matrix(), atol=TOL)
    X = _reference_frames(m.replace(base_position=tuple(moved[:3]), base_rotation=tuple(map(tuple, Rb))), qf)
    np.testing.assert_allclose(_pass_frames(ps), X, atol=TOL)


def test_gravity_moments_are_the_sums_over_the_distal_masses():
    # mass_sums, compliant_vectors, joint_moments: M_p = sum_k ((c_k - O_p) x (m_k g)) . u_p (section 2)
    m, qf = _model_and_readings(5)
    lay = layout(m)
    ps = kinematic_pass(m, lay, parameter_vector(m), qf)
    C1, msub = mass_sums(m, lay, ps, None)
    M, _, _ = joint_moments(m, ps, C1, msub)
    u, Q, _ = compliant_vectors(m, ps)
    X = _reference_frames(m, qf)
    g = np.asarray(m.gravity)
    payload = m.payload
    for i in range(m.n_frames):
        distal = np.nonzero(lay.subtree[i])[0]
        masses = [(X[:, k] @ np.append(m.frames[k].com, 1.0))[:, :3] for k in distal]
        weights = [m.frames[k].mass for k in distal]
        if (payload.frame if payload.frame >= 0 else m.n_frames - 1) in distal:
            masses.append((X[:, payload.frame] @ np.append(payload.com, 1.0))[:, :3])
            weights.append(payload.mass)
        for c, step in enumerate(("theta", "alpha", "beta")):
            row = 3 * i + c
            axis, point = u[:, row].T, Q[:, row].T
            want = sum(np.einsum("nk,nk->n", np.cross(ck - point, w * g), axis) for ck, w in zip(masses, weights))
            np.testing.assert_allclose(M[row], want, atol=1e-11, err_msg=f"{m.frames[i].name} {step}")
