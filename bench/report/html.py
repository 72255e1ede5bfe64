"""``write_report(input_dir, out_dir=None)``: the HTML report of whatever ``input_dir`` holds.

Inputs (``bench.report.inputs``): sweep datasets, false-boundary studies, sensing runs,
reconstructions (with their score.json), rendered samples, compare.json files and the score
documents of ``platebench evaluate`` on other programs' outputs, in
``input_dir`` itself or up to two levels below it (the demo's folder is one report). The page
(``OUT/index.html``, default ``OUT = input_dir/report``) starts with a headline (the
experiment's key figures and the paper's bound met or not, each dataset's and study's summary,
a sensing run's outcome; a dataset's key figures per method in a table, a plausibility warning
beside the figure it concerns), then one section per input. A method has one colour in every plot
(``bench.report.colours``); a plot or panel with nothing to show is left out and said in one line.
Paths are shown relative to the input folder or to the report's folder, by the names they have once
in place (never a staging folder's). It comes from the Jinja2 templates in
``templates/`` (autoescaped; no scripts, no external assets). Every image is embedded as a data
URI, so ``index.html`` alone is the report: the plots (kept as PNG files in ``OUT/plots/`` too)
and thumbnails of the samples' images; links to sample and reconstruction folders are relative
to ``OUT``.

The report follows the output rule (``bench.io.outputs``): ``OUT`` is new, or, with
``overwrite``, an earlier report (its ``index.html`` carries ``<meta name="generator"
content="platebench report">``) or an empty folder; it is never the input, a folder holding it,
or a folder inside it other than ``input_dir/report``. It is staged and renamed into place: it
appears complete or not at all. Damaged inputs (a truncated JSON file, a results table that is
not one, a sample_id leading out of its dataset) raise ``ReportInputError`` (one line) before
anything is written. What the report cannot show faithfully (a sample folder that is gone, a
truncated or unreadable image, a file that differs from its recorded checksum, a link leading
out of the input) is left out and said: in the page's notes and to ``warn(message)``.
"""
from __future__ import annotations

import datetime as _dt
import functools
import os
from importlib import metadata
from pathlib import Path

import jinja2

from platebench.bench.files import require_dir
from platebench.bench.io.atomic import write_text
from platebench.bench.io.outputs import output_dir
from platebench.bench.report.colours import method_colours
from platebench.bench.report.dataset import dataset_section
from platebench.bench.report.experiment import compare_section, recon_section, sample_section, score_section
from platebench.bench.report.inputs import (
    GENERATOR,
    Inputs,
    ReportInputError,
    detect_inputs,
    load_compare,
    load_results,
    recon_sample_dir,
)
from platebench.bench.report.page import Page, normalise_section
from platebench.bench.report.sensing import sensing_section, study_section
from platebench.bench.report.values import fmt

__all__ = ["write_report", "render_page", "ReportInputError", "GENERATOR", "MAX_COMPARES"]

TEMPLATES = Path(__file__).resolve().parent / "templates"
MAX_COMPARES = 12


@functools.cache
def _environment() -> jinja2.Environment:
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(TEMPLATES), autoescape=True,
                             undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True)
    env.filters["fmt"] = fmt
    return env


def render_page(template: str, **context) -> str:
    """Render one of ``templates/`` with ``context`` (every value escaped)."""
    return _environment().get_template(template).render(**context)


def _numbered(paths: list, kind: str) -> list[tuple[Path, str]]:
    """(path, anchor) with anchors kind, or kind1, kind2, ... when there are several."""
    return [(p, kind if len(paths) == 1 else f"{kind}{i + 1}") for i, p in enumerate(paths)]


def _generic(page: Page, builder, path: Path, anchor: str, nav: str) -> dict:
    d = normalise_section(page, builder(path, page.section_dir(anchor)), page.section_dir(anchor), path)
    d = {**d, "summary": page.shown(d["summary"]), "notes": [page.shown(n) for n in d["notes"]]}
    figures = d["figures"][:6] + [f for f in d["figures"][6:] if f.get("warning")]  # a warned figure always
    head = {"label": f"{d['title']} ({page.rel(path)})", "figures": figures,
            "text": (f"Outcome: {d['outcome']}. " if d["outcome"] else "") + d["summary"], "met": None}
    return {**d, "kind": "generic", "rel": page.rel(path), "anchor": anchor, "nav": nav, "headline": head}


