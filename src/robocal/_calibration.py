"""Identification: least squares on the identifiable parameters, with uncertainty and statistics."""

from __future__ import annotations

import copy
import warnings
from dataclasses import dataclass, field
from functools import lru_cache
from datetime import datetime, timezone

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from ._measurements import Measurements
from ._errors import (ConvergenceWarning, DegenerateDataError, IdentifiabilityWarning, InputError,
                      MisfitWarning)
from ._identifiability import DEFAULT_TOL, IdentifiabilityResult, analyse, singular_values
from ._kinematics import _evaluate_state, _jacobian_columns, evaluate, layout, model_from_vector, parameter_vector
from ._misfit import characteristic_length, misfit_notes
from ._model import RobotModel
from ._parameters import candidate_parameters, unit_of

SCHEMA = "robocal.result/1"
# least_squares' step, cost and gradient tolerances: Gauss-Newton converges quadratically here, so
# the step that meets them leaves an error far below them (noise-free recovery is ~1e-16)
SOLVER_TOL = 1e-10
LOSSES = ("linear", "soft_l1", "huber", "cauchy", "arctan")


def error_stats(norms) -> dict:
    """mean, std, rms, max and count of error norms (metres); NaN entries are not measured."""
    v = np.asarray(norms, dtype=float).ravel()
    v = v[np.isfinite(v)]
    if v.size == 0:
        return {"n": 0, "mean": None, "std": None, "rms": None, "max": None}
    return {"n": int(v.size), "mean": float(v.mean()), "std": float(v.std(ddof=1)) if v.size > 1 else 0.0,
            "rms": float(np.sqrt(np.mean(v ** 2))), "max": float(v.max())}


