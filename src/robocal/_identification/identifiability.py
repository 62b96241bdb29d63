"""Which parameters the data can identify, and what absorbs the others (docs/method.md section 4).

The Jacobian stacked over every pose and measured row is scaled to unit column norms (lengths and
angles then weigh alike). Its singular values give the numerical rank, the condition number and the
observability indices. Which parameters to keep is decided by a rank-revealing QR whose pivots are
taken in the preference order (``candidate_parameters``): a parameter is kept when the part of its unit column
outside the span of the columns kept before it exceeds ``tol``; otherwise it is eliminated, and
least squares on the kept columns gives the linear combination that absorbs it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import cast

import numpy as np

from .._base.arguments import (
    FLAG,
    FRACTION,
    MAPPING,
    NAMES,
    POSITIVE,
    SEED,
    accepts,
    columns_of,
    is_a,
    names_in,
    optional,
    readings_of,
    shaped,
    whole,
)
from .._base.arrays import frozen_mapping
from .._base.linalg import reduced, solve_upper
from .._base.options import MAX_POSES
from .._base.threads import one_blas_thread
from .._model.configurations import design_measurements, random_configurations
from .._model.measurements import Measurements
from .._model.parameters import (
    FRAME_KINDS,
    candidate_parameters,
    needs_compliance,
    parameter_layout,
    parameter_names,
    parameter_vector,
)
from .._model.robot import RobotModel
from .contact_blocks import ContactRows
from .points import Points
from .problem import ROW_KINDS, Problem

DEFAULT_TOL = 1e-6
NO_EFFECT = 1e-10
# A parameter whose predicted standard deviation exceeds its bound is weakly identifiable: the rank
# tolerance keeps it, but the data cannot pin it down (docs/checks.md). Compliances are bounded by
# the deflection their uncertainty gives at the RMS moment of the poses.
# a joint counts as resting on a side of its lost motion where |side| exceeds this
ONE_SIDE = 0.5
WEAK_STD = {"length": 1e-3, "angle": np.deg2rad(0.1), "compliance": np.deg2rad(0.1), "ratio": 1e-3}


@dataclass(frozen=True)
class Absorption:
    """An eliminated parameter: ``d(name) = sum(coef * d(absorber))`` moves the tool the same way."""

    name: str
    reason: str
    absorbers: tuple[tuple[str, float], ...]
    residual: float


@dataclass(frozen=True)
class IdentifiabilityResult:
    """Outcome of the identifiability analysis.

    Attributes
    ----------
    candidates : tuple of str
        The parameters considered.
    identified : tuple of str
        Those identified; with ``eliminated`` they partition ``candidates``.
    eliminated : tuple of Absorption
        Those held at nominal, each with the combination of identified ones that absorbs it.
    tol : float
        The rank tolerance, relative to the largest singular value.
    rank : int
        The rank of the column-scaled Jacobian of the candidates.
    condition_number : float
        That of the column-scaled Jacobian of the identified parameters.
    singular_values : tuple of float
        Its singular values.
    observability : Mapping
        The indices O1..O5 of Borm-Menq and Nahvi-Hollerbach (O1 = geometric mean of singular
        values / sqrt(n_rows), O2 = min/max, O3 = min, O4 = min^2/max, O5 = 1 / sum(1/sigma));
        read-only.
    n_rows : int
        The rows (equations) of the Jacobian.
    column_scale : Mapping
        name -> the norm its Jacobian column was scaled by (the rows' units per unit of the
        parameter); read-only.
    """

    candidates: tuple[str, ...]
    identified: tuple[str, ...]
    eliminated: tuple[Absorption, ...]
    tol: float
    rank: int
    condition_number: float
    singular_values: tuple[float, ...]
    observability: Mapping[str, float]
    n_rows: int
    column_scale: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "singular_values", tuple(self.singular_values))
        object.__setattr__(self, "observability", frozen_mapping(self.observability))
        object.__setattr__(self, "column_scale", frozen_mapping(self.column_scale))

    def status(self, name: str) -> str:
        """'I' identified, 'E' eliminated, '-' not considered."""
        if name in self.identified:
            return "I"
        if any(a.name == name for a in self.eliminated):
            return "E"
        return "-"

    def absorption(self, name: str) -> Absorption | None:
        return next((a for a in self.eliminated if a.name == name), None)



@accepts(result=is_a(IdentifiabilityResult), frame_names=NAMES)
def status_table(result: IdentifiabilityResult, frame_names) -> list[dict]:
    """Per frame, the status (I, E or -) of each of its parameter kinds: the paper's table.

    Parameters
    ----------
    {result, frame_names}

    Returns
    -------
    list of dict
        One row per frame: each kind's status (identified, eliminated, fixed).
    """
    return [{"frame": f, **{k: result.status(f"{f}.{k}") for k in FRAME_KINDS}} for f in frame_names]


def singular_values(A: np.ndarray, vectors: bool = False):
    """Singular values of a tall matrix (and V^T with ``vectors``) through its R factor.

    A = Q R, so A and R share singular values and right singular vectors; the SVD then runs on
    a k x k matrix instead of the stacked rows (several times faster for thousands of rows).
    """
    A = reduced(A)
    if vectors:
        _, s, vt = np.linalg.svd(A, full_matrices=False)
        return s, vt
    return np.linalg.svd(A, compute_uv=False)


@accepts(J=shaped(None, None), names=columns_of("J"), quantities=optional(columns_of("J")), tol=FRACTION,
         max_terms=whole(1, 1000), n_rows=optional(whole(1)))
@one_blas_thread
def analyse(J: np.ndarray, names, *, quantities=None, tol: float = DEFAULT_TOL, max_terms: int = 6,
            n_rows: int | None = None) -> IdentifiabilityResult:
    """Identifiability of the columns of ``J`` (n_rows, n_candidates) named ``names``, in preference order.

    ``quantities`` (n_candidates,): what each parameter measures ("length", "angle", ...); a column
    has no effect when it is round-off next to the largest column of the same quantity. Default:
    all alike. ``J`` may be replaced by any matrix with the same Gram matrix (``reduced(J)``);
    ``n_rows`` then gives the rows it stands for (the observability index O1 divides by them).

    Parameters
    ----------
    {J}
    names : sequence of str
        Name of each column of ``J``.
    quantities : sequence of str, optional
        Quantity of each column (default: all alike).
    tol : float
        Rank tolerance relative to the largest singular value, in (0, 1).
    {max_terms, n_rows}

    Returns
    -------
    IdentifiabilityResult
        Rank, identified and eliminated parameters, absorbing combinations.
    """
    names = tuple(names)
    J = np.asarray(J, dtype=float)
    m = J.shape[0] if n_rows is None else int(n_rows)
    scale, nz = _column_scale(J, quantities, len(names))
    An = np.zeros_like(J)
    An[:, nz] = J[:, nz] / scale[nz]
    An = reduced(An)
    kept_idx, dep, Rk, basis = _preference_qr(An, nz, tol)
    eliminated = sorted([(k, "has no effect on the measurements") for k in np.nonzero(~nz)[0]]
                        + [(k, "is a combination of identified parameters") for k in dep])
    coefs = _absorbing_combinations(An, dep, basis, Rk)
    absorptions = []
    for k, reason in eliminated:
        if k not in coefs:
            absorptions.append(Absorption(names[k], reason, (), 0.0))
            continue
        c, resid = coefs[k]
        coef = c * scale[k] / scale[kept_idx]  # back to parameter units
        order = np.argsort(-np.abs(c))
        terms = tuple((names[kept_idx[i]], float(coef[i])) for i in order[:max_terms] if abs(c[i]) > 1e-6)
        absorptions.append(Absorption(names[k], reason, terms, resid))
    s = singular_values(Rk) if len(kept_idx) else np.zeros(0)
    obs, cond = _observability(s, m)
    all_s = singular_values(An[:, nz]) if nz.any() else np.zeros(0)
    rank = int(np.sum(all_s > tol * all_s[0])) if len(all_s) else 0
    return IdentifiabilityResult(
        candidates=names, identified=tuple(names[i] for i in kept_idx), eliminated=tuple(absorptions),
        tol=tol, rank=rank, condition_number=cond, singular_values=tuple(float(v) for v in s),
        observability=obs, n_rows=m, column_scale={n: float(v) for n, v in zip(names, scale)},
    )


def _column_scale(J: np.ndarray, quantities, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Column norms of ``J`` and which columns have an effect: a column is "no effect" when it is
    round-off next to the largest column of the same quantity (e.g. the torsion of a joint whose
    distal centre of mass lies on its axis)."""
    scale = np.linalg.norm(J, axis=0)
    units = np.array(["" for _ in range(n)] if quantities is None else list(quantities))
    nz = np.zeros(n, dtype=bool)
    for u in set(units):
        sel = units == u
        nz[sel] = scale[sel] > NO_EFFECT * scale[sel].max()
    return scale, nz


