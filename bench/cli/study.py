"""``platebench study KIND``: one sub-command per study, each with only its own flags (``args.which``
names the kind). ``false-boundary``: the sensing loop on plates of every family; outcome classes, each
detector's precision and recall, the targets; the smallest hiding bend and the L formula.
``accuracy``: the paper's accuracy test under a real rig's errors, with an error budget.
``cut-squares``: the paper's pipeline on oblique bends, cut squares set apart."""
from __future__ import annotations

import sys
from pathlib import Path

from platebench.bench.cli._args import add_verify_grid_flag
from platebench.bench.config.study import (
    ACCURACY_SPP,
    DEFAULT_WIDTH,
    DEFAULT_WORKERS,
    MAX_PERTURB_AXIS_DEG,
    MAX_PERTURB_MM,
    MAX_WORKERS,
)

# bench.run.sensing.study (the sensing loop, the renderer) is imported where it is used, once the flags are
# checked (bench.config.study); the parser's defaults are plain values (bench.config.sensing, bench.config.study)
HELP = ("studies: 'study false-boundary' runs the sensing loop on plates of every family; 'study accuracy' the "
        "paper's accuracy test under a real rig's errors, with an error budget; 'study cut-squares' the paper's "
        "pipeline on oblique bends, cut squares set apart")


FALSE_BOUNDARY_TEXT = ("the sensing loop (stages 1-3, verification views, cures) on cylinders convex and concave "
                       "about the --axes at the --bend angles, folds, twists, a dome and a bowl, dents, a second "
                       "aspect ratio and a second distance (61 plates by default). Reports each plate's outcome "
                       "class, each detector's precision and recall against ground truth (per bend and per "
                       "family), the targets, the smallest hiding bend and the L formula. Writes study.json and "
                       "study.csv")
ACCURACY_TEXT = ("the paper's accuracy test (V-D): passive stereo on the corners of a square of the hand/eye target "
                 "block 0.40 m away, errors in the block's frame (paper: depth within 2 mm, x/y within 1 mm), as a "
                 "Monte Carlo over --draws draws of every error source of --realism (the camera's lens distortion, "
                 "non-square pixels, defocus, line jitter and noise; the robot's repeatability and accuracy; the "
                 "hand/eye and intrinsics estimates), and the same on the reference plate's 16 square centres "
                 "(world frame). Each trial's worst corner is what the paper reports; the median over draws and its "
                 "spread are compared with it. The error budget runs no source, each source alone, all but one and "
                 "all. Writes accuracy.json (every trial and the statistics), accuracy.csv (one row per trial: "
                 "realism, draw seed, errors) and accuracy.png")
CUT_SQUARES_TEXT = ("the paper's pipeline on oblique bends (--bend, --axes, --distances; default 40,60,90,120 deg "
                    "about 20,30,45,60,75 deg at 0.40,0.45,0.50 m), the centres of cut squares set apart and kept, "
                    "each scored against the paper's bound. Writes cut_study.json")


def add_parser(sub) -> None:
    """``study`` and one sub-command per study kind (``false-boundary``, ``accuracy``, ``cut-squares``),
    each with only its own flags; ``args.which`` names the kind."""
    from platebench.bench.config.sensing import DEFAULT_BENDS_DEG  # noqa: PLC0415

    bends = ",".join(f"{b:g}" for b in DEFAULT_BENDS_DEG)
    p = sub.add_parser("study", help=HELP,
                       description="Three studies, each a sub-command with its own flags ('platebench study KIND "
                                   "--help'). false-boundary: " + FALSE_BOUNDARY_TEXT + f" (--bend default {bends})."
                                   " accuracy: " + ACCURACY_TEXT + ". cut-squares: " + CUT_SQUARES_TEXT + ".")
    kinds = p.add_subparsers(dest="which", metavar="KIND", required=True, help="the study to run")
    _add_false_boundary(kinds, bends)
    _add_accuracy(kinds)
    _add_cut_squares(kinds)
    p.set_defaults(run=run)


