"""The public face of a calibration: ``calibrate`` runs the identification (``_identification``: one
sequence of steps for every kind of observation) and then the diagnosis of its data (docs/diagnosis.md),
whose verdict joins the checks as "diagnosis": a decisive cause fails the calibration, a possible one
warns. ``compare`` does the same for identifications nested in one another. The arguments are checked
here, once."""

from __future__ import annotations

import inspect
import warnings
from dataclasses import replace
from typing import cast, overload

import numpy as np

from .._base.arguments import FLAG, FRACTION, accepts, both, is_a, measured_on, optional
from .._base.errors import DegenerateDataError, InputError, warn
from .._base.threads import one_blas_thread
from .._identification.calibrate import check_inputs, nested_test, options_of, run
from .._identification.checks import BEFORE_SOLVING, Check, error_where_used
from .._identification.holdout import DEFAULT_FOLDS
from .._identification.identifiability import DEFAULT_TOL
from .._identification.judgement import warn_checks
from .._identification.result import CalibrationResult, Comparison, Diagnosis, NestedTest, compared_name
from .._identification.steps import COMPARED_NFEV, Fit, Options
from .._model.contacts import Contacts
from .._model.measurements import Measurements
from .._model.parameters import transmission_names
from .._model.robot import RobotModel
from .contacts import diagnose_contacts
from .measured import diagnosed
from .reference import reference


@overload
def calibrate(model: RobotModel, data: Measurements, *, contacts: None = None, **options) -> CalibrationResult: ...


@overload
def calibrate(model: RobotModel, data: Measurements | None = None, *, contacts: Contacts,
              **options) -> CalibrationResult: ...


@one_blas_thread
def calibrate(model: RobotModel, data: Measurements | None = None, *, contacts: Contacts | None = None,
              parameters=("geometric",), known=(), validation=None, loss: str = "linear",
              f_scale: float | None = None, tol: float = DEFAULT_TOL, max_nfev: int | None = None,
              initial_base: str = "model", limit=None, noise=None, on_outliers: str = "refit",
              weak: str = "eliminate", nonnegative_compliance: bool = False, folds: int = DEFAULT_FOLDS,
              register_validation: bool = False):
    """Identify the identifiable parameters of ``model`` from ``data`` (measured points or poses)
    and/or ``contacts`` (sockets, planes, ball bars, known distances), and judge the result.

    Parameters
    ----------
    model : RobotModel
        The nominal robot; the solve starts from it.
    data : Measurements, optional
        The fitted campaign of measured points or poses (may be left out with ``contacts``).
    contacts : Contacts, optional
        Joint-only contact recordings, fitted alone or beside ``data`` in one problem (its rows in
        their stated standard deviations, ``f_scale`` too); the result's ``contacts`` then holds the
        kit's figures (socket consistency, spacing error) fitted and held out by placement, and
        ``validation`` is held-out ``Contacts`` or measured points (without ``data`` the base and
        tool are registered on them). ``initial_base="register"`` needs ``data`` (contacts
        alone fix no frame); ``register_validation`` has nothing to register on held-out contacts
        (their figures do not depend on the frame) and ``folds`` gives way to the placements.
    parameters : str or sequence of str
        What to identify: families (``geometric``, ``compliance``, ``backlash``, ``base``,
        ``markers``, ``frames``) or parameter names and patterns.
    known : str or sequence of str
        Families, names or patterns held at the model's values.
    validation : Measurements or Contacts, optional
        Held-out poses (with ``contacts``: held-out contacts) to judge the result on; without them
        it is judged by ``folds``-fold cross-validation (docs/checks.md, "Accuracy in use"), and
        contacts placement by placement.
    loss : str
        Least-squares loss: ``linear`` or a robust one of scipy's.
    f_scale : float, optional
        For a robust loss, the residual size where it bends (m, or standard deviations when the
        data state them; None: estimated).
    tol : float
        Identifiability tolerance, in (0, 1).
    max_nfev : int, optional
        Evaluations the solver may take.
    initial_base : {"model", "register"}
        Start from the model's base pose, or from a rigid registration of the nominal robot.
    limit : AccuracyLimit or float, optional
        The limit of absolute accuracy (m): the accuracy in use is judged against it, and weak
        parameters are judged at the scatter it implies (never holding back what helps in use).
    noise : Noise or str, optional
        The measurement noise where the data state none (an instrument class of
        ``INSTRUMENT_NOISE``; default a laser tracker's).
    on_outliers : {"refit", "flag"}
        Set measured points that stand out aside and fit again without them, or only name them.
    weak : {"eliminate", "flag"}
        Hold weakly identifiable parameters at nominal where that does not worsen the accuracy in
        use, or keep them all and warn.
    nonnegative_compliance : bool
        Keep compliances >= 0.
    folds : int
        Folds of the cross-validation (>= 2), without a validation set or a series column.
    register_validation : bool
        With ``validation`` from another set-up: register base and tool on it (for the models
        before and after alike) before taking its errors.

    Returns
    -------
    CalibrationResult
        Estimates, covariance, errors, the accuracy in use, the diagnosis of its data (``diagnosis``:
        mistakes tested against them, docs/diagnosis.md) and the checks; ``verdict`` says whether
        it can be trusted (docs/checks.md): a decisive cause fails it.
    """
    options = dict(parameters=parameters, known=known, loss=loss, f_scale=f_scale, tol=tol, max_nfev=max_nfev,
                   initial_base=initial_base, limit=limit, noise=noise, on_outliers=on_outliers, weak=weak,
                   nonnegative_compliance=nonnegative_compliance, folds=folds, register_validation=register_validation)
    check_inputs(model, data, contacts, validation, options)
    settled = options_of(options)
    return screened(model, data, contacts, *run(model, data, contacts, validation, settled), settled)


