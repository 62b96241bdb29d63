"""Checks on a calibration: each names what it looked at, says pass, warn or fail with the figures
behind it and, where one exists, the likely cause and the fix (docs/checks.md).

A result that fails a check cannot be mistaken for a good one: its verdict is "fail". Every
threshold is a named constant here, and docs/checks.md gives each one with its reason.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import numpy as np
from scipy.special import gammainc, gammainccinv, ndtr, stdtrit

from .._base.arguments import accepts, each_a, is_a, optional, shaped, whole
from .._base.arrays import column_extent, mean_and_error, point_spread, vector_norms
from .._base.errors import InputError, excerpt
from .._model.measurements import Measurements, Noise
from .._model.robot import RobotModel
from .holdout import USE_MARGIN, within_noise

STATUSES = ("pass", "warn", "fail")
# the limit of absolute accuracy counts as reached up to this many times it
LIMIT_REACHED_WITHIN = 1.15

# residual RMS per axis over the expected noise beyond which the fit leaves more than the noise
# explains (a warning: a robot's repeatability and unmodelled effects do; whether the model still
# places the robot better is the accuracy in use's question); below its inverse, the stated noise
# is too large
FIT_RATIO = 3.0
# a reading this share of its joint's range beyond a limit is still within it: a joint driven to its
# limit reads beyond it by its encoder's noise
READING_SLACK = 1e-3
# residuals below a third of what was stated warn only when as small a scatter has less than this
# chance under the stated figures (a chi-squared lower tail over the rows' degrees of freedom)
BELOW_STATED_P = 1e-3
# a measured point is an outlier beyond this many robust standard deviations (3D residual norm),
# raised on large campaigns so that clean Gaussian noise names a point in at most this share of them
OUTLIER_SIGMAS = 5.0
OUTLIER_FALSE_ALARM = 0.01
# beyond this share of outliers the data do not fit: setting them aside would hide a real misfit
OUTLIER_SHARE_MAX = 0.2
# only points beyond this factor times the outlier bar are set aside as blunders: between the bar and
# this, a point is as likely the tail of an effect the model leaves out (an elastic robot's residuals
# reach 5 to 9 robust standard deviations at its extreme poses) and is named, not set aside
GROSS_FACTOR = 2.0
# a blunder stands apart from the rest: beyond GROSS_FACTOR times the bar with no score between the bar
# and that, or this many times past the largest such score (an elastic arm's residuals form a
# continuous tail from the bar to twice it and beyond; a mistyped measurement lies far past them all)
BLUNDER_SEPARATION = 3.0
# points far beyond the bar are set aside when that lowers the cross-validated error of every point
# (those set aside predicted without them) by this many standard errors: 3 to 6 mm blunders among 48
# tracker points lower it by 5.7 to 18, an elastic arm's extreme poses by 3.2 at most
# (benchmarks/judgement_corpus.py)
REFIT_GAIN_SIGMAS = 4.0
# outliers at this many consecutive poses or more are a systematic error (a bump, a payload, a
# drift), not blunders: they are named, not set aside
OUTLIER_RUN = 4
# the robust scale of the outlier test does not fall below this share of the expected noise (a
# noise-free fit names nothing), so that a noise stated far too large cannot hide a blunder
OUTLIER_SCALE_FLOOR = 0.01
# an estimate within this many standard deviations of its nominal is not supported by the data
SIGNIFICANCE_SIGMAS = 2.0
# a compliance this many standard deviations below zero is non-physical, not noise (a stricter bar
# than significance: a robot has a dozen compliances, and each is a one-sided test)
NEGATIVE_COMPLIANCE_SIGMAS = 4.0
# a backlash (half a lost motion) this many standard deviations below zero is non-physical: the same
# one-sided bar as the compliances'
NEGATIVE_BACKLASH_SIGMAS = NEGATIVE_COMPLIANCE_SIGMAS
# pairs of identified parameters correlated beyond this are named
CORRELATION_MAX = 0.99
# ... and beyond this they are interchangeable at these poses (each estimate trades one for one
# against the other; only their combination is determined): a warning
CORRELATION_SINGULAR = 0.9999
# the accuracy in use: held-out errors this many times those of the fitted poses are overfitting
# (a warning), and beyond OVERFIT_GROSS times (and a millimetre more) they do not come from the
# fitted set-up at all (a failure)
OVERFIT_RATIO = 2.0
OVERFIT_GROSS = 10.0
OVERFIT_GROSS_EXCESS = 1e-3
# registering base and tool on the validation set names another set-up when it takes away at least
# this share of the held-out errors' excess over the fitted ones (and leaves them within OVERFIT_RATIO
# times those): a registration that trims a little off errors of other poses explains nothing
REGISTERED_SHARE = 0.5
# how the registered errors are figured (``AccuracyInUse.registered_after``), in the checks' words
REGISTERED = "allowing for the equations the registration takes up"
# a validation set whose errors one joint's constant offset explains (``AccuracyInUse.rehomed``), as
# a registration would have to: the joint homed otherwise between the campaigns
REHOMED_CAUSE = "joint {} homed otherwise between the fitted campaign and the validation set (or its encoder slipped)"
REHOMED_FIX = ("home joint {} and measure the validation poses again, or calibrate on poses of one homing; if the "
               "validation set's homing is the robot's from now on, calibrate on poses measured with it")
# worse in use than before beyond this many standard errors of the (paired) difference is a failure;
# within it, "no better" is a warning (a handful of held-out poses cannot tell the two apart). On n
# points the bar is Student's t quantile of the same probability, n - 1 degrees of freedom
# (``paired_sigmas``): 2.05 at 48 points, 4.5 at 3, 14 at 2 (two points' spread says little of it)
WORSE_SIGMAS = 2.0
# two markers of one frame at least this far apart in the model, calibrated to less than this share of
# their distance, are one point: no tool does that
MARKERS_APART_MIN = 5e-3
MARKERS_MERGED = 0.2
# a calibrated model whose mean error in use exceeds this share of the robot's reach places it nowhere
# a robot can be: real robots' calibrations leave a few per mille of it, the nominal models' errors a
# percent or two; beyond, the data do not come from this model (shuffled rows, another robot's file)
IN_USE_SHARE_MAX = 0.05
# no better in use while the fit leaves this many times what the instrument explains is a mistake,
# not the robot's own errors (a real robot's repeatability leaves tens of times a tracker's noise)
GROSS_MISFIT = 300.0
# coverage: a campaign whose points spread less than this share of the workspace's, or whose
# parameters' uncertainty grows more than EXTRAPOLATION_MAX times from the measured poses to the
# workspace, is validated only near its poses (a warning)
COVERAGE_SPREAD_MIN = 0.25
EXTRAPOLATION_MAX = 3.0
# ... and only when that uncertainty would raise the RMS error in use there by more than this factor
COVERAGE_GROWTH = 1.5
# a calibrated geometry that moves the tool where the robot is used (RMS) more than this many times
# both the nominal's error at the measured points and its own uncertainty there corrects what the
# campaign left free, not the robot (real campaigns: 1.6 to 2.3 times; joints that never moved: 12)
CORRECTION_GROWTH_MAX = 5.0
# the measured cloud against the robot's predicted one: a size ratio outside these bounds fails
CLOUD_RATIO = (0.67, 1.5)
# known unit mix-ups, as the factor between the measured and the predicted sizes
UNIT_FACTORS = {1000.0: "metres declared as millimetres (or the reverse)", 25.4: "inches declared as millimetres",
                10.0: "centimetres declared as millimetres"}
# half-width (relative) within which a size ratio names a unit factor
UNIT_FACTOR_TOL = 0.2
# readings whose largest magnitude is within pi degrees look like radians declared as degrees
RADIANS_AS_DEGREES = np.pi * np.pi / 180
# a mean limit error corresponds to this many per-axis standard deviations (the mean of a 3D
# Gaussian error's norm is 2 sqrt(2/pi) sigma)
MEAN_NORM_PER_SIGMA = 2.0 * np.sqrt(2.0 / np.pi)


# how far a parameter may move from its nominal before the change is implausible, per (family,
# quantity), SI; None for no bound (a base pose is often only guessed). Compliances are bounded by
# the largest deflection they give under the poses' gravity moments. A model file's 'tolerances'
# key overrides these.
DEFAULT_TOLERANCES = {
    ("frames", "length"): 10e-3, ("frames", "angle"): np.deg2rad(2.0),
    ("markers", "length"): 0.1, ("markers", "angle"): np.deg2rad(10.0),
    ("base", "length"): None, ("base", "angle"): None,
    # gear-driven arms deflect tenths of a degree under gravity, cable-driven arms and humanoids degrees
    ("compliance", "compliance"): np.deg2rad(5.0),
    # half a lost motion: gear trains are specified in arc minutes, worn ones reach a few tenths of
    # a degree; ball screws in hundredths of a millimetre
    ("backlash", "angle"): np.deg2rad(0.5), ("backlash", "length"): 0.5e-3,
    # a gear ratio off by a few percent (a wrong ratio entered), harmonics of eccentric gears in
    # hundredths to tenths of a degree
    ("transmission", "ratio"): 0.05, ("transmission", "angle"): np.deg2rad(0.5),
}


def tolerances(model: RobotModel) -> dict:
    """The plausibility tolerances for ``model``: the defaults, with the model file's own over them."""
    out = dict(DEFAULT_TOLERANCES)
    out.update({(family, quantity): value for family, quantity, value in model.tolerances})
    return out