def _add_output_flags(p, files: str) -> None:
    p.add_argument("--out", type=Path, required=True, metavar="DIR",
                   help=f"output directory ({files}); created, must not exist unless --overwrite"
                        + (" or --resume" if "study.json" in files else ""))
    p.add_argument("--overwrite", action="store_true", help="replace a study 'platebench study' wrote (nothing else "
                   "is replaced)")


def _add_seed(p) -> None:
    p.add_argument("--seed", type=int, default=0, help="base render seed (default 0; allowed an integer 0 to 2^31-1)")


def _add_false_boundary(kinds, bends: str) -> None:
    from platebench.bench.config.realism import REALISM_PRESETS  # noqa: PLC0415
    from platebench.bench.config.sensing import REFERENCE_ASPECT, STUDY_AXES_DEG  # noqa: PLC0415

    p = kinds.add_parser("false-boundary", help=f"the sensing loop on plates of every family (--bend default {bends})",
                         description=FALSE_BOUNDARY_TEXT + ".",
                         epilog="Columns of the printed table: the legend under it. Every flag that chooses plates "
                                "(--bend, --axes, --families) restricts every set the study builds, the second "
                                "aspect ratio's and the second distance's plates too.")
    _add_output_flags(p, "study.json, study.csv and one folder per plate")
    p.add_argument("--bend", help="cylinder bend angles in DEGREES, START:STOP:STEP or a,b,c (default " + bends
                   + "; allowed 0 to 350)")
    p.add_argument("--families", default="all", help="comma list of deformation families to run (flat, cylinder, "
                   "fold, twist, dome, dent, ...: every key of plates.spec.FAMILIES; a family outside the default "
                   "set adds its own example plates) or 'all' (default: the 61 plates)")
    p.add_argument("--axes",
                   help="the cylinders' bend axes in DEGREES from the plate's width direction, a,b,c or "
                        "START:STOP:STEP (default " + ",".join(f"{a:g}" for a in STUDY_AXES_DEG)
                        + "; allowed 0 to 179.9); the second aspect ratio's and the second distance's cylinders "
                          "take the first and the last of them, unless --extra-axes")
    p.add_argument("--extra-axes", metavar="FIRST,LAST",
                   help="the bend axes in DEGREES of the second aspect ratio's and the second distance's cylinders "
                        "(two values, allowed 0 to 179.9; default the first and the last of --axes)")
    p.add_argument("--aspect", type=float, default=REFERENCE_ASPECT,
                   help=f"length / width of the plates at the reference plate's area (default {REFERENCE_ASPECT:.3f}, "
                        "the paper's plate; allowed 0.25 to 8); the second aspect ratio's and the second "
                        "distance's few plates keep theirs")
    p.add_argument("--limit", type=int, help="run only the first N plates of the set")
    p.add_argument("--dry-run", action="store_true",
                   help="print the plates the flags select (one a line) and their count, and stop: nothing is "
                        "rendered or written")
    p.add_argument("--grid", metavar="ROWSxCOLS@PX",
                   help="stage 3's projected square grid (default: the paper's 16 squares, as sense projects them; "
                        "4x4@40 spaces their rows twice as far)")
    add_verify_grid_flag(p)
    p.add_argument("--l-bends", default="", help="convex bends (deg) for the L-formula check (default none; "
                   "e.g. 120,150,165,172)")
    p.add_argument("--width", type=int, help="image width in px (default 640, the height 3/4 of it; f scales with "
                   "it; under --realism the camera's own size, its field of view and aspect kept at another width)")
    p.add_argument("--spp", type=int, help="samples per pixel (default 2)")
    _add_seed(p)
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
    p.add_argument("--realism", choices=tuple(REALISM_PRESETS), default=None,
                   help="the error model (default ideal: none; 1995: the paper's PULNiX camera moved by a PUMA 560; "
                        "modern: a rigid head on a current arm); under a preset each plate's poses are taken by the "
                        "robot with its errors (one draw per plate: --seed plus the CRC-32 of its name, recorded in "
                        "each row) and the loop measures and merges through the commanded poses and the estimated "
                        "hand/eye and calibration")
    _add_realism_scale(p, "study.json's")


