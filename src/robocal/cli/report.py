"""``robocal report``: the HTML report of a result file."""

from __future__ import annotations

from . import common

EXAMPLE = """example:
  robocal report runs/compare/result.json --out report.html"""

def register(sub) -> None:
    p = common.command(sub, "report", summary="write an HTML report of a result.json (needs robocal[report])",
                       description="Write the self-contained HTML report of a calibration result file.",
                       example=EXAMPLE)
    p.add_argument("result", metavar="RESULT.json", help="a result file of robocal calibrate, or the folder it wrote")
    p.add_argument("--out", required=True, metavar="FILE.html", help="the report to write (one file, plots inline)")
    p.add_argument("--force", action="store_true", help="overwrite an existing file")
    p.set_defaults(func=run)


def run(args) -> int:
    from .._files.result import read_result

    report = common.report_module()
    common.refuse_existing([args.out], args.force)
    result = read_result(args.result)
    common.write_outputs({}, force=args.force, report=(report, result, args.out))
    print(f"wrote {args.out}")
    return 0
