"""The ``contacts`` part of a result file: what a calibration that fitted contacts adds to its
result (``ContactFigures``), written and read back checked key by key (docs/formats.md).

The reader takes the result reader's document (its typed access names the file and the key path of
any departure from the schema)."""

from __future__ import annotations

import numpy as np

from .._identification.contact_figures import ContactErrors, ContactFigures
from .._identification.identifiability import ContactIdentifiability, IdentifiabilityResult, Unreachable

# the figures of a ``ContactErrors`` by their file keys (SI), and the summaries written beside them
_FIGURES = (("spread_m", "spread"), ("distance_error_m", "distance"), ("plane_rms_m", "plane"),
            ("bar_error_m", "bar"))
_SUMMARIES = (("consistency_mean_m", "consistency_mean"), ("consistency_max_m", "consistency_max"),
              ("spacing_error_mean_m", "spacing_mean"), ("spacing_error_max_m", "spacing_max"))
_SETS = (("fit_before", "fit_before"), ("fit_after", "fit_after"), ("validation_before", "validation_before"),
         ("validation_after", "validation_after"), ("held_out_by_placement_before", "held_out_before"),
         ("held_out_by_placement", "held_out"))


def _errors_dict(e: ContactErrors | None) -> dict | None:
    if e is None:
        return None
    return {**{key: dict(getattr(e, name)) for key, name in _FIGURES},
            "consistency_m": {k: {"mean": m, "max": x} for k, (m, x) in e.consistency.items()},
            "seatings_m": {k: np.asarray(v).tolist() for k, v in e.seatings.items()},
            **{key: getattr(e, name) for key, name in _SUMMARIES}}


def contacts_to_dict(c: ContactFigures | None, residual_dof: float) -> dict | None:
    """The file form of a result's ``contacts`` (None without contacts); ``residual_dof`` the fit's
    (the solver's), stored with them."""
    if c is None:
        return None
    ident = c.identifiability
    return {
        "source": c.source, "rows": dict(c.rows),
        "contributions": {k: list(v) for k, v in ident.contributions.items()}, "together": list(ident.together),
        "lost_without": {k: list(v) for k, v in ident.lost_without.items()},
        "unreachable": [{"name": u.name, "reason": u.reason, "components": list(u.components), "residual": u.residual}
                        for u in ident.unreachable],
        "nuisance": {k: {"estimate": v[0], "std": v[1]} for k, v in c.nuisance.items()},
        **{key: _errors_dict(getattr(c, name)) for key, name in _SETS},
        "noise_ratio": dict(c.noise_ratio),
        "weak": [{"name": n, "predicted_std": s} for n, s in c.weak], "weak_kept": c.weak_kept,
        "residual_dof": residual_dof,
    }


def _numbers(doc, d: dict, where: str) -> dict:
    """A mapping of names to numbers."""
    return {str(k): doc.number(v, f"{where}.{k}") for k, v in d.items()}


def _names_by_key(doc, d: dict, where: str) -> dict:
    return {str(k): doc.strings(v, f"{where}.{k}") for k, v in d.items()}


def _pairs(doc, d: dict, where: str, a: str, b: str) -> dict:
    """A mapping of names to mappings of two numbers ``a`` and ``b``, as name -> (a, b)."""
    out = {}
    for k, v in d.items():
        w = f"{where}.{k}"
        if not isinstance(v, dict):
            raise doc.error(w, f"expected a mapping of {a} and {b}")
        out[str(k)] = (doc.get(v, a, w, float), doc.get(v, b, w, float))
    return out


def _errors(doc, d: dict | None, where: str) -> ContactErrors | None:
    if d is None:
        return None
    figures = {name: _numbers(doc, doc.get(d, key, where, dict), f"{where}.{key}") for key, name in _FIGURES}
    consistency = _pairs(doc, doc.get(d, "consistency_m", where, dict), f"{where}.consistency_m", "mean", "max")
    seatings = {str(k): doc.array(v, f"{where}.seatings_m.{k}", (None,))
                for k, v in doc.get(d, "seatings_m", where, dict).items()}
    for k, a in seatings.items():
        if a.size == 0 or not np.isfinite(a).all() or (a < 0).any():
            raise doc.error(f"{where}.seatings_m.{k}", "expected distances: finite numbers of at least 0, one or more")
    return ContactErrors(**figures, consistency=consistency, seatings=seatings)


def contacts_from_dict(doc, d: dict | None, identifiability: IdentifiabilityResult) -> ContactFigures | None:
    """The ``ContactFigures`` of a result file's ``contacts`` (None when absent); ``doc`` the result
    reader's document, ``identifiability`` the result's own (the robot's parameters), which becomes
    the analysis of what the contacts reach."""
    if d is None:
        return None
    w = "contacts"
    unreachable = []
    for i, u in enumerate(doc.get(d, "unreachable", w, list)):
        wu = f"{w}.unreachable[{i}]"
        if not isinstance(u, dict):
            raise doc.error(wu, "expected a mapping")
        unreachable.append(Unreachable(doc.get(u, "name", wu, str), doc.get(u, "reason", wu, str),
                                       doc.strings(doc.get(u, "components", wu, list), f"{wu}.components"),
                                       doc.get(u, "residual", wu, float)))
    ident = ContactIdentifiability(
        analysis=identifiability, identified=identifiability.identified, eliminated=identifiability.eliminated,
        contributions=_names_by_key(doc, doc.get(d, "contributions", w, dict), f"{w}.contributions"),
        together=doc.strings(doc.get(d, "together", w, list), f"{w}.together"), unreachable=tuple(unreachable),
        lost_without=_names_by_key(doc, doc.get(d, "lost_without", w, dict), f"{w}.lost_without"))
    nuisance = _pairs(doc, doc.get(d, "nuisance", w, dict), f"{w}.nuisance", "estimate", "std")
    weak = []
    for i, v in enumerate(doc.get(d, "weak", w, list)):
        ww = f"{w}.weak[{i}]"
        if not isinstance(v, dict):
            raise doc.error(ww, "expected a mapping of name and predicted_std")
        weak.append((doc.get(v, "name", ww, str), doc.get(v, "predicted_std", ww, str)))
    rows = {}
    counts = doc.get(d, "rows", w, dict)
    for k in counts:
        n = doc.get(counts, k, f"{w}.rows", int)
        if n < 0:
            raise doc.error(f"{w}.rows.{k}", f"expected a count, got {n}")
        rows[str(k)] = n
    sets = {name: _errors(doc, doc.get(d, key, w, dict, optional=name not in ("fit_before", "fit_after")),
                          f"{w}.{key}") for key, name in _SETS}
    fit_before, fit_after = sets.pop("fit_before"), sets.pop("fit_after")
    if fit_before is None or fit_after is None:
        raise doc.error(f"{w}.fit_before", "missing figures")
    return ContactFigures(identifiability=ident, nuisance=nuisance, fit_before=fit_before, fit_after=fit_after, **sets,
                          noise_ratio=_numbers(doc, doc.get(d, "noise_ratio", w, dict), f"{w}.noise_ratio"),
                          weak=tuple(weak), weak_kept=doc.get(d, "weak_kept", w, bool), rows=rows,
                          source=doc.get(d, "source", w, str))


def contact_residual_dof(doc, d: dict | None) -> float:
    """The fit's residual degrees of freedom a result file's ``contacts`` holds (0 without them, or
    in a file written before they were stored)."""
    if d is None:
        return 0.0
    return doc.get(d, "residual_dof", "contacts", float, optional=True) or 0.0
