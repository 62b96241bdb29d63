"""Result files (JSON): calibration results and accuracy limits, with their schema versions.

``result_to_dict`` / ``result_from_dict`` are the only translation between a ``CalibrationResult``
and its file form (docs/formats.md); reading checks the whole document against the schema before
anything uses it and gives back the typed record. Values are SI; NaN and infinities are stored
as null (strict JSON has neither).
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any, cast

import numpy as np

from .._accuracy.limit import AccuracyLimit, PoseRepeatability, PrecisionResult, RepeatabilityResult
from .._base.arguments import (
    FLAG,
    PATH,
    TEXT,
    accepts,
    is_a,
    optional,
)
from .._base.errors import InputError, excerpt
from .._identification.checks import STATUSES, Check, verdict
from .._identification.estimates import ErrorStats, ParameterEstimate
from .._identification.holdout import AccuracyInUse, Coverage, JointOffset, UseStats
from .._identification.identifiability import Absorption, IdentifiabilityResult, status_table
from .._identification.result import (
    CalibrationResult,
    Diagnosis,
    ErrorSummary,
    Finding,
    LimitJudgement,
    PoseSet,
    SolverRecord,
)
from .._model.parameters import parameter_layout
from .contact_result import contact_residual_dof, contacts_from_dict, contacts_to_dict
from .measurements import MAX_MAGNITUDE
from .model import model_from_dict, model_to_dict
from .text import MAX_FILE_BYTES, load_json, read_bytes, read_text, refuse_other_form, sidecar_path, write_texts

SCHEMA = "robocal.result/1"
SCHEMAS = (SCHEMA,)
LIMIT_SCHEMA = "robocal.limit/1"


def plain(obj):
    """JSON-ready copy: numpy types to Python, mappings to dicts, NaN and infinities to null."""
    if isinstance(obj, str):
        return obj
    if isinstance(obj, Mapping):
        return {str(k): plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        if all(type(v) is str for v in obj):    # pose labels: a million of them in a large campaign
            return list(obj)
        return [plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return plain(obj.tolist())
    if isinstance(obj, (np.bool_, bool)):
        return bool(obj)
    if isinstance(obj, (np.integer, int)):
        return int(obj)
    if isinstance(obj, (np.floating, float)):
        return float(obj) if math.isfinite(obj) else None
    return obj


def to_json(d: dict) -> str:
    """The file text of a dict of results."""
    return json.dumps(plain(d), indent=1, allow_nan=False) + "\n"


# -- calibration results -----------------------------------------------------------------------

def identifiability_to_dict(ident: IdentifiabilityResult) -> dict:
    return {"candidates": list(ident.candidates), "identified": list(ident.identified),
            "eliminated": [{"name": a.name, "reason": a.reason, "residual": a.residual,
                            "absorbed_by": [{"name": n, "coefficient": c} for n, c in a.absorbers]}
                           for a in ident.eliminated],
            "tol": ident.tol, "rank": ident.rank, "condition_number": ident.condition_number,
            "singular_values": list(ident.singular_values), "observability": dict(ident.observability),
            "n_rows": ident.n_rows}


# result.json "errors" key "{set}_{part}": the set (the result's ``fit`` or ``validation``), and
# each part's ``PoseSet`` field; fitted poses first, then held-out ones
_SETS = ("fit", "validation")
_PARTS = (("before", "errors_before"), ("after", "errors_after"), ("residual_vectors", "residual_vectors"),
          ("positions", "measured_positions"), ("readings", "readings"),
          ("rotation_before", "rotation_errors_before"), ("rotation_after", "rotation_errors_after"))
_ERROR_ARRAYS = tuple((f"{which}_{part}", which, field) for which in _SETS for part, field in _PARTS)


# the nominal model as given on the fitted and held-out poses (optional: files written before them lack them)
NOMINAL_KEYS = ("fit_nominal", "validation_nominal")


def _stats_dict(s: ErrorStats) -> dict:
    return {"n": s.n, "mean": s.mean, "std": s.std, "rms": s.rms, "max": s.max}


def _summary_dict(summary: ErrorSummary) -> dict:
    return {**{k: _stats_dict(getattr(summary, k)) for k in ErrorSummary.KEYS},
            **{k: None if getattr(summary, k) is None else _stats_dict(getattr(summary, k)) for k in NOMINAL_KEYS}}


def _array(a):
    return None if a is None else np.where(np.isfinite(a), a, np.nan).tolist()


def _pose_arrays(result: CalibrationResult) -> dict[str, np.ndarray | None]:
    """Every per-pose array under its key of ``errors``, None where the result holds none."""
    sets = {"fit": result.fit, "validation": result.validation}
    return {key: None if sets[which] is None else getattr(sets[which], field) for key, which, field in _ERROR_ARRAYS}


def per_pose_arrays(result: CalibrationResult) -> dict[str, np.ndarray]:
    """The per-pose arrays of ``result`` under their keys of ``errors`` (the sidecar's names), as
    float arrays; those the result does not hold are left out."""
    return {key: np.asarray(a, dtype=float) for key, a in _pose_arrays(result).items() if a is not None}


@accepts(result=is_a(CalibrationResult), per_pose=FLAG)
def result_to_dict(result: CalibrationResult, *, per_pose: bool = True) -> dict:
    """The file form of a calibration result (plain Python types); ``per_pose=False`` leaves the
    per-pose arrays of ``errors`` out (:func:`result_files` puts them in a sidecar file).

    Parameters
    ----------
    {result, per_pose}

    Returns
    -------
    dict
        The result as its JSON file holds it.
    """
    lim, solver = result.limit, result.solver
    return {
        "schema": SCHEMA,
        "success": solver.success, "status": solver.status, "message": solver.message, "nfev": solver.nfev,
        "families": list(result.families), "loss": solver.loss, "sigma0_m": solver.sigma0,
        "parameters": [{"name": p.name, "unit": p.unit, "family": p.family, "quantity": p.quantity,
                        "nominal": p.nominal, "estimate": p.estimate, "change": p.change, "std": p.std}
                       for p in result.parameters],
        "correlation": result.correlation.tolist(), "covariance": result.covariance.tolist(),
        "identifiability": identifiability_to_dict(result.identifiability),
        "identifiability_table": status_table(result.identifiability, result.nominal_model.frame_names),
        "stats": {**_summary_dict(result.stats),
                  "rotation": None if result.rotation_stats is None else _summary_dict(result.rotation_stats)},
        "errors": {"unit": "m", "rotation_unit": "rad", "markers": list(result.nominal_model.marker_names),
                   **({key: _array(a) for key, a in _pose_arrays(result).items()} if per_pose else {})},
        "notes": list(result.notes),
        "verdict": result.verdict,
        "checks": [{"name": c.name, "status": c.status, "summary": c.summary, "cause": c.cause, "fix": c.fix,
                    "items": list(c.items)} for c in result.checks],
        "limit": None if lim is None else {"limit_m": lim.limit_m, "compared": lim.compared,
                                           "mean_error_m": lim.mean_error_m, "ratio": lim.ratio,
                                           "reached": lim.reached},
        "in_use": in_use_to_dict(result.in_use),
        "coverage": coverage_to_dict(result.coverage),
        "contacts": contacts_to_dict(result.contacts, result.solver.residual_dof),
        "provenance": plain(result.provenance),
        "nominal_model": model_to_dict(result.nominal_model),
        "calibrated_model": model_to_dict(result.calibrated_model),
        **({} if result.diagnosis is None else {"diagnosis": diagnosis_to_dict(result.diagnosis)}),
    }


_USE_FIELDS = ("n", "mean", "rms", "p95", "max")


def _use_dict(s) -> dict | None:
    return None if s is None else {f: getattr(s, f) for f in _USE_FIELDS}


def in_use_to_dict(in_use: AccuracyInUse | None) -> dict | None:
    """The accuracy in use (statistics only; SI: m and rad)."""
    if in_use is None:
        return None
    return {"method": in_use.method, "k": in_use.folds, "grouping": in_use.grouping,
            "position_before": _use_dict(in_use.position_before), "position_after": _use_dict(in_use.position_after),
            "rotation_before": _use_dict(in_use.rotation_before), "rotation_after": _use_dict(in_use.rotation_after),
            "fit_after": _use_dict(in_use.fit_after), "measured_after": _use_dict(in_use.measured_after),
            "measured_fit": _use_dict(in_use.measured_fit), "measured_points": _use_dict(in_use.measured_points),
            "noise_m": in_use.noise, "registered_after": _use_dict(in_use.registered_after),
            "cross_validated": _use_dict(in_use.cross_validated),
            "rehomed": None if in_use.rehomed is None else {
                "joint": in_use.rehomed.joint, "offset": in_use.rehomed.offset, "quantity": in_use.rehomed.quantity,
                "errors": _use_dict(in_use.rehomed.errors)},
            "spacing_before_m": None if in_use.spacing_before is None else in_use.spacing_before.tolist(),
            "spacing_after_m": None if in_use.spacing_after is None else in_use.spacing_after.tolist()}


def coverage_to_dict(cover: Coverage | None) -> dict | None:
    """Where the calibration was measured (SI)."""
    if cover is None:
        return None
    return {"joint_span": cover.joint_span.tolist(), "joint_ranges": [list(r) for r in cover.joint_ranges],
            "box_m": [list(cover.box[0]), list(cover.box[1])], "spread_ratio": cover.spread_ratio,
            "uncertainty_measured_m": cover.uncertainty_measured,
            "uncertainty_workspace_m": cover.uncertainty_workspace,
            "use_from_campaign": list(cover.use_from_campaign)}


def _use_stats(doc: _Doc, d: dict | None, where: str) -> UseStats | None:
    if d is None:
        return None
    n = doc.get(d, "n", where, int)
    vals = {f: (doc.size(d, f, where, optional=True) if n else None) for f in _USE_FIELDS[1:]}
    return UseStats(n=n, **{f: (None if v is None or math.isnan(v) else v) for f, v in vals.items()})


def _in_use(doc: _Doc, d: dict | None) -> AccuracyInUse | None:
    """The accuracy in use of a result file (its statistics; the per-point errors are not stored)."""
    if d is None:
        return None
    w = "in_use"
    k = doc.get(d, "k", w, int, optional=True)
    stats: dict[str, Any] = {key: _use_stats(doc, doc.get(d, key, w, dict, optional=True), f"{w}.{key}")
             for key in ("position_before", "position_after", "rotation_before", "rotation_after", "fit_after",
                         "measured_after", "measured_fit", "measured_points", "registered_after", "cross_validated")}
    moved = doc.get(d, "rehomed", w, dict, optional=True)
    stats["rehomed"] = None if moved is None else JointOffset(
        joint=doc.get(moved, "joint", f"{w}.rehomed", str), offset=doc.get(moved, "offset", f"{w}.rehomed", float),
        quantity=doc.get(moved, "quantity", f"{w}.rehomed", str),
        errors=cast(UseStats, _use_stats(doc, doc.get(moved, "errors", f"{w}.rehomed", dict), f"{w}.rehomed.errors")))
    for key in ("spacing_before", "spacing_after"):
        values = doc.get(d, key + "_m", w, list, optional=True)
        stats[key] = None if values is None else doc.array(values, f"{w}.{key}_m", (None,))
    for key in ("position_before", "position_after", "fit_after"):
        if stats[key] is None:
            raise doc.error(f"{w}.{key}", "missing key")
    noise = doc.get(d, "noise_m", w, float, optional=True)
    return AccuracyInUse(method=doc.get(d, "method", w, str), folds=k, grouping=doc.get(d, "grouping", w, str),
                         noise=0.0 if noise is None else noise, errors_before=np.zeros(0), errors_after=np.zeros(0),
                         **stats)


def diagnosis_to_dict(diagnosis: Diagnosis) -> dict:
    """The file form of a ``Diagnosis`` (the ``diagnosis`` key of result.json): residuals in metres."""
    return {"status": diagnosis.status, "summary": diagnosis.summary, "rms_m": diagnosis.rms,
            "tested": list(diagnosis.tested), "untestable": list(diagnosis.untestable),
            "refitted": list(diagnosis.refitted),
            "findings": [{"hypothesis": f.hypothesis, "status": f.status, "cause": f.cause, "evidence": f.evidence,
                          "score": f.score, "items": list(f.items), "rms_before_m": f.rms_before,
                          "rms_after_m": f.rms_after, "fix": f.fix} for f in diagnosis.findings]}


def _diagnosis(doc: _Doc, d: dict | None) -> Diagnosis | None:
    """The diagnosis of a result file (None where it holds none)."""
    if d is None:
        return None
    found = []
    for w, f in _mappings(doc, doc.get(d, "findings", "diagnosis", list), "diagnosis.findings"):
        status = doc.get(f, "status", w, str)
        if status not in STATUSES[1:]:
            raise doc.error(f"{w}.status", f"expected warn or fail, got {excerpt(status)}")
        found.append(Finding(doc.get(f, "hypothesis", w, str), doc.get(f, "cause", w, str),
                             doc.get(f, "evidence", w, str), doc.get(f, "score", w, float),
                             doc.strings(doc.get(f, "items", w, list), f"{w}.items"),
                             doc.get(f, "rms_before_m", w, float, optional=True),
                             doc.get(f, "rms_after_m", w, float, optional=True), doc.get(f, "fix", w, str), status))

    def names(key):
        return doc.strings(doc.get(d, key, "diagnosis", list), f"diagnosis.{key}")

    return Diagnosis(findings=tuple(found), tested=names("tested"), summary=doc.get(d, "summary", "diagnosis", str),
                     rms=doc.size(d, "rms_m", "diagnosis"), untestable=names("untestable"),
                     refitted=names("refitted"))


@accepts(result=is_a(CalibrationResult))
def result_to_json(result: CalibrationResult) -> str:
    """The result file text of a CalibrationResult (its diagnosis under the ``diagnosis`` key).

    Parameters
    ----------
    {result}

    Returns
    -------
    str
        The JSON text.
    """
    return to_json(result_to_dict(result))


@accepts(result=is_a(CalibrationResult), path=PATH, per_pose=FLAG)
def result_files(result: CalibrationResult, path, *, per_pose: bool = True) -> dict:
    """The files of a calibration result: ``{path: JSON text, sidecar: bytes}``.

    The JSON holds the summary, estimates, covariance, checks and statistics; the per-pose arrays
    (errors before and after, residual vectors, measured positions, readings, per pose) go to a
    NumPy ``.npz`` archive beside it (:func:`sidecar_path`), named with its SHA-256 in
    ``errors.file``, so that the JSON does not grow with the campaign (docs/formats.md).

    Parameters
    ----------
    result : CalibrationResult
    path : str or Path
        The result file (``result.json``).
    per_pose : bool
        False leaves the per-pose arrays out altogether (no sidecar; the report then has no
        per-pose plots).

    Returns
    -------
    dict
        {Path: str or bytes}, to write together (``write_texts``).
    """
    d = result_to_dict(result, per_pose=False)
    counts = {"n_fit": int(result.fit.errors_before.shape[0]),
              "n_validation": None if result.validation is None else int(result.validation.errors_before.shape[0])}
    if not per_pose:
        d["errors"]["file"] = None
        d["errors"].update(counts)
        return {Path(path): to_json(d)}
    buf = io.BytesIO()
    arrays: dict[str, Any] = per_pose_arrays(result)
    np.savez(buf, **arrays)
    blob = buf.getvalue()
    sidecar = sidecar_path(path)
    d["errors"]["file"] = {"name": sidecar.name, "format": "npz", "sha256": hashlib.sha256(blob).hexdigest(),
                           **counts}
    return {Path(path): to_json(d), sidecar: blob}


@accepts(result=is_a(CalibrationResult), path=PATH, force=FLAG, per_pose=FLAG)
def write_result(result: CalibrationResult, path, *, force: bool = False, per_pose: bool = True) -> None:
    """Write a calibration result, atomically: the JSON at ``path`` and its per-pose arrays beside it
    (:func:`result_files`); an existing file is an InputError unless ``force``.

    Parameters
    ----------
    {result, path, force, per_pose}

    Returns
    -------
    None
    """
    write_texts(result_files(result, path, per_pose=per_pose), force=force)


class _Doc:
    """Typed access to a parsed result document; every error names the source and the key path."""

    def __init__(self, source: str):
        self.source = source

    def error(self, where: str, message: str) -> InputError:
        return InputError(message, source=self.source, where=where)

    def get(self, d: dict, key: str, where: str, kind, *, optional: bool = False):
        path = f"{where}.{key}" if where else key
        if key not in d:
            if optional:
                return None
            raise self.error(path, "missing key")
        v = d[key]
        if v is None and optional:
            return None
        if kind is float:
            return self.number(v, path)
        if kind is int and not (isinstance(v, int) and not isinstance(v, bool)):
            raise self.error(path, f"expected a whole number, got {excerpt(v)}")
        if kind is not int and not isinstance(v, kind):
            raise self.error(path, f"expected {_KIND_NAMES.get(kind, kind.__name__)}, got {excerpt(v)}")
        return v

    def size(self, d: dict, key: str, where: str, *, optional: bool = False):
        """A figure that is never negative (a standard deviation, an RMS, an error's size); null reads as NaN."""
        v = self.get(d, key, where, float, optional=optional)
        if v is not None and v < 0:
            raise self.error(f"{where}.{key}" if where else key, f"{key} is never negative, got {v:g}")
        return v

    def number(self, v, where: str) -> float:
        """A float; null reads as NaN (how the writer stores non-finite values)."""
        if v is None:
            return float("nan")
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise self.error(where, f"expected a number, got {excerpt(v)}")
        return float(v)

    def strings(self, v, where: str) -> tuple[str, ...]:
        if not isinstance(v, list) or not all(isinstance(s, str) for s in v):
            raise self.error(where, f"expected a list of names, got {excerpt(v)}")
        return tuple(v)

    def array(self, v, where: str, shape: tuple) -> np.ndarray:
        """A nested list of numbers (null for NaN) of ``shape`` (None in a dimension: any size)."""
        try:
            a = np.array(v, dtype=float)
        except (TypeError, ValueError):
            raise self.error(where, "expected a nested list of numbers") from None
        if a.size == 0 and a.ndim == 1 and len(shape) > 1:
            a = a.reshape((0,) + tuple(s or 0 for s in shape[1:]))
        if a.ndim != len(shape) or any(s is not None and s != n for s, n in zip(shape, a.shape)):
            want = " x ".join("n" if s is None else str(s) for s in shape)
            raise self.error(where, f"expected an array of shape {want}, got shape {a.shape}")
        return a


_KIND_NAMES = {dict: "a mapping", list: "a list", str: "text", bool: "true or false"}


def _identifiability(doc: _Doc, d: dict) -> IdentifiabilityResult:
    w = "identifiability"
    eliminated = []
    for we, e in _mappings(doc, doc.get(d, "eliminated", w, list), f"{w}.eliminated"):
        terms = [(doc.get(t, "name", wt, str), doc.get(t, "coefficient", wt, float))
                 for wt, t in _mappings(doc, doc.get(e, "absorbed_by", we, list), f"{we}.absorbed_by")]
        eliminated.append(Absorption(doc.get(e, "name", we, str), doc.get(e, "reason", we, str), tuple(terms),
                                     doc.get(e, "residual", we, float)))
    obs = doc.get(d, "observability", w, dict)
    return IdentifiabilityResult(
        candidates=doc.strings(doc.get(d, "candidates", w, list), f"{w}.candidates"),
        identified=doc.strings(doc.get(d, "identified", w, list), f"{w}.identified"),
        eliminated=tuple(eliminated), tol=doc.get(d, "tol", w, float), rank=doc.get(d, "rank", w, int),
        condition_number=doc.get(d, "condition_number", w, float),
        singular_values=tuple(doc.number(v, f"{w}.singular_values") for v in doc.get(d, "singular_values", w, list)),
        observability={str(k): doc.number(v, f"{w}.observability.{k}") for k, v in obs.items()},
        n_rows=doc.get(d, "n_rows", w, int))


def _stats(doc: _Doc, d: dict, where: str = "stats") -> ErrorSummary:
    def one(key: str, optional: bool = False) -> ErrorStats | None:
        s = doc.get(d, key, where, dict, optional=optional)
        if s is None:
            return None             # the nominal as given: not in files written before it
        w = f"{where}.{key}"
        n = doc.get(s, "n", w, int)
        if n < 0:
            raise doc.error(f"{w}.n", f"expected a count, got {n}")
        vals = {f: (doc.size(s, f, w, optional=True) if n else None) for f in ("mean", "std", "rms", "max")}
        return ErrorStats(n=n, **{f: (None if v is None or math.isnan(v) else v) for f, v in vals.items()})

    return ErrorSummary(*(cast(ErrorStats, one(key)) for key in ErrorSummary.KEYS),
                        *(one(key, optional=True) for key in NOMINAL_KEYS))


def _solver(doc: _Doc, d: dict) -> SolverRecord:
    """The solver's record; its residual degrees of freedom are stored with contacts only (else 0)."""
    dof = contact_residual_dof(doc, doc.get(d, "contacts", "", dict, optional=True))
    return SolverRecord(success=doc.get(d, "success", "", bool), status=doc.get(d, "status", "", int),
                        message=doc.get(d, "message", "", str), nfev=doc.get(d, "nfev", "", int),
                        loss=doc.get(d, "loss", "", str), sigma0=doc.size(d, "sigma0_m", ""), residual_dof=dof)


def _limit_judgement(doc: _Doc, d: dict | None) -> LimitJudgement | None:
    if d is None:
        return None
    w = "limit"
    return LimitJudgement(limit_m=doc.get(d, "limit_m", w, float), compared=doc.get(d, "compared", w, str),
                          mean_error_m=doc.get(d, "mean_error_m", w, float), ratio=doc.get(d, "ratio", w, float),
                          reached=doc.get(d, "reached", w, bool))


def _mappings(doc: _Doc, items: list, where: str):
    """(key path, mapping) for each item of a list that must hold mappings."""
    for i, item in enumerate(items):
        w = f"{where}[{i}]"
        if not isinstance(item, dict):
            raise doc.error(w, f"expected a mapping, got {excerpt(item)}")
        yield w, item


def _provenance(doc: _Doc, prov: dict) -> dict:
    """Scalars (software, version, date...) and inputs ({source, sha256, n_poses, labels})."""
    for key, v in prov.items():
        w = f"provenance.{key}"
        if isinstance(v, dict):
            for field, kind in (("source", str), ("sha256", str), ("n_poses", int), ("labels", list)):
                doc.get(v, field, w, kind, optional=True)
            if v.get("n_poses") is not None and v["n_poses"] < 0:
                raise doc.error(f"{w}.n_poses", f"expected a count, got {v['n_poses']}")
            if v.get("labels") is not None:
                doc.strings(v["labels"], f"{w}.labels")
        elif v is not None and (isinstance(v, (list, dict)) or not isinstance(v, (str, int, float))):
            raise doc.error(w, f"expected text or a number, got {excerpt(v)}")
    return prov


def _checks(doc: _Doc, d: list) -> tuple[Check, ...]:
    out = []
    for w, c in _mappings(doc, d, "checks"):
        status = doc.get(c, "status", w, str)
        if status not in STATUSES:
            raise doc.error(f"{w}.status", f"expected one of {', '.join(STATUSES)}, got {excerpt(status)}")
        out.append(Check(name=doc.get(c, "name", w, str), status=status, summary=doc.get(c, "summary", w, str),
                         cause=doc.get(c, "cause", w, str), fix=doc.get(c, "fix", w, str),
                         items=doc.strings(doc.get(c, "items", w, list), f"{w}.items")))
    return tuple(out)


def _verdict(doc: _Doc, d: dict, checks: tuple[Check, ...]) -> None:
    """The verdict a file states is one of pass, warn, fail, and the one its checks give (the worst):
    what reads the file (a report, the store) takes the checks' word, so a file saying otherwise was
    edited or is damaged."""
    stated = doc.get(d, "verdict", "", str, optional=True)
    if stated is None:
        return
    if stated not in STATUSES:
        raise doc.error("verdict", f"expected one of {', '.join(STATUSES)}, got {excerpt(stated)}")
    if stated != verdict(checks):
        raise doc.error("verdict", f"says {stated}, but its checks give {verdict(checks)} (the worst of them): the "
                                   "file was edited or is damaged; write it again from the calibration")


def _parameters(doc: _Doc, d: list, nominal) -> tuple[ParameterEstimate, ...]:
    lay = parameter_layout(nominal)
    out = []
    for w, p in _mappings(doc, d, "parameters"):
        name = doc.get(p, "name", w, str)
        if name not in lay:
            raise doc.error(f"{w}.name", f"{excerpt(name)} is not a parameter of the nominal model")
        out.append(ParameterEstimate(name, doc.get(p, "unit", w, str), doc.get(p, "nominal", w, float),
                                     doc.get(p, "estimate", w, float), doc.size(p, "std", w),
                                     family=lay[name].family, quantity=lay[name].quantity))
    return tuple(out)


def _sidecar(doc: _Doc, d: dict, folder: Path | None) -> dict | None:
    """The per-pose arrays of ``errors.file`` (the sidecar beside the result file), checked against
    its SHA-256; None when the arrays are inline."""
    if "file" not in d:
        return None
    ref = doc.get(d, "file", "errors", dict, optional=True)
    if ref is None:
        return {}  # left out on request
    name = doc.get(ref, "name", "errors.file", str)
    if folder is None or Path(name).name != name or not name.endswith(".npz"):
        raise doc.error("errors.file.name", f"cannot read the per-pose arrays {excerpt(name)} here (a file name "
                                            "beside the result file, ending .npz)")
    path = folder / name
    raw = read_bytes(path, limit=MAX_FILE_BYTES * 16, text=False, regular=True)  # (4 GB of a stream: no)
    if hashlib.sha256(raw).hexdigest() != doc.get(ref, "sha256", "errors.file", str):
        raise InputError("is not the per-pose file of this result (its SHA-256 differs from the one in "
                         f"{doc.source}); write them again together", source=str(path))
    try:
        with np.load(io.BytesIO(raw), allow_pickle=False) as z:
            out = {k: z[k] for k in z.files}
    except (ValueError, OSError, zipfile.BadZipFile, KeyError, EOFError):
        raise InputError("not a NumPy .npz archive of arrays", source=str(path)) from None
    for k, a in out.items():
        if a.dtype.kind != "f":
            raise InputError(f"array {excerpt(k)} is not of floating point numbers", source=str(path))
    return out


def _errors(doc: _Doc, d: dict, n_markers: int, n_joints: int, folder: Path | None = None
            ) -> tuple[PoseSet, PoseSet | None]:
    """The fitted and held-out poses' arrays (inline, or in the sidecar ``errors.file``); every
    set's arrays agree in their number of poses."""
    stored = _sidecar(doc, d, folder)
    if stored is not None:
        known = {key for key, _, _ in _ERROR_ARRAYS}
        extra = sorted(set(stored) - known)
        if extra:
            raise doc.error("errors.file", f"the per-pose file holds an unknown array {excerpt(extra[0])}")
        if not stored:  # left out: no poses to show
            stored = {"fit_before": np.empty((0, n_markers)), "fit_after": np.empty((0, n_markers)),
                      "fit_residual_vectors": np.empty((0, n_markers, 3))}
        d = {**d, **stored}
    shapes = {"before": (n_markers,), "after": (n_markers,), "residual_vectors": (n_markers, 3),
              "positions": (n_markers, 3), "readings": (n_joints,), "rotation_before": (n_markers,),
              "rotation_after": (n_markers,)}
    required = {"fit_before", "fit_after", "fit_residual_vectors"}
    out: dict[str, np.ndarray | None] = {}
    n_poses: dict[str, int] = {}
    for key, which, _ in _ERROR_ARRAYS:
        part = key.removeprefix(f"{which}_")
        value = d.get(key) if stored is not None else doc.get(d, key, "errors", list, optional=key not in required)
        if value is None and key in required:
            raise doc.error(f"errors.{key}", "missing array")
        if value is None:
            out[key] = None
            continue
        a = doc.array(value, f"errors.{key}", (n_poses.get(which),) + shapes[part])
        far = np.abs(a) > MAX_MAGNITUDE  # NaN compares False: a point not measured
        if far.any():
            raise doc.error(f"errors.{key}", f"{a[far].flat[0]:g} is beyond any error, position or reading "
                                             f"(magnitude up to {MAX_MAGNITUDE:g}, SI)")
        n_poses.setdefault(which, a.shape[0])
        out[key] = a
    if out["fit_positions"] is None:
        out["fit_positions"] = np.full(cast(np.ndarray, out["fit_residual_vectors"]).shape, np.nan)
    held = [key for key, which, _ in _ERROR_ARRAYS if which == "validation" and out[key] is not None]
    if held and (out["validation_before"] is None or out["validation_after"] is None):
        raise doc.error("errors", "validation_before and validation_after must both be given or both be null (and "
                                  "null with every other validation array)")
    def pose_set(which: str) -> PoseSet:
        return PoseSet(**cast("dict[str, Any]", {field: out[key] for key, w, field in _ERROR_ARRAYS if w == which}))

    return pose_set("fit"), pose_set("validation") if held else None


@accepts(source=TEXT, folder=optional(PATH))
def result_from_dict(d, *, source: str = "<dict>", folder=None) -> CalibrationResult:
    """The CalibrationResult stored in ``d`` (the parsed result file); InputError naming the key
    where it departs from the schema. ``folder``: where its per-pose file (``errors.file``) is.

    Parameters
    ----------
    d : dict
        A result as ``result_to_dict`` gives it (the parsed JSON file).
    {source, folder}

    Returns
    -------
    CalibrationResult
        The stored result.
    """
    doc = _Doc(source)
    if not isinstance(d, dict) or "schema" not in d:
        raise doc.error("schema", "not a robocal result: no 'schema' key")
    if d["schema"] not in SCHEMAS:
        raise doc.error("schema", f"unknown schema {excerpt(d['schema'])}; this robocal reads {', '.join(SCHEMAS)}")
    nominal = model_from_dict(doc.get(d, "nominal_model", "", dict), source=f"{source}: nominal_model")
    calibrated = model_from_dict(doc.get(d, "calibrated_model", "", dict), source=f"{source}: calibrated_model")
    params = _parameters(doc, doc.get(d, "parameters", "", list), nominal)
    k = len(params)
    errors = doc.get(d, "errors", "", dict)
    markers = doc.strings(doc.get(errors, "markers", "errors", list), "errors.markers")
    if markers != nominal.marker_names:
        raise doc.error("errors.markers", f"the markers {list(markers)} are not the nominal model's "
                                          f"{list(nominal.marker_names)}")
    stats = doc.get(d, "stats", "", dict)
    rotation = doc.get(stats, "rotation", "stats", dict, optional=True)
    ident = _identifiability(doc, doc.get(d, "identifiability", "", dict))
    fit, validation = _errors(doc, errors, len(markers), nominal.n_joints, None if folder is None else Path(folder))
    checks = _checks(doc, doc.get(d, "checks", "", list, optional=True) or [])
    _verdict(doc, d, checks)
    return CalibrationResult(
        nominal_model=nominal, calibrated_model=calibrated, parameters=params,
        covariance=doc.array(doc.get(d, "covariance", "", list), "covariance", (k, k)),
        correlation=doc.array(doc.get(d, "correlation", "", list), "correlation", (k, k)),
        identifiability=ident, solver=_solver(doc, d),
        families=doc.strings(doc.get(d, "families", "", list), "families"), fit=fit, validation=validation,
        stats=_stats(doc, stats), rotation_stats=None if rotation is None else _stats(doc, rotation, "stats.rotation"),
        contacts=contacts_from_dict(doc, doc.get(d, "contacts", "", dict, optional=True), ident),
        notes=doc.strings(doc.get(d, "notes", "", list), "notes"),
        limit=_limit_judgement(doc, doc.get(d, "limit", "", dict, optional=True)),
        checks=checks, in_use=_in_use(doc, doc.get(d, "in_use", "", dict, optional=True)),
        provenance=_provenance(doc, doc.get(d, "provenance", "", dict, optional=True) or {}),
        diagnosis=_diagnosis(doc, doc.get(d, "diagnosis", "", dict, optional=True)))


@accepts(path=PATH)
def read_result(path) -> CalibrationResult:
    """The CalibrationResult stored by ``write_result``; InputError if it is not a robocal result of a
    known schema, naming the key that departs from it. A folder reads its ``result.json`` (the
    folder ``robocal calibrate --out`` writes).

    Parameters
    ----------
    {path}

    Returns
    -------
    CalibrationResult
        The stored result.
    """
    if Path(path).is_dir():
        if not (Path(path) / "result.json").is_file():
            raise InputError("is a folder without a result.json (give the result file, or the folder robocal "
                             "calibrate --out wrote)", source=str(path))
        path = Path(path) / "result.json"
    source = str(path)
    text = read_text(path)[0]
    refuse_other_form(text, source, "a calibration's result (result.json)", ("result", "json"))
    return result_from_dict(load_json(text, source), source=source, folder=Path(path).parent)


# -- the limit of absolute accuracy ------------------------------------------------------------

def _pose_id(pose):
    """A pose id as a JSON type (numpy scalars become Python ones)."""
    pose = pose.item() if isinstance(pose, np.generic) else pose
    return pose if isinstance(pose, (str, int)) else str(pose)


def _repeatability_dict(r: RepeatabilityResult) -> dict:
    def pose(p: PoseRepeatability) -> dict:
        return {"pose": _pose_id(p.pose), "n_cycles": p.n_cycles, "barycentre": list(p.barycentre), "l": list(p.l),
                "l_mean": p.l_mean, "s_l": p.s_l, "rp": p.rp}
    return {"rp": r.rp, "worst_pose": _pose_id(r.worst_pose), "poses": [pose(p) for p in r.poses]}


def _precision_dict(p: PrecisionResult) -> dict:
    return {"statistic": "mean", "n_samples": p.n_samples, "mean": p.mean, "std": p.std,
            "standard_error": p.standard_error, "rms": p.rms, "rms_standard_error": p.rms_standard_error,
            "percentiles": {f"p{pct:g}": v for pct, v in p.percentiles}, "max": p.max,
            "encoder_resolution": list(p.encoder_resolution), "length_quantum": p.length_quantum,
            "angle_quantum": p.angle_quantum, "markers": p.markers, "rounded_parameters": list(p.rounded_parameters),
            "method": p.method}


@accepts(limit=is_a(AccuracyLimit))
def limit_to_dict(limit: AccuracyLimit) -> dict:
    """The file form of the limit of absolute accuracy (metres).

    Parameters
    ----------
    limit : AccuracyLimit
        The limit of absolute accuracy.

    Returns
    -------
    dict
        The limit as its JSON record holds it.
    """
    return {"schema": LIMIT_SCHEMA, "unit": "m", "limit": limit.limit, "limit_p95": limit.limit_p95,
            "repeatability": limit.repeatability, "precision": limit.precision,
            "precision_p95": limit.precision_p95, "precision_statistic": limit.precision_statistic,
            "repeatability_detail": None if limit.repeatability_detail is None
            else _repeatability_dict(limit.repeatability_detail),
            "precision_detail": _precision_dict(limit.precision_detail)}
