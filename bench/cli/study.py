"""``platebench study false-boundary``: false boundaries by bend angle, the counting test, the cures."""
from __future__ import annotations

import csv
import io
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np

from platebench.bench.config import SampleConfig, SceneParams, parse_grid
from platebench.bench.io.atomic import write_json, write_text
from platebench.bench.progress import bar
from platebench.bench.run.study import (
    VisibilityProbe,
    cure_case,
    l_formula_table,
    precision_recall,
    smallest_hiding_bend,
)
from platebench.errors import UserValueError
from platebench.scenes.scene_spec import RenderSettings


def parse_range(text: str, name: str, lo: float, hi: float) -> list[float]:
    """'START:STOP:STEP' (inclusive stop) or 'a,b,c' -> floats within [lo, hi]."""
    try:
        if ":" in text:
            a, b, c = (float(x) for x in text.split(":"))
            if c <= 0:
                raise UserValueError
            vals = list(np.arange(a, b + c * 1e-9, c))
        else:
            vals = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise UserValueError(f"{name} = {text!r} is not START:STOP:STEP or a comma list") from None
    if not vals:
        raise UserValueError(f"{name} = {text!r} is an empty range")
    bad = [v for v in vals if not (lo <= v <= hi)]
    if bad:
        raise UserValueError(f"{name} value {bad[0]:g} is out of range: allowed {lo:g} to {hi:g}")
    return [float(v) for v in vals]


def add_parser(sub) -> None:
    p = sub.add_parser("study", help="studies; 'study false-boundary' sweeps bend angles",
                       description="false-boundary: over bend angles (convex and concave), plate aspect ratios "
                                   "and distances: how often ground truth hides part of the boundary, how often "
                                   "the counting test detects it (precision, recall), how often each cure removes "
                                   "it, the L formula against ground truth, and errors vs bend.")
    p.add_argument("which", choices=["false-boundary"], help="the study to run")
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--overwrite", action="store_true")
    p.add_argument("--bend", default="0:180:20", help="bend angles in DEGREES, START:STOP:STEP or a,b,c "
                   "(default 0:180:20; allowed 0 to 350)")
    p.add_argument("--directions", default="down,up", help="bend directions: down (convex), up (concave)")
    p.add_argument("--aspects", default="1.585", help="plate length/width ratios (default 1.585, the paper's)")
    p.add_argument("--distances-m", default="0.4", help="rig distances in metres (default 0.4)")
    p.add_argument("--axes-deg", default="0", help="bend axes in DEGREES from the plate's width direction "
                   "(0: bent along its length, baseline across the axis; 90: across its width, baseline along "
                   "the bend); default 0")
    p.add_argument("--grid", metavar="ROWSxCOLS@PX", help="projected square grid (default 4x4@40, the paper's; "
                   "6x12@12 lets the counting test see false boundaries off the surface)")
    p.add_argument("--l-bends", default="120,150,165,172", help="convex bends (deg) for the L-formula check")
    p.add_argument("--width", type=int, default=640, help="image width in px (default 640; f scales with it)")
    p.add_argument("--spp", type=int, default=4)
    p.set_defaults(run=run)