@dataclass(frozen=True)
class Check:
    """One check of a result.

    Attributes
    ----------
    name : str
        What is checked ("solver convergence", "accuracy in use", ...; docs/checks.md).
    status : str
        "pass", "warn" or "fail".
    summary : str
        What it found, with its figures.
    cause : str
        The likely cause of a warning or failure ("" when it passed).
    fix : str
        What to do about it ("" when it passed).
    items : tuple of str
        What it names: parameters, pose labels and markers.
    """

    name: str
    status: str
    summary: str
    cause: str = ""
    fix: str = ""
    items: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "items", tuple(self.items))


@accepts(checks=each_a(Check))
def verdict(checks) -> str:
    """The worst status among ``checks`` ("pass" when there are none).

    Parameters
    ----------
    {checks}

    Returns
    -------
    str
        ``pass``, ``warn`` or ``fail``.
    """
    return max((c.status for c in checks), key=STATUSES.index, default="pass")


def _listed(items, n: int = 6) -> str:
    items = list(items)
    return ", ".join(items[:n]) + (f" and {len(items) - n} more" if len(items) > n else "")


# -- the inputs, before solving --------------------------------------------------------------------

READINGS = "joint readings within the limits"
READING_UNITS = "joint reading units"
CLOUD_SIZE = "measured points against the robot's size"
# the checks of the inputs that can fail: a mistake in the data, whatever model is fitted to them
BEFORE_SOLVING = (READINGS, READING_UNITS, CLOUD_SIZE)


def readings_check(model: RobotModel, q: np.ndarray, labels) -> Check:
    """Every joint reading ``q`` (n, n_joints) within the model's limits; readings beyond them named
    by pose (``labels``) and joint."""
    name = READINGS
    lo, hi = model.lower_limits, model.upper_limits
    span = np.abs(np.where(np.isfinite(hi - lo), hi - lo, 0.0))
    slack = np.maximum(1e-9 * np.maximum(1.0, span), READING_SLACK * span)
    out = (q < lo - slack) | (q > hi + slack)
    if not out.any():
        return Check(name, "pass", f"all {len(q)} poses within the joint limits")
    rows, cols = np.nonzero(out)
    angle = np.array([k == "angle" for k in model.reading_quantities])
    items = tuple(f"{labels[r]}: {model.joint_names[c]} = {_reading(q[r, c], angle[c])}" for r, c in
                  zip(rows, cols))
    cause = "a mistyped reading, a reading in another unit, or limits in the model that are too narrow"
    turns = whole_turns(model, q)
    if np.any(turns[out.any(axis=0)] != 0) and np.all(turns[out.any(axis=0)] != 0):
        cause = ("readings a whole number of turns off the joint's range: a turn count of the controller or an "
                 "unwrapped log (the kinematics are the same a turn away)")
    elif np.any(np.abs(q[:, angle][out[:, angle]]) > 2 * np.pi):
        cause = "readings of several turns: degrees declared as radians, or a mistyped reading"
    return Check(name, "fail", f"{out.sum()} reading(s) in {len(set(rows))} pose(s) beyond the joint limits: "
                 f"{_listed(items, 3)}", cause=cause,
                 fix="correct or remove those rows, declare the joint units, or widen the limits in the model file",
                 items=items)


# readings off by more turns than this are no turn count (degrees read as radians spread over dozens)
MOST_TURNS = 2


def whole_turns(model: RobotModel, q: np.ndarray) -> np.ndarray:
    """(n_joints,) per revolute joint the whole number of turns by which every one of its readings
    ``q`` beyond the limits lies off them (one count for them all, at most ``MOST_TURNS``, each reading
    within the limits once it is taken off); 0 where none is beyond, or where turns do not explain them."""
    lo, hi = model.lower_limits, model.upper_limits
    out = np.zeros(q.shape[1], dtype=int)
    for j, kind in enumerate(model.reading_quantities):
        if kind != "angle" or not (np.isfinite(lo[j]) and np.isfinite(hi[j])):
            continue
        v = q[:, j]
        beyond = (v < lo[j]) | (v > hi[j])
        if not beyond.any():
            continue
        k = np.where(v[beyond] > hi[j], np.ceil((v[beyond] - hi[j]) / (2 * np.pi)),
                     np.floor((v[beyond] - lo[j]) / (2 * np.pi)))
        back = v[beyond] - 2 * np.pi * k
        if 0 < abs(k[0]) <= MOST_TURNS and np.all(k == k[0]) and np.all((back >= lo[j]) & (back <= hi[j])):
            out[j] = int(k[0])
    return out


def _reading(v: float, angle: bool) -> str:
    return f"{np.degrees(v):.6g} deg" if angle else f"{v * 1e3:.6g} mm"


def reading_units_check(model: RobotModel, q: np.ndarray) -> Check:
    """A revolute reading that moves but stays within pi degrees, where its limits allow far more,
    looks like radians declared as degrees: a failure when every moving angle reading does so (no
    campaign keeps every joint within three degrees), a warning for some (a joint may barely move)."""
    name = READING_UNITS
    angle = np.array([k == "angle" for k in model.reading_quantities])
    span = model.upper_limits - model.lower_limits
    lo, hi = column_extent(q)
    moving = angle & (span > 4 * RADIANS_AS_DEGREES) & (hi - lo > 0)
    small = moving & (np.maximum(-lo, hi) <= RADIANS_AS_DEGREES)
    if not small.any():
        return Check(name, "pass", "no moving angle reading stays within 3.14 degrees of zero, as radians declared "
                     "as degrees would")
    joints = tuple(model.joint_names[j] for j in np.nonzero(small)[0])
    status = "fail" if small.sum() == moving.sum() else "warn"
    return Check(name, status, f"every reading of {_listed(joints)} stays within 3.14 degrees, where the limits "
                 "allow far more", cause="joint angles in radians declared as degrees, or a joint the poses "
                 "barely move", fix="declare the joint columns in rad (j1_rad, or --units ...-rad); or move "
                 "those joints over their range (robocal plan)", items=joints)


def cloud_size_check(model: RobotModel, data: Measurements, predicted: np.ndarray) -> Check:
    """The measured points' spread against the spread the nominal robot predicts at the same readings.

    ``predicted`` (n_poses, n_data_markers, 3): nominal marker positions, any base pose (the spread
    does not depend on it).
    """
    name = CLOUD_SIZE
    m = data.mask
    if m.all():       # every point measured: the points as they are, in the order the mask would pick them
        measured, nominal = point_spread(data.positions), point_spread(predicted)
    else:
        measured, nominal = point_spread(data.positions[m]), point_spread(predicted[m])
    if nominal <= 0 or measured <= 0:
        return Check(name, "pass", "too few distinct points to compare sizes")
    ratio = measured / nominal
    summary = f"the measured points spread {measured * 1e3:.4g} mm, the nominal robot's {nominal * 1e3:.4g} mm " \
              f"(ratio {ratio:.4g})"
    if CLOUD_RATIO[0] <= ratio <= CLOUD_RATIO[1]:
        return Check(name, "pass", summary)
    factor = max(ratio, 1.0 / ratio)
    known = next((why for f, why in UNIT_FACTORS.items() if abs(factor / f - 1.0) < UNIT_FACTOR_TOL), None)
    cause = known or "the measured points do not come from this robot's workspace: another robot's file, wrong " \
                     "marker columns, joint readings in another unit or order"
    return Check(name, "fail", summary, cause=cause,
                 fix="declare the units of the marker columns (x_mm or x_m) and check the file belongs to this model")


