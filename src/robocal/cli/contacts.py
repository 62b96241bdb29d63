"""``robocal calibrate --contacts``: calibration from joint-only contact recordings, alone or with a
tracker file (docs/cli.md)."""

from __future__ import annotations

import json
from pathlib import Path

from .._errors import DegenerateDataError, InputError
from . import common

FAILED = 3


def _record(result, args) -> dict:
    """What calibrated.yaml says of its calibration from contacts (see ``calibration_record``)."""
    from datetime import datetime, timezone

    data = str(args.contacts) + (f" and {args.csv}" if args.csv else "")
    return {"verdict": result.verdict, "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "data": data, "families": list(args.parameters or ("geometric",)), "nominal": result.nominal_model.name}


def _result_json(result) -> str:
    """The parameters, the analysis, the kit's figures and the checks, SI (keys say the units)."""
    ident = result.identifiability

    def figures(e):
        return None if e is None else {
            "spread_m": e.spread, "distance_error_m": e.distance, "plane_rms_m": e.plane, "bar_error_m": e.bar,
            "consistency_m": {k: {"mean": m, "max": x} for k, (m, x) in e.consistency.items()},
            "consistency_mean_m": e.consistency_mean, "consistency_max_m": e.consistency_max,
            "spacing_error_mean_m": e.spacing_mean, "spacing_error_max_m": e.spacing_max}

    out = {
        "robocal_contacts_result": 1, "verdict": result.verdict,
        "parameters": [{"name": p.name, "unit": p.unit, "nominal": p.nominal, "estimate": p.estimate, "std": p.std}
                       for p in result.parameters],
        "identified": list(ident.identified),
        "eliminated": [{"name": a.name, "reason": a.reason, "absorbers": [list(t) for t in a.absorbers]}
                       for a in ident.eliminated],
        "contributions": {k: list(v) for k, v in ident.contributions.items()}, "together": list(ident.together),
        "lost_without": {k: list(v) for k, v in ident.lost_without.items()},
        "unreachable": [{"name": u.name, "reason": u.reason, "components": list(u.components)}
                        for u in ident.unreachable],
        "nuisance": {k: {"estimate": v[0], "std": v[1]} for k, v in result.nuisance.items()},
        "fit_before": figures(result.fit_before), "fit_after": figures(result.fit_after),
        "validation_before": figures(result.validation_before), "validation_after": figures(result.validation_after),
        "held_out_by_placement": figures(result.held_out),
        "weak": [{"name": n, "predicted_std": s} for n, s in result.weak], "weak_kept": result.weak_kept,
        "checks": [{"name": c.name, "status": c.status, "summary": c.summary} for c in result.checks],
    }
    return json.dumps(out, indent=1) + "\n"


def run(args) -> int:
    import numpy as np

    from .._calibration import calibrate
    from .._files.contacts import read_contacts
    from .._files.model import model_to_yaml, read_model
    from .._measurements import Noise
    from .._presentation.contacts import contact_summary

    for flag, value in (("--compare", args.compare), ("--validation", args.validation), ("--holdout", args.holdout),
                        ("--register-base", args.register_base),
                        ("--register-validation", args.register_validation), ("--diagnose", args.diagnose)):
        if value:
            raise InputError("is not available with --contacts (hold out placements with --holdout-placement)",
                             where=flag)
    out = Path(args.out)
    common.refuse_existing([out / "calibrated.yaml", out / "contacts-result.json"]
                           + ([out / "report.html"] if args.report else []), args.force)
    model = common.masses_as_asked(args, read_model(args.model))
    if args.backlash_side is not None:
        model = model.replace(backlash_side=args.backlash_side)
    contacts = read_contacts(args.contacts, model)
    validation = None
    if args.holdout_placement:
        missing = [p for p in args.holdout_placement if p not in contacts.placements()]
        if missing:
            raise InputError(f"no placement {missing[0]!r} (placements: {', '.join(contacts.placements())})",
                             source=args.contacts, where="--holdout-placement")
        contacts, validation = contacts.split_placements(args.holdout_placement)
    data = common.read_data(args, model, args.csv) if args.csv else None
    noise = Noise.of(args.instrument, position=None if args.noise_mm is None else args.noise_mm / common.MM,
                     rotation=None if args.noise_deg is None else args.noise_deg / common.DEG)
    try:
        result = calibrate(model, data, contacts=contacts, validation=validation,
                           parameters=args.parameters or ("geometric",), known=args.known, noise=noise, tol=args.tol,
                           loss=args.loss, on_outliers=args.on_outliers, weak=args.weak,
                           limit=None if args.limit_mm is None else args.limit_mm / common.MM,
                           nonnegative_compliance=args.nonnegative_compliance, folds=args.folds)
    except DegenerateDataError as e:
        raise DegenerateDataError(f"{args.contacts}: {e}") from None
    except np.linalg.LinAlgError as e:  # what the numbers leave of the fit is singular: the data's to fix
        raise DegenerateDataError(f"{args.contacts}: the fit is numerically singular on these contacts ({e})") \
            from None
    common.require_finite("the contact calibration", {f"{p.name} ({k})": v for p in result.parameters
                                                      for k, v in (("estimate", p.estimate), ("std", p.std))})
    print(contact_summary(result))
    files = {out / "contacts-result.json": _result_json(result)}
    failed = result.verdict == "fail"
    if not failed or args.write_failed:
        files[out / "calibrated.yaml"] = model_to_yaml(result.calibrated_model, units=args.out_units,
                                                       calibration=_record(result, args))
    if args.report:
        from .._presentation.html import render_contact_report

        files[out / "report.html"] = render_contact_report(result)
    common.write_outputs(files, force=args.force)
    print(f"wrote {', '.join(str(p) for p in files)}")
    return FAILED if failed else 0
