"""``robocal simulate``: a perturbed 'true' robot near a model, and noisy measurements of it."""

from __future__ import annotations

from . import common

EXAMPLE = """example:
  robocal simulate examples/th8/model.yaml --out sim.csv --poses 60 --seed 1 --true-model true.yaml"""

def register(sub) -> None:
    p = common.command(sub, "simulate", summary="simulate a measurement campaign on a perturbed robot",
                       description="Draw a 'true' robot near MODEL and write noisy measurements of it.",
                       example=EXAMPLE, inputs=[("model", "MODEL", "nominal model file (YAML)")])
    p.add_argument("--out", required=True, metavar="CSV", help="measurement file to write")
    p.add_argument("--poses", type=common.poses, required=True, metavar="N", help="number of random poses")
    p.add_argument("--seed", type=common.seed, default=0, help="random seed (default 0)")
    p.add_argument("--noise-mm", type=common.length_mm, default=0.02, help="measurement noise std, mm (default 0.02)")
    p.add_argument("--length-error-mm", type=common.floats(2, 1e3, ordered=True), default=(0.1, 1.0), metavar="LO,HI",
                   help="range of length errors, mm (default 0.1,1)")
    p.add_argument("--angle-error-deg", type=common.floats(2, 180.0, ordered=True), default=(0.01, 0.1),
                   metavar="LO,HI",
                   help="range of angle errors, deg (default 0.01,0.1)")
    p.add_argument("--parameters", type=common.names, default=("geometric",),
                   help="families to perturb (default geometric)")
    p.add_argument("--true-model", metavar="OUT.yaml", help="also write the true model")
    p.add_argument("--units", type=common.units, default="mm-deg", help="units of the written files (default mm-deg)")
    p.add_argument("--force", action="store_true", help="overwrite existing output files")
    p.set_defaults(func=run)


def run(args) -> int:
    from .._files.measurements import measurements_to_csv
    from .._files.model import model_to_yaml, read_model
    from .._model.parameters import parameter_vector
    from .._simulation.simulate import simulate

    files = [args.out] + ([args.true_model] if args.true_model else [])
    common.refuse_existing(files, args.force)
    model = read_model(args.model)
    true, data = simulate(model, args.poses, parameters=args.parameters,
                          length_error=tuple(v / common.MM for v in args.length_error_mm),
                          angle_error=tuple(v / common.DEG for v in args.angle_error_deg),
                          noise=args.noise_mm / common.MM, seed=args.seed)
    common.require_finite("the simulated campaign", {"joint readings": data.q, "positions": data.positions,
                                                     "true model": parameter_vector(true)})
    texts = {args.out: measurements_to_csv(data, model=model, units=args.units)}
    if args.true_model:
        texts[args.true_model] = model_to_yaml(true, units=args.units)
    common.write_outputs(texts, force=args.force)
    print(f"simulated {data.n_poses} poses of {model.name} (noise {args.noise_mm} mm): wrote "
          f"{', '.join(map(str, texts))}")
    return 0