def markers_check(model: RobotModel, seen) -> Check:
    """Every marker of the model is observed (``seen``: the names); the parameters of the others are held."""
    name = "every marker measured"
    missing = tuple(n for n in model.marker_names if n not in seen)
    if not missing:
        return Check(name, "pass", f"all {len(model.marker_names)} marker(s) measured")
    return Check(name, "warn", f"marker(s) {_listed(missing)} never measured: their parameters are held at nominal",
                 cause="no columns (or only empty cells) for them in the measurement file",
                 fix="measure them, or remove them from the model if they are not used", items=missing)


# -- the solution --------------------------------------------------------------------------------

def markers_apart_check(nominal: RobotModel, calibrated: RobotModel, seen) -> Check:
    """Two markers of one frame the nominal model holds apart, calibrated to one point: no tool does
    that; two columns measured one reflector (a copied column, a marker labelled twice)."""
    name = "markers apart"
    bad = []
    for i, a in enumerate(nominal.markers):
        for b in nominal.markers[i + 1:]:
            if a.frame != b.frame or a.name not in seen or b.name not in seen:
                continue
            d0 = float(np.linalg.norm(np.subtract(a.position, b.position)))
            ca, cb = (calibrated.markers[calibrated.marker_names.index(m.name)] for m in (a, b))
            d1 = float(np.linalg.norm(np.subtract(ca.position, cb.position)))
            if d0 > MARKERS_APART_MIN and d1 < MARKERS_MERGED * d0:
                bad.append(f"{a.name} and {b.name}: {_mm(d0)} apart in the model, {_mm(d1)} calibrated")
    if not bad:
        return Check(name, "pass", "every pair of markers of one frame stays apart")
    return Check(name, "fail", f"{len(bad)} pair(s) of markers calibrated to one point: {_listed(bad, 3)}",
                 cause="two marker columns that measured one reflector (a copied column, a marker labelled twice)",
                 fix="check the marker columns of the measurement file", items=tuple(bad))


def convergence_check(success: bool, message: str, nfev: int, *, n_free: int, n_rows: int,
                      can_register: bool, max_nfev: int | None = None) -> Check:
    """The solver's own test. Not converged, the cause said is the caller's ``max_nfev`` when that
    stopped it; the model's size when the data leave fewer residual degrees of freedom than it has
    parameters (a fit that crawls along directions the data barely fix); else a far start, with a
    registered base to try when the fit did not start from one (``can_register``)."""
    name = "solver convergence"
    if success:
        return Check(name, "pass", f"converged after {nfev} evaluations")
    said = f"the solver stopped without converging after {nfev} evaluations: {message}"
    if max_nfev is not None and nfev >= max_nfev:
        return Check(name, "fail", said, cause=f"the {max_nfev} evaluations of the residuals max_nfev allows",
                     fix="allow more evaluations (max_nfev), or leave it out for the solver's default")
    if n_rows - n_free < n_free:
        return Check(name, "fail", said, cause=f"a model these data barely determine: {n_free} parameters on "
                     f"{n_rows} equations", fix="identify fewer parameters (--parameters, --known) or add poses "
                     "(robocal plan)")
    return Check(name, "fail", said,
                 cause="a start far from the truth (units, a rough base guess) or data the model cannot fit",
                 fix="check the other checks first" + ("; start from a registered base (--register-base)"
                                                       if can_register else ""))


def expected_noise(noise: Noise, limit_m: float | None) -> tuple[float, str]:
    """Per-axis scatter (m) a good fit leaves: the instrument's and, with a limit of absolute
    accuracy, the robot's own (its mean error converted to a per-axis standard deviation)."""
    if limit_m is None:
        return noise.position, f"the instrument's {noise.position * 1e3:.3g} mm ({noise.source})"
    robot = limit_m / MEAN_NORM_PER_SIGMA
    total = float(np.hypot(noise.position, robot))
    return total, f"{total * 1e3:.3g} mm (instrument {noise.position * 1e3:.3g} mm, robot {robot * 1e3:.3g} mm " \
                  "from the limit of absolute accuracy)"


def fit_check(residuals: np.ndarray, sigma: np.ndarray | None, noise: Noise, limit_m: float | None,
              outliers: np.ndarray, *, stated: bool = False, kind: str = "tracker", dof: float | None = None,
              explained: bool = False) -> Check:
    """The residuals (n, k) of one kind of observation against what the instrument (and the
    robot's limit) explain.

    Never a failure: a robot's repeatability and unmodelled effects leave residuals of any size, and
    whether the model still places the robot better is the accuracy in use's question (a mistake
    shows there, in the plausibility of the changes, or in the diagnosis). A warning beyond
    ``FIT_RATIO`` times the expected scatter, and below its inverse when the noise (or each
    observation's deviation) was stated: then the stated figures are too large, and so are the
    standard deviations. ``sigma`` (n,) stated standard deviations, or None (measured points: the
    instrument's noise); with a limit of absolute accuracy the robot's own scatter is added to them.
    ``outliers`` (n,) bool, left out. ``kind``: "tracker" for measured points ("fit against the
    instrument"), else a kind of contact ("fit of the socket contacts"). ``dof``: the residual
    degrees of freedom of these rows (default their number): a fit below the stated figures warns
    only when that many rows make it significant (``BELOW_STATED_P``), so that three known
    distances the fit nearly determines do not. ``explained``: the calibration places the robot
    better in use and its held-out errors scatter as its fitted ones do; residuals beyond the
    instrument's are then the robot's own (its repeatability, effects the model leaves out), what
    the accuracy in use already reports: a pass that says so.
    """
    name = "fit against the instrument" if kind == "tracker" else f"fit of the {kind} contacts"
    keep = ~outliers
    r = np.reshape(residuals, (len(outliers), -1))[keep]
    if not len(r):
        return Check(name, "warn", f"every {'measured point' if kind == 'tracker' else kind + ' contact'} is an "
                     "outlier")
    expected, said = expected_noise(noise, limit_m)
    robot = 0.0 if limit_m is None else limit_m / MEAN_NORM_PER_SIGMA
    per_axis = float(np.sqrt(np.mean(r ** 2)))
    scale = expected if sigma is None else np.hypot(sigma[keep], robot)
    ratio = float(np.sqrt(np.mean((r / np.reshape(scale, (-1, 1))) ** 2)))
    source = "the stated standard deviations" if sigma is not None else said
    summary = f"residuals {per_axis * 1e3:.4g} mm RMS per axis, {ratio:.3g} times {source}"
    if ratio > FIT_RATIO and explained:
        return Check(name, "pass", summary + ": the robot's own scatter beyond the instrument (repeatability, effects "
                     "the model leaves out); held-out errors show as much and the model places the robot better in "
                     "use (accuracy in use)")
    if ratio > FIT_RATIO:
        return Check(name, "warn", summary, cause="the robot's own repeatability and effects the model leaves out "
                     "(elasticity, gear errors, drift), or a mistake in the data: the accuracy in use and the "
                     "diagnosis tell which", fix="give the limit of absolute accuracy (--limit-mm) or the expected "
                     "noise (--noise-mm) to judge against; read the diagnosis")
    n_dof = float(r.size if dof is None else dof)
    below = n_dof > 0 and gammainc(n_dof / 2.0, n_dof * ratio ** 2 / 2.0) < BELOW_STATED_P
    if ratio < 1.0 / FIT_RATIO and (stated or sigma is not None) and below:
        return Check(name, "warn", summary + f": {1 / ratio:.3g} times below what was stated",
                     cause="a stated noise (or stated deviations) too large: the standard deviations are "
                     "overstated by as much", fix="state the instrument's real noise (--noise-mm) or deviations")
    return Check(name, "pass", summary)