def _preference_qr(An: np.ndarray, nz: np.ndarray, tol: float):
    """Gram-Schmidt over the unit columns ``An`` in preference order: a column is kept when the part
    outside the span of those kept before it exceeds ``tol``. Returns the kept and the dependent
    indices, the kept columns' triangular factor ``Rk`` and orthonormal ``basis`` (An[:, kept] =
    basis @ Rk)."""
    n_rows, n_cols = An.shape
    basis = np.zeros((n_rows, n_cols))
    Rk = np.zeros((n_cols, n_cols))
    cols = np.nonzero(nz)[0]
    # the leading columns up to the first dependent one, from one QR of them all (its k-th diagonal
    # entry is the part of column k outside the span of those before it)
    first = 0
    if n_rows >= len(cols) > 0:
        Qa, Ra = qr_factors(An[:, cols])
        small = np.nonzero(np.abs(np.diag(Ra)) <= tol)[0]
        first = int(small[0]) if len(small) else len(cols)
        basis[:, :first], Rk[:first, :first] = Qa[:, :first], Ra[:first, :first]
    kept, dep = [int(k) for k in cols[:first]], []
    for k in cols[first:]:
        a = An[:, k]
        B = basis[:, :len(kept)]
        proj, nr = _project(B, a)
        if nr > tol:
            j = len(kept)
            Rk[:j, j] = proj
            Rk[j, j] = nr
            basis[:, j] = (a - B @ proj) / nr
            kept.append(int(k))
        else:
            dep.append(int(k))
    nk = len(kept)
    return np.array(kept, dtype=int), dep, Rk[:nk, :nk], basis[:, :nk]


