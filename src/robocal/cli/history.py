"""``robocal history``: a robot's calibrations and what changed, or robots of one type side by side."""

from __future__ import annotations

from .._base.errors import InputError
from . import common, record

EXAMPLE = """examples:
  robocal history SN-1042
  robocal history SN-1042 --report sn-1042.html
  robocal history --type th8

Changes between consecutive calibrations are judged against their combined uncertainty, at a threshold
that names a change in an unchanged robot's whole history in 5 % of robots (--alpha)."""


def register(sub) -> None:
    p = common.command(sub, "history", summary="a robot's calibrations and changes, or robots of one type",
                       description="Show a robot's calibrations, each parameter over time with its standard "
                                   "deviation and the changes between consecutive calibrations; or, with --type, "
                                   "the robots of one type side by side and which ones stand out.",
                       example=EXAMPLE, inputs=[("robot", "ROBOT", "the robot (or give --type)", "?")])
    p.add_argument("--type", dest="robot_type", type=common.checked_by(record._name("--type")), metavar="TYPE",
                   help="compare the robots of this type (their latest calibrations)")
    record.store_option(p)
    p.add_argument("--alpha", type=common.number_in(lambda v: 0 < v < 0.5, "a share between 0 and 0.5"),
                   default=0.05, help="the chance of naming a change in an unchanged robot (default 0.05)")
    p.add_argument("--report", metavar="FILE.html", help="also write the robot's history report (needs "
                                                         "robocal[report])")
    p.add_argument("--force", action="store_true", help="overwrite an existing report")
    p.set_defaults(func=run)


def run(args) -> int:
    from .._presentation.history import history_summary, type_summary
    from .._store.store import check_name, history, type_comparison

    if (args.robot is None) == (args.robot_type is None):
        raise InputError("give a robot or --type TYPE (one of them)", where="history")
    if args.report and args.robot is None:
        raise InputError("the report is of one robot; give ROBOT", where="--report")
    module = common.report_module() if args.report else None
    if args.report:
        common.refuse_existing([args.report], args.force)
    with record.open_store(args) as store:
        if args.robot_type is not None:
            print(type_summary(type_comparison(store, args.robot_type, alpha=args.alpha)))
            return 0
        h = history(store, check_name(args.robot, "ROBOT"), alpha=args.alpha)
    if module is not None:
        from .._presentation.history import render_history

        common.write_outputs({args.report: render_history(h)}, force=args.force)
    print(history_summary(h))
    if args.report:
        print(f"wrote {args.report}")
    return 0