class _Problem:
    """Residuals and Jacobian of one model on one data set, over a chosen set of parameters.

    Rows are ordered marker by marker, then pose by pose (x, y, z), then, with orientations, the
    rotation rows in the same order. The Jacobian is returned column-major (a transposed view),
    as MINPACK works on columns. ``fun`` and ``jac`` at the same parameters share one pass.
    """

    def __init__(self, model: RobotModel, data: Measurements, free: tuple[str, ...], *, compliance: bool):
        self.model = model
        self.data = data
        self.lay = layout(model)
        self.free_idx = self._indices(free)
        self.compliance = compliance
        self.qf = data.q @ model.coupling_matrix.T
        self.marker_idx = np.array([model.marker_names.index(n) for n in data.marker_names], dtype=int)
        self.use_rot = data.has_orientation
        self.sel = [np.nonzero(data.mask[:, j])[0] for j in range(len(data.marker_names))]
        self.w = [np.ones(len(s)) if data.sigma is None else 1.0 / data.sigma[s, j] for j, s in enumerate(self.sel)]
        self.meas = [data.positions[s, j] for j, s in enumerate(self.sel)]
        if self.use_rot:
            self.sel_r = [np.nonzero(data.rot_mask[:, j])[0] for j in range(len(data.marker_names))]
            sr = data.sigma_rot
            self.w_r = [np.ones(len(s)) if sr is None else 1.0 / sr[s, j] for j, s in enumerate(self.sel_r)]
        self._cache_key = None
        self._cache = None

    def _indices(self, free) -> np.ndarray:
        index = {n: i for i, n in enumerate(self.lay.names)}
        return np.array([index[n] for n in free], dtype=int)

    def over(self, free: tuple[str, ...]) -> _Problem:
        """The same problem over other free parameters, keeping the evaluation already made."""
        other = copy.copy(self)
        other.free_idx = self._indices(free)
        return other

    @property
    def n_rows(self) -> int:
        return 3 * sum(len(s) for s in self.sel) + (3 * sum(len(s) for s in self.sel_r) if self.use_rot else 0)

    def _state(self, p):
        key = p.tobytes()
        if key != self._cache_key:
            self._cache = _evaluate_state(self.model, self.lay, p, self.qf, compliance=self.compliance,
                                          orientations=self.use_rot, payload_mass=self.data.payload_mass)
            self._cache_key = key
        return self._cache

    def predicted(self, p):
        """Marker positions (n_poses, n_data_markers, 3) and orientations (or None) at ``p``."""
        st = self._state(p)
        pos = st.ps.P[self.marker_idx].transpose(1, 0, 2)
        rot = np.stack([st.ps.RM[m] for m in self.marker_idx], axis=1) if self.use_rot else None
        return pos, rot

    def errors(self, p) -> np.ndarray:
        """(n_poses, n_data_markers, 3) predicted minus measured positions, NaN where not measured."""
        pos, _ = self.predicted(p)
        return np.where(self.data.mask[..., None], pos - self.data.positions, np.nan)

    def _rotation_errors(self, st, j) -> np.ndarray:
        """(n, 3) rotation vectors of R_pred R_meas^T in W for marker j's measured orientations."""
        s = self.sel_r[j]
        Rp = st.ps.RM[self.marker_idx[j]][s]
        Rm = self.data.rotations[s, j]
        return Rotation.from_matrix(Rp @ np.swapaxes(Rm, -1, -2)).as_rotvec()

    def residuals(self, p) -> np.ndarray:
        st = self._state(p)
        parts = [((st.ps.P[m][s] - meas) * w[:, None]).ravel()
                 for m, s, meas, w in zip(self.marker_idx, self.sel, self.meas, self.w)]
        if self.use_rot:
            parts += [(self._rotation_errors(st, j) * w[:, None]).ravel() for j, w in enumerate(self.w_r)]
        return np.concatenate(parts)

    def rotation_residuals(self, p) -> np.ndarray | None:
        """(n, 3) unweighted rotation residuals in rad, or None for point data."""
        if not self.use_rot:
            return None
        st = self._state(p)
        return np.concatenate([self._rotation_errors(st, j) for j in range(len(self.sel_r))])

    def jacobian(self, p) -> np.ndarray:
        """Weighted Jacobian of ``residuals`` over the free parameters: (n_rows, n_free), column-major."""
        st = self._state(p)
        rows = 6 if self.use_rot else 3
        k = len(self.free_idx)
        cols = [_jacobian_columns(self.model, self.lay, st, self.free_idx, m, rows) for m in self.marker_idx]
        parts = []
        for C, s, w in zip(cols, self.sel, self.w):
            if len(s) == C.shape[1] and self.data.sigma is None:
                parts.append(C[:, :, :3].reshape(k, -1))
            else:
                parts.append((C[:, s, :3] * w[None, :, None]).reshape(k, -1))
        if self.use_rot:
            parts += [(C[:, s, 3:] * w[None, :, None]).reshape(k, -1) for C, s, w in zip(cols, self.sel_r, self.w_r)]
        Jt = parts[0] if len(parts) == 1 else np.concatenate(parts, axis=1)
        return Jt.T

    def pose_blocks(self, p) -> np.ndarray:
        """(n_poses, rows_per_pose, n_free) unweighted Jacobian grouped by pose (all markers seen)."""
        st = self._state(p)
        rows = 6 if self.use_rot else 3
        cols = [_jacobian_columns(self.model, self.lay, st, self.free_idx, m, rows) for m in self.marker_idx]
        return np.concatenate([C.transpose(1, 2, 0) for C in cols], axis=1)


@dataclass(frozen=True)
class ParameterEstimate:
    name: str
    unit: str
    nominal: float
    estimate: float
    std: float

    @property
    def change(self) -> float:
        return self.estimate - self.nominal

    def to_dict(self) -> dict:
        return {"name": self.name, "unit": self.unit, "nominal": self.nominal, "estimate": self.estimate,
                "change": self.change, "std": self.std}