def _add_realism_scale(p, where: str) -> None:
    p.add_argument("--realism-scale", default=None, metavar="SOURCE=F[,SOURCE=F]",
                   help="scale error sources of --realism from their sourced magnitude (1 = as sourced; allowed 0 to "
                        "the realism module's maximum), e.g. robot_accuracy=0.5 for an arm twice as accurate as the "
                        f"figure the preset cites; recorded in {where} settings")


def _add_accuracy(kinds) -> None:
    from platebench.bench.config.realism import REALISM_PRESETS, SOURCES  # noqa: PLC0415

    p = kinds.add_parser("accuracy", help="the paper's accuracy test under a real rig's errors, with an error budget",
                         description=ACCURACY_TEXT + ".",
                         epilog="error sources: " + "; ".join(f"{k}: {v}" for k, v in SOURCES.items())
                                + ". Sources and magnitudes, each with its citation: bench/config/hardware_camera.py, "
                                  "bench/config/hardware_robot.py. README: what each source costs in accuracy.")
    _add_output_flags(p, "accuracy.json, accuracy.csv, accuracy.png")
    p.add_argument("--realism", choices=tuple(REALISM_PRESETS), default=None,
                   help="the error model (default 1995: the paper's PULNiX camera moved by a PUMA 560; modern: a "
                        "rigid head on a current arm; ideal: none); the realism's camera sets the image size")
    _add_realism_scale(p, "accuracy.json's")
    p.add_argument("--draws", type=int, default=30,
                   help="Monte Carlo draws per budget row (default 30; allowed 1 to 1000): each draws new robot "
                        "errors, a new hand/eye and intrinsics estimate, new line jitter and sensor noise; draw k "
                        "uses seed --seed + k in every row, so rows compare like with like")
    p.add_argument("--targets", default="block",
                   help="block (the target block's square, the paper's test; default), plate (the reference "
                        "plate's 16 square centres, four renders a draw: about twice the time) or block,plate")
    p.add_argument("--no-budget", action="store_true",
                   help="run only every source on (the budget runs 2N+2 rows for N sources)")
    p.add_argument("--corners", choices=("edges", "pixels"), default="edges",
                   help="how the block's corners are located: edges (default), the intersections of lines "
                        "fitted to the square's edges, sub-pixel; pixels, the vertices of the polygon fitted to "
                        "its binary outline, on the pixel grid, as the paper's contour following and corner "
                        "detection found them (its [11], no sub-pixel step)")
    p.add_argument("--spp", type=int, help=f"samples per pixel (default {ACCURACY_SPP}: the corners are fitted to "
                   "edges, and the renderer's Monte Carlo noise at the edge pixels would add to the camera's)")
    _add_seed(p)


def _add_cut_squares(kinds) -> None:
    import argparse  # noqa: PLC0415

    p = kinds.add_parser("cut-squares", help="the paper's pipeline on oblique bends, cut squares set apart",
                         description=CUT_SQUARES_TEXT + ".")
    _add_output_flags(p, "cut_study.json")
    p.add_argument("--bend", help="bend angles in DEGREES, START:STOP:STEP or a,b,c (default 40,60,90,120; allowed "
                   "0 to 350)")
    p.add_argument("--axes", help="bend axes in DEGREES from the plate's width direction, a,b,c or START:STOP:STEP "
                   "(default 20,30,45,60,75; allowed 0 to 179.9)")
    p.add_argument("--distances", help="rig distances in METRES, a,b,c (default 0.40,0.45,0.50; allowed 0.2 to 2)")
    p.add_argument("--grid", metavar="ROWSxCOLS@PX",
                   help="the projected square grid (default: the paper's 16 squares)")
    p.add_argument("--width", type=int, help=f"image width in px (default {DEFAULT_WIDTH}, the height 3/4 of it; "
                   "f scales with it)")
    p.add_argument("--spp", type=int, help="samples per pixel (default 2)")
    _add_seed(p)
    # refused with their reason (the study places its cameras itself and has no error source); not listed
    p.add_argument("--realism", default=None, help=argparse.SUPPRESS)
    p.add_argument("--realism-scale", default=None, help=argparse.SUPPRESS)