def run(args) -> int:
    bends = parse_range(args.bend, "--bend", 0.0, 350.0)
    dirs = [d.strip() for d in args.directions.split(",") if d.strip()]
    if not dirs or any(d not in ("up", "down") for d in dirs):
        raise UserValueError(f"--directions = {args.directions!r}: allowed up, down")
    aspects = parse_range(args.aspects, "--aspects", 0.2, 5.0)
    distances = parse_range(args.distances_m, "--distances-m", 0.1, 3.0)
    l_bends = parse_range(args.l_bends, "--l-bends", 1.0, 179.0)
    axes = parse_range(args.axes_deg, "--axes-deg", 0.0, 179.99)
    pattern = parse_grid(args.grid) if args.grid else {}
    if args.out.exists():
        if not args.overwrite:
            raise FileExistsError(f"{args.out} already exists (use --overwrite to replace it)")
        shutil.rmtree(args.out)
    base = SampleConfig(scene=SceneParams(width=args.width, height=args.width * 3 // 4,
                                          pattern=pattern),
                        render=RenderSettings(spp=args.spp))
    area = base.plate.length_m * base.plate.width_m
    rows, renderer = [], None
    cases = [(b, d, a, dist, ax) for a in aspects for dist in distances for ax in axes for d in dirs for b in bends]
    with bar(len(cases) + len(l_bends) + 2, "study false-boundary", unit="case") as pbar:
        for b, d, a, dist, ax in cases:
            cfg = replace(base, plate=replace(base.plate, length_m=float(np.sqrt(area * a)),
                                              width_m=float(np.sqrt(area / a))))
            pbar.set_postfix_str(f"{d} {b:g} deg, axis {ax:g} deg, aspect {a:g}, {dist:g} m")
            row, renderer = cure_case(cfg, b, d, renderer, axis_rad=float(np.radians(ax)), distance_m=dist)
            row["aspect"] = a
            rows.append(row)
            pbar.update(1)
        probe = VisibilityProbe(base)
        pbar.set_postfix_str("smallest hiding bend")
        smallest = {d: smallest_hiding_bend(probe, base, d, base.scene.distance_m) for d in ("down", "up")}
        pbar.update(2)
        pbar.set_postfix_str("L formula")
        l_rows = l_formula_table(base, l_bends, probe)
        pbar.update(len(l_bends))
    pr = {k: precision_recall(rows, k) for k in ("detected", "counting_test", "arrays_disagree")}
    hidden = [r for r in rows if r["false_boundary_gt"]]
    cures = {f"cure{i}_removed_frac": (sum(1 for r in hidden if r.get(f"cure{i}_removed")) / len(hidden)
                                       if hidden else None) for i in (1, 2)}
    study = {"rows": rows, "l_formula": l_rows, "smallest_hiding_bend_deg": smallest, "precision_recall": pr,
             "cures": cures, "settings": {"bends_deg": bends, "directions": dirs, "aspects": aspects,
                                          "distances_m": distances, "axes_deg": axes, "grid": args.grid or "4x4@40",
                                          "width_px": args.width, "spp": args.spp}}
    args.out.mkdir(parents=True, exist_ok=True)
    write_json(args.out / "study.json", study)
    write_text(args.out / "study.csv", _csv(rows))
    _print(study)
    print(f"written         {args.out / 'study.json'}, {args.out / 'study.csv'}")
    return 0


def _csv(rows: list[dict]) -> str:
    keys = list(dict.fromkeys(k for r in rows for k in r))
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=keys)
    w.writeheader()
    w.writerows(rows)
    return buf.getvalue()


def _fmt(v, spec=".3f"):
    return "-" if v is None else format(v, spec)


def _print(study: dict) -> None:
    print(f"{'dir':5s} {'axis':>4s} {'bend':>6s} {'hidden L/R %':>13s} {'GT':>3s} {'count':>5s} {'arrays':>6s} "
          f"{'cure1':>5s} {'cure2':>5s} {'depth RMS mm':>12s} {'bnd mean mm':>11s}")
    for r in study["rows"]:
        print(f"{r['direction']:5s} {r['axis_deg']:4.0f} {r['bend_deg']:6.1f} {r['hidden_frac_left'] * 100:6.1f}/{r['hidden_frac_right'] * 100:5.1f} "
              f"{'yes' if r['false_boundary_gt'] else 'no':>3s} {str(r.get('counting_test')):>5s} "
              f"{str(r.get('arrays_disagree')):>6s} {str(r.get('cure1_removed', '-')):>5s} "
              f"{str(r.get('cure2_removed', '-')):>5s} {_fmt(r.get('depth_rms_mm'), '12.4f')} "
              f"{_fmt(r.get('boundary_mean_mm'), '11.3f')}")
    for k, v in study["precision_recall"].items():
        print(f"detection by {k:16s} precision {_fmt(v['precision'], '.2f')}, recall {_fmt(v['recall'], '.2f')} "
              f"(TP {v['true_positive']}, FP {v['false_positive']}, FN {v['false_negative']})")
    sm = study["smallest_hiding_bend_deg"]
    print(f"smallest bend hiding the boundary at the default rig: convex {_fmt(sm['down'], '.1f')} deg, "
          f"concave {_fmt(sm['up'], '.1f')} deg")
    for r in study["l_formula"]:
        print(f"L formula {r['bend_deg']:5.1f} deg: predicted {r['predicted_distance_m'] * 1e3:7.1f} mm, ground truth "
              f"{r['gt_distance_baseline_along_axis_m'] * 1e3:7.1f} mm (ratio "
              f"{_fmt(r['ratio_gt_over_predicted_baseline_along_axis'], '.3f')}); baseline along the bend "
              f"{r['gt_distance_baseline_along_bend_m'] * 1e3:7.1f} mm")