@dataclass(frozen=True, eq=False)
class CalibrationResult:
    """Everything a calibration produced. Fields are always present; absent data are None.

    ``residual_vectors`` (n_poses, n_markers, 3) calibrated minus measured and ``measured_positions``
    likewise, metres in W, NaN where not measured.
    ``errors_before``/``errors_after``: (n_poses, n_markers) position error norms in metres on the
    fitted poses (NaN where not measured); ``validation_before``/``validation_after`` likewise on
    held-out poses, or None. ``stats`` maps "fit_before", "fit_after", "validation_before",
    "validation_after" to ``error_stats`` dicts. ``correlation`` is indexed like ``parameters``.
    """

    nominal_model: RobotModel
    calibrated_model: RobotModel
    parameters: tuple[ParameterEstimate, ...]
    covariance: np.ndarray
    correlation: np.ndarray
    identifiability: IdentifiabilityResult
    stats: dict
    errors_before: np.ndarray
    errors_after: np.ndarray
    validation_before: np.ndarray | None
    validation_after: np.ndarray | None
    residual_vectors: np.ndarray
    measured_positions: np.ndarray
    success: bool
    status: int
    message: str
    nfev: int
    sigma0: float
    families: tuple[str, ...]
    loss: str
    notes: tuple[str, ...] = ()
    limit: dict | None = None
    provenance: dict = field(default_factory=dict)

    def estimate(self, name: str) -> ParameterEstimate:
        return next(p for p in self.parameters if p.name == name)

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    def to_dict(self) -> dict:
        def arr(a):
            return None if a is None else np.where(np.isfinite(a), a, np.nan).tolist()

        from ._files.model import model_to_dict  # late: the file form of a model lives with the readers

        return {
            "schema": SCHEMA,
            "success": self.success, "status": self.status, "message": self.message, "nfev": self.nfev,
            "families": list(self.families), "loss": self.loss, "sigma0_m": self.sigma0,
            "parameters": [p.to_dict() for p in self.parameters],
            "correlation": self.correlation.tolist(), "covariance": self.covariance.tolist(),
            "identifiability": self.identifiability.to_dict(),
            "identifiability_table": self.identifiability.table(self.nominal_model.frame_names),
            "stats": self.stats,
            "errors": {"unit": "m", "markers": list(self.nominal_model.marker_names),
                       "fit_before": arr(self.errors_before), "fit_after": arr(self.errors_after),
                       "validation_before": arr(self.validation_before),
                       "validation_after": arr(self.validation_after),
                       "fit_residual_vectors": arr(self.residual_vectors),
                       "fit_positions": arr(self.measured_positions)},
            "notes": list(self.notes), "limit": self.limit, "provenance": self.provenance,
            "nominal_model": model_to_dict(self.nominal_model),
            "calibrated_model": model_to_dict(self.calibrated_model),
        }


def register_base(model: RobotModel, data: Measurements) -> RobotModel:
    """The model with ``X_WB`` from a closed-form rigid registration (Kabsch/Horn, via scipy).

    The nominal marker positions in frame 0 are matched to the measured ones in W; needs three
    non-collinear measured points.
    """
    origin = model.replace(base_position=(0.0, 0.0, 0.0),
                           base_rotation=((1.0, 0, 0), (0, 1.0, 0), (0, 0, 1.0)))
    ev = evaluate(origin, data.q, payload_mass=data.payload_mass)
    mi = np.array([model.marker_names.index(n) for n in data.marker_names])
    pb = ev.positions[:, mi][data.mask]
    pw = data.positions[data.mask]
    if len(pb) < 3 or np.linalg.matrix_rank(pb - pb.mean(0), tol=1e-6) < 2:
        raise DegenerateDataError("base registration needs at least three measured points that are not collinear")
    cb, cw = pb.mean(0), pw.mean(0)
    rot, _ = Rotation.align_vectors(pw - cw, pb - cb)
    R = rot.as_matrix()
    t = cw - R @ cb
    return model.replace(base_position=tuple(float(v) for v in t),
                         base_rotation=tuple(tuple(float(v) for v in row) for row in R))


def random_configurations(model: RobotModel, n: int, rng=None) -> np.ndarray:
    """``n`` joint readings drawn uniformly within the joint limits (unbounded joints within +-pi)."""
    rng = np.random.default_rng(rng)
    lo = np.nan_to_num(model.lower_limits, neginf=-np.pi, posinf=np.pi)
    hi = np.nan_to_num(model.upper_limits, neginf=-np.pi, posinf=np.pi)
    return rng.uniform(lo, hi, size=(n, model.n_joints))


