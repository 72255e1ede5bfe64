"""``platebench sense``: the paper's three sensing stages, false-boundary test and cures, on one plate."""
from __future__ import annotations

import shutil
from pathlib import Path

from platebench.bench.cli.render import add_sample_flags, config_from_args
from platebench.bench.progress import bar, step_callback
from platebench.bench.run.sensing import SensingOptions, run_sensing
from platebench.errors import UserValueError


def add_parser(sub) -> None:
    p = sub.add_parser("sense", help="run the three sensing stages (and cures) with a simulated robot",
                       description="Stage 1: far pose, rough boundary. Stage 2: centre line through the boundary "
                                   "centre perpendicular to the boundary plane, baseline perpendicular to the "
                                   "most-bent direction, precise boundary. Stage 3: projector on the centre line, "
                                   "active stereo, false-boundary test; cures (re-orient, move back) until the "
                                   "counts agree. Writes each stage's sample and reconstruction and sensing.json.")
    p.add_argument("--out", type=Path, required=True, help="output directory")
    p.add_argument("--overwrite", action="store_true")
    p.add_argument("--max-cures", type=int, default=4, help="cure iterations before giving up (default 4)")
    p.add_argument("--workspace-mm", type=float, default=150.0,
                   help="radius of the workspace stage 1 must cover, in MILLIMETRES (default 150)")
    add_sample_flags(p)
    p.set_defaults(run=run)


def run(args) -> int:
    cfg = config_from_args(args)
    if not (10 <= args.workspace_mm <= 2000):
        raise UserValueError(f"--workspace-mm = {args.workspace_mm} is out of range: allowed 10 to 2000 mm")
    if not (0 <= args.max_cures <= 20):
        raise UserValueError(f"--max-cures = {args.max_cures} is out of range: allowed 0 to 20")
    if args.out.exists():
        if not args.overwrite:
            raise FileExistsError(f"{args.out} already exists (use --overwrite to replace it)")
        shutil.rmtree(args.out)
    opts = SensingOptions(workspace_radius_m=args.workspace_mm * 1e-3, max_cures=args.max_cures)
    with bar(8 + 4 * args.max_cures, "sense") as pbar:
        s = run_sensing(cfg, args.out, opts, progress=step_callback(pbar))
    for st in s["steps"]:
        if "stage" in st:
            extra = ""
            if st["stage"] == 3:
                fb = st["false_boundary"]
                why = [name for k, name in (("counting_test", "counting test"), ("arrays_disagree", "arrays disagree"))
                       if fb[k]]
                extra = (f"squares L/R {fb['detected']['left_active']}/{fb['detected']['right_active']} of "
                         f"{fb['expected']} expected; false boundary "
                         f"{'DETECTED (' + ', '.join(why) + ')' if why else 'not detected'}")
            gv = st["gt_visibility"]
            print(f"stage {st['stage']}{' cure ' + str(st.get('cure')) if st.get('cure') else ''}: distance "
                  f"{st['pose']['distance_m'] * 1e3:.0f} mm; GT boundary visible L/R "
                  f"{gv['left']['visible_fraction'] * 100:.0f}/{gv['right']['visible_fraction'] * 100:.0f} %  {extra}")
        else:
            print(f"decision: {st.get('decision')}: {st.get('reason')}")
    f = s["final"]
    a = f["accuracy"]
    gv = f["gt_visibility"]

    def mm(v):
        return "-" if v is None else f"{v:.3f} mm"
    print(f"final: {f['stage_dir']}, {f['matched']} points, false boundary "
          f"{'detected' if f['false_boundary']['false_boundary_detected'] else 'not detected'}; ground truth: "
          f"boundary visible L/R {gv['left']['visible_fraction'] * 100:.0f}/{gv['right']['visible_fraction'] * 100:.0f} %, "
          f"depth RMS {mm(a['depth_rms_mm'])}, boundary mean {mm(a['boundary_mean_mm'])}, "
          f"surface RMS {mm(a['surface_rms_mm'])}")
    print(f"written: {args.out / 'sensing.json'}")
    return 0
