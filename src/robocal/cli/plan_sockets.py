"""``robocal plan-sockets``: how many placements of a socket plate, and how many seatings per
socket, before the robot is booked."""

from __future__ import annotations

from . import common

EXAMPLE = """example:
  robocal plan-sockets examples/arm7/model.yaml --placements 3,6 --poses-per-socket 20,30 \\
      --length-std-mm 0.02 --angle-std-deg 0.002 --out sockets.csv

The plate is the default 3-socket plate with known spacing (docs/formats.md). The written file
holds the chosen design's seatings on the nominal robot, as joint targets near which to seat the
ball; record the readings where it actually seats, and run 'robocal calibrate MODEL --contacts'."""


def counts(text: str) -> tuple[int, ...]:
    return tuple(common.integer(1, 1000)(t) for t in text.split(","))


def register(sub) -> None:
    p = common.command(sub, "plan-sockets", summary="choose the placements and seatings of a socket-plate campaign",
                       description="Predict, for each number of plate placements and seatings per socket, the "
                                   "standard deviation of every parameter a socket plate reaches, and recommend the "
                                   "smallest design within the bounds.",
                       example=EXAMPLE, inputs=[("model", "MODEL", "nominal model file (YAML)")])
    p.add_argument("--placements", type=counts, default=(3, 5, 7, 9), metavar="N,...",
                   help="numbers of plate placements to compare (default 3,5,7,9)")
    p.add_argument("--poses-per-socket", type=counts, default=(20, 25, 30, 35), metavar="N,...",
                   help="numbers of seatings per socket to compare (default 20,25,30,35)")
    p.add_argument("--joint-noise-deg", type=common.noise_deg, default=0.001146, metavar="X",
                   help="deviation of a joint reading, degrees (default 0.001146, 2e-5 rad)")
    p.add_argument("--length-std-mm", type=common.noise_mm, default=1.0, metavar="X",
                   help="bound on a length's predicted standard deviation (default 1, docs/checks.md)")
    p.add_argument("--angle-std-deg", type=common.noise_deg, default=0.1, metavar="X",
                   help="bound on an angle's predicted standard deviation (default 0.1)")
    p.add_argument("--seed", type=common.seed, default=0, help="random seed (default 0)")
    p.add_argument("--out", metavar="CSV", help="write the chosen design's seatings as a contact file")
    p.add_argument("--force", action="store_true", help="overwrite an existing file")
    p.set_defaults(func=run)


def run(args) -> int:
    import math

    from .._files.contacts import contacts_to_csv
    from .._files.model import read_model
    from .._presentation.text import socket_plan_summary
    from .._simulation.sockets import plan_sockets

    if args.out:
        common.refuse_existing([args.out], args.force)
    model = read_model(args.model)
    plan = plan_sockets(model, placements=args.placements, poses_per_socket=args.poses_per_socket,
                        joint_noise=math.radians(args.joint_noise_deg), seed=args.seed,
                        bounds={"length": args.length_std_mm / common.MM, "angle": math.radians(args.angle_std_deg)})
    print(socket_plan_summary(plan))
    if args.out and plan.campaign is not None:
        common.write_outputs({args.out: contacts_to_csv(plan.campaign, model)}, force=args.force)
        print(f"wrote {args.out}")
    return 0