def identifiability(model: RobotModel, data: Measurements | np.ndarray | None = None, *,
                    parameters=("geometric",), known=(), orientation: bool | None = None,
                    tol: float = DEFAULT_TOL, n_random: int = 200, rng=0) -> IdentifiabilityResult:
    """Which parameters are identifiable at the poses of ``data`` (Measurements or readings q).

    With ``data=None`` the analysis uses ``n_random`` configurations drawn within the joint limits:
    what theory allows for this robot, whatever the poses.
    """
    if data is None:
        q = random_configurations(model, n_random, rng)
    elif isinstance(data, Measurements):
        q = data.q
    else:
        q = np.atleast_2d(np.asarray(data, dtype=float))
    meas = data if isinstance(data, Measurements) else design_measurements(model, q, bool(orientation))
    if orientation is None:
        orientation = meas.has_orientation
    names = candidate_parameters(model, parameters, orientation=orientation, known=known)
    prob = _Problem(model, meas, names, compliance=needs_compliance(model, names))
    return analyse(prob.jacobian(parameter_vector(model)), names, tol=tol)


def design_measurements(model: RobotModel, q, orientation: bool = False) -> Measurements:
    """Configurations without measured values, for what depends on the poses only (the Jacobian)."""
    n, m = len(q), len(model.markers)
    return Measurements(q=q, positions=np.zeros((n, m, 3)), marker_names=model.marker_names,
                        rotations=np.broadcast_to(np.eye(3), (n, m, 3, 3)) if orientation else None)


def needs_compliance(model: RobotModel, names) -> bool:
    """Whether evaluating ``names`` on ``model`` needs the gravity moments."""
    return model.has_compliance or any(n.rsplit(".", 1)[1].startswith("k_") for n in names)


def _as_tuple(v) -> tuple:
    return (v,) if isinstance(v, str) else tuple(v)


@lru_cache(maxsize=32)
def _theory(model: RobotModel, parameters: tuple, known: tuple, orientation: bool, tol: float) -> IdentifiabilityResult:
    """What this robot's structure allows to identify (random configurations, fixed seed)."""
    return identifiability(model, None, parameters=parameters, known=known, orientation=orientation, tol=tol, rng=0)


def _check_data(model: RobotModel, data: Measurements, what: str) -> None:
    src = data.source or what
    if data.q.shape[1] != model.n_joints:
        raise InputError(f"{data.q.shape[1]} joint columns for a model with {model.n_joints} joints "
                         f"({', '.join(model.joint_names)})", source=src)
    for n in data.marker_names:
        if n not in model.marker_names:
            raise InputError(f"marker {n!r} is not in the model (markers: {', '.join(model.marker_names)})",
                             source=src)


def _norms(prob: _Problem, p) -> np.ndarray:
    """(n_poses, n_data_markers) position error norms, NaN where not measured."""
    return np.linalg.norm(prob.errors(p), axis=2)