def run(args) -> int:
    if args.which == "accuracy":
        return run_accuracy(args)
    if args.which == "cut-squares":
        return run_cut_squares(args)
    from platebench.bench.config.study import StudySettings, false_boundary_flags  # noqa: PLC0415

    flags = false_boundary_flags(args)
    # the flags are good: the loop and the study
    from platebench.bench.io.codecs import encode  # noqa: PLC0415
    from platebench.bench.io.sensing_records import StudyRealism  # noqa: PLC0415
    from platebench.bench.progress import bar  # noqa: PLC0415
    from platebench.bench.run.journal import journal_path  # noqa: PLC0415
    from platebench.bench.run.sensing import SensingOptions  # noqa: PLC0415
    from platebench.bench.run.sensing.records import auto_verify_grid  # noqa: PLC0415
    from platebench.bench.run.sensing.study import (  # noqa: PLC0415
        perturbed_cases,
        study_cases,
        with_realism_seeds,
        write_study,
    )

    cases = study_cases(list(flags.bends_deg), flags.family_filter, list(flags.axes_deg), flags.aspect,
                        None if flags.extra_axes_deg is None else list(flags.extra_axes_deg))
    if flags.limit is not None:
        cases = cases[:flags.limit]
    cases = perturbed_cases(cases, flags.perturb_axis_deg, flags.perturb_distance_mm)
    if args.dry_run:
        for line in plate_lines(cases):
            print(line)
        return 0
    base, options_extra = study_base(args, flags.render)
    if not base.realism.is_ideal:
        cases = with_realism_seeds(cases, flags.render.seed)
    verify_grid = flags.verify_grid
    if verify_grid == "auto":
        verify_grid = auto_verify_grid(base.scene.width)
    options = SensingOptions(verify_grid=verify_grid, **options_extra)
    settings = encode(StudySettings.of(flags, base, verify_grid, len(cases)))
    if not base.realism.is_ideal:
        settings.update(encode(StudyRealism(
            base.realism.name, base.realism.sources,
            "--seed + CRC-32 of the plate's name, modulo 2^31 (each row's realism_seed)",
            options.corner_noise_px, tuple(base.realism.scales.items()))))
    ran = 0
    with bar(len(cases), "study false-boundary", unit="plate") as pbar:
        def progress(row):
            nonlocal ran
            ran += 1
            pbar.update(1)
            pbar.write(f"{row.case:38s} {row.outcome:12s} {row.time_s:6.1f} s")
            sys.stdout.flush()  # a plate's line as it finishes, also through a pipe (tee, a log, a test)
        try:
            study = write_study(args.out, cases, base, args.overwrite, progress, settings, list(flags.l_bends_deg),
                                flags.workers, args.resume, options)
        except (KeyboardInterrupt, Exception):
            if ran and journal_path(args.out).exists():
                print(f"platebench: {ran} finished plates are kept in {journal_path(args.out)}; "
                      "the same command with --resume runs the rest", file=sys.stderr)
            raise
    from platebench.bench.report.text import table_lines  # noqa: PLC0415

    if study.resumed_plates:
        print(f"resumed         {study.resumed_plates} plates from the journal of an interrupted run")
    for line in table_lines(study):
        print(line)
    print(f"written         {args.out / 'study.json'}, {args.out / 'study.csv'}")
    return 0


def study_base(args, render) -> tuple:
    """The false-boundary study's sample configuration before each plate's
    (``bench.config.study.study_sample_config`` of ``args.realism``, ``args.realism_scale``, ``args.grid``,
    ``args.width``) and the sensing options it adds: under a realism preset with estimates, the corner
    noise of its calibration views measured once for every plate (``bench.run.realism.measure_corner_noise``)."""
    from platebench.bench.config.study import study_sample_config  # noqa: PLC0415

    cfg = study_sample_config(args.realism, args.realism_scale, args.grid, args.width, render)
    if args.realism in (None, "ideal"):
        return cfg, {}
    from platebench.bench.run.realism import measure_corner_noise  # noqa: PLC0415

    noise = measure_corner_noise(cfg) if cfg.realism.estimates else 0.0
    return cfg, {"corner_noise_px": noise}