@accepts(n_points=whole(0))
def outlier_bar(n_points: int) -> float:
    """The outlier threshold in robust standard deviations for ``n_points`` 3D residuals: 5, or more
    where n points of pure Gaussian noise would put one beyond 5 in more than ``OUTLIER_FALSE_ALARM``
    of campaigns (the norm over sigma is chi-distributed with 3 degrees of freedom).

    Parameters
    ----------
    n_points : int
        Measured points judged (>= 0).

    Returns
    -------
    float
        The threshold, robust standard deviations.

    >>> outlier_bar(48), round(outlier_bar(1_000_000), 2)
    (5.0, 6.33)
    """
    tail = OUTLIER_FALSE_ALARM / max(n_points, 1)
    return max(OUTLIER_SIGMAS, float(np.sqrt(2.0 * gammainccinv(1.5, tail))))


def outlier_scores(residuals: np.ndarray, sigma: np.ndarray | None, noise: Noise) -> np.ndarray:
    """(n,) each 3D residual's norm in robust standard deviations (see ``outlier_check``)."""
    if sigma is None:
        comps = residuals.ravel()
        robust = 1.4826 * float(np.median(np.abs(comps - np.median(comps)))) if comps.size else 0.0
        return vector_norms(residuals) / max(robust, OUTLIER_SCALE_FLOOR * noise.position)
    # in stated deviations: the robust spread of the standardised residuals sets the scale, never
    # below the stated deviation itself (a kind of one row has no spread of its own)
    u = residuals / np.reshape(sigma, (-1, 1))
    comps = u.ravel()
    robust = 1.4826 * float(np.median(np.abs(comps - np.median(comps)))) if comps.size else 0.0
    return vector_norms(u) / max(robust, 1.0)


def _deviations(value, name, args):
    """(n,) positive finite standard deviations, one per row of ``residuals``."""
    a = shaped(len(args["residuals"]))(value, name, args)
    if np.any(a <= 0):
        raise InputError("must be positive standard deviations", where=name)


def _row_labels(value, name, args):
    """A label per row of ``residuals`` (any sized, indexable sequence)."""
    if isinstance(value, (str, bytes)) or not (hasattr(value, "__len__") and hasattr(value, "__getitem__")):
        raise InputError(f"must be a sequence of labels, got {excerpt(value)}", where=name)
    if len(value) != len(args["residuals"]):
        raise InputError(f"must hold one label per row of residuals ({len(args['residuals'])}), got {len(value)}",
                         where=name)


@accepts(residuals=shaped(None, None), sigma=optional(_deviations), noise=is_a(Noise), labels=_row_labels)
def outlier_check(residuals: np.ndarray, sigma: np.ndarray | None, noise: Noise, labels) -> tuple[Check, np.ndarray]:
    """Measured points whose residual norm exceeds ``OUTLIER_SIGMAS`` robust standard deviations.

    ``residuals`` (n, k) of the observations named by ``labels`` (n,). The scale is the residuals'
    own robust spread (median absolute deviation), floored at ``OUTLIER_SCALE_FLOOR`` of the
    instrument's noise (a noise-free fit flags nothing, a noise stated far too large hides no
    blunder); with stated deviations, the robust spread of the residuals in those deviations, never
    below the stated deviation (a kind of a single row has no spread of its own, and is no outlier
    by construction).
    Returns the check and the (n,) outlier mask.

    Parameters
    ----------
    residuals : array_like, shape (n, k)
        Residual vector of each measured point (k = 3 for a point), m.
    sigma : array_like, shape (n,), optional
        Stated standard deviation of each point (None: none stated).
    noise : Noise
        The instrument's expected noise.
    labels : sequence of str
        A label per point, for messages.

    Returns
    -------
    (Check, numpy.ndarray)
        The check and the (n,) outlier mask.
    """
    name = "outliers"
    z = outlier_scores(residuals, sigma, noise)
    bar = outlier_bar(len(z))
    out = z > bar
    if not out.any():
        return Check(name, "pass", f"no measured point beyond {bar:.3g} robust standard deviations"), out
    order = np.argsort(-z[out])
    items = tuple(f"{labels[i]}: {np.linalg.norm(residuals[i]) * 1e3:.3g} mm, {z[i]:.3g} sd"
                  for i in np.nonzero(out)[0][order])
    return Check(name, "warn", f"{out.sum()} of {len(z)} measured point(s) beyond {bar:.3g} robust standard "
                 f"deviations: {_listed(items, 3)}", cause="a blunder: a mistyped or misassigned measurement, a "
                 "reading taken while the robot moved", fix="remove them, or let the calibration set them aside "
                 "(--on-outliers refit)", items=items), out


def held_out_outlier_check(errors: np.ndarray, sigma: np.ndarray | None, noise: Noise, labels) -> Check:
    """The held-out points (a validation set) whose errors after calibration (n, 3) stand out from
    the others' as blunders: beyond ``GROSS_FACTOR`` times ``outlier_check``'s bar, where the fit sets
    its own aside (held-out errors are predictions, whose spread varies over the workspace more than
    a fit's residuals: on simulated robots beyond the model 1 draw in 10 put a point just beyond the
    bar itself). The accuracy in use counts every held-out point, so a blunder there moves its
    figures; named with the mean error as measured without them."""
    name = "outliers among the held-out points"
    z = outlier_scores(errors, sigma, noise)
    bar = GROSS_FACTOR * outlier_bar(len(z))
    out = z > bar
    if not out.any():
        return Check(name, "pass", f"no held-out point beyond {bar:.3g} robust standard deviations of the others'")
    norms = vector_norms(errors)
    order = np.nonzero(out)[0][np.argsort(-z[out])]
    items = tuple(f"{labels[i]}: {norms[i] * 1e3:.3g} mm, {z[i]:.3g} sd" for i in order)
    return Check(name, "warn", f"{out.sum()} of {len(z)} held-out point(s) beyond {bar:.3g} robust standard "
                 f"deviations of the others': {_listed(items, 3)}; the mean held-out error as measured is "
                 f"{_mm(float(norms[~out].mean()))} without them, {_mm(float(norms.mean()))} with them",
                 cause="a blunder in the validation set: a mistyped or misassigned measurement, a reading taken while "
                 "the robot moved", fix="check those measurements; the accuracy in use counts them", items=items)


@dataclass(frozen=True)
class WorkspaceChange:
    """How far the calibrated geometry moves the measured markers from where the nominal one puts
    them, over ``n_poses`` configurations within the joint limits, once base and markers are
    registered (m): ``max_m`` and ``rms_m``; ``tolerance_m`` the bar (None for none) and ``reach_m`` the
    largest distance of the markers from the base over those configurations."""

    max_m: float
    rms_m: float
    tolerance_m: float | None
    reach_m: float
    n_poses: int


def paired_sigmas(n: int) -> float:
    """The bar, in standard errors of a paired difference over ``n`` points, that ``WORSE_SIGMAS``
    normal standard errors set: Student's t quantile of the same one-sided probability with n - 1
    degrees of freedom (infinite below two points).

    >>> round(paired_sigmas(1000), 3), round(paired_sigmas(3), 2)
    (2.003, 4.53)
    """
    return float(stdtrit(n - 1, ndtr(WORSE_SIGMAS))) if n > 1 else float("inf")


def better_in_use(in_use, reach_m: float | None = None) -> bool:
    """Whether the calibration places the robot better in use than the nominal model: its mean
    held-out error fell by more than ``WORSE_SIGMAS`` standard errors of the paired difference (not
    on one point, which has none), to what a robot's calibration can leave (below
    ``IN_USE_SHARE_MAX`` of its reach ``reach_m``). The normal bar, not ``paired_sigmas``: being
    better in use holds back failures of other checks, and a failure is what needs the stronger
    evidence."""
    if in_use is None or in_use.registration_only or not in_use.position_after.n:
        return False
    gain, se = in_use.improvement
    plausible = reach_m is None or in_use.position_after.mean <= IN_USE_SHARE_MAX * reach_m
    return gain > WORSE_SIGMAS * se and plausible