def calibrate(model: RobotModel, data: Measurements, *, parameters=("geometric",), known=(),
              validation: Measurements | None = None, loss: str = "linear", f_scale: float | None = None,
              tol: float = DEFAULT_TOL, max_nfev: int | None = None, initial_base: str = "model",
              limit=None) -> CalibrationResult:
    """Identify the identifiable parameters of ``model`` from ``data``.

    ``parameters``: families (``geometric``, ``compliance``, ``base``, ``markers``, ``frames``)
    and/or explicit names; ``known``: families or names held at their model values.
    ``initial_base``: ``"model"`` starts from the model's base pose, ``"register"`` from a
    closed-form rigid registration of the nominal robot onto the measurements.
    ``loss``: least-squares loss (``linear`` or a robust one of scipy's); ``f_scale`` the residual
    size (m, or in standard deviations when the data carry them) where a robust loss bends.
    ``limit``: an ``AccuracyLimit`` or a value in metres; the result then states the validation
    error (held-out poses, or the fitted ones without them) against it.
    """
    if loss not in LOSSES:
        raise InputError(f"loss must be one of {', '.join(LOSSES)}, got {loss!r}", where="loss")
    if initial_base not in ("model", "register"):
        raise InputError(f"initial_base must be 'model' or 'register', got {initial_base!r}", where="initial_base")
    _check_data(model, data, "data")
    if validation is not None:
        _check_data(model, validation, "validation")
    notes: list[str] = []
    nominal = model
    if initial_base == "register":
        model = register_base(model, data)
        notes.append("base pose started from a closed-form registration of the nominal robot on the data")
    orientation = data.has_orientation
    names = candidate_parameters(model, parameters, orientation=orientation, known=known)
    compliance = needs_compliance(model, names)
    p0 = parameter_vector(model)

    theory = _theory(model, _as_tuple(parameters), _as_tuple(known), orientation, tol)
    n_unique = len(np.unique(data.q, axis=0))
    if n_unique < data.n_poses:
        notes.append(f"{data.n_poses - n_unique} of {data.n_poses} poses repeat an earlier joint configuration "
                     "exactly: they average noise but add no information")
    prob0 = _Problem(model, data, names, compliance=compliance)
    rows_per_pose = 3 * (1 + int(orientation))
    needed = len(theory.identified)
    distinct_rows = prob0.n_rows * n_unique // data.n_poses
    if distinct_rows <= needed:
        raise DegenerateDataError(
            f"{data.n_poses} poses ({n_unique} distinct) give {distinct_rows} equations for {needed} identifiable "
            f"parameters; at least {needed // rows_per_pose + 1} distinct poses are needed, and several times "
            "that for a useful estimate")
    J0 = prob0.jacobian(p0)
    ident = analyse(J0, names, tol=tol)
    lost = [n for n in theory.identified if n not in ident.identified]
    if lost:
        msg = (f"the poses cannot separate {len(lost)} parameter(s) that this robot's structure allows to "
               f"identify: {', '.join(lost)}; they are held at their nominal values. Add poses that move "
               "the joints more widely (the design is rank-deficient)")
        notes.append(msg)
        warnings.warn(msg, IdentifiabilityWarning, stacklevel=2)
    free = ident.identified
    if not free:
        raise DegenerateDataError("no parameter is identifiable from these data")
    prob = prob0.over(free)          # the solve starts where the analysis evaluated the model
    if prob.n_rows <= len(free):
        raise DegenerateDataError(f"{prob.n_rows} equations for {len(free)} parameters")

    def full(x):
        p = p0.copy()
        p[prob.free_idx] = x
        return p

    x0 = p0[prob.free_idx]
    fun = lambda x: prob.residuals(full(x))  # noqa: E731
    jac = lambda x: prob.jacobian(full(x))  # noqa: E731
    kw = dict(jac=jac, x_scale="jac", xtol=SOLVER_TOL, ftol=SOLVER_TOL, gtol=SOLVER_TOL, max_nfev=max_nfev)
    if loss == "linear":
        sol = least_squares(fun, x0, method="lm", **kw)
    else:
        if f_scale is None:
            # scale from the residuals' median absolute deviation, re-estimated from the robust fit
            # until it settles: the first, non-robust fit spreads outliers over every residual
            sol = least_squares(fun, x0, method="lm", **kw)
            for _ in range(6):
                mad = 1.4826 * float(np.median(np.abs(sol.fun - np.median(sol.fun))))
                new_scale = max(3.0 * mad, 1e-12)
                if f_scale is not None and abs(new_scale - f_scale) < 0.05 * f_scale:
                    break
                f_scale = new_scale
                sol = least_squares(fun, sol.x, method="trf", loss=loss, f_scale=f_scale, **kw)
            unit = "standard deviations" if data.sigma is not None else "m"
            notes.append(f"robust loss {loss} bends at {f_scale:.3g} {unit} (3 robust standard deviations)")
        else:
            sol = least_squares(fun, x0, method="trf", loss=loss, f_scale=f_scale, **kw)
    p_hat = full(sol.x)
    r = sol.fun if loss == "linear" else prob.residuals(p_hat)
    # method "lm" returns the Jacobian at the solution; the robust losses return a reweighted one
    J = sol.jac if loss == "linear" else prob.jacobian(p_hat)
    dof = prob.n_rows - len(free)
    s2 = float(r @ r) / dof
    # columns mix metres, radians and rad/(N m): invert the normal matrix in unit-column scaling
    col = np.linalg.norm(J, axis=0)
    col[col == 0] = 1.0
    s, Vt = singular_values(J / col, vectors=True)
    if s[-1] <= s[0] * 1e-12:
        raise DegenerateDataError("the normal matrix is singular at the solution: the parameters "
                                  "identifiable at the nominal model are not at the estimate")
    cov = (Vt.T / s ** 2) @ Vt * s2 / np.outer(col, col)
    std = np.sqrt(np.diag(cov))
    corr = cov / np.outer(std, std)
    success = bool(sol.status > 0)
    if not success:
        warnings.warn(f"identification did not converge: {sol.message}", ConvergenceWarning, stacklevel=2)
    if data.sigma is not None and s2 > 9.0:
        msg = (f"residuals are {np.sqrt(s2):.1f} times the stated measurement standard deviations: the model or "
               "the data declaration (units, orientation convention, marker names) does not fit")
        notes.append(msg)
        warnings.warn(msg, MisfitWarning, stacklevel=2)
    # the solution's pass is cached from the solver's last Jacobian
    vectors = prob.errors(p_hat)
    if orientation:
        # a wrong orientation convention converges quietly: test the rotations, with or without stated sigmas
        Rp = prob.predicted(p_hat)[1][data.rot_mask]
        rot_res = Rotation.from_matrix(Rp @ np.swapaxes(data.rotations[data.rot_mask], -1, -2)).as_rotvec()
        for msg in misfit_notes(vectors[data.mask], rot_res,
                                characteristic_length_m=characteristic_length(data.positions[data.mask]),
                                sigma_rot_rad=None if data.sigma_rot is None else data.sigma_rot[data.rot_mask]):
            notes.append(msg)
            warnings.warn(msg, MisfitWarning, stacklevel=2)

    calibrated = model_from_vector(model, p_hat)
    # "nominal" is the start of the solve: the user's model, or with registration the registered
    # base (rotation corrections and their standard deviations are small angles about it)
    est = tuple(
        ParameterEstimate(n, unit_of(n), float(p0[prob.free_idx[k]]), float(p_hat[prob.free_idx[k]]), float(std[k]))
        for k, n in enumerate(free)
    )
    if initial_base == "register":
        notes.append("base parameters are reported against the registered base (nominal column), not the "
                     "model file's")
    if nominal is model:
        # the analysis evaluated it there (a compliance deflects nothing at p0 unless the model has one)
        before = _norms(prob0, p0)
    else:
        before = _norms(_Problem(nominal, data, free, compliance=nominal.has_compliance), parameter_vector(nominal))
    after = np.linalg.norm(vectors, axis=2)
    stats = {"fit_before": error_stats(before), "fit_after": error_stats(after),
             "validation_before": error_stats([]), "validation_after": error_stats([])}
    vb = va = None
    if validation is not None:
        vb = _norms(_Problem(nominal, validation, free, compliance=nominal.has_compliance), parameter_vector(nominal))
        va = _norms(_Problem(calibrated, validation, free, compliance=compliance), parameter_vector(calibrated))
        stats["validation_before"] = error_stats(vb)
        stats["validation_after"] = error_stats(va)
    limit_d = None
    if limit is not None:
        limit_d = judge_against_limit(limit, stats)
    from . import __version__

    prov = {"software": "robocal", "version": __version__, "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "data": {"source": data.source, "sha256": data.sha256, "n_poses": data.n_poses,
                     "labels": list(data.labels)}}
    if validation is not None:
        # the labels say which rows of the errors are which poses of the user's files
        prov["validation"] = {"source": validation.source, "sha256": validation.sha256,
                              "n_poses": validation.n_poses, "labels": list(validation.labels)}
    fam = (parameters,) if isinstance(parameters, str) else tuple(parameters)
    return CalibrationResult(
        nominal_model=nominal, calibrated_model=calibrated, parameters=est, covariance=cov, correlation=corr,
        identifiability=ident, stats=stats, errors_before=before, errors_after=after,
        validation_before=vb, validation_after=va, residual_vectors=vectors,
        measured_positions=np.where(data.mask[..., None], data.positions, np.nan), success=success,
        status=int(sol.status), message=str(sol.message), nfev=int(sol.nfev), sigma0=float(np.sqrt(s2)),
        families=fam, loss=loss, notes=tuple(notes), limit=limit_d, provenance=prov,
    )


