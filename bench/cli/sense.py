"""``platebench sense``: the sensing loop (stages 1-3, verification views, cures) on one plate."""
from __future__ import annotations

from pathlib import Path

from platebench.bench.cli._args import add_sample_flags, add_verify_grid_flag
from platebench.bench.config.sample_flags import config_from_args
from platebench.bench.io.config_files import load_config
from platebench.bench.io.outputs import output_dir

# bench.run.sensing (renderer, pipeline, trimesh, SciPy) is imported where it is used, once the flags are
# checked; the parser's defaults are plain values (bench.config.sensing)
HELP = "run the sensing loop (three stages, verification views, cures) with a simulated robot"


def add_parser(sub) -> None:
    from platebench.bench.config.sensing import MAX_CURE_VIEWS, MAX_CURES_ALLOWED, WORKSPACE_MM  # noqa: PLC0415

    p = sub.add_parser("sense", help=HELP,
                       description="Stage 1: far pose, rough boundary. Stage 2: centre line through the boundary "
                                   "centre perpendicular to the boundary plane, precise boundary. Stage 3: projector "
                                   "on the centre line, active stereo, the paper's false-boundary test. Then "
                                   "verification views (every plate) and cures chosen from the measured geometry "
                                   "until the boundary is verified without ground truth, or a stop with the reason. "
                                   "Writes sensing.json, multiview.npz and stage 3's sample and reconstruction.")
    p.add_argument("--out", type=Path, required=True, help="output directory")
    p.add_argument("--overwrite", action="store_true", help="replace a sensing run 'platebench sense' wrote "
                   "(nothing else is replaced)")
    p.add_argument("--max-cures", type=int, default=MAX_CURE_VIEWS,
                   help=f"cure poses at most (default {MAX_CURE_VIEWS}; allowed 0 to {MAX_CURES_ALLOWED})")
    p.add_argument("--workspace-mm", type=float, default=WORKSPACE_MM,
                   help=f"radius of the workspace stage 1 must cover, in MILLIMETRES (default {WORKSPACE_MM:g})")
    add_verify_grid_flag(p)
    add_sample_flags(p)
    p.set_defaults(run=run)


def run(args) -> int:
    from platebench.bench.config.sensing import sense_settings  # noqa: PLC0415

    cfg = config_from_args(args, load_config(args.config, args.width, args.height))
    asked = sense_settings(args.workspace_mm, args.max_cures, args.verify_grid)
    from platebench.bench.progress import bar, step_callback  # noqa: PLC0415  (the flags are good: the loop)
    from platebench.bench.report.text import step_lines, summary_lines  # noqa: PLC0415
    from platebench.bench.run.sensing import SensingOptions, run_sensing  # noqa: PLC0415

    opts = SensingOptions(workspace_radius_m=asked.workspace_radius_m, max_cures=asked.max_cures,
                          verify_grid=asked.verify_grid)
    # the output rule (bench.io.outputs) before the first render; staged, replaced only once complete
    with output_dir(args.out, "sensing run", overwrite=args.overwrite, inputs=[args.config]) as stage:
        with bar(4 + opts.max_views, "sense") as pbar:
            s = run_sensing(cfg, stage, opts, progress=step_callback(pbar))
    for line in step_lines(s) + summary_lines(s):
        print(line)
    print(f"written: {args.out / 'sensing.json'}")
    return 0