@accepts(model=is_a(RobotModel), data=optional(both(is_a(Measurements), measured_on())),
         contacts=optional(is_a(Contacts)), validation=optional(is_a(Measurements, Contacts)), alpha=FRACTION,
         backlash=FLAG, transmission=FLAG)
@one_blas_thread
def compare(model: RobotModel, data: Measurements | None = None, *, contacts: Contacts | None = None,
            validation=None, alpha: float = 0.01, backlash: bool = False, transmission: bool = True,
            **kwargs) -> Comparison:
    """Run geometric and geometric-plus-compliance identifications on the same data (the paper's two),
    with ``backlash`` a third (backlash added to the one kept), and with ``transmission`` the
    transmission terms added to the one kept then. Each larger identification keeps the parameters of
    the one it adds to (``nested_test`` judges it against that one: it helps when the F test says so
    and it places the robot better in use, where measured and over the range of use, as the check
    "where the model holds" predicts). The warnings said are those of the identification kept, named
    as it (the others' are in their checks). A model without link masses skips what needs them and
    says so (``skipped``);
    data that fail a check made before solving (readings, their units, the points' size) compare
    nothing beyond the geometric calibration, saying so. A larger model is solved within
    ``COMPARED_NFEV`` evaluations of the residuals (``max_nfev`` when given), as the model choice's
    designs are: one not converged by then (a model the data barely determine, which could crawl on
    for thousands) is left out, saying so.

    Keyword arguments other than ``parameters`` go to every ``calibrate`` call.

    Parameters
    ----------
    model : RobotModel
        The nominal robot.
    data : Measurements, optional
        The fitted campaign (may be left out with ``contacts``).
    contacts : Contacts, optional
        Contacts fitted alone or beside ``data``; each calibration is then judged in use by the
        socket consistency of its held-out placements (none with one placement: the simpler kept).
    validation : Measurements or Contacts, optional
        Held-out poses (with ``contacts``: held-out contacts) to judge the calibrations on (None:
        cross-validation, or each placement predicted by the others).
    alpha : float
        Significance level of the F tests, in (0, 1).
    backlash : bool
        Also calibrate with backlash added to the identification kept so far, tested against it.
    transmission : bool
        Also calibrate with transmission terms (``TRANSMISSION_LEVELS``) added to the identification
        kept so far, test them against it, and keep, of those that helped, the one with the smallest
        error in use over the range of use.
    **kwargs
        Further arguments of ``calibrate`` (``parameters`` excepted), for every calibration.

    Returns
    -------
    Comparison
        The calibrations (each diagnosed, as ``calibrate``'s), the F statistics, p-values and the
        verdict on what helped.
    """
    kwargs.pop("parameters", None)
    if data is None and contacts is None:
        raise InputError("give measurements or contacts to compare the identifications on", where="data")
    # calibrate's options, with its defaults, checked once for the calibrations that share them
    given = inspect.signature(calibrate).bind(model, data, contacts=contacts, validation=validation, **kwargs)
    given.apply_defaults()
    options = {k: v for k, v in given.arguments.items() if k not in ("model", "data", "contacts", "validation")}
    check_inputs(model, data, contacts, validation, options)

    fit = _Fitter(model, data, contacts, validation, options)
    found: dict = {"geometric": fit("geometric"), "skipped": []}
    wrong = [c.name for c in found["geometric"].checks if c.status == "fail" and c.name in BEFORE_SOLVING]
    if wrong:       # a larger model fitted to a mistake says nothing of the robot
        found["skipped"].append(f"nothing compared: the data fail {', '.join(wrong)}, checked before solving; "
                                "correct them and compare again")
    else:
        _compare_compliance(model, fit, found, validation, alpha)
        if backlash:
            _compare_backlash(model, fit, found, validation, alpha)
        if transmission:
            _compare_transmission(model, fit, found, validation, alpha)
    comparison = Comparison(skipped=tuple(found.pop("skipped")), **found)
    fit.warn_kept(comparison.best)
    return comparison


