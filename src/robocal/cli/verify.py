"""``robocal verify``: a short campaign against a robot's stored calibrated model (docs/store.md)."""

from __future__ import annotations

from . import common, record

# exit code of a verification that says recalibrate (as a failed calibration, docs/cli.md)
RECALIBRATE = 3

EXAMPLE = """examples:
  robocal verify SN-1042 examples/th8/verification.csv
  robocal verify SN-1042 examples/th8/verification.csv --register-base --no-record

10 to 30 poses measured as for a calibration. Exit code 3 when the verdict is recalibrate."""


def register(sub) -> None:
    p = common.command(sub, "verify", summary="check a robot against its stored calibration with a few poses",
                       description="Hold a short campaign (10 to 30 poses) against the robot's latest stored "
                                   "calibrated model: accuracy now against accuracy at calibration, ISO 9283 "
                                   "positional accuracy, and a verdict (within accuracy / recalibrate). The "
                                   "verification is kept in the store.", example=EXAMPLE,
                       inputs=[("robot", "ROBOT", "the robot"), ("csv", "CSV", "the verification measurements")])
    record.store_option(p)
    p.add_argument("--register-base", action="store_true",
                   help="re-register the base on these poses first (the instrument was set up again)")
    p.add_argument("--alpha", type=common.number_in(lambda v: 0 < v < 0.5, "a share between 0 and 0.5"),
                   default=0.01, help="the share of verifications of an unchanged robot that say recalibrate "
                                      "(default 0.01)")
    p.add_argument("--no-record", action="store_true", help="do not keep the verification in the store")
    p.add_argument("--at", type=common.checked_by(record._date("--at")), metavar="ISO-DATE",
                   help="when it was measured (default now)")
    common.csv_options(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from .._accuracy.verification import FEW_POSES, MANY_POSES
    from .._accuracy.verification import RECALIBRATE as SAYS_RECALIBRATE
    from .._presentation.history import verification_summary
    from .._store.store import check_name, latest_usable, verify_robot

    robot = check_name(args.robot, "ROBOT")
    with record.open_store(args, create=False, write=not args.no_record) as store:
        against = latest_usable(store, robot)
        data = common.read_data(args, store.model(against.calibrated_model), args.csv)
        v, _ = verify_robot(store, robot, data, register=args.register_base, alpha=args.alpha,
                            save=not args.no_record, at=args.at)
    if not FEW_POSES <= data.n_poses <= MANY_POSES:
        print(f"note: {data.n_poses} poses; a verification takes {FEW_POSES} to {MANY_POSES}")
    print(verification_summary(v, robot, against))
    return RECALIBRATE if v.verdict == SAYS_RECALIBRATE else 0
