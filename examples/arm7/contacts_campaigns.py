"""Calibration without a tracker, over many simulated campaigns of the 7-joint arm (model.yaml).

    python examples/arm7/contacts_campaigns.py [--campaigns 10] [--seed 0]
    python examples/arm7/contacts_campaigns.py --write-sockets examples/arm7/sockets.csv
    python examples/arm7/contacts_campaigns.py --write-seatings examples/arm7/seatings

Each campaign draws a true arm (errors of 0.1 to 1 mm and 0.01 to 0.1 deg on what the campaign can
identify), puts a 3-socket plate at 3 to 9 placements plus one held out, seats the ball 20 to 35
times per socket with encoder-level joint noise (2e-5 rad) and 5 um seating scatter, and prints:

- sockets with known spacing: the largest |z| = |estimate - truth| / reported std, the share of
  |z| < 3 and the spread of z; the held-out placement's socket spread with the calibrated arm over
  the spread the true arm gives on the same readings (noise alone); the unreachable directions named
  with and without the spacing;
- a tracker campaign of 20 poses with and without a socket campaign, and the sockets alone: the RMS
  error on 40 held-out tracker poses;
- plane contacts (unknown planes) and ball bars: |z| as above.
"""

from __future__ import annotations

import argparse
import time
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

import robocal as rc
from robocal.identification import Problem, contact_errors, contact_identifiability
from robocal.sim import bar_campaign, plane_campaign, socket_campaign

MODEL = Path(__file__).resolve().parent / "model.yaml"
ENCODER = 2e-5


def z_scores(result, true, nominal) -> np.ndarray:
    truth = dict(zip(rc.parameter_names(true), rc.parameter_vector(true, nominal)))
    return np.array([(p.estimate - truth[p.name]) / p.std for p in result.parameters])


def truth_for(m, campaign, rng):
    """A true arm with errors on what ``campaign`` identifies (found on the nominal arm)."""
    names = rc.candidate_parameters(m, ("geometric",))
    ident = contact_identifiability(Problem(m, names, contacts=campaign(m, rng), compliance=False), names)
    return rc.perturb_model(m, [n for n in ident.identified if not n.startswith("base.")], rng=rng)


def sockets(m, rng):
    placements, poses = int(rng.integers(3, 10)), int(rng.integers(20, 36))

    def campaign(robot, r):
        return socket_campaign(robot, placements=placements + 1, poses_per_socket=poses, joint_noise=ENCODER, rng=r)

    true = truth_for(m, campaign, rng)
    c = campaign(true, rng)
    held = c.placements()[-1]
    fit, val = c.split_placements([held])
    res = rc.calibrate(m, contacts=fit, validation=val)
    names = rc.candidate_parameters(m, ("geometric",))
    without = contact_identifiability(Problem(m, names, contacts=replace(fit, distances=()), compliance=False), names)
    ratio = res.contacts.validation_after.mean_spread / contact_errors(true, val).mean_spread
    return dict(placements=placements, poses=poses, z=z_scores(res, true, m), ratio=ratio,
                named=[u.name for u in res.contacts.identifiability.unreachable],
                named_without=[u.name for u in without.unreachable])


def with_tracker(m, rng):
    true = rc.perturb_model(m, rc.identifiability(m).identified, rng=rng)

    def tracker(n):
        d = rc.measure(true, rc.random_configurations(m, n, rng), noise=2e-5, rng=rng)
        return replace(d, q=d.q + rng.normal(0.0, ENCODER, d.q.shape))

    fit_t, val_t = tracker(20), tracker(40)
    c = socket_campaign(true, placements=3, poses_per_socket=20, joint_noise=ENCODER, rng=rng)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        models = [rc.calibrate(m, fit_t).calibrated_model, rc.calibrate(m, contacts=c).calibrated_model,
                  rc.calibrate(m, contacts=c, data=fit_t).calibrated_model, true]
    return [float(np.sqrt(np.mean(np.sum((rc.forward_kinematics(x, val_t.q).positions - val_t.positions) ** 2,
                                         axis=2)))) for x in models]


def others(m, rng, kind):
    def campaign(robot, r):
        if kind == "plane":
            return plane_campaign(robot, planes=6, poses_per_plane=25, joint_noise=ENCODER, rng=r)
        return bar_campaign(robot, pairs=90, joint_noise=ENCODER, rng=r)

    true = truth_for(m, campaign, rng)
    return z_scores(rc.calibrate(m, contacts=campaign(true, rng)), true, m)


def _z_line(label, zs):
    z = np.concatenate(zs)
    worst = [float(np.abs(v).max()) for v in zs]
    return (f"{label}: max |z| per campaign {', '.join(f'{w:.2f}' for w in worst)}; |z| < 3 for "
            f"{np.mean(np.abs(z) < 3) * 100:.1f} % of {len(z)} estimates; z mean {z.mean():+.3f}, std {z.std():.3f}")