def _absorbing_combinations(An: np.ndarray, dep: list, basis: np.ndarray, Rk: np.ndarray) -> dict:
    """Per dependent column, the least-squares combination of the kept columns (through their QR
    factors: c = Rk^-1 basis^T a) and the norm of what it leaves."""
    if not dep or not len(Rk):
        return {}
    D = An[:, dep]
    proj = basis.T @ D
    C = solve_upper(Rk, proj)
    R = np.linalg.norm(D - basis @ proj, axis=0)
    return {k: (C[:, i], float(R[i])) for i, k in enumerate(dep)}


def _observability(s: np.ndarray, m: int) -> tuple[dict, float]:
    """The observability indices O1..O5 of singular values ``s`` over ``m`` rows, and the condition number."""
    if len(s) and s[-1] > 0:
        obs = {"O1": float(np.exp(np.mean(np.log(s))) / np.sqrt(m)), "O2": float(s[-1] / s[0]),
               "O3": float(s[-1]), "O4": float(s[-1] ** 2 / s[0]), "O5": float(1.0 / np.sum(1.0 / s))}
        return obs, float(s[0] / s[-1])
    return {k: 0.0 for k in ("O1", "O2", "O3", "O4", "O5")}, float("inf")


def _data_rule(value, name: str, args) -> None:
    """Measurements, or joint readings (n_poses, n_joints) of the model, or None (random poses)."""
    if value is not None and not isinstance(value, Measurements):
        readings_of()(value, name, args)


@accepts(model=is_a(RobotModel), data=_data_rule, parameters=NAMES,
         known=NAMES, orientation=optional(FLAG), tol=FRACTION, n_random=whole(1, MAX_POSES), rng=SEED,
         markers=optional(NAMES))
@one_blas_thread
def identifiability(model: RobotModel, data: Measurements | np.ndarray | None = None, *,
                    parameters=("geometric",), known=(), orientation: bool | None = None,
                    tol: float = DEFAULT_TOL, n_random: int = 200, rng=0, markers=None) -> IdentifiabilityResult:
    """Which parameters are identifiable at the poses of ``data`` (Measurements or readings q).

    With ``data=None`` the analysis uses ``n_random`` configurations drawn within the joint limits:
    what theory allows for this robot, whatever the poses. ``markers``: the markers measured, when
    ``data`` does not say (default all).

    Parameters
    ----------
    {model}
    data : Measurements or array_like of shape (n_poses, n_joints), optional
        Measurements, or joint readings, the analysis is made at (None: ``n_random`` random
        configurations).
    {parameters, known}
    orientation : bool, optional
        Whether orientations are measured (None: from ``data``).
    tol : float
        Rank tolerance relative to the largest singular value, in (0, 1).
    {n_random, rng}
    markers : str or sequence of str, optional
        Markers measured (default: those of ``data``, or all).

    Returns
    -------
    IdentifiabilityResult
        What is identifiable, what is eliminated and what absorbs it.
    """
    if data is None:
        q = random_configurations(model, n_random, rng)
    elif isinstance(data, Measurements):
        q = data.q
    else:
        q = np.atleast_2d(np.asarray(data, dtype=float))
    meas = data if isinstance(data, Measurements) else design_measurements(model, q, bool(orientation), markers)
    if orientation is None:
        orientation = meas.has_orientation
    names = candidate_parameters(model, parameters, orientation=orientation, known=known)
    prob = Points(model, meas, names, compliance=needs_compliance(model, names))
    return analyse_problem(prob, names, tol=tol)