# the model file's key that sets each tolerance, for the messages
_TOLERANCE_KEY = {"compliance": "tolerances.compliance.deflection"}


def _tolerance_key(family: str, quantity: str) -> str:
    return _TOLERANCE_KEY.get(family, f"tolerances.{family}.{quantity}")


def plausibility_check(estimates, tolerances: dict, deflections: dict, *, workspace: WorkspaceChange | None = None,
                       unknown_rotations=(), better: bool = False) -> Check:
    """What the calibrated robot does, against what a real robot's errors can be.

    The geometry is judged by its effect over the configurations of use (``workspace``): equivalent
    parametrisations and interchangeable pairs move the tool nowhere, a model error of a hundred
    millimetres does; the bar is the frames' length tolerance plus their angle tolerance over the
    reach. Markers, compliances (by the largest deflection, ``deflections[name]``, rad) and backlash
    keep their family's tolerance on each parameter (``tolerances[(family, quantity)]``, SI, None for
    none); a marker's rotation declared unknown (``unknown_rotations``: marker names) has none.
    Beyond a bar is a failure only when the calibration does not place the robot better in use
    (``better``, ``better_in_use``): a robot may deflect more than a tolerance assumed (an elastic
    humanoid's joints by degrees), and a nominal model may be wrong by more than one; then it warns,
    naming the model file's key that sets the tolerance.
    """
    name = "plausible changes"
    bad = []
    rotation = False
    for e in estimates:
        family, quantity = e.family, e.quantity
        if family in ("frames", "base") or (family == "markers" and quantity == "angle" and
                                            e.name.split(".")[0] in set(unknown_rotations)):
            continue
        tol = tolerances.get((family, quantity))
        value = abs(deflections.get(e.name, 0.0)) if quantity == "compliance" else abs(e.change)
        if tol is not None and value > tol:
            what = "deflection " if quantity == "compliance" else ""
            rotation |= family == "markers" and quantity == "angle"
            bad.append(f"{e.name}: {what}{_size(value, quantity)} (tolerance {_size(tol, quantity)}, "
                       f"{_tolerance_key(family, quantity)})")
    moved = ""
    if workspace is not None:
        moved = (f"the calibrated geometry moves the tool up to {workspace.max_m * 1e3:.4g} mm "
                 f"({workspace.rms_m * 1e3:.4g} mm RMS) from the nominal's over {workspace.n_poses} configurations "
                 "of use, base and markers registered")
        if workspace.tolerance_m is not None and workspace.max_m > workspace.tolerance_m:
            bad.insert(0, moved + f", beyond {workspace.tolerance_m * 1e3:.4g} mm (tolerances.frames.length plus "
                       f"tolerances.frames.angle over a reach of {workspace.reach_m * 1e3:.4g} mm)")
            moved = ""
    if not bad:
        return Check(name, "pass", "every change within its family's tolerance" + (f"; {moved}" if moved else ""))
    hint = "; a marker whose orientation is not known: declare 'rotation: unknown' for it in the model file" \
        if rotation else ""
    if better:
        return Check(name, "warn", f"{len(bad)} change(s) beyond their tolerance, though the calibration places the "
                     f"robot better in use: {_listed(bad, 3)}",
                     cause="a robot that deflects or differs from its nominal model more than the tolerances assume, "
                           "or a nominal model that is wrong there", fix="check those parameters in the model file; "
                     "widen the tolerances named if the robot does this" + hint, items=tuple(bad))
    return Check(name, "fail", f"{len(bad)} implausible change(s): {_listed(bad, 3)}",
                 cause="the data pull the model somewhere no real robot is: a sign or unit error in the model file, "
                       "data in the wrong unit or order, or a parameter the data cannot pin down",
                 fix="check those parameters' nominal values and the data's units; the tolerances are in the model "
                     "file's 'tolerances' key" + hint, items=tuple(bad))


def _size(v: float, quantity: str) -> str:
    return f"{v * 1e3:.4g} mm" if quantity == "length" else f"{np.degrees(v):.4g} deg"


# families whose estimates may all be noise about zero: (said as, which estimates, why none shows, fix)
_UNSEEN_FAMILIES = (
    ("compliance", lambda e: e.quantity == "compliance", "the data show none to find (too little load, too few "
     "poses)", "calibrate the geometry alone (--compare tells which places the robot better), or measure with a "
     "payload and more poses"),
    ("backlash", lambda e: e.family == "backlash", "the data show no lost motion (too little, or sides not visited "
     "both ways)", "calibrate without the backlash family (--compare tells which is better), or approach the poses "
     "from both sides"),
    ("transmission term", lambda e: e.family == "transmission", "the data show no gear error (none to find, or a "
     "joint's range too short to tell its harmonics from its offset and scale)", "calibrate without the transmission "
     "family (--compare tells which is better), or spread the poses over each joint's range"),
)


def support_check(estimates) -> Check:
    """Estimates whose change is within ``SIGNIFICANCE_SIGMAS`` standard deviations of zero.

    They are named, not failed: a parameter already at its true value changes by noise. A
    compliance (backlash, transmission) family none of whose estimates the data support is said, with the
    advice to leave it out: what it does to the robot in use is the accuracy in use's question.
    """
    name = "estimates supported by the data"
    weak = [e for e in estimates if abs(e.change) < SIGNIFICANCE_SIGMAS * e.std]
    items = tuple(f"{e.name} ({e.change / e.std:+.2g} sd)" for e in weak)
    weak_names = {e.name for e in weak}          # names, not records compared field by field
    for label, belongs, why, fix in _UNSEEN_FAMILIES:
        family = [e for e in estimates if belongs(e)]
        if family and all(e.name in weak_names for e in family):
            return Check(name, "pass", f"no {label} differs from zero by {SIGNIFICANCE_SIGMAS:g} standard deviations: "
                         f"{why}; the accuracy in use judges the model with it", fix=fix, items=items)
    if not weak:
        return Check(name, "pass", f"every change beyond {SIGNIFICANCE_SIGMAS:g} standard deviations")
    return Check(name, "pass", f"{len(weak)} change(s) within {SIGNIFICANCE_SIGMAS:g} standard deviations of zero, "
                 "kept at their estimates (the data do not distinguish them from nominal)", items=items)


def compliance_sign_check(estimates) -> Check:
    """Compliances are stiffnesses' inverses: one significantly negative is non-physical. Negative
    estimates within their uncertainty are named (noise around zero), not failed."""
    name = "physical compliances"
    neg = [e for e in estimates if e.quantity == "compliance" and e.estimate < 0]
    if not neg:
        return Check(name, "pass", "no negative compliance")
    significant = [e for e in neg if -e.estimate > NEGATIVE_COMPLIANCE_SIGMAS * e.std]
    if significant:
        items = tuple(f"{e.name} ({e.estimate / e.std:+.2g} sd)" for e in significant)
        return Check(name, "warn", f"{len(significant)} compliance(s) significantly negative: {_listed(items, 3)}",
                     cause="masses or centres of mass on the wrong side, gravity in the wrong direction, or another "
                           "effect the compliance takes up (the accuracy in use says whether it helps)",
                     fix="check the masses, centres of mass and gravity in the model file; --nonnegative-compliance "
                         "keeps them at zero or above", items=items)
    items = tuple(f"{e.name} ({e.estimate / e.std:+.2g} sd)" for e in neg)
    return Check(name, "pass", f"{len(neg)} compliance(s) negative within their uncertainty (noise about zero): "
                 f"{_listed(items, 3)}; --nonnegative-compliance keeps them at zero or above", items=items)


def backlash_sign_check(estimates) -> Check:
    """A backlash is half a lost motion: one significantly negative is non-physical (the side
    model or the load's sign is wrong). Negative estimates within their uncertainty are named."""
    name = "physical backlash"
    neg = [e for e in estimates if e.family == "backlash" and e.estimate < 0]
    if not neg:
        return Check(name, "pass", "no negative backlash")
    items = tuple(f"{e.name} ({e.estimate / e.std:+.2g} sd)" for e in neg)
    significant = [i for e, i in zip(neg, items) if -e.estimate > NEGATIVE_BACKLASH_SIGMAS * e.std]
    if significant:
        return Check(name, "warn", f"{len(significant)} backlash(es) significantly negative: {_listed(significant, 3)}",
                     cause="the joints rest on the other side than the model says: gravity in the wrong direction, "
                           "masses on the wrong side, or approach directions reversed",
                     fix="check gravity and the masses in the model file, the backlash side model and the approach "
                         "columns", items=tuple(significant))
    return Check(name, "pass", f"{len(neg)} backlash(es) negative within their uncertainty (noise about zero): "
                 f"{_listed(items, 3)}", items=items)