def _sections(page: Page, inp: Inputs) -> list[dict]:
    """One section per input: experiments first, then sensing runs, datasets, studies, comparisons."""
    out = []
    shown: set = set()  # samples already shown with a reconstruction
    for path, a in _numbered(inp.recons, "recon"):
        sample = recon_sample_dir(path)
        key = None if sample is None else sample.resolve()
        out.append({**recon_section(page, path, f"{a}_", show_sample=key not in shown), "anchor": a,
                    "nav": f"reconstruction {page.rel(path)}"})
        shown.add(key)
    for path, a in _numbered(inp.samples, "sample"):
        out.append({**sample_section(page, path, f"{a}_"), "anchor": a, "nav": f"sample {page.rel(path)}"})
    for path, a in _numbered(inp.scores, "score"):
        out.append(_generic(page, score_section, path, a, f"score {page.rel(path)}"))
    for path, a in _numbered(inp.sensing, "sensing"):
        out.append(_generic(page, sensing_section, path, a, f"sensing {page.rel(path)}"))
    for path, a in _numbered(inp.datasets, "dataset"):
        out.append({**dataset_section(page, path, f"{a}_"), "anchor": a, "nav": f"dataset {page.rel(path)}"})
    for path, a in _numbered(inp.studies, "study"):
        out.append(_generic(page, study_section, path, a, f"study {page.rel(path)}"))
    for i, path in enumerate(inp.compares[:MAX_COMPARES]):
        a = f"compare{i + 1}"
        out.append({**compare_section(page, path, f"{a}_"), "anchor": a, "nav": f"compare {page.rel(path.parent)}"})
    if len(inp.compares) > MAX_COMPARES:
        page.notes.append(f"{len(inp.compares) - MAX_COMPARES} more compare.json files not shown")
    return out


def _methods(inp: Inputs) -> set[str]:
    """Every method the report's plots show: the datasets' and the comparisons' (one colour map)."""
    out: set[str] = set()
    for ds in inp.datasets:
        frame, _ = load_results(ds)
        if frame is not None and "method" in frame.columns:
            out |= {str(m) for m in frame["method"].dropna()}
    for path in inp.compares[:MAX_COMPARES]:
        out |= {str(m) for m in (load_compare(path).get("methods") or {})}
    return out


def _found(inp: Inputs) -> str:
    kinds = (("datasets", "dataset(s)"), ("studies", "study(ies)"), ("sensing", "sensing run(s)"),
             ("recons", "reconstruction(s)"), ("samples", "sample(s)"), ("compares", "compare.json file(s)"),
             ("scores", "score document(s)"))
    return ", ".join(f"{len(getattr(inp, k))} {label}" for k, label in kinds if getattr(inp, k))


def _version() -> str:
    try:
        return metadata.version("platebench")
    except metadata.PackageNotFoundError:
        return "?"


def write_report(input_dir, out_dir=None, overwrite: bool = False, warn=None) -> Path:
    """Write the HTML report of whatever ``input_dir`` holds (see module doc); returns index.html's path.

    Raises ReportInputError (one line) when ``input_dir`` holds nothing to report or a damaged
    input; ``bench.io.outputs.OutputRefusedError`` when ``out_dir`` may not be written (module doc).
    ``warn(message)``: told of each part left out of the page (also in the page's notes)."""
    root = require_dir(Path(input_dir), "directory", ReportInputError)
    inp = detect_inputs(root)
    if inp.empty:
        raise ReportInputError(f"{root} holds neither a sweep dataset (manifest.json / results.csv) nor a "
                               "false-boundary study (study.json / study.csv) nor a sensing run (sensing.json) nor "
                               "a reconstruction (recon.json) nor a sample (sample.json) nor a compare.json nor a "
                               "score document of 'platebench evaluate' (F.score.json): nothing to report")
    out = Path(out_dir) if out_dir is not None else root / "report"
    with output_dir(out, "report", overwrite=overwrite, inputs=[root], slots=[root / "report"]) as stage:
        page = Page(stage, out, root, warn=warn, colours=method_colours(_methods(inp)))
        for link in inp.links:
            page.leave_out(f"{link} is a symbolic link (to {os.readlink(link)}): not followed, not reported")
        sections = _sections(page, inp)
        text = render_page("report.html", generator=GENERATOR, name=page.root_name, input=page.from_report(root),
                           found=_found(inp), version=_version(), notes=page.notes, sections=sections,
                           headline=[s["headline"] for s in sections if s.get("headline")],
                           generated=_dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"))
        write_text(stage / "index.html", text)
    return out / "index.html"
