"""``platebench render``: render one sample (4 images + exact ground truth) to a directory."""
from __future__ import annotations

from pathlib import Path

from platebench.bench.cli._args import add_sample_flags
from platebench.bench.config.sample_flags import config_from_args, sample_moves
from platebench.bench.io.config_files import load_config
from platebench.bench.io.outputs import output_dir
from platebench.bench.io.report_records import RunTimings

HELP = "render one sample of a bent plate with exact ground truth"


def add_parser(sub) -> None:
    p = sub.add_parser("render", help=HELP,
                       description="Render the left/right images under passive and active (projected squares) "
                                   "lighting, cast ground truth at pixel centres, and write a dataset sample "
                                   "(layout v1, see README). Default: the paper's reference experiment "
                                   "(116.5 x 73.5 mm plate bent 10 degrees, cameras 0.40 m above).")
    p.add_argument("--out", type=Path, required=True, help="sample directory to create")
    p.add_argument("--overwrite", action="store_true", help="replace a sample directory 'platebench render' wrote "
                   "(nothing else is replaced)")
    add_sample_flags(p)
    p.set_defaults(run=run)


def run(args) -> int:
    cfg = config_from_args(args, load_config(args.config, args.width, args.height))
    # the output rule (bench.io.outputs) before the render: --out new, or with --overwrite a sample this
    # command wrote; staged, so it is replaced only once the new sample is complete
    with output_dir(args.out, "sample", overwrite=args.overwrite, inputs=[args.config]) as stage:
        # imported once the configuration and --out are checked: a bad one is refused at once
        from platebench.bench.io.sample_files import write_sample  # noqa: PLC0415
        from platebench.bench.progress import bar, step_callback  # noqa: PLC0415
        from platebench.bench.report.text import acquisition_lines  # noqa: PLC0415
        from platebench.bench.run.render import render_sample  # noqa: PLC0415

        with bar(8 if sample_moves(cfg) else 7, "render") as pbar:
            sample, _ = render_sample(cfg, progress=step_callback(pbar), on_pass=pass_postfix(pbar))
            pbar.set_postfix_str("write")
            write_sample(stage, sample, into=True)
            pbar.update(pbar.total - pbar.n)
    t = sample.timings_s
    vis = sample.visibility
    if sample.acquisition is not None:
        for line in acquisition_lines(cfg, sample.acquisition):
            print(line)
    print(f"sample      {args.out}")
    print(f"plate       {cfg.plate.deformation}  {cfg.plate.length_m * 1e3:.1f} x {cfg.plate.width_m * 1e3:.1f} mm, "
          f"mesh {len(sample.plate.mesh.vertices)} vertices")
    print(f"images      4 x {cfg.scene.width}x{cfg.scene.height} px, spp {cfg.render.spp}, seed {cfg.render.seed}, "
          f"variant {sample.variant}")
    for cam in ("left", "right"):
        g = sample.gt[cam]
        print(f"gt {cam:5s}    plate pixels {int(g.mask.sum())}, lit features {len(set(g.feature[g.feature >= 0].tolist()))}, "
              f"boundary visible {vis[cam].visible_fraction * 100:.1f} %, false boundary {vis[cam].false_boundary}")
    rt = RunTimings.from_dict(t)
    print(f"time        {rt.total_s:.1f} s (renders {rt.renders_s or 0.0:.1f} s, ground truth {rt.ground_truth_s:.1f} s)")
    return 0


def pass_postfix(pbar):
    """An ``on_pass(image_name, done_spp, spp)`` callback (``bench.run.render.render_sample``) that shows a
    render split into passes advancing on ``pbar``'s postfix."""
    def on_pass(name: str, done: int, spp: int) -> None:
        if done < spp:
            pbar.set_postfix_str(f"render {name} {done}/{spp} spp")
    return on_pass