def interchangeable_pairs(names, corr: np.ndarray, loose=None) -> tuple[str, ...]:
    """Pairs of identified parameters correlated beyond ``CORRELATION_SINGULAR`` of which one at
    least is not pinned down (``loose``: the names whose standard deviation exceeds the bound of
    practical identifiability; None: every name), as text. Two well-determined parameters may be
    that correlated (a joint's two flexions under gravity): only their estimates' spread matters."""
    iu = np.triu_indices(len(names), 1)
    high = np.abs(corr[iu]) > CORRELATION_SINGULAR
    loose = set(names) if loose is None else set(loose)
    return tuple(f"{names[i]} ~ {names[j]} (r = {corr[i, j]:+.4f})" for i, j in zip(iu[0][high], iu[1][high])
                 if names[i] in loose or names[j] in loose)


def correlation_check(names, corr: np.ndarray, loose=None) -> Check:
    """Pairs of identified parameters correlated beyond ``CORRELATION_MAX``, named. Their standard
    deviations already include the correlation (and practical identifiability bounds them), so the
    pairs are information for the engineer; beyond ``CORRELATION_SINGULAR`` the two are
    interchangeable at these poses, which is a warning when one of them is not pinned down
    (``loose``, see ``interchangeable_pairs``)."""
    name = "correlated parameters"
    iu = np.triu_indices(len(names), 1)
    high = np.abs(corr[iu]) > CORRELATION_MAX
    if not high.any():
        return Check(name, "pass", f"no pair of identified parameters correlated beyond |r| = {CORRELATION_MAX:g}")
    pairs = tuple(f"{names[i]} ~ {names[j]} (r = {corr[i, j]:+.4f})" for i, j in zip(iu[0][high], iu[1][high]))
    singular = interchangeable_pairs(names, corr, loose)
    if singular:
        return Check(name, "warn", f"{len(singular)} pair(s) interchangeable at these poses (|r| > "
                     f"{CORRELATION_SINGULAR:g}): {_listed(singular, 3)}; only their combination is determined",
                     cause="poses that do not separate the two (a joint barely moved, a tool point near an axis)",
                     fix="add poses that move the joints more widely (robocal plan), or hold one of each pair "
                         "(--known NAME)", items=pairs)
    return Check(name, "pass", f"{len(pairs)} pair(s) correlated beyond |r| = {CORRELATION_MAX:g}, each estimate "
                 f"trading against the other (their standard deviations include it): {_listed(pairs, 3)}",
                 fix="to separate them, add poses that move the joints more widely (robocal plan)", items=pairs)


def identifiability_check(lost, weak, *, weak_kept: bool = False, interchangeable=(),
                          kept_in_use: bool = False, size_unreached: bool = False) -> Check:
    """Parameters the structure allows but the poses cannot separate (``lost``: a warning), and those
    they cannot pin down (``weak``: (name, predicted std text) pairs). Weak ones are held at nominal
    and named, which is the right handling (a pass), unless they were kept (``weak_kept``: a warning).
    Identified pairs that are interchangeable (``interchangeable``) are a warning too: the analysis
    cannot say every parameter is pinned down beside them. ``kept_in_use``: the weak ones were kept
    because the accuracy in use is better with them (a pass). ``size_unreached``: contacts that fix
    the robot's shape and not its size (a warning: the accuracy in use, of contacts alike, cannot see
    a size error)."""
    name = "identifiability at these poses"
    if size_unreached:      # said first, beside what the poses say of the other parameters
        rest = identifiability_check(lost, weak, weak_kept=weak_kept, interchangeable=interchangeable,
                                     kept_in_use=kept_in_use)
        return Check(name, "warn", "the robot's size is out of reach of these contacts: its lengths are fitted "
                     "relative to one another at the nominal model's scale, and the contacts' accuracy in use "
                     "cannot show an error of size" + ("" if rest.status == "pass" and not rest.items else
                                                      f"; {rest.summary}"),
                     cause="no known length among the observations",
                     fix="state a known distance between two sockets ('# distance:' or the manifest's spacings), "
                         "or add a ball bar, a known plane or tracker points", items=rest.items)
    items = tuple(lost) + tuple(f"{n} (predicted std {s})" for n, s in weak) + tuple(interchangeable)
    if interchangeable:
        return Check(name, "warn", f"kept but interchangeable at these poses: {_listed(interchangeable, 3)}",
                     cause="poses that do not separate the two", fix="add poses over the whole workspace (robocal "
                     "plan), or hold one of each pair at its nominal value (--known NAME)", items=items)
    if not items:
        return Check(name, "pass", "every parameter the robot's structure allows is identified")
    summary = []
    if lost:
        summary.append(f"the poses cannot separate {_listed(lost)}; they are held at their nominal values")
    if weak:
        summary.append(f"weakly identifiable (predicted standard deviation beyond its bound): "
                       f"{_listed(n for n, _ in weak)}" + (
                           "; kept, as the accuracy in use (cross-validated) is better with them" if kept_in_use else
                           "; kept, their estimates are unreliable" if weak_kept else "; held at their nominal values"))
    status = "warn" if lost or (weak_kept and not kept_in_use) else "pass"
    return Check(name, status, "; ".join(summary),
                 cause="poses that do not move the joints widely enough, or a tool point nearly on an axis",
                 fix="add poses over the whole workspace (robocal plan); or accept the nominal values", items=items)


# -- in use ---------------------------------------------------------------------------------------

def _mm(v: float) -> str:
    return f"{v * 1e3:.4g} mm"


def in_use_check(in_use, misfit: float | None = None, reach_m: float | None = None, noise_cost: float = 0.0
                 ) -> Check:
    """Will the model place the robot better than the nominal one, and how well (``AccuracyInUse``)?

    A failure when the mean error in use is worse after calibration than before (beyond
    ``WORSE_SIGMAS`` standard errors of the paired difference, and by more than ``noise_cost``, m:
    what the stated noise alone costs the estimates at positions they were not fitted on, a
    calibration with nothing to correct being that much worse; within it, a warning), when the
    held-out errors are beyond anything the fit explains (``OVERFIT_GROSS`` times the fitted poses'
    and a millimetre more: another set-up, or a mistake), or when it is no better than before while
    the fit leaves ``GROSS_MISFIT`` times what the instrument explains (``misfit``: a mistake, not
    the robot). A warning when it is no better than before within a standard error, when its worst
    error grew, or when held-out errors are ``OVERFIT_RATIO`` times those of the fitted poses:
    overfitting when the campaign's own cross-validation shows it too, another set-up when
    registering base and tool on the validation set explains it, other poses otherwise. A failure
    too when the mean error in use after calibration exceeds ``IN_USE_SHARE_MAX`` of the robot's
    reach ``reach_m``: no robot is placed that far off by a model of it. Otherwise a pass, with the
    figures."""
    name = "accuracy in use"
    b, a, fit = in_use.position_before, in_use.position_after, in_use.fit_after
    how = in_use.method + (f", {in_use.grouping}" if in_use.method == "cross-validation" else "")
    if not a.n:
        return Check(name, "warn", "no held-out position to judge the calibration in use")
    noise, spread = within_noise(a.rms, in_use.noise), f" (95 % within {_mm(a.p95)}, max {_mm(a.max)})"
    if in_use.registration_only:
        return Check(name, "pass", f"a registration of base and markers only: mean error "
                     f"{noise or _mm(a.mean) + spread} on {a.n} held-out point(s) ({how}), the robot's kinematics "
                     "unchanged")
    summary = (f"mean error {_mm(b.mean)} before, " + (f"{noise} after" if noise else f"{_mm(a.mean)} after{spread}")
               + f" on {a.n} held-out point(s) ({how})"
               + (f"; {within_noise(fit.rms, in_use.noise) or _mm(fit.mean)} on the fitted ones" if fit.n else
                  "; no measured point fitted"))
    seen = in_use.measured_after
    if seen is not None and seen.n and seen.mean != a.mean:     # the robot's figure beside what was measured
        summary += f"; held out as measured (the instrument's noise in) {_mm(seen.mean)}"
    for judge in (_beyond_the_fit, _another_set_up, partial(_no_better, noise_cost=noise_cost), _held_out_larger,
                  _worst_grew):
        check = judge(in_use, summary, misfit, reach_m)
        if check is not None:
            return check
    return Check(name, "pass", summary)