def judge_against_limit(limit, stats: dict) -> dict:
    """The validation mean error against the limit of absolute accuracy (metres)."""
    value = float(getattr(limit, "limit", limit))
    key = "validation_after" if stats["validation_after"]["n"] else "fit_after"
    mean = stats[key]["mean"]
    ratio = mean / value
    return {"limit_m": value, "compared": key, "mean_error_m": mean, "ratio": ratio,
            # the limit is a mean-error bar; within 15 % of it counts as reaching it
            "reached": bool(ratio <= 1.15)}


@dataclass(frozen=True, eq=False)
class Comparison:
    """Geometric-only against geometric-and-compliance identification on the same data.

    ``f_statistic``/``p_value``: the nested-model F test on the fitted residuals (does adding the
    compliance parameters reduce the residual more than their number explains?). ``helped`` is
    True when p < ``alpha`` and, with held-out poses, the held-out RMS error fell too.
    """

    geometric: CalibrationResult
    combined: CalibrationResult
    f_statistic: float
    p_value: float
    helped: bool
    verdict: str

    @property
    def best(self) -> CalibrationResult:
        return self.combined if self.helped else self.geometric

    def to_dict(self) -> dict:
        def row(r):
            return {"fit": r.stats["fit_after"], "validation": r.stats["validation_after"],
                    "n_parameters": len(r.parameters)}
        return {"schema": "robocal.comparison/1", "geometric": row(self.geometric),
                "geometric_and_compliance": row(self.combined), "f_statistic": self.f_statistic,
                "p_value": self.p_value, "helped": self.helped, "verdict": self.verdict}