def analyse_problem(prob: Points, names, *, tol: float = DEFAULT_TOL) -> IdentifiabilityResult:
    """``analyse`` of a problem's Jacobian at its model's values (``backlash_reasons`` added)."""
    lay = parameter_layout(prob.model)
    p = parameter_vector(prob.model)
    res = analyse(prob.jacobian(p), names, tol=tol, quantities=[lay[n].quantity for n in names])
    return backlash_reasons(res, prob.backlash_sides(p))


def backlash_reasons(res: IdentifiabilityResult, sides: dict) -> IdentifiabilityResult:
    """``res`` with each eliminated backlash saying why when its joint rests on one side (or
    mid-gap) at every pose (``sides``: per backlash parameter, the sides its joint rests on)."""
    if not any(a.name in sides for a in res.eliminated):
        return res
    return replace(res, eliminated=tuple(replace(a, reason=a.reason + _one_side(sides[a.name])) if a.name in sides
                                         else a for a in res.eliminated))


def _one_side(s: np.ndarray) -> str:
    """Why a backlash whose joint never changes side cannot be told from the joint's offset."""
    if np.all(s > ONE_SIDE) or np.all(s < -ONE_SIDE):
        return (": its joint rests on the same side of its lost motion at every pose, so the joint offset absorbs "
                "it (visit both sides: reverse the approach, or poses where the gravity load changes sign)")
    if np.all(np.abs(s) < ONE_SIDE):
        return ": its joint rests mid-gap at every pose (no gravity load to push it to a side)"
    return ""


def theoretical_identifiability(model: RobotModel, parameters: tuple, known: tuple, orientation: bool,
                                tol: float, markers: tuple | None = None) -> IdentifiabilityResult:
    """What this robot's structure allows to identify with ``markers`` measured (default all), at
    random configurations (fixed seed). Made once per model object and arguments and kept with the
    model; every caller gets the same record, which nobody can change (its mappings are read-only)."""
    args = (parameters, known, orientation, tol, markers)
    return model.derived((theoretical_identifiability, args), lambda: identifiability(
        model, None, parameters=parameters, known=known, orientation=orientation, tol=tol, rng=0, markers=markers))


@one_blas_thread
def predicted_std(J: np.ndarray, sigma: float) -> np.ndarray:
    """Standard deviations of the parameters of the columns of ``J`` (n_rows, k) for residuals of
    standard deviation ``sigma`` (in the rows' units): sqrt(diag(sigma^2 (J^T J)^-1)), inverted in
    unit-column scaling."""
    col = np.linalg.norm(J, axis=0)
    col[col == 0] = 1.0
    s, vt = singular_values(J / col, vectors=True)
    inv = (vt.T / np.maximum(s, s[0] * 1e-15) ** 2) @ vt
    return sigma * np.sqrt(np.diag(inv)) / col


@accepts(J=shaped(None, None), names=columns_of("J"), quantities=columns_of("J"), sigma=POSITIVE,
         moments=optional(MAPPING), bounds=optional(MAPPING), floor=NAMES)