def _beyond_the_fit(in_use, summary: str, misfit, reach_m) -> Check | None:
    """Held-out errors no model of this robot explains: another set-up (when registering base and
    tool on the validation set explains them), else data that do not belong to the model."""
    a, seen, seen_fit = in_use.position_after, in_use.measured_after or in_use.position_after, \
        in_use.measured_fit or in_use.fit_after
    far = seen_fit.n and seen.mean > OVERFIT_GROSS * seen_fit.mean and seen.mean > seen_fit.mean + OVERFIT_GROSS_EXCESS
    off_reach = reach_m is not None and a.mean > IN_USE_SHARE_MAX * reach_m
    moved, homed = _registration_explains(in_use), _rehoming_explains(in_use)
    if homed is not None and (far or off_reach):
        return Check("accuracy in use", "fail", summary + ": the held-out errors are beyond anything the fit "
                     f"explains; {_rehomed_words(homed)}", cause=REHOMED_CAUSE.format(homed.joint),
                     fix=REHOMED_FIX.format(homed.joint))
    if moved is not None and (far or off_reach):
        return Check("accuracy in use", "fail", summary + ": the held-out errors are beyond anything the fit "
                     f"explains; with base and tool registered on the validation set, {_mm(moved.mean)} ({REGISTERED})",
                     cause="held-out poses of another set-up (the instrument or the base moved, another tool)",
                     fix="register base and tool on the validation set (--register-validation)")
    if off_reach:
        return Check("accuracy in use", "fail", summary + f": {100 * a.mean / reach_m:.3g} % of the robot's reach "
                     f"({_mm(reach_m)}), where no model of it places it", cause="data that do not come from this "
                     "model: rows shuffled against the readings, another robot's file, joints in another order",
                     fix="read the diagnosis; check the files")
    if far:
        return Check("accuracy in use", "fail", summary + ": the held-out errors are beyond anything the fit explains",
                     cause="held-out poses of another set-up (base or tool moved) or another robot, or a mistake in "
                           "the data", fix="for a campaign of another set-up, register base and tool on it "
                           "(--register-validation); else check the files")
    return None


def _no_better(in_use, summary: str, misfit, reach_m, noise_cost: float = 0.0) -> Check | None:
    """Worse than before by more than the stated noise costs the estimates (a failure), or no better
    within a standard error: a failure when the fit leaves ``GROSS_MISFIT`` times what the
    instrument explains, else a warning."""
    gain, se = in_use.improvement
    if not np.isfinite(se):
        return Check("accuracy in use", "warn", summary + ": one held-out point has no standard error, so neither "
                     "better nor worse than before is established", cause="too few held-out points to judge by",
                     fix="give more validation poses, spread over the workspace (robocal plan)")
    worse = gain < -paired_sigmas(in_use.errors_after.size) * se
    if worse and -gain > noise_cost:
        return Check("accuracy in use", "fail", summary + ": worse than before calibration",
                     cause="a model that fits the fitted poses but not others: too many parameters for the poses, "
                           "or data that do not belong together", fix="read the other checks and the diagnosis; "
                           "measure more poses over the workspace (robocal plan)")
    if gain > se:
        return None
    if misfit is not None and misfit > GROSS_MISFIT:
        return Check("accuracy in use", "fail", summary + f": no better than before, while the fit leaves "
                     f"{misfit:.3g} times what the instrument explains", cause="data that do not come from this "
                     "model: a mistake in the data or the model file, not the robot's own errors",
                     fix="read the diagnosis; check joint order, signs, units and the marker columns")
    if worse:
        return Check("accuracy in use", "warn", summary + f": worse than before by {_mm(-gain)}, no more than the "
                     f"stated noise costs the estimates at positions they were not fitted on ({_mm(noise_cost)}): "
                     "nothing these data show needs correcting", cause="a robot as its nominal model, or errors "
                     "below what the campaign resolves", fix="keep the nominal model; or measure more poses")
    return Check("accuracy in use", "warn", summary + f": no better than before within its standard error "
                 f"({_mm(se)})", cause="errors the model cannot take up (repeatability, unmodelled effects)",
                 fix="calibrate with the compliance or backlash families if the robot has them, or keep the "
                     "nominal model")


def _worst_grew(in_use, summary: str, misfit, reach_m) -> Check | None:
    b, a = in_use.position_before, in_use.position_after
    if b.max is not None and a.max > b.max:
        return Check("accuracy in use", "warn", summary + f": the worst error grew ({_mm(b.max)} before)",
                     cause="a few poses the model places worse than the nominal one",
                     fix="look at the held-out poses with the largest errors in the report")
    return None


def spacing_check(in_use) -> list[Check]:
    """The known distances between the sockets of placements the fit did not see, before and after:
    the scale of the robot in use. Worse after calibration (beyond ``WORSE_SIGMAS`` standard errors
    of the paired difference) fails, as a worse accuracy in use does; none held out, no check."""
    before, after = in_use.spacing_before, in_use.spacing_after
    if before is None or after is None or not len(after):
        return []
    name = "spacing in use"
    d = before - after
    gain, se = mean_and_error(d)
    summary = (f"held-out spacing error (calibrated minus known, absolute) mean {_mm(float(before.mean()))} before, "
               f"{_mm(float(after.mean()))} after, max {_mm(float(after.max()))}, over {len(after)} held-out "
               "placement and pair(s)")
    if gain < -paired_sigmas(d.size) * se and after.mean() > before.mean():
        return [Check(name, "fail", summary + ": worse than before calibration", cause="a robot scaled to meet "
                      "something else than the plate: a stated spacing that is wrong, spacing rows set aside, or "
                      "joint readings in another unit", fix="check the stated distances and their deviations; read "
                      "the diagnosis")]
    return [Check(name, "pass", summary)]


def _registration_explains(in_use):
    """The calibrated model's errors on the validation set once base and tool are registered on it
    (allowing for the equations that takes up), when they are within ``OVERFIT_RATIO`` times the
    fitted poses' and the registration took ``REGISTERED_SHARE`` of the held-out errors' excess over
    those away (another set-up), else None."""
    fit, reg = in_use.measured_fit or in_use.fit_after, in_use.registered_after
    seen = in_use.measured_after or in_use.position_after
    if reg is not None and reg.n and fit.n and reg.mean <= OVERFIT_RATIO * fit.mean and \
            seen.mean - reg.mean >= REGISTERED_SHARE * (seen.mean - fit.mean):
        return reg
    return None


def _rehoming_explains(in_use):
    """The joint offset on the validation set (``AccuracyInUse.rehomed``) when it explains its errors
    as a registration would have to (``_registration_explains``'s bars) and the registration alone
    does not (the simpler explanation first: a joint more also takes up some of the robot's own
    errors); else None."""
    fit, homed = in_use.measured_fit or in_use.fit_after, in_use.rehomed
    seen = in_use.measured_after or in_use.position_after
    if homed is None or not (homed.errors.n and fit.n) or homed.errors.mean > OVERFIT_RATIO * fit.mean or \
            seen.mean - homed.errors.mean < REGISTERED_SHARE * (seen.mean - fit.mean):
        return None
    return None if _registration_explains(in_use) is not None else homed


def _rehomed_words(homed) -> str:
    off = f"{np.degrees(homed.offset):+.4g} deg" if homed.quantity == "angle" else f"{homed.offset * 1e3:+.4g} mm"
    return (f"with joint {homed.joint}'s readings {off} off on the validation set (base and tool registered too), "
            f"{_mm(homed.errors.mean)} ({REGISTERED}, and the offset)")


