"""``robocal verify``: a short campaign against a robot's stored calibrated model (docs/store.md)."""

from __future__ import annotations

from . import common, record

# exit code of a verification that says recalibrate (as a failed calibration, docs/cli.md)
RECALIBRATE = 3

EXAMPLE = """examples:
  robocal verify SN-1042 examples/th8/verification.csv
  robocal verify SN-1042 examples/th8/verification.csv --register-base --no-record
  robocal calibrate examples/arm7/model.yaml --contacts examples/arm7/seatings --out runs/kit --record A7-01
  robocal verify A7-01 --contacts examples/arm7/seatings_check

10 to 30 poses measured as for a calibration; or, for a robot calibrated from seatings, ball seatings
in sockets (each socket seated two times or more, in varied configurations; the second example).
Exit code 3 when the verdict is recalibrate."""


def register(sub) -> None:
    p = common.command(sub, "verify", summary="check a robot against its stored calibration with a few poses",
                       description="Hold a short campaign (10 to 30 poses) against the robot's latest stored "
                                   "calibrated model: accuracy now against accuracy at calibration, ISO 9283 "
                                   "positional accuracy, and a verdict (within accuracy / recalibrate). The "
                                   "verification is kept in the store.", example=EXAMPLE,
                       inputs=[("robot", "ROBOT", "the robot"),
                               ("csv", "CSV", "the verification measurements (or --contacts)", "?")])
    p.add_argument("--contacts", metavar="FILE", help="socket seatings (a contact file or folder of seatings, "
                   "docs/formats.md) to verify a robot calibrated from seatings with, in place of CSV")
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
    from .._accuracy.verification import FEW_POSES, MANY_POSES, NO_BASE_TO_REGISTER
    from .._accuracy.verification import RECALIBRATE as SAYS_RECALIBRATE
    from .._base.errors import InputError
    from .._files.contacts import read_contacts
    from .._presentation.history import verification_summary
    from .._store.store import check_name, latest_usable, verify_robot

    robot = check_name(args.robot, "ROBOT")
    if (args.csv is None) == (args.contacts is None):
        raise InputError("give the verification measurements (CSV) or socket seatings (--contacts), one of them",
                         where="CSV" if args.csv is None else "--contacts")
    if args.contacts is not None and args.register_base:
        raise InputError(NO_BASE_TO_REGISTER, where="--register-base")
    with record.open_store(args, create=False, write=not args.no_record) as store:
        against = latest_usable(store, robot)
        model = store.model(against.calibrated_model)
        data = common.read_data(args, model, args.csv) if args.contacts is None else read_contacts(args.contacts, model)
        v, _ = verify_robot(store, robot, data, register=args.register_base, alpha=args.alpha,
                            save=not args.no_record, at=args.at)
    if args.contacts is None and not FEW_POSES <= data.n_poses <= MANY_POSES:
        print(f"note: {data.n_poses} poses; a verification takes {FEW_POSES} to {MANY_POSES}")
    if v.registered_base and not args.register_base:
        print("note: nothing the calibration fitted fixes the instrument's frame (contacts alone): the base is "
              "registered on these poses")
    print(verification_summary(v, robot, against))
    return RECALIBRATE if v.verdict == SAYS_RECALIBRATE else 0