def compare(model: RobotModel, data: Measurements, *, validation: Measurements | None = None, alpha: float = 0.01,
            **kwargs) -> Comparison:
    """Run geometric and geometric-plus-compliance identifications on the same data (the paper's two).

    Keyword arguments other than ``parameters`` go to both ``calibrate`` calls.
    """
    from scipy.stats import f as f_dist

    kwargs.pop("parameters", None)
    geo = calibrate(model, data, parameters=("geometric",), validation=validation, **kwargs)
    both = calibrate(model, data, parameters=("geometric", "compliance"), validation=validation, **kwargs)
    n_rows = 3 * int(data.mask.sum()) + (3 * int(data.rot_mask.sum()) if data.has_orientation else 0)
    p1, p2 = len(geo.parameters), len(both.parameters)
    ssr1 = geo.sigma0 ** 2 * (n_rows - p1)
    ssr2 = both.sigma0 ** 2 * (n_rows - p2)
    dfn, dfd = max(p2 - p1, 1), n_rows - p2
    F = max((ssr1 - ssr2) / dfn, 0.0) / (ssr2 / dfd)
    p_value = float(f_dist.sf(F, dfn, dfd))
    significant = p_value < alpha
    if validation is not None:
        v1 = geo.stats["validation_after"]["rms"]
        v2 = both.stats["validation_after"]["rms"]
        helped = significant and v2 < v1
        detail = f"held-out RMS {v1 * 1e3:.4f} mm -> {v2 * 1e3:.4f} mm"
    else:
        helped = significant
        detail = f"fitted RMS {geo.stats['fit_after']['rms'] * 1e3:.4f} mm -> {both.stats['fit_after']['rms'] * 1e3:.4f} mm"
    verdict = (f"compliance helped: {detail}; F = {F:.3g}, p = {p_value:.2g}" if helped else
               f"compliance did not help: {detail}; F = {F:.3g}, p = {p_value:.2g} (threshold {alpha})")
    return Comparison(geometric=geo, combined=both, f_statistic=float(F), p_value=p_value, helped=bool(helped),
                      verdict=verdict)