@one_blas_thread
def weakly_identifiable(J: np.ndarray, names, quantities, sigma: float, *, moments: dict | None = None,
                        bounds: dict | None = None, floor=()) -> list[tuple[str, str, float, float]]:
    """Parameters to eliminate because the design cannot pin them down.

    ``J`` (n_rows, k): the (weighted) Jacobian of the identified parameters ``names``, in preference
    order; ``sigma`` the expected residual standard deviation in the rows' units. A parameter's
    predicted standard deviation (for a compliance: times the RMS of its moments, a deflection) is
    compared with ``bounds[quantity]`` (default ``WEAK_STD``). As in the rank analysis, parameters
    are taken in preference order, each joining those kept before it: one that leaves itself or a
    kept one beyond its bound is eliminated (the later member of a near-dependent group goes, as
    the later member of an exactly dependent one does). Parameters named in ``floor`` join first
    whatever their spread, unjudged (an identification's a larger one adds to), the others judged
    beside them. Returns, in order, (name, the parameter beyond its bound with it: itself or an earlier
    one, that one's predicted effect, its bound).

    Parameters
    ----------
    {J}
    names : sequence of str
        Name of each column of ``J``.
    {quantities, sigma, moments, bounds}
    floor : str or sequence of str
        Parameters kept, unjudged.

    Returns
    -------
    list of (str, str, float, float)
        Each weak parameter with its quantity, predicted standard deviation and bound.
    """
    bounds = WEAK_STD if bounds is None else bounds
    floor = {floor} if isinstance(floor, str) else set(floor)
    names, quantities = list(names), list(quantities)
    if floor:                   # the floor first, the others in their order
        first = sorted(range(len(names)), key=lambda i: names[i] not in floor)
        J, names, quantities = np.asarray(J)[:, first], [names[i] for i in first], [quantities[i] for i in first]
    scale = np.array([np.sqrt(np.mean(moments[n] ** 2)) if q == "compliance" and moments else 1.0
                      for n, q in zip(names, quantities)])
    limit = np.array([np.inf if n in floor else bounds.get(q, np.inf) for n, q in zip(names, quantities)])
    norms = np.linalg.norm(J, axis=0)
    norms[norms == 0] = 1.0
    A = reduced(J / norms)
    k0, Q, Rinv, inv_diag = _kept_prefix(A, sigma, scale / (norms * limit))
    if k0 == len(names):
        return []
    # from the first trial that fails on: the kept columns' QR grows one column at a time (Q
    # orthonormal, the rows of R^-1 and their squared norms), each trial costing one projection
    kept, out = list(range(k0)), []
    for k in range(k0, len(names)):
        j = len(kept)
        proj, s = _project(Q[:, :j], A[:, k])
        # R' = [[R, proj], [0, s]]: its inverse gains the column [-R^-1 proj / s; 1 / s]
        with np.errstate(divide="ignore", invalid="ignore"):
            c = -(Rinv[:j, :j] @ proj) / s
            trial_diag = np.append(inv_diag[:j] + c ** 2, 1.0 / np.float64(s) ** 2)  # inf: in the span
        trial = kept + [k]
        effect = sigma * np.sqrt(np.nan_to_num(trial_diag, nan=np.inf)) / norms[trial] * scale[trial]
        ratio = np.where(np.isinf(limit[trial]), 0.0, effect / limit[trial])    # an unbounded quantity never fails
        worst = int(np.argmax(ratio))
        if ratio[worst] > 1.0 and names[k] not in floor:
            out.append((names[k], names[trial[worst]], float(effect[worst]), float(limit[trial[worst]])))
            continue
        Q[:, j] = (A[:, k] - Q[:, :j] @ proj) / s
        Rinv[:j, j], Rinv[j, j] = c, 1.0 / s
        inv_diag[:j + 1] = trial_diag
        kept.append(k)
    return out


def _kept_prefix(A: np.ndarray, sigma: float, factor: np.ndarray):
    """How many leading columns of ``A`` (unit columns, in preference order) pass the weak test
    together, with what the one-at-a-time test continues from: the orthonormal basis of those
    columns, the inverse of their R factor and the diagonal of their (A^T A)^-1.

    Every leading block at once: with A = Q R, the first k columns' (A^T A)^-1 is R_k^-1 R_k^-T
    and R_k^-1 is the leading block of R^-1, so its diagonal is a running sum of squares along the
    rows of R^-1. ``factor``: what turns sqrt of a diagonal entry times ``sigma`` into the ratio to
    the bound."""
    k = A.shape[1]
    Q = np.zeros((A.shape[0], k))
    Rinv = np.zeros((k, k))
    if A.shape[0] < k:
        return 0, Q, Rinv, np.zeros(k)
    Qa, Ra = qr_factors(A)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        inv = solve_upper(Ra, np.eye(k))           # NaN if singular: then every trial goes one at a time
        running = np.cumsum(inv ** 2, axis=1)                     # [i, m]: i's entry among the first m + 1
        ratio = sigma * np.sqrt(running) * factor[:, None]
    ratio = np.where(np.triu(np.ones((k, k), dtype=bool)) & (factor[:, None] > 0), np.nan_to_num(ratio, nan=np.inf),
                     0.0)
    failing = np.nonzero(ratio.max(axis=0) > 1.0)[0]
    k0 = int(failing[0]) if len(failing) else k
    Q[:, :k0] = Qa[:, :k0]
    Rinv[:k0, :k0] = inv[:k0, :k0]
    return k0, Q, Rinv, np.concatenate([running[:k0, k0 - 1] if k0 else np.zeros(0), np.zeros(k - k0)])