def write_sockets(m, path: Path, seed: int) -> None:
    """The shipped socket file: a simulated arm with errors, a 3-socket plate at 4 placements (P4 to
    hold out), 20 seatings per socket."""
    rng = np.random.default_rng(seed)
    c = socket_campaign(m, placements=4, poses_per_socket=20, joint_noise=ENCODER, rng=rng)
    true = truth_for(m, lambda robot, r: c, rng)
    rc.io.write_contacts(socket_campaign(true, placements=4, poses_per_socket=20, joint_noise=ENCODER, rng=rng),
                         path, m, force=True)


def write_seatings(m, folder: Path, seed: int) -> None:
    """The shipped folder of seatings: a simulated arm with errors, a plate of sockets hole_0, hole_1,
    hole_2 at 3 placements, 10 seatings per socket, one headerless joint file (rad) per socket and
    placement, and seatings.yaml stating the joint order, the units, the deviation and the spacings;
    beside it, ``seatings_check``: the same arm seated again, 8 times per socket on a new placement
    (``P4``), what ``robocal verify --contacts`` holds against the calibration."""
    check = folder.parent / "seatings_check"
    for f in (folder, check):
        if f.exists():
            raise SystemExit(f"{f}: exists; remove it first")
    rng = np.random.default_rng(seed)
    plate = {"hole_0": (0.0, 0.0, 0.0), "hole_1": (0.2, 0.0, 0.0), "hole_2": (0.0, 0.15, 0.0)}

    def campaign(robot, r, placements=3, poses=10):
        return socket_campaign(robot, placements=placements, poses_per_socket=poses, plate=plate, joint_noise=ENCODER,
                               rng=r)

    true = truth_for(m, campaign, rng)
    c = campaign(true, rng)
    again = campaign(true, rng, placements=1, poses=8)
    spacings = "".join(f"  - {{sockets: [{d.a}, {d.b}], length: {d.length * 1e3:.3f}, sigma: {d.sigma * 1e3:g}}}\n"
                       for d in c.distances)
    manifest = ("# simulated (examples/arm7/contacts_campaigns.py --write-seatings)\n"
                f"units: mm-rad\njoints: [{', '.join(m.joint_names)}]\nmarker: {c.marker[0]}\n"
                f"sigma: {np.sqrt(np.mean(c.sigma ** 2)) * 1e3:.3f}\ndistances:\n{spacings}")
    files = {folder / "seatings.yaml": manifest, check / "seatings.yaml": manifest}
    for at, seated, rename in ((folder, c, None), (check, again, "P4")):
        for g in seated.groups():
            files[at / (rename or g.placement) / f"{g.target}.csv"] = "".join(
                ",".join(f"{v:.9f}" for v in seated.q[i]) + "\n" for i in g.rows)
    for path, text in files.items():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--campaigns", type=int, default=10)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--write-sockets", type=Path, metavar="CSV", help="write the simulated socket file that ships")
    ap.add_argument("--write-seatings", type=Path, metavar="FOLDER",
                    help="write the simulated folder of seatings that ships, and seatings_check beside it")
    args = ap.parse_args(argv)
    m = rc.read_model(MODEL)
    if args.write_sockets:
        return write_sockets(m, args.write_sockets, args.seed)
    if args.write_seatings:
        return write_seatings(m, args.write_seatings, args.seed)
    rng = np.random.default_rng(args.seed)
    t0 = time.perf_counter()
    runs = [sockets(m, rng) for _ in range(args.campaigns)]
    print(f"sockets with known spacing, {args.campaigns} campaigns (placements fitted, poses per socket): "
          + ", ".join(f"{r['placements']}x{r['poses']}" for r in runs))
    print(_z_line("  parameters", [r["z"] for r in runs]))
    ratios = np.array([r["ratio"] for r in runs])
    print(f"  held-out spread / noise alone: {', '.join(f'{v:.3f}' for v in ratios)}; mean {ratios.mean():.3f}")
    print(f"  unreachable named: with spacing {sorted({tuple(r['named']) for r in runs})}, without "
          f"{sorted({tuple(r['named_without']) for r in runs})}")
    rms = np.array([with_tracker(m, rng) for _ in range(args.campaigns)]) * 1e3
    print(f"held-out tracker RMS (mm), mean over {args.campaigns}: tracker alone {rms[:, 0].mean():.4f}, sockets alone "
          f"{rms[:, 1].mean():.4f}, together {rms[:, 2].mean():.4f} (true arm {rms[:, 3].mean():.4f}); together best "
          f"in {int(np.sum((rms[:, 2] < rms[:, 0]) & (rms[:, 2] < rms[:, 1])))} of {args.campaigns}")
    for kind in ("plane", "bar"):
        print(_z_line(f"{kind} contacts", [others(m, rng, kind) for _ in range(args.campaigns)]))
    print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
