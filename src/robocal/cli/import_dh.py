"""``robocal import-dh``: a robocal model file from a classic or modified DH table."""

from __future__ import annotations

from .._base.errors import InputError
from . import common

EXAMPLE = """example:
  robocal import-dh examples/dh/ur5-dh.csv --out ur5.yaml

A table with columns name, joint (revolute or prismatic), theta, d, a, alpha, each with its
unit suffix (theta_deg, d_mm, ...), and optionally lower/upper limits, is classic DH or modified
DH in Craig's layout: say which (--convention, or a '# convention: classic' line); a 'base' row
(joint 'base': x, y, z, roll, pitch, yaw) places DH frame 0 in the measurement frame, and
'marker' rows place measured points in the last DH frame. robocal's own modified DH table
(frame, parent, reading, beta, alpha, d, theta, r, ...) is what 'robocal export --format mdh-csv'
writes. docs/formats.md has them all."""


def register(sub) -> None:
    p = common.command(sub, "import-dh", summary="write a robocal model file from a classic or modified DH table",
                       description="Convert a DH table (classic, modified in Craig's layout, or robocal's modified "
                                   "table) into a robocal model file (modified DH with Hayati's beta where axes are "
                                   "parallel).",
                       example=EXAMPLE, inputs=[("table", "TABLE.csv", "DH table")])
    common.imported_model_options(p)
    p.add_argument("--name", help="robot name (default: the table's file name)")
    p.add_argument("--convention", choices=("classic", "modified"),
                   help="what a theta, d, a, alpha table is: classic DH, or modified DH in Craig's layout "
                        "(alpha and a of the frame before on each row); default: the table's '# convention:' line")
    p.set_defaults(func=run)


def run(args) -> int:
    from .._files.dh import read_dh_table

    common.refuse_existing([args.out], args.force)
    try:
        model = read_dh_table(args.table, name=args.name, convention=args.convention)
    except InputError as e:
        if e.source is None:  # the model's own checks (e.g. its size) know no file
            raise InputError(e.detail, source=args.table, where=e.where) from None
        raise
    common.write_imported_model(args, model, "", source=args.table)
    return 0
