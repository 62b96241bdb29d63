"""``robocal import-urdf``: a robocal model file from the chain of a URDF file."""

from __future__ import annotations

from pathlib import Path

from .._errors import InputError
from . import common


def register(sub) -> None:
    p = sub.add_parser("import-urdf", help="write a robocal model file from a URDF serial chain",
                       description="Convert the chain of a URDF file (metres and radians by the URDF rule) "
                                   "into a robocal model file (modified DH with Hayati's beta).")
    p.add_argument("urdf", metavar="URDF", help="URDF file")
    p.add_argument("--out", required=True, metavar="MODEL.yaml", help="model file to write")
    p.add_argument("--base-link", help="first link of the chain (default: the root link)")
    p.add_argument("--tip-link", help="last link of the chain (default: the leaf of an unbranched chain)")
    p.add_argument("--marker-mm", action="append", type=common.marker_mm, metavar="NAME,X,Y,Z",
                   help="a measured point in the tip link's frame, mm (repeatable; default one marker "
                        "'tool' at the tip link's origin)")
    p.add_argument("--units", type=common.units, default="mm-deg", help="units of the written file (default mm-deg)")
    p.add_argument("--force", action="store_true", help="overwrite an existing file")
    p.set_defaults(func=run)


def run(args) -> int:
    from .._files.model import model_from_dict, model_to_dict, model_to_yaml
    from .._files.urdf import read_urdf

    common.refuse_existing([args.out], args.force)
    if not Path(args.urdf).is_file():
        raise InputError("no such file", source=args.urdf)
    model = read_urdf(args.urdf, base_link=args.base_link, tip_link=args.tip_link, markers=args.marker_mm)
    try:  # never write a model file robocal would then refuse to read
        model_from_dict(model_to_dict(model, units=args.units), source=args.out)
    except InputError as e:
        raise InputError(f"the model it gives cannot be written as a robocal model: {e.where or ''} {e.detail}",
                         source=args.urdf) from None
    common.write_outputs({args.out: model_to_yaml(model, units=args.units)}, force=args.force)
    print(f"{model.name}: {model.n_joints} joints ({', '.join(model.joint_names)}), {len(model.frames)} frames, "
          f"markers {', '.join(model.marker_names)}: wrote {args.out}")
    return 0