def run_accuracy(args) -> int:
    """``study accuracy`` (``bench.run.accuracy``): its flags checked, the study run, written and printed."""
    from platebench.bench.config.study import accuracy_flags  # noqa: PLC0415
    from platebench.bench.io.atomic import write_json, write_text  # noqa: PLC0415
    from platebench.bench.io.outputs import output_dir  # noqa: PLC0415
    from platebench.bench.progress import bar  # noqa: PLC0415
    from platebench.bench.report.plots import plot_accuracy_study  # noqa: PLC0415
    from platebench.bench.run.accuracy import TARGETS, AccuracySettings, budget_configs, run_accuracy_study  # noqa: PLC0415
    from platebench.bench.run.accuracy import accuracy_csv  # noqa: PLC0415

    flags = accuracy_flags(args, TARGETS)
    realism = flags.realism
    settings = AccuracySettings(realism, flags.draws, flags.targets, flags.budget, flags.spp, flags.seed,
                                corners=flags.corners)
    confs = budget_configs(realism, settings.budget)
    total = len(confs) * flags.draws * len(flags.targets)
    with output_dir(args.out, "accuracy study", overwrite=args.overwrite) as stage:
        done: dict = {}
        with bar(total, f"study accuracy ({realism.name})", unit="trial") as pbar:
            def progress(trial):
                pbar.update(1)
                key = (trial.target, trial.config)
                done.setdefault(key, []).append(trial)
                if len(done[key]) == flags.draws:
                    pbar.write(config_line(trial.target, trial.config, done[key]))
                    sys.stdout.flush()
            study = run_accuracy_study(settings, progress)
        write_json(stage / "accuracy.json", study.to_dict())
        write_text(stage / "accuracy.csv", accuracy_csv(study.rows))
        plot_accuracy_study(study, stage / "accuracy.png")
    for line in accuracy_lines(study):
        print(line)
    print(f"written         {args.out / 'accuracy.json'}, {args.out / 'accuracy.csv'}, {args.out / 'accuracy.png'}")
    return 0


def config_line(target: str, config: str, rows: list) -> str:
    """One finished budget row (its ``AccuracyTrial``s): the median worst corner over its draws (mm)."""
    import numpy as np  # noqa: PLC0415

    ok = [r for r in rows if r.ok]
    if not ok:
        return f"{target:6s} {config:32s} every draw failed: {rows[0].error}"
    d = np.median([r.worst_depth_mm for r in ok])
    xy = np.median([r.worst_xy_mm for r in ok])
    return (f"{target:6s} {config:32s} worst corner, median of {len(ok)} draws: depth {d:.3f} mm, x/y {xy:.3f} mm"
            + (f" ({len(rows) - len(ok)} failed)" if len(ok) < len(rows) else ""))