class _Fitter:
    """The identifications of one comparison: ``fit(*families, on=smaller)`` calibrates and diagnoses
    one, nested on ``smaller`` (whose parameters it keeps, adding to them); with ``screen=False``
    the diagnosis waits for ``screen(result)``, asked only of the one a choice keeps (the
    transmission levels: each is fitted, one is kept). Each one's warnings are held, by what it
    identifies, for ``warn_kept``."""

    def __init__(self, model, data, contacts, validation, options: dict):
        self.model, self.data, self.contacts, self.validation, self.options = model, data, contacts, validation, options
        self.pending: dict = {}
        self.warned: dict = {}

    def __call__(self, *families: str, on: CalibrationResult | None = None, screen: bool = True) -> CalibrationResult:
        floor = () if on is None else on.parameter_names
        return self._held(families, lambda: self._fitted(families, floor, screen))

    def screen(self, result: CalibrationResult) -> CalibrationResult:
        """``result``'s diagnosis, when its fit left it for later; else ``result``."""
        if id(result) not in self.pending:
            return result
        chosen, settled = self.pending.pop(id(result))
        return self._held(result.families, lambda: screened(self.model, self.data, self.contacts, result, chosen,
                                                            settled))

    def warn_kept(self, kept: CalibrationResult) -> None:
        """The warnings of the identification kept, named as it: the others' are in their checks."""
        for message, category in self.warned.get(kept.families, ()):
            warn(f"{_identification_label(kept.families)}: {message}", category)

    def _held(self, families, work):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            result = work()
        self.warned.setdefault(tuple(families), []).extend((w.message, w.category) for w in caught)
        return result

    def _fitted(self, families: tuple, floor: tuple, screen: bool) -> CalibrationResult:
        # a larger model is offered, not asked for: it gets the model choice's budget of evaluations
        options = self.options
        given = options["max_nfev"] is not None
        budget = options["max_nfev"] if given or families == ("geometric",) else COMPARED_NFEV
        settled = replace(options_of({**options, "parameters": families, "max_nfev": budget}), floor=floor)
        result, chosen = run(self.model, self.data, self.contacts, self.validation, settled)
        if families != ("geometric",) and not result.solver.success:      # not diagnosed: it is left out
            raise _NotConverged(f"its fit had not converged within the {budget} evaluations of the residuals "
                                "max_nfev allows" if given else
                                f"its fit had not converged after {result.solver.nfev} evaluations of the "
                                f"residuals: a model of {len(result.parameters)} parameters these data barely "
                                "determine")
        if not screen:
            self.pending[id(result)] = (chosen, settled)
            return result
        return screened(self.model, self.data, self.contacts, result, chosen, settled)


