"""``robocal record``: keep a calibration result in the store of calibrations (docs/store.md)."""

from __future__ import annotations

from pathlib import Path

from .._base.errors import InputError
from . import common

EXAMPLE = """example:
  robocal record runs/compare/result.json --robot SN-1042 --type th8

The store is --store, else $ROBOCAL_STORE, else $XDG_DATA_HOME/robocal/store.sqlite (XDG_DATA_HOME by
default ~/.local/share; docs/store.md); a plant's store on a PostgreSQL server:
--store postgresql://cal@plant-db/robocal."""


def store_option(p) -> None:
    """--store: a SQLite file or a postgresql:// URL."""
    p.add_argument("--store", metavar="PATH|URL", help="the store: a SQLite file or a postgresql:// URL (default "
                                                       "$ROBOCAL_STORE, else $XDG_DATA_HOME/robocal/store.sqlite, "
                                                       "XDG_DATA_HOME by default ~/.local/share)")


def open_store(args, *, create: bool = False, write: bool | None = None):
    """The store the options name, open (read-only unless ``create`` or ``write``); MissingExtra
    for PostgreSQL without psycopg."""
    from .._store.store import open_store as open_

    return open_(_location(args), create=create, write=write)


def check_store(args, robot: str) -> None:
    """The store ``calibrate --record`` will write, checked before the calibration's work
    (``check_recordable``): a store that cannot take the record fails the command at once."""
    from .._store.store import check_recordable

    check_recordable(_location(args), robot)


def _location(args) -> str:
    """The store the options name; MissingExtra for PostgreSQL without psycopg."""
    from .._store.store import is_url, store_location

    location = store_location(args.store)
    if is_url(location):
        try:
            import psycopg  # noqa: F401
        except ImportError:
            raise common.MissingExtra("a PostgreSQL store needs psycopg (pip install 'robocal[store-pg]')") from None
    return location


def register(sub) -> None:
    p = common.command(sub, "record", summary="keep a calibration result in the store of calibrations",
                       description="Store a result.json as a calibration of a robot: its models, every estimate "
                                   "with its standard deviation, the verdict and checks, the accuracy reached, the "
                                   "limit and a fingerprint of the input files.", example=EXAMPLE,
                       inputs=[("result", "RESULT.json", "a result file of robocal calibrate, or the folder it wrote")])
    p.add_argument("--robot", required=True, type=common.checked_by(_name("--robot")), metavar="ROBOT",
                   help="the robot's serial or name")
    record_options(p)
    p.set_defaults(func=run)


# what a calibration is recorded with: calibrate takes them with --record only
RECORD_OPTIONS = (("--type", "robot_type"), ("--at", "at"), ("--store", "store"))


def record_options(p, *, robot: bool = False) -> None:
    """--type, --at and --store (and with ``robot``, calibrate's --record ROBOT)."""
    if robot:
        p.add_argument("--record", type=common.checked_by(_name("--record")), metavar="ROBOT",
                       help="also keep the result in the store of calibrations as a calibration of ROBOT")
    p.add_argument("--type", dest="robot_type", type=common.checked_by(_name("--type")), metavar="TYPE",
                   help="the robot's type, to compare robots of one type (robocal history --type)")
    p.add_argument("--at", type=common.checked_by(_date("--at")), metavar="ISO-DATE",
                   help="when the calibration was made, e.g. 2026-03-02T10:00:00Z (default: the result's date)")
    store_option(p)


def _name(option: str):
    def check(text: str) -> str:
        from .._store.store import check_name

        return check_name(text, option)
    return check


def _date(option: str):
    def check(text: str) -> str:
        from .._store.store import utc_text

        return utc_text(text, where=option)
    return check


def recorded_line(rec, location: str) -> str:
    return (f"recorded calibration #{rec.id} of {rec.robot} ({rec.calibrated_at}, verdict {rec.verdict}) in "
            f"{location}")


def record_result(args, result, robot: str, source: str, at=None, files=None) -> None:
    """Store ``result`` and write ``files`` ({path: text}, with --force as ``args.force``) as one
    outcome, both or neither; then say so, with the changes since the robot's previous calibration.

    The result is made a record first, and the store is checked (ours, writable, whole; the robot's
    earlier records readable), so that a result that cannot be recorded or an unusable store leaves
    nothing written: not even a new, empty store. Once the record is committed, reading the history
    can no longer fail the command: damage found then is reported on stderr."""
    import logging

    from .._store.store import history, stored_calibration

    prepared = stored_calibration(result, robot, robot_type=args.robot_type, at=at, source=source)  # before any store
    with open_store(args, create=True) as store:
        store.check()
        store.calibrations(robot), store.verifications(robot)   # damaged earlier records: nothing written
        written = False
        try:
            with store.recording(result, prepared) as rec:
                if files:
                    common.write_outputs(files, force=args.force)
                    written = True
        except BaseException:
            if written:     # the record did not commit: the files it belongs with go too
                for p in files or ():
                    Path(p).unlink(missing_ok=True)
            raise
        if files:
            print(f"wrote {', '.join(str(p) for p in files)}")
        print(recorded_line(rec, store.location))
        try:
            h = history(store, robot)
        except InputError as e:
            logging.getLogger("robocal").warning("recorded, but the earlier records of %s cannot be read for the "
                                                 "changes: %s", robot, e)
            return
    _print_changes(h, rec)


def _print_changes(h, rec) -> None:
    from .._presentation.history import apart_line, change_line, overall_line

    changes = [change_line(c) for c in h.changes if c.at == rec.calibrated_at]
    changes += [overall_line(o) for o in h.overall if o.named and o.at == rec.calibrated_at]
    changes += [apart_line(o) for o in h.overall if not o.compared and o.at == rec.calibrated_at]
    if len(h.calibrations) > 1:
        print("changes since the previous calibration: " + ("; ".join(changes) if changes
                                                             else f"none beyond {h.threshold:.2f} sigma"))


def run(args) -> int:
    from .._files.result import read_result

    result = read_result(args.result)
    record_result(args, result, args.robot, str(args.result), at=args.at)
    return 0
