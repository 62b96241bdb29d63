"""``robocal export``: a calibrated model in the forms a controller or planner takes."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from .._base.errors import InputError
from . import common

FORMATS = ("urdf", "mdh-csv", "dh-csv")
# the extension each format's file is named by
EXTENSION = {"urdf": ".urdf", "mdh-csv": ".csv", "dh-csv": ".csv"}

EXAMPLE = """examples:
  robocal export examples/th8/true_model.yaml --format urdf --out th8.urdf
  robocal export examples/th8/true_model.yaml --format mdh-csv --out th8-mdh.csv
  robocal export examples/th8/model.yaml --format dh-csv --out th8-dh.csv

urdf: one link per frame, each joint's origin the frame's constant transform (exact), a link per
marker. mdh-csv: the modified-DH table with Hayati's beta, the base and marker rows and the joint
limits. dh-csv: classic DH; refused where nearly parallel axes make it ill-conditioned (offsets of
hundreds of metres that cancel), unless --allow-ill-conditioned."""


def register(sub) -> None:
    p = common.command(sub, "export", summary="write a model as URDF or a DH table",
                       description="Write MODEL (a calibrated model file) as URDF, a modified-DH table or a classic "
                                   "DH table; each reproduces the model's forward kinematics.",
                       example=EXAMPLE, inputs=[("model", "MODEL", "model file (YAML), e.g. OUT/calibrated.yaml")])
    p.add_argument("--format", choices=FORMATS, help="what to write (default urdf for an --out ending in .urdf; a "
                                                     "table needs it: mdh-csv or dh-csv)")
    p.add_argument("--out", required=True, metavar="FILE", help="file to write (.urdf for urdf, .csv for a table; a "
                                                                "name of another kind (.yaml, .mod...) is refused)")
    p.add_argument("--units", type=common.units, default="mm-deg", help="units of a DH table (default mm-deg)")
    p.add_argument("--allow-ill-conditioned", action="store_true",
                   help="dh-csv: write even where nearly parallel axes need huge offsets (with a warning)")
    p.add_argument("--force", action="store_true", help="overwrite an existing file")
    p.set_defaults(func=run)


def _exported(args, model) -> str:
    """The text of ``model`` in ``args.format``; what its geometry refuses names the model file (and,
    for a classic DH table it makes ill-conditioned, the option that writes it anyway)."""
    from .._files.dh import dh_csv, mdh_csv
    from .._files.urdf import urdf_text

    writers = {"urdf": lambda: urdf_text(model), "mdh-csv": lambda: mdh_csv(model, units=args.units),
               "dh-csv": lambda: dh_csv(model, units=args.units,
                                        max_offset=float("inf") if args.allow_ill_conditioned else None)}
    try:
        return writers[args.format]()
    except InputError as e:
        if e.source is not None:
            raise
        hint = ", or --allow-ill-conditioned to write it anyway (with a warning)" if "ill-conditioned" in e.detail \
            else ""
        raise InputError(e.detail + hint, source=args.model, where=e.where) from None


def _left_out(model) -> str:
    """What of ``model`` no export carries ("" for nothing): compliance, backlash, transmission errors."""
    terms = [name for name, has in (("compliance", model.has_compliance), ("backlash", model.has_backlash),
                                    ("transmission errors (gear scales, harmonics)", model.has_transmission)) if has]
    if not terms:
        return ""
    verb = "are" if len(terms) > 1 or model.has_transmission else "is"
    return f"{', '.join(terms[:-1]) + ' and ' if len(terms) > 1 else ''}{terms[-1]} {verb} not exported"


def _moved(model, n: int = 1000) -> str:
    """How far the geometry alone puts the markers from where ``model`` puts them: the largest
    distance over ``n`` readings within the joint limits, so that the user can judge the export."""
    from .._files.checked import sample_readings, without_transmission
    from .._model.kinematics import evaluate

    q = sample_readings(model, n)
    full = evaluate(model, q).positions
    geometry = evaluate(without_transmission(model), q, compliance=False, backlash=False).positions
    gap = np.linalg.norm(full - geometry, axis=-1).max() * common.MM
    return (f"the markers ({', '.join(model.marker_names)}) up to {gap:.3g} mm from the model's ({n} readings "
            "within the joint limits)")


def run(args) -> int:
    from .._files.checked import check_export
    from .._files.model import read_model_and_record
    from .._model.conversion import to_standard_dh

    if args.format is None:
        if not args.out.lower().endswith(".urdf"):
            raise InputError("needed: urdf, mdh-csv (modified DH with Hayati's beta) or dh-csv (classic DH); only an "
                             "--out ending in .urdf says which", where="--format")
        args.format = "urdf"
    others = [f for f, ext in EXTENSION.items() if ext == Path(args.out).suffix.lower() and f != args.format]
    common.refuse_misnamed(args.out, "URDF" if args.format == "urdf" else "CSV", f"--format {args.format}",
                           f", or --format {' or '.join(others)}" if others else "")
    common.refuse_existing([args.out], args.force)
    model, record = read_model_and_record(args.model)
    common.warn_if_failed(args.model, record, f"the {args.format} file, which cannot say so, is written from")
    text = _exported(args, model)
    if args.format == "dh-csv":
        far = to_standard_dh(model, max_offset=float("inf")).offsets
        if far:
            print(f"robocal: warning: classic DH of {args.model} is ill-conditioned: offsets "
                  f"{', '.join(f'{n} {v:.3g} m' for n, v in far)}; rounding them moves the tool", file=sys.stderr)
    check_export(model, text, args.format, source=args.model)
    left_out = _left_out(model)
    if left_out:
        print(f"robocal: warning: {args.model}: {left_out}: {args.format} holds the geometry only, which puts "
              f"{_moved(model)}", file=sys.stderr)
    common.write_outputs({args.out: text}, force=args.force)
    print(f"{model.name}: {args.format} of {model.n_joints} joints, markers {', '.join(model.marker_names)}: "
          f"wrote {args.out}")
    return 0