NO_MASSES = "the model has no link masses (--assume-masses assumes them from the geometry)"


def _fitted_or_skipped(fit, found: dict, what: str, *families: str, on: CalibrationResult,
                       screen: bool = True) -> CalibrationResult | None:
    """The calibration of ``families`` nested on ``on``, or None with ``what`` and why in
    ``found["skipped"]`` when the data cannot determine that larger model (too few poses for its
    parameters, or a solve that did not converge within its evaluations: ``COMPARED_NFEV`` unless
    ``max_nfev`` is given): the comparison of the others stands."""
    try:
        return fit(*families, on=on, screen=screen)
    except (DegenerateDataError, _NotConverged) as e:
        found["skipped"].append(f"{what} not compared: {e}")
        return None


class _NotConverged(Exception):
    """A larger model's fit that had not converged within its evaluations: left out of a comparison."""


def _kept(found: dict) -> CalibrationResult:
    """The identification kept so far: the one the next adds to."""
    return Comparison(skipped=(), **{k: v for k, v in found.items() if k != "skipped"}).best


def _compare_compliance(model: RobotModel, fit, found: dict, validation, alpha: float) -> None:
    """Geometric and compliance against geometric, when the model has masses."""
    if not model.has_masses:
        found["skipped"].append(f"compliance not compared: {NO_MASSES}")
        return
    geometric = found["geometric"]
    combined = _fitted_or_skipped(fit, found, "compliance", "geometric", "compliance", on=geometric)
    if combined is None:
        return
    found["combined"] = combined
    found["compliance_test"] = nested_test(geometric, combined, validation, alpha, "compliance")


def _compare_backlash(model: RobotModel, fit, found: dict, validation, alpha: float) -> None:
    """Backlash added to the identification kept so far (geometric alone without masses, when the
    approach-sided model needs none)."""
    if not model.has_masses and model.backlash_side == "gravity":
        found["skipped"].append(f"backlash not compared: its gravity-sided model needs masses and {NO_MASSES}")
        return
    small = _kept(found)
    what = f"backlash (on {compared_name(small.families)})"
    large = _fitted_or_skipped(fit, found, what, *small.families, "backlash", on=small)
    if large is None:
        return
    found["backlash"] = large
    found["backlash_test"] = nested_test(small, found["backlash"], validation, alpha, what)


# the transmission terms the comparison offers, each level adding to the one before: the gears'
# scales (one term a joint), the first harmonic of the joint angle, the second, the motor's (where a
# ratio is stated)
TRANSMISSION_LEVELS = (("gear scale", ("gear_scale",)), ("first harmonic", ("gear_cos1", "gear_sin1")),
                       ("second harmonic", ("gear_cos2", "gear_sin2")),
                       ("motor harmonics", ("motor_cos1", "motor_sin1", "motor_cos2", "motor_sin2")))


