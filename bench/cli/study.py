"""``platebench study false-boundary``: the sensing loop on plates of every family; outcome classes,
each detector's precision and recall, the targets; the smallest hiding bend and the L formula."""
from __future__ import annotations

import sys
from pathlib import Path

from platebench.bench.config import SampleConfig, SceneParams, parse_grid
from platebench.bench.config.ranges import parse_range_text
from platebench.errors import UserValueError
from platebench.scenes.scene_spec import RenderSettings

# bench.run.study (the sensing loop, the renderer) is imported where it is used: by add_parser (the
# default bends) only when 'study' is the command (see main.build_parser)
HELP = "studies; 'study false-boundary' runs the sensing loop on plates of every family"
DEFAULT_GRID = "6x12@12"
MAX_BENDS = 400  # bend values a study accepts (each gives 8 cylinders)
MAX_PERTURB_AXIS_DEG = 10.0  # --perturb: small shifts only (the study's plates, moved a little)
MAX_PERTURB_MM = 50.0
DEFAULT_WORKERS = 2  # plates at once (study --workers)
MAX_WORKERS = 64


def add_parser(sub) -> None:
    from platebench.bench.run.study import DEFAULT_BENDS_DEG  # noqa: PLC0415

    p = sub.add_parser("study", help=HELP,
                       description="false-boundary: the sensing loop (stages 1-3, verification views, cures) on "
                                   "cylinders convex and concave about axes 0/30/60/90 degrees at the --bend angles, "
                                   "folds, twists, a dome and a bowl, dents, a second aspect ratio and a second "
                                   "distance (61 plates by default). Reports each plate's outcome class, each "
                                   "detector's precision and recall against ground truth (per bend and per family), "
                                   "the targets, the smallest hiding bend and the L formula. Writes study.json and "
                                   "study.csv.")
    p.add_argument("which", choices=["false-boundary"], help="the study to run")
    p.add_argument("--out", type=Path, required=True, metavar="DIR",
                   help="output directory: study.json, study.csv and one folder per plate (created; must not exist "
                        "unless --overwrite or --resume)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output directory")
    p.add_argument("--bend", default=",".join(f"{b:g}" for b in DEFAULT_BENDS_DEG),
                   help="cylinder bend angles in DEGREES, START:STOP:STEP or a,b,c (default "
                        + ",".join(f"{b:g}" for b in DEFAULT_BENDS_DEG) + "; allowed 0 to 350)")
    p.add_argument("--families", default="all", help="comma list of families to keep (flat, cylinder, fold, "
                   "twist, dome, dent) or 'all' (default)")
    p.add_argument("--limit", type=int, help="run only the first N plates of the set")
    p.add_argument("--grid", metavar="ROWSxCOLS@PX", default=DEFAULT_GRID,
                   help=f"projected square grid (default {DEFAULT_GRID}; the paper's is 4x4@40)")
    p.add_argument("--l-bends", default="", help="convex bends (deg) for the L-formula check (default none; "
                   "e.g. 120,150,165,172)")
    p.add_argument("--width", type=int, default=640, help="image width in px (default 640; f scales with it)")
    p.add_argument("--spp", type=int, default=2, help="samples per pixel (default 2)")
    p.add_argument("--seed", type=int, default=0, help="base render seed (default 0; allowed an integer 0 to 2^31-1)")
    p.add_argument("--resume", action="store_true",
                   help="finish an interrupted study: the plates it finished (kept in OUT.journal.jsonl beside "
                        "OUT, one line each as they finish) are not run again; the other settings must be the same")
    p.add_argument("--workers", type=int, default=DEFAULT_WORKERS,
                   help=f"plates run at once, each in its own process, the CPU cores shared among them (allowed 1 to "
                        f"{MAX_WORKERS}; default {DEFAULT_WORKERS}: the loop's decisions use one core, its renders "
                        "all it is given, so two plates at a time keep a 2-core machine busy; 1 runs in this process)")
    p.add_argument("--perturb", metavar="AXIS_DEG,DISTANCE_MM", default="0,0",
                   help="shift every plate a little to check that the rates are no knife-edge results: bend axes "
                        f"turned by AXIS_DEG (allowed -{MAX_PERTURB_AXIS_DEG:g} to {MAX_PERTURB_AXIS_DEG:g}; a fold "
                        "whose axis would leave 0-180 degrees keeps it, as turning it would mirror the fold), working "
                        f"distances changed by DISTANCE_MM (allowed -{MAX_PERTURB_MM:g} to {MAX_PERTURB_MM:g}); "
                        "default 0,0 (e.g. --perturb 1,5; write --perturb=-1,-5 when the first is negative)")
    p.set_defaults(run=run)