def qr_factors(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.linalg.qr(A)``; a square upper triangular ``A`` (a factor ``reduced`` made) is its own R
    with Q the identity, as LAPACK's Householder QR returns them for it (each reflection is the
    identity), without running it."""
    n, k = A.shape
    if n == k and not np.tril(A, -1).any():
        return np.eye(k), A
    Q, R = np.linalg.qr(A)
    return Q, R


def _project(B: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, float]:
    """The coordinates of ``a`` on the orthonormal columns ``B`` and the norm of what is left
    (projected twice: one classical Gram-Schmidt pass loses orthogonality for nearly dependent
    columns)."""
    r1 = a @ B
    res = a - B @ r1
    r2 = res @ B
    res -= B @ r2
    return r1 + r2, math.sqrt(res @ res)


@one_blas_thread
def eliminate(result: IdentifiabilityResult, J: np.ndarray, names, quantities, dropped: dict,
              *, max_terms: int = 6, n_rows: int | None = None) -> IdentifiabilityResult:
    """The analysis of ``J`` (n_rows, n_candidates) with the identified parameters in ``dropped``
    (name -> reason) eliminated too: each absorbed by the least-squares combination of the
    parameters kept. ``n_rows``: the rows ``J`` stands for when it is reduced (see ``analyse``)."""
    names = list(names)
    n_rows = J.shape[0] if n_rows is None else n_rows
    scale = np.linalg.norm(J, axis=0)
    scale[scale == 0] = 1.0
    J = reduced(J / scale) * scale   # the same Gram matrix in k rows, factored in unit-column scaling
    sub = [k for k, n in enumerate(names) if n not in dropped]
    kept = analyse(J[:, sub], [names[k] for k in sub], quantities=[quantities[k] for k in sub], tol=result.tol,
                   n_rows=n_rows)
    rank_of = {n: i for i, n in enumerate(names)}
    cols = [rank_of[n] for n in kept.identified]
    A = J[:, cols] / scale[cols]
    gone = [rank_of[name] for name in dropped]
    B = J[:, gone] / scale[gone]
    C = np.linalg.lstsq(A, B, rcond=None)[0]       # every dropped column from one factorization
    left = np.linalg.norm(A @ C - B, axis=0)
    extra = []
    for (name, reason), k, c, resid in zip(dropped.items(), gone, C.T, left.tolist()):
        coef = c * scale[k] / scale[cols]
        order = np.argsort(-np.abs(c))
        terms = tuple((kept.identified[i], float(coef[i])) for i in order[:max_terms] if abs(c[i]) > 1e-6)
        extra.append(Absorption(name, reason, terms, resid))
    # a reason the first analysis gave in more words (a one-sided backlash) is kept
    said = {a.name: a.reason for a in result.eliminated}
    again = tuple(replace(a, reason=said[a.name]) if said.get(a.name, "").startswith(a.reason) else a
                  for a in kept.eliminated)
    eliminated = tuple(sorted(again + tuple(extra), key=lambda a: rank_of[a.name]))
    return IdentifiabilityResult(candidates=tuple(names), identified=kept.identified, eliminated=eliminated,
                                 tol=kept.tol, rank=kept.rank, condition_number=kept.condition_number,
                                 singular_values=kept.singular_values, observability=kept.observability,
                                 n_rows=kept.n_rows, column_scale=result.column_scale)


# the part of a direction's effect the nuisance parameters leave (relative) below which it is unreachable
UNREACHABLE_TOL = 1e-6

_WHY = {
    "base": "a rigid motion of the whole robot carries every contact with it: the unknown socket points and "
            "planes follow, and nothing in these data is fixed in the measurement frame (a tracker, or a known "
            "plane, fixes it)",
    "scale": "socket and plane contacts fix shape, not size: the robot and every unknown point scaled alike "
             "give the same readings (a known distance between sockets, a ball bar or a tracker fixes it)",
}


@dataclass(frozen=True)
class Unreachable:
    """A direction of the robot's parameters no observation in the data can see, and why.
    ``components``: the parameters it moves (for the base, those of its six it cannot reach);
    ``residual``: the relative part of its effect left once the nuisance parameters take theirs."""

    name: str
    reason: str
    components: tuple[str, ...]
    residual: float


@dataclass(frozen=True, eq=False)
class ContactIdentifiability:
    """What each kind of observation reaches, for a problem with contacts. ``analysis`` holds
    nuisance and robot columns (nuisance first: what they absorb is eliminated from the robot);
    ``identified``/``eliminated`` are the robot's; ``contributions`` maps each kind present to the
    robot parameters its rows identify alone, ``lost_without`` to those the others cannot identify
    without it; ``together`` those only the kinds together identify; ``unreachable`` the directions
    no kind reaches."""

    analysis: IdentifiabilityResult
    identified: tuple[str, ...]
    eliminated: tuple[Absorption, ...]
    contributions: Mapping[str, tuple[str, ...]]
    together: tuple[str, ...]
    unreachable: tuple[Unreachable, ...]
    lost_without: Mapping[str, tuple[str, ...]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "contributions", frozen_mapping(self.contributions))
        object.__setattr__(self, "lost_without", frozen_mapping(self.lost_without))


@dataclass(frozen=True, eq=False)
class StackAnalysis:
    """The identifiability of a problem's robot parameters, whatever its blocks: ``result`` (the
    robot's view: nuisance absorbed, the analysis' figures over every column), ``full`` the analysis
    with the nuisance columns first, ``J`` a matrix with the Gram matrix of the robot columns once
    the nuisance columns take their part (what weak parameters are judged on), ``R`` the reduced
    Jacobian over nuisance then robot columns, and ``names`` the candidates."""

    result: IdentifiabilityResult
    full: IdentifiabilityResult
    J: np.ndarray
    R: np.ndarray
    names: tuple[str, ...]


def robot_part(R: np.ndarray, nn: int) -> np.ndarray:
    """The robot columns of ``R`` (after ``nn`` nuisance columns) less their projection on the span
    of the nuisance columns: the same Gram matrix as the robot's columns of the Jacobian once the
    nuisance takes its part."""
    Jr, N = R[:, nn:], R[:, :nn]
    if not nn:
        return Jr
    U, s, _ = np.linalg.svd(N / np.maximum(np.linalg.norm(N, axis=0), 1e-300), full_matrices=False)
    U = U[:, s > s[0] * 1e-10]
    return Jr - U @ (U.T @ Jr)


def analyse_stack(problem: Problem, names: tuple[str, ...], p: np.ndarray, *, tol: float) -> StackAnalysis:
    """The identifiability of the robot parameters ``names`` (the problem's free ones) at ``p``: one
    analysis over every block, nuisance columns first (what a socket point or a plane absorbs leaves
    the robot), structurally at readings where the model meets every contact exactly."""
    lay = parameter_layout(problem.model)
    at = problem.at_contact()
    R = at.reduced_jacobian(p)
    k, nn = len(names), problem.n_nuisance
    order = np.r_[np.arange(k, k + nn), np.arange(k)].astype(int)
    R = R[:, order]
    all_names = problem.nuisance_names + tuple(names)
    full = analyse(R, all_names, quantities=problem.nuisance_quantities + tuple(lay[n].quantity for n in names),
                   tol=tol, n_rows=problem.n_rows)
    result = full
    if nn:
        robot = set(names)
        identified = tuple(n for n in full.identified if n in robot)
        result = replace(full, candidates=tuple(names), identified=identified,
                         eliminated=tuple(a for a in full.eliminated if a.name in robot),
                         rank=full.rank - (len(full.identified) - len(identified)),
                         column_scale={n: v for n, v in full.column_scale.items() if n in robot})
    result = backlash_reasons(result, problem.backlash_sides(p))
    return StackAnalysis(result, full, robot_part(R, nn), R, tuple(names))


def _kind_rows(problem: Problem) -> dict:
    """Row masks per kind present, tracker positions and rotations together."""
    kinds = np.asarray(problem.row_kinds())
    names = np.array(["tracker" if k < 2 else ROW_KINDS[k] for k in kinds], dtype=object)
    return {str(n): names == n for n in dict.fromkeys(names)}


def kinds_reach(problem: Problem, analysis: StackAnalysis, p: np.ndarray) -> ContactIdentifiability:
    """What each kind of observation of ``problem`` identifies alone, what the others lose without
    it, what only they together identify, and what none reaches (``unreachable``)."""
    names, tol = analysis.names, analysis.full.tol
    lay = parameter_layout(problem.model)
    at = problem.at_contact()
    k, nn = len(names), problem.n_nuisance
    order = np.r_[np.arange(k, k + nn), np.arange(k)].astype(int)
    all_names = problem.nuisance_names + tuple(names)
    quantities = problem.nuisance_quantities + tuple(lay[n].quantity for n in names)
    robot = set(names)
    identified = analysis.result.identified
    groups = _kind_rows(at)
    contributions, lost = {}, {}
    if len(groups) == 1:
        contributions[next(iter(groups))] = identified
    else:
        J = at.jacobian(p)[:, order]
        for kind, rows in groups.items():
            alone = analyse(J[rows], all_names, quantities=quantities, tol=tol)
            contributions[kind] = tuple(n for n in alone.identified if n in robot)
            rest = set(analyse(J[~rows], all_names, quantities=quantities, tol=tol).identified)
            lost[kind] = tuple(n for n in identified if n not in rest)
    seen = set().union(*contributions.values()) if contributions else set()
    return ContactIdentifiability(
        analysis=analysis.full, identified=identified, eliminated=analysis.result.eliminated,
        contributions=contributions, together=tuple(n for n in identified if n not in seen),
        unreachable=unreachable(problem, p) if problem.contacts is not None else (), lost_without=lost)


def _unabsorbed(v: np.ndarray, N: np.ndarray, ref: float) -> float:
    """The norm of ``v`` outside the span of the columns of ``N``, relative to ``ref`` (the size of
    the direction's effect on the marker positions: a ball bar sees a rotation of the whole robot
    as round-off, not as zero)."""
    if ref == 0:
        return 0.0
    if N.shape[1] == 0:
        return float(np.linalg.norm(v) / ref)
    c = np.linalg.lstsq(N, v, rcond=None)[0]
    return float(np.linalg.norm(v - N @ c) / ref)


def unreachable(problem: Problem, p: np.ndarray) -> tuple[Unreachable, ...]:
    """The base's components and the scale whose effect the nuisance parameters absorb entirely."""
    lay = parameter_layout(problem.model)
    base = tuple(n for n in lay.names if lay[n].role == "base")
    lengths = tuple(n for n in lay.names if lay[n].quantity == "length" and lay[n].role != "base")
    met = problem.at_contact().over(base + lengths)
    J = met.jacobian(p)
    k = len(base) + len(lengths)
    N = J[:, k:]
    N = N / np.maximum(np.linalg.norm(N, axis=0), 1e-300)
    # the effect on the marker positions, in the rows' weights: what "absorbed" is relative to
    rows = cast(ContactRows, met.contacts)
    Jm = (rows.marker_jacobian(p[:met.n_robot], met.robot_idx) / rows.contacts.sigma[:, None, None]).reshape(-1, k)
    n_points = 0 if met.points is None else met.points.n_rows
    Jm = np.vstack([J[:n_points, :k], Jm])     # measured points as they are
    out = []
    hidden = [(n, _unabsorbed(J[:, i], N, float(np.linalg.norm(Jm[:, i])))) for i, n in enumerate(base)]
    gone = tuple(n for n, r in hidden if r < UNREACHABLE_TOL)
    if gone:
        out.append(Unreachable("base", _WHY["base"], gone, max(r for n, r in hidden if n in gone)))
    v = p[lay.indices(lengths)]
    scale = J[:, len(base):k] @ v
    r = _unabsorbed(scale, N, float(np.linalg.norm(Jm[:, len(base):] @ v)))
    if r < UNREACHABLE_TOL:
        out.append(Unreachable("scale", _WHY["scale"], lengths, r))
    return tuple(out)


@accepts(problem=is_a(Problem), names=names_in(lambda a: parameter_names(a["problem"].model)), tol=FRACTION,
         p=optional(shaped(None)))
def contact_identifiability(problem: Problem, names, *, tol: float = DEFAULT_TOL,
                            p: np.ndarray | None = None) -> ContactIdentifiability:
    """Which of the robot parameters ``names`` the union of the problem's observations identifies
    (at the full vector ``p``, default the start), what each kind identifies alone, and what none
    reaches.

    Parameters
    ----------
    {problem}
    names : sequence of str
        Candidate parameter names (the problem's free ones).
    tol : float
        Identifiability tolerance, in (0, 1).
    p : array_like, optional
        Parameter vector the analysis is made at (default: the problem's start).

    Returns
    -------
    ContactIdentifiability
        What the observations identify, and what they cannot reach.
    """
    p = problem.start_vector() if p is None else np.asarray(p, dtype=float)
    stack = analyse_stack(problem.over(tuple(names)), tuple(names), p, tol=tol)
    return kinds_reach(problem.over(tuple(names)), stack, p)