def _compare_transmission(model: RobotModel, fit, found: dict, validation, alpha: float) -> None:
    """Transmission terms added, level after level, to the identification kept so far; kept: of the
    levels that helped (``nested_test``), the one with the smallest error in use over the range of
    use (else that one of them all, shown and not kept)."""
    names = transmission_names(model)
    tried = _transmission_levels(_kept(found), names, fit, found, validation, alpha)
    if not tried:
        if not names:
            found["skipped"].append("transmission not compared: no joint can carry a transmission term")
        return
    helped = [t for t in tried if t[2].helped]
    _, large, test = min(helped or tried, key=lambda t: _where_used(t[1]))
    others = "".join(f"; {w}: RMS in use {_in_use_rms(r) * 1e3:.4f} mm, over the range of use "
                     f"{_where_used(r) * 1e3:.4f} mm" for w, r, _ in tried if r is not large)
    found["transmission"] = fit.screen(large)
    found["transmission_test"] = NestedTest(test.f_statistic, test.p_value, test.helped, test.summary + others)


def _transmission_levels(small: CalibrationResult, names, fit, found: dict, validation, alpha: float) -> list:
    """(what, result, test) of each level of transmission terms added to ``small``, up to the first the
    data cannot determine (said in ``found["skipped"]``; the levels above it have more parameters)."""
    tried = []
    kinds: tuple = ()
    done: tuple = ()
    for label, level in TRANSMISSION_LEVELS:
        kinds += level
        terms = tuple(n for n in names if n.rsplit(".", 1)[1] in kinds)
        if terms == done:
            continue                    # nothing new at this level (no stated ratio)
        done = terms
        what = f"transmission (up to the {label}, on {compared_name(small.families)})"
        large = _fitted_or_skipped(fit, found, what, *small.families, *terms, on=small, screen=False)
        if large is None:
            break
        tried.append((what, large, nested_test(small, large, validation, alpha, what)))
    return tried


def _identification_label(families) -> str:
    """'the geometric and compliance identification', 'the geometric identification with transmission
    terms up to the first harmonic': one of a comparison's, as its warnings name it."""
    base = tuple(f for f in families if "." not in f)
    kinds = {f.rsplit(".", 1)[1] for f in families if "." in f}
    levels = [label for label, level in TRANSMISSION_LEVELS if kinds & set(level)]
    terms = f" with transmission terms up to the {levels[-1]}" if levels else ""
    return f"the {compared_name(base)} identification{terms}"


def _in_use_rms(r: CalibrationResult) -> float:
    return np.inf if r.in_use is None else cast(float, r.in_use.position_after.rms)


def _where_used(r: CalibrationResult) -> float:
    """The error in use over the range of use (the check "where the model holds"), m RMS."""
    return np.inf if r.in_use is None else error_where_used(r.coverage, _in_use_rms(r))


def screened(model: RobotModel, data: Measurements | None, contacts: Contacts | None, result: CalibrationResult,
             fitted: Fit, options: Options) -> CalibrationResult:
    """``result`` with the diagnosis of its data and its check "diagnosis" (warned when it does not pass);
    ``fitted``: the calibration's fit, whose residuals and Jacobian the diagnosis takes up."""
    if contacts is not None:
        diagnosis = diagnose_contacts(model, contacts, result, data=data, noise=options.noise)
    else:
        diagnosis = diagnosed(reference(model, cast(Measurements, data), result, options.noise, options.limit_m,
                                        options.folds, fitted))
    check = diagnosis_check(diagnosis)
    warn_checks([check])
    return replace(result, checks=result.checks + (check,), diagnosis=diagnosis)


def diagnosis_check(diagnosis: Diagnosis) -> Check:
    """The check of a diagnosis: "fail" when a cause is decisive, "warn" when one is possible, with the
    first cause and its fix."""
    first = diagnosis.cause
    if first is None:
        return Check("diagnosis", "pass", diagnosis.summary)
    return Check("diagnosis", diagnosis.status, diagnosis.summary, cause=first.cause, fix=first.fix, items=first.items)
