"""``robocal import-urdf``: a robocal model file from the chain of a URDF file."""

from __future__ import annotations

from pathlib import Path

from .._base.errors import InputError
from . import common

EXAMPLE = """example:
  robocal import-urdf examples/urdf/gen3_like.urdf --out gen3.yaml --marker-mm tcp,0,0,120

Without --tip-link the chain ends where the arm ends: branches of fixed links only (a flange, a
tool point) are not branches, and joints beyond the point where a gripper's fingers part are
not imported. The command says at which link the chain ended and why, and names the links
further down (through fixed joints: a ball, a tool) that --tip-link could end it at."""

def register(sub) -> None:
    p = common.command(sub, "import-urdf", summary="write a robocal model file from a URDF serial chain",
                       description="Convert the chain of a URDF file (metres and radians by the URDF rule) "
                                   "into a robocal model file (modified DH with Hayati's beta).",
                       example=EXAMPLE, inputs=[("urdf", "URDF", "URDF file")])
    common.imported_model_options(p)
    p.add_argument("--base-link", help="first link of the chain (default: the root link)")
    p.add_argument("--tip-link", help="last link of the chain (default: where the arm ends, below)")
    p.add_argument("--marker-mm", action="append", type=common.marker_mm, metavar="NAME,X,Y,Z",
                   help="a measured point in the tip link's frame, mm (repeatable; default: the tip link "
                        "itself, named after it, when the chain ends in fixed joints, else one marker "
                        "'tool' at the tip link's origin)")
    p.set_defaults(func=run)


def run(args) -> int:
    from .._files.urdf import chain_end, read_urdf

    common.refuse_existing([args.out], args.force)
    if not Path(args.urdf).is_file():
        raise InputError("no such file", source=args.urdf)
    try:
        model = read_urdf(args.urdf, base_link=args.base_link, tip_link=args.tip_link, markers=args.marker_mm)
    except InputError as e:
        if e.where in ("base_link", "tip_link"):   # name the option as the user types it
            flag = "--" + e.where.replace("_", "-")
            raise InputError(e.detail.replace(e.where.replace("_", " "), flag), source=e.source, where=flag) from None
        if e.source is None:  # the model's own checks (e.g. its size) know no file
            raise InputError(e.detail, source=args.urdf, where=e.where) from None
        raise
    common.write_imported_model(args, model, f"{len(model.frames)} frames, ", source=args.urdf)
    print(_end_line(chain_end(args.urdf, base_link=args.base_link)) if args.tip_link is None else
          f"the chain ends at link {args.tip_link!r} (--tip-link)")
    return 0


def _end_line(end) -> str:
    """Where the chain ended and why; the links further down that could end it, as --tip-link."""
    line = f"the chain ends at link {end.link!r}: {end.reason}"
    if end.further:
        shown = ", ".join(end.further[:5]) + (f" and {len(end.further) - 5} more" if len(end.further) > 5 else "")
        line += (f"; to end at a link further down give --tip-link NAME (links below it through fixed joints: "
                 f"{shown})")
    return line