def _held_out_excess(in_use) -> float | None:
    """How many times the fitted poses' error the held-out one is (as measured), when it is
    ``OVERFIT_RATIO`` times or more and beyond 3 standard errors; else None."""
    fit, seen = in_use.measured_fit or in_use.fit_after, in_use.measured_after or in_use.position_after
    if not (fit.n and seen.mean > OVERFIT_RATIO * fit.mean and seen.mean - fit.mean > 3 * in_use.standard_error):
        return None
    return seen.mean / fit.mean if fit.mean > 0 else float("inf")


def _times_fitted(ratio: float) -> str:
    return f"{ratio:.3g} times the fitted poses' error" if np.isfinite(ratio) else "the fitted poses fitted exactly"


def _another_set_up(in_use, summary: str, misfit=None, reach_m=None) -> Check | None:
    """Held-out errors ``OVERFIT_RATIO`` times the fitted ones that registering base and tool on the
    validation set explains: another set-up. Judged before "no better than before": the nominal
    model's errors there are that set-up's too."""
    ratio, reg, homed = _held_out_excess(in_use), _registration_explains(in_use), _rehoming_explains(in_use)
    if ratio is not None and homed is not None:
        return Check("accuracy in use", "warn", summary + f": {_times_fitted(ratio)}; {_rehomed_words(homed)}",
                     cause=REHOMED_CAUSE.format(homed.joint), fix=REHOMED_FIX.format(homed.joint))
    if ratio is None or reg is None:
        return None
    return Check("accuracy in use", "warn", summary + f": {_times_fitted(ratio)}; with base and tool registered on "
                 f"the validation set, {_mm(reg.mean)} ({REGISTERED}): another set-up",
                 cause="a validation campaign measured with the instrument or the tool placed otherwise",
                 fix="register base and tool on it (--register-validation)")


def _held_out_larger(in_use, summary: str, misfit=None, reach_m=None) -> Check | None:
    """Held-out errors ``OVERFIT_RATIO`` times the fitted ones that no registration explains, named by
    what does; None when they are not."""
    ratio = _held_out_excess(in_use)
    if ratio is None:
        return None
    name, fit, cv = "accuracy in use", in_use.measured_fit or in_use.fit_after, in_use.cross_validated
    summary += f": {_times_fitted(ratio)}"
    if cv is not None and cv.n and cv.mean <= OVERFIT_RATIO * fit.mean:
        return Check(name, "warn", summary + f"; the fitted campaign's own poses held out show {_mm(cv.mean)}: the "
                     "validation poses differ from the fitted ones", cause="validation poses in another region of "
                     "the workspace or at another time (warm-up, a payload) than the fitted ones",
                     fix="measure validation poses where and when the fitted ones were, or more poses where the "
                         "validation ones are (robocal plan)")
    return Check(name, "warn", summary + " (overfitting)", cause="more parameters than the poses pin down, or poses "
                 "that do not cover where the model is used", fix="measure more poses over the workspace (robocal "
                 "plan); hold weak parameters (--weak eliminate)")


def _joint_spans(cover) -> str:
    """Each joint's measured span over its range of use, in words; joints whose range of use is the
    campaign's own (limits of a full turn or more) are named apart, their span saying nothing."""
    turn = np.array(cover.use_from_campaign or [False] * len(cover.joint_span), dtype=bool)
    if not turn.any():
        return "joints over " + ", ".join(f"{100 * s:.0f} %" for s in cover.joint_span) + " of their ranges of use"
    margin = f"widened by {100 * USE_MARGIN:g} % on each side"
    if turn.all():
        return f"every joint's limits allow a full turn or more: their ranges of use are the campaign's, {margin}"
    names = [n for n, t in zip(cover.joint_names, turn) if t]
    spans = ", ".join(f"{n} {100 * s:.0f} %" for n, s, t in zip(cover.joint_names, cover.joint_span, turn) if not t)
    ranges = "its range of use is" if len(names) == 1 else "their ranges of use are"
    return (f"joints over their ranges of use: {spans}; the limits of {', '.join(names)} allow a full turn or more: "
            f"{ranges} the campaign's, {margin}")


def error_where_used(cover, rms: float) -> float:
    """The accuracy in use over the range of use (m RMS): the held-out error ``rms`` with the
    uncertainty the parameters gain from the measured poses to the configurations of use
    (``Coverage``); ``rms`` itself without a coverage (contacts)."""
    if cover is None:
        return rms
    return float(np.sqrt(rms ** 2 + max(cover.uncertainty_workspace ** 2 - cover.uncertainty_measured ** 2, 0.0)))


def coverage_check(cover, in_use, change: WorkspaceChange | None = None, missed: float = 0.0) -> Check:
    """Where the accuracy in use holds: the campaign's points against the spread of the robot's at
    the configurations of use (``use_box``), and the parameters' uncertainty carried from the
    measured poses to those configurations (``Coverage``); the cause named is the one the figures show.
    A failure when the calibrated geometry moves the tool at those configurations (``change``) far
    more than the nominal misses the fitted points by (``missed``, RMS, m) and than its own
    uncertainty there (``CORRECTION_GROWTH_MAX``): the accuracy in use, held out among the measured
    poses, does not reach where that correction lies."""
    name = "where the model holds"
    summary = (f"the measured points spread {100 * cover.spread_ratio:.3g} % of the robot's at the configurations of "
               f"use ({_joint_spans(cover)}); the parameters' uncertainty is "
               f"{_mm(cover.uncertainty_measured)} RMS at the measured poses, {_mm(cover.uncertainty_workspace)} "
               "at the configurations of use")
    seen = max(missed, cover.uncertainty_workspace, 1e-300)
    if change is not None and change.rms_m > CORRECTION_GROWTH_MAX * seen:
        before = _mm(missed)
        return Check(name, "fail", summary + f": the calibrated geometry moves the tool {_mm(change.rms_m)} RMS "
                     f"from the nominal's there, {change.rms_m / seen:.3g} times what the nominal misses the fitted "
                     f"points by ({before} RMS) and its own uncertainty there: a correction the measured poses do not "
                     "show, which no held-out figure judges", cause="poses that leave the parameters free where the "
                     "robot is used (a joint that hardly moves), taken up as a large change",
                     fix="measure poses that move every joint over its range of use (robocal plan)")
    small = cover.spread_ratio < COVERAGE_SPREAD_MIN
    rms = in_use.position_after.rms or 0.0
    there = error_where_used(cover, rms)
    grows = cover.extrapolation > EXTRAPOLATION_MAX and there > COVERAGE_GROWTH * rms
    if not (small or grows):
        return Check(name, "pass", summary)
    if small:
        return Check(name, "warn", summary + ": the accuracy in use holds near the measured poses only",
                     cause="a campaign that covers a small part of the configurations of use",
                     fix="measure poses over the whole workspace the robot will use (robocal plan), or use the model "
                         "only where it was measured")
    return Check(name, "warn", summary + f": {cover.extrapolation:.3g} times larger where the robot is used, where "
                 f"the error in use would be about {_mm(there)} RMS rather than {_mm(rms)}; the accuracy in use holds "
                 "near the measured poses only", cause="poses that pin the parameters down "
                 "only where they were measured (the points spread widely, the configurations do not)",
                 fix="add poses whose joint readings vary where the robot is used (robocal plan)")


def limit_check(judged) -> Check:
    """The mean error in use against the limit of absolute accuracy (``LimitJudgement``): a warning
    when not reached (the robot is placed better, but not as well as it could be)."""
    name = "limit of absolute accuracy"
    summary = (f"mean error in use {_mm(judged.mean_error_m)}, {judged.ratio:.3g} times the limit of "
               f"{_mm(judged.limit_m)}")
    if judged.reached:
        within = "" if judged.ratio <= 1.0 else f", within the {LIMIT_REACHED_WITHIN:g} times it the check allows"
        return Check(name, "pass", summary + f" (reached{within})")
    return Check(name, "warn", summary + " (not reached)", cause="errors the model leaves out (compliance, backlash, "
                 "thermal drift), or poses that do not pin the parameters down",
                 fix="add the compliance or backlash families, or poses over the workspace")