def accuracy_lines(study) -> list[str]:
    """The accuracy study's tables (``bench.io.accuracy_records.AccuracyStudy``): per target, each
    budget row beside the paper's figures."""
    from platebench.bench.run.accuracy import dominant_sources  # noqa: PLC0415

    paper = study.paper
    st = study.settings
    cam = study.camera
    out = [f"realism {st.realism.name}: camera {cam.name} {cam.width_px}x{cam.height_px} px, "
           f"fx/fy {cam.fx_px:.1f}/{cam.fy_px:.1f} px, baseline {cam.baseline_m * 1e3:.0f} mm, distance "
           f"{cam.distance_m * 1e3:.0f} mm; {st.draws} draws per row; paper (V-D): depth <= "
           f"{paper.depth_mm:g} mm, x/y <= {paper.xy_mm:g} mm (one trial's worst corner)"]
    if st.realism.scales:
        out.append("scaled from the sourced magnitudes: " + ", ".join(f"{k} x{v:g}" for k, v in st.realism.scales.items()))
    if "block" in study.summary:
        out.append("block corners: " + ("the vertices of the polygon fitted to the square's binary outline, on the "
                                        "pixel grid (the paper's method, its [11])" if st.corners == "pixels" else
                                        "the intersections of lines fitted to the square's edges (sub-pixel)"))
    if study.robot:
        r = study.robot
        out.append(f"robot {r.name}: {r.description}")
    if study.corner_noise_px:
        vals = sorted(set(round(v, 4) for v in study.corner_noise_px.values()))
        out.append(f"calibration views: corner noise measured on rendered target images, {vals[0]:.3f}-{vals[-1]:.3f} "
                   "px per axis (by the camera defects on)")
    head = (f"{'':34s} {'depth: worst corner (mm)':>32s}  {'all corners (mm)':>20s}   "
            f"{'x/y: worst corner (mm)':>32s}  {'all corners (mm)':>20s}")
    sub = (f"{'budget row':34s} {'median':>8s} {'q05-q95':>15s} {'<=2':>5s}   {'RMS':>6s} {'p95':>6s} {'max':>6s}   "
           f"{'median':>8s} {'q05-q95':>15s} {'<=1':>5s}   {'RMS':>6s} {'p95':>6s} {'max':>6s}")
    for target, rows in study.summary.items():
        what = ("the target block's square, 4 corners, block frame" if target == "block"
                else "the reference plate, 16 square centres, world frame")
        out += ["", f"{target}: {what}", head, sub]
        for label, s in rows.items():
            if s.depth is None:
                out.append(f"{label:34s} every draw failed")
                continue
            cells = []
            for v in (s.depth, s.xy):
                q = v.worst_quantiles_mm
                cells.append(f"{v.worst_median_mm:8.3f} {q['q05']:6.3f}-{q['q95']:<8.3f} {v.within_paper_frac * 100:4.0f}%"
                             f"   {v.rms_mm:6.3f} {v.p95_mm:6.3f} {v.max_mm:6.3f}")
            out.append(f"{label:34s} " + "   ".join(cells) + (f"  ({s.failed} failed)" if s.failed else ""))
        for m, name in (("depth", "depth"), ("xy", "x/y")):
            ranked = dominant_sources(rows, m)
            if ranked:
                out.append(f"  added to the no-source floor alone ({name}, median worst): "
                           + ", ".join(f"{k} {v:+.3f} mm" for k, v in ranked))
    out.append(f"time: {study.time_s:.0f} s")
    return out


def run_cut_squares(args) -> int:
    """``study cut-squares`` (``bench.run.cut_study``): its flags checked, the study run and printed."""
    from platebench.bench.config.study import cut_squares_settings  # noqa: PLC0415
    from platebench.bench.io.codecs import encode  # noqa: PLC0415
    from platebench.bench.progress import bar  # noqa: PLC0415
    from platebench.bench.run.cut_study import (  # noqa: PLC0415
        CUT_AXES_DEG,
        CUT_BENDS_DEG,
        CUT_DISTANCES_M,
        table_lines,
        write_cut_study,
    )

    st = cut_squares_settings(args, CUT_BENDS_DEG, CUT_AXES_DEG, CUT_DISTANCES_M)
    with bar(st.plates, "study cut-squares", unit="plate") as pbar:
        doc = write_cut_study(args.out, st.base, args.overwrite, lambda row: pbar.update(1), encode(st),
                              bends_deg=list(st.bends_deg), axes_deg=list(st.axes_deg),
                              distances_m=list(st.distances_m))
    for line in table_lines(doc):
        print(line)
    print(f"written         {args.out / 'cut_study.json'}")
    return 0


def plate_lines(cases) -> list[str]:
    """``study false-boundary --dry-run``: each plate (``bench.run.sensing.study.StudyCase``) on a line, then the count."""
    def value(v, unit):
        return "-" if v is None else f"{v:g}{unit}"
    out = [f"{'plate':44s} {'family':9s} {'bend':>6s} {'dir':>4s} {'axis':>6s} {'aspect':>6s} {'distance':>8s}"]
    out += [f"{c.name:44s} {c.family:9s} {value(c.bend_deg, ''):>6s} {c.direction or '-':>4s} "
            f"{value(c.axis_deg, ''):>6s} {c.aspect:6.3f} {c.distance_m:7.3f}m" for c in cases]
    out.append(f"{len(cases)} plates (bend and axis in degrees; nothing run or written: --dry-run)")
    return out