def run(args) -> int:
    from platebench.bench.progress import bar  # noqa: PLC0415
    from platebench.bench.run.study import perturbed_cases, study_cases, write_study  # noqa: PLC0415

    bends = parse_range_text(args.bend, "--bend", 0.0, 350.0, max_count=MAX_BENDS)
    l_bends = parse_range_text(args.l_bends, "--l-bends", 1.0, 179.0, max_count=MAX_BENDS) \
        if args.l_bends.strip() else []
    if not (160 <= args.width <= 4096):
        raise UserValueError(f"--width = {args.width} is out of range: allowed 160 to 4096")
    if not (1 <= args.spp <= 1024):
        raise UserValueError(f"--spp = {args.spp} is out of range: allowed 1 to 1024")
    try:
        render = RenderSettings(spp=args.spp, seed=args.seed)  # its own checks, as 'render --seed' has them
    except ValueError as e:
        raise UserValueError(f"--{e}") from None
    if not (1 <= args.workers <= MAX_WORKERS):
        raise UserValueError(f"--workers = {args.workers} is out of range: allowed 1 to {MAX_WORKERS}")
    axis_deg, distance_mm = parse_perturb(args.perturb)
    cases = study_cases(bends)
    fams = [f.strip() for f in args.families.split(",") if f.strip()]
    if fams != ["all"]:
        known = {c.family for c in study_cases()}
        bad = [f for f in fams if f not in known]
        if bad:
            raise UserValueError(f"--families value {bad[0]!r} is unknown: allowed all or " + ", ".join(sorted(known)))
        cases = [c for c in cases if c.family in fams]
    if args.limit is not None:
        if args.limit < 1:
            raise UserValueError(f"--limit = {args.limit} is out of range: allowed >= 1")
        cases = cases[:args.limit]
    cases = perturbed_cases(cases, axis_deg, distance_mm)
    base = SampleConfig(scene=SceneParams(width=args.width, height=args.width * 3 // 4, pattern=parse_grid(args.grid)),
                        render=render)
    settings = {"bends_deg": bends, "families": fams, "grid": args.grid, "width_px": args.width,
                "height_px": args.width * 3 // 4, "spp": args.spp, "seed": args.seed,
                "perturb_axis_deg": axis_deg, "perturb_distance_mm": distance_mm, "plates": len(cases),
                "workers": args.workers}
    from platebench.bench.run.journal import journal_path  # noqa: PLC0415

    ran = 0
    with bar(len(cases), "study false-boundary", unit="plate") as pbar:
        def progress(row):
            nonlocal ran
            ran += 1
            pbar.update(1)
            pbar.write(f"{row['case']:38s} {row['outcome']:12s} {row['time_s']:6.1f} s")
            sys.stdout.flush()  # a plate's line as it finishes, also through a pipe (tee, a log, a test)
        try:
            doc = write_study(args.out, cases, base, args.overwrite, progress, settings, l_bends, args.workers,
                              args.resume)
        except (KeyboardInterrupt, Exception):
            if ran and journal_path(args.out).exists():
                print(f"platebench: {ran} finished plates are kept in {journal_path(args.out)}; "
                      "the same command with --resume runs the rest", file=sys.stderr)
            raise
    if doc.get("resumed_plates"):
        print(f"resumed         {doc['resumed_plates']} plates from the journal of an interrupted run")
    for line in table_lines(doc):
        print(line)
    print(f"written         {args.out / 'study.json'}, {args.out / 'study.csv'}")
    return 0


def parse_perturb(text: str) -> tuple[float, float]:
    """'AXIS_DEG,DISTANCE_MM' -> (degrees, millimetres), each within the allowed small shift."""
    parts = [p.strip() for p in str(text).split(",")]
    try:
        if len(parts) != 2:
            raise ValueError
        axis_deg, distance_mm = float(parts[0]), float(parts[1])
    except ValueError:
        raise UserValueError(f"--perturb = {text!r} is not AXIS_DEG,DISTANCE_MM: allowed two numbers, e.g. 1,5") from None
    if not (abs(axis_deg) <= MAX_PERTURB_AXIS_DEG):
        raise UserValueError(f"--perturb axis = {axis_deg:g} deg is out of range: allowed -{MAX_PERTURB_AXIS_DEG:g} "
                             f"to {MAX_PERTURB_AXIS_DEG:g}")
    if not (abs(distance_mm) <= MAX_PERTURB_MM):
        raise UserValueError(f"--perturb distance = {distance_mm:g} mm is out of range: allowed -{MAX_PERTURB_MM:g} "
                             f"to {MAX_PERTURB_MM:g}")
    return axis_deg, distance_mm


def _f(v, spec=".2f"):
    return "-" if v is None else format(v, spec)


def _pct(frac):
    return _f(None if frac is None else frac * 100, ".0f")


def _yn(v):
    return "-" if v is None else ("Y" if v else ".")


def table_lines(doc: dict) -> list[str]:
    """The per-plate table, outcome counts, detector scores and targets as text lines."""
    from platebench.reconstruction.strategy.detectors import DETECTORS  # noqa: PLC0415

    short = {"counting_test": "cnt", "arrays_disagree": "arr", "viewpoint_consistency": "vpc",
             "occluding_contour": "occ", "end_tangents": "end"}
    out = [f"{'plate':38s} {'outcome':12s} {'cur':>3s} {'vws':>3s} " + " ".join(f"{short[d]:>3s}" for d in DETECTORS)
           + f" {'GT vis 1st':>10s} {'final':>6s} {'reach':>5s} {'verif':>5s} {'bnd mm':>6s} {'cover':>5s} {'time s':>6s}"]
    for r in doc["rows"]:
        if r["outcome"] == "error":
            out.append(f"{r['case']:38s} {'error':12s} {r['error']}")
            continue
        out.append(f"{r['case']:38s} {r['outcome']:12s} {r['cures']:3d} {r['views']:3d} "
                   + " ".join(f"{_yn(r.get('det_' + d)):>3s}" for d in DETECTORS)
                   + f" {_f(r['gt_visible_first'], '10.3f')} {_f(r['gt_visible_final'], '6.3f')} "
                   f"{_yn(r.get('gt_reachable')):>5s} {_yn(r.get('gt_verifiable')):>5s} "
                   f"{_f(r.get('merged_boundary_mean_mm'), '6.2f')} "
                   f"{_f(r.get('merged_surface_coverage'), '5.2f')} {r['time_s']:6.1f}")
    out.append("outcomes: " + ", ".join(f"{k} {v}" for k, v in doc["outcomes"].items()))
    for fam, c in doc["outcomes_by_family"].items():
        out.append(f"  {fam:9s} " + ", ".join(f"{k} {v}" for k, v in c.items() if v))
    for b, c in doc["outcomes_by_bend"].items():
        out.append(f"  bend {b:>4s} " + ", ".join(f"{k} {v}" for k, v in c.items() if v))
    for d, s in doc["detectors"]["all"].items():
        out.append(f"detector {d:22s} precision {_f(s['precision'])}, recall {_f(s['recall'])} (TP {s['true_positive']}, "
                   f"FP {s['false_positive']}, FN {s['false_negative']}, TN {s['true_negative']})")
    t = doc["targets"]
    out.append(f"targets: silent {t['silent']}, errors {t['errors']}, cured {t['seen_all_of_curable']}/{t['curable']} "
               f"({_pct(t['seen_all_frac'])} %: the final poses see it all), verified {t['cured_of_verifiable']} of the "
               f"{t['verifiable']} verifiable ({_pct(t['cured_of_verifiable_frac'])} %), false alarms "
               f"{t['false_alarms']}/{t['nothing_hidden']} ({_pct(t['false_alarm_frac'])} %); "
               + ", ".join(f"{k}: {'n/a' if v is None else ('met' if v else 'NOT met')}" for k, v in t["met"].items()))
    out.append(f"  the loop verified the boundary on {t['cured_of_curable']} of the {t['curable']} curable plates "
               f"({_pct(t['cured_frac'])} %); the others it names as unverified (outcome unconfirmed or honest); "
               f"{t['verifiable']} of the {t['curable']} are verifiable by pairs of reachable poses (GT)")
    n = len(doc["rows"])
    ran = doc.get("plates_run", n)  # the plates this run measured (the others came from a journal)
    w = doc.get("settings", {}).get("workers", 1)
    each = sum(r.get("time_s") or 0.0 for r in doc["rows"])
    out.append(f"time: {doc['time_s']:.0f} s for {ran} plates ({doc['time_s'] / max(ran, 1):.1f} s per plate; {w} "
               f"worker{'s' if w != 1 else ''}, each plate's own run {each / max(n, 1):.1f} s on average)"
               + (f"; {n - ran} more from the journal of an interrupted run" if ran != n else ""))
    return out
