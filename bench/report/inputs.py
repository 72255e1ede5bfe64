"""What a report reads: find the inputs under a directory, read them, refuse damaged ones.

Kinds of input, each recognised by the file that defines it:

* ``dataset``  a sweep dataset (``platebench sweep``): ``results.parquet`` / ``results.csv``,
  or a ``manifest.json`` of format ``platebench-sweep``; samples under ``samples/<id>/``;
* ``study``    a false-boundary study (``platebench study false-boundary``): ``study.json``,
  else ``study.csv``;
* ``sensing``  a sensing run (``platebench sense``): ``sensing.json``;
* ``recon``    a reconstruction (``platebench reconstruct``): ``recon.json``, with
  ``score.json`` beside it once ``platebench evaluate`` has scored it; or another method's
  output with its ``score.json`` (a peer's folder in a dataset sample);
* ``sample``   a rendered sample (``platebench render``): ``sample.json``;
* ``compare``  ``compare.json`` files of ``platebench compare``;
* ``score``    score documents of ``platebench evaluate`` on another program's output
  (``--disparity``, ``--depth``, ``--points``, ``--mesh``: ``F.score.json`` beside the file, or
  ``--out``): any JSON file holding ``kind`` (one of those four) and a ``score`` object.

``detect_inputs`` looks at the directory itself, then (where it is neither a dataset, a study,
a sensing run nor a reconstruction) two levels of subdirectories, so that the demo's folder
(``reference/{sample,recon}``, ``sensing/``, sweeps, ``study/``) is one report. A sample that a
reported reconstruction was made from is shown with that reconstruction, not twice.

Reading is strict: a truncated JSON file or a results table that is not one gives a one-line
``ReportInputError`` naming the file, never a report of half the input. Every ``sample_id``
of a results table must name a folder inside the dataset's own ``samples/`` (no ``..``, no
separator, no absolute path, no link leading out) before any file of it is opened.
"""
from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa

from platebench.bench.config.axes import PARAMETERS
from platebench.bench.files import JSON_MAX_BYTES, read_capped
from platebench.bench.io.layout import FORMAT, MANIFEST, RESULTS_CSV, RESULTS_PARQUET, SAMPLES
from platebench.bench.io.images import DatasetError
from platebench.bench.io.outputs import GENERATOR_REPORT, KINDS
from platebench.bench.io.parquet import read_parquet
from platebench.bench.io.table_checksums import verify_table
from platebench.errors import UserValueError
from platebench.evaluation.metrics_row import METRIC_FIELDS

__all__ = ["ReportInputError", "Inputs", "detect_inputs", "read_json", "read_manifest", "load_results",
           "load_study", "sample_folder", "records", "GENERATOR", "DATASET_FORMAT", "load_score_document",
           "score_document_paths", "SCORE_KINDS"]

GENERATOR = GENERATOR_REPORT  # index.html's <meta name="generator">: what marks a folder as a report
DATASET_FORMAT = FORMAT  # the sweep dataset's names come from bench/io/layout.py
MAX_DEPTH = 2  # subdirectory levels looked into
MAX_DIRS = 400  # directories looked at, at most
_SKIP = {"images", "gt", "plots", "thumbs", "__pycache__"}

# results-table columns by type (the typed parquet needs none of this; results.csv does)
TEXT_COLUMNS = ("sample_id", "method", "status", "error", "variant", "worker", "params_json",
                 *(p.name for p in PARAMETERS if p.kind == "str"))
NUMBER_COLUMNS = (*(p.name for p in PARAMETERS if p.kind != "str"),
                   *(n for n, f in METRIC_FIELDS.items() if f.metadata["kind"] in ("float", "int")),
                   "time_render_s", "time_recon_s", "time_eval_s", "time_total_s", "worker_maxrss_mb", "index")
FLAG_COLUMNS = tuple(n for n, f in METRIC_FIELDS.items() if f.metadata["kind"] == "bool")


class ReportInputError(UserValueError):
    """The input holds nothing to report, a damaged file, or the output directory cannot be used."""


@dataclass
class Inputs:
    """Directories (and compare.json files) found under ``root``, by kind, in a stable order."""

    root: Path
    datasets: list = field(default_factory=list)
    studies: list = field(default_factory=list)
    sensing: list = field(default_factory=list)
    recons: list = field(default_factory=list)
    samples: list = field(default_factory=list)
    compares: list = field(default_factory=list)
    links: list = field(default_factory=list)  # symbolic links under root: not followed (the report says so)
    scores: list = field(default_factory=list)  # score documents (files) of 'platebench evaluate' on outputs

    @property
    def empty(self) -> bool:
        return not (self.datasets or self.studies or self.sensing or self.recons or self.samples or self.compares
                    or self.scores)


# ----------------------------------------------------------------------------- files
def read_json(path: Path, what: str = "file"):
    """Parsed JSON of ``path``; a damaged file is a ReportInputError naming it (OSError passes)."""
    path = Path(path)
    data = read_capped(path, JSON_MAX_BYTES, what, ReportInputError, missing=f"{what} is missing")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise ReportInputError(f"{path}: not a UTF-8 text file (a damaged {what}?)") from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise ReportInputError(f"{path}: not valid JSON ({e.msg} at line {e.lineno}, column {e.colno}): "
                               f"a truncated or damaged {what}") from None


def _read_dict(path: Path, what: str) -> dict:
    doc = read_json(path, what)
    if not isinstance(doc, dict):
        raise ReportInputError(f"{path}: a {what} must be a JSON object, got {type(doc).__name__}")
    return doc


def read_manifest(dataset: Path) -> dict:
    """The dataset's manifest.json ({} when there is none; a damaged one is an error), its state as it
    stands: "running" only while a sweep writes it, "interrupted" once that sweep is gone
    (``bench.sweep.dataset.live_state``)."""
    from platebench.bench.sweep.dataset import live_state  # noqa: PLC0415

    path = Path(dataset) / MANIFEST
    if not path.is_file():
        return {}
    doc = _read_dict(path, "sweep manifest")
    if doc.get("format") != DATASET_FORMAT:
        raise ReportInputError(f"{path}: format {doc.get('format')!r}, expected {DATASET_FORMAT!r}")
    return live_state(doc, dataset)


# ----------------------------------------------------------------------------- detection
def _is_report(d: Path) -> bool:
    return KINDS["report"].recognised(d)


def _kinds(d: Path) -> set:
    kinds = set()
    if (d / RESULTS_PARQUET).is_file() or (d / RESULTS_CSV).is_file():
        kinds.add("dataset")
    elif (d / MANIFEST).is_file():
        doc = read_json(d / MANIFEST, "manifest")
        if isinstance(doc, dict) and doc.get("format") == DATASET_FORMAT:
            kinds.add("dataset")
    if (d / "study.json").is_file() or (d / "study.csv").is_file():
        kinds.add("study")
    if (d / "sensing.json").is_file():
        kinds.add("sensing")
    if (d / "recon.json").is_file() or (d / "score.json").is_file():
        kinds.add("recon")
    if (d / "sample.json").is_file():
        kinds.add("sample")
    return kinds


def _subdirs(d: Path, links: list | None = None) -> list[Path]:
    """The folders of ``d`` to look into; links among them go to ``links`` (never followed)."""
    try:
        found = sorted(p for p in d.iterdir() if p.is_dir() and not p.name.startswith(".")
                       and p.name not in _SKIP and not _is_report(p))
    except OSError:
        return []
    if links is not None:
        links += [p for p in found if p.is_symlink()]
    return [p for p in found if not p.is_symlink()]


def _through_link(root: Path, path: Path) -> bool:
    """Whether ``path`` (under ``root``) passes through a symbolic link below ``root``."""
    p = Path(root)
    for part in Path(path).relative_to(root).parts:
        p = p / part
        if p.is_symlink():
            return True
    return False


def recon_sample_dir(recon: Path, meta: dict | None = None) -> Path | None:
    """The sample a reconstruction was made from: ``recon.json``'s ``sample_dir`` if it exists,
    else a ``sample/`` beside the reconstruction's folder (the dataset and demo layouts)."""
    if meta is None:
        meta = _read_dict(Path(recon) / "recon.json", "reconstruction summary") \
            if (Path(recon) / "recon.json").is_file() else {}
    cands = [Path(str(meta["sample_dir"]))] if isinstance(meta.get("sample_dir"), str) else []
    cands += [Path(recon).parent / "sample", Path(recon).parent.parent / "sample"]
    return next((c for c in cands if (c / "sample.json").is_file()), None)


def detect_inputs(input_dir: Path) -> Inputs:
    """Datasets, studies, sensing runs, reconstructions, samples and compare.json files under
    ``input_dir`` (see the module doc)."""
    root = Path(input_dir)
    inp = Inputs(root)
    if not root.is_dir():
        return inp
    queue, seen = [(root, 0)], 0
    while queue and seen < MAX_DIRS:
        d, depth = queue.pop(0)
        seen += 1
        kinds = _kinds(d)
        for kind, bucket in (("dataset", inp.datasets), ("study", inp.studies), ("sensing", inp.sensing),
                             ("recon", inp.recons), ("sample", inp.samples)):
            if kind in kinds:
                bucket.append(d)
        inp.scores += _score_documents(d)  # e.g. a sensing run's merged surface, scored with evaluate --mesh
        if not kinds - {"sample"} and depth < MAX_DEPTH:  # a sample may hold its reconstruction
            queue += [(s, depth + 1) for s in _subdirs(d, inp.links)]
    inp.recons.sort(key=lambda r: (str(r.parent), r.name != "paper", r.name))  # the paper's pipeline first
    shown = {p.resolve() for r in inp.recons if (p := recon_sample_dir(r)) is not None}
    inp.samples = [s for s in inp.samples if s.resolve() not in shown]
    inp.compares = _find_compares(root, inp.datasets)
    return inp


SCORE_KINDS = ("disparity", "depth", "points", "mesh")
# JSON files that are something else: never read as score documents
_NOT_SCORES = {"manifest.json", "study.json", "sensing.json", "recon.json", "sample.json", "calib.json",
               "pattern.json", "compare.json", "visibility.json", "export.json", "result.json", "score.json"}
_MAX_SCORE_BYTES = 4 * 2**20


def _score_documents(d: Path) -> list[Path]:
    """The score documents in folder ``d`` (module doc), sorted by name."""
    out = []
    try:
        files = sorted(p for p in d.glob("*.json") if p.is_file() and p.name not in _NOT_SCORES)
    except OSError:
        return out
    for p in files:
        if p.stat().st_size > _MAX_SCORE_BYTES:
            continue
        try:
            doc = json.loads(p.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError):
            continue  # not a score document (any other JSON file of the folder)
        if isinstance(doc, dict) and doc.get("kind") in SCORE_KINDS and isinstance(doc.get("score"), dict):
            out.append(p)
    return out


def load_score_document(path: Path) -> dict:
    """A score document (module doc); anything else is a ReportInputError naming the file."""
    doc = _read_dict(Path(path), "score document")
    if doc.get("kind") not in SCORE_KINDS or not isinstance(doc.get("score"), dict):
        raise ReportInputError(f"{path}: not a score document of 'platebench evaluate' (needs kind one of "
                               f"{', '.join(SCORE_KINDS)} and a score object)")
    return doc


def _found_path(text, near: Path, sibling_stem: str | None = None) -> Path | None:
    """A path a score document names, as written when it was scored (relative to where evaluate ran):
    as it is, else relative to the document's folder or the folders above it; for the output, else
    a file beside the document with its stem (F.score.json is written beside F)."""
    cands = []
    if isinstance(text, str) and text:
        p = Path(text)
        cands.append(p)
        if not p.is_absolute():
            cands += [base / p for base in [near, *list(near.parents)[:3]]]
            cands += [near / p.name]
    if sibling_stem:
        cands += sorted(q for q in near.glob(f"{sibling_stem}.*") if not q.name.endswith(".json"))
    return next((c for c in cands if c.exists()), None)


def score_document_paths(path: Path, doc: dict) -> tuple[Path | None, Path | None]:
    """(the sample directory, the scored output file) a score document names, where they are found."""
    path = Path(path)
    stem = path.name[: -len(".score.json")] if path.name.endswith(".score.json") else None
    sample = _found_path(doc.get("sample"), path.parent)
    if sample is not None and not (sample / "sample.json").is_file():
        sample = None
    output = _found_path(doc.get("input"), path.parent, stem)
    return sample, (output if output is not None and output.is_file() else None)


def _find_compares(root: Path, datasets: list) -> list[Path]:
    found = []
    for pattern in ("compare.json", "*/compare.json", "*/*/compare.json"):
        found += sorted(root.glob(pattern))
    for ds in datasets:
        found += sorted((ds / SAMPLES).glob("*/sample/compare/compare.json"))
        found += sorted((ds / SAMPLES).glob("*/compare/compare.json"))
    out, seen = [], set()
    for p in found:
        if _through_link(root, p):
            continue  # never followed out of the input
        rp = p.resolve()
        inside = p.relative_to(root).parts[:-1]
        if rp in seen or any(_is_report(root.joinpath(*inside[:k + 1])) for k in range(len(inside))):
            continue
        doc = _read_dict(p, "comparison")
        if isinstance(doc.get("methods"), dict):
            seen.add(rp)
            out.append(p)
    return out


# ----------------------------------------------------------------------------- results table
def records(frame: pd.DataFrame) -> list[dict]:
    """The rows of ``frame`` as dicts of plain Python values, None where missing."""
    return [{k: _plain(v) for k, v in r.items()} for r in frame.to_dict("records")]


def _plain(v):
    if v is None or v is pd.NA or v is pd.NaT:
        return None
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, float) and math.isnan(v):
        return None
    return v


def _read_table(path: Path) -> pd.DataFrame:
    """results.parquet (typed) or results.csv (types from the column registries) as a frame."""
    if path.suffix == ".parquet":
        try:
            return read_parquet(path).to_pandas(use_threads=False)
        except (pa.ArrowException, ValueError) as e:
            raise ReportInputError(f"{path}: not a readable Parquet table ({_first_line(e)})") from None
    return _read_csv(path, TEXT_COLUMNS)


def _read_csv(path: Path, text_columns) -> pd.DataFrame:
    try:
        return pd.read_csv(path, dtype={c: object for c in text_columns}, keep_default_na=False, na_values=[""],
                           encoding="utf-8")
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError, csv.Error) as e:
        raise ReportInputError(f"{path}: not a readable CSV table ({_first_line(e)})") from None


def _first_line(e: BaseException) -> str:
    text = str(e).strip()
    return (text.splitlines()[0] if text else type(e).__name__)[:200]


def _check_table(frame: pd.DataFrame, path: Path) -> pd.DataFrame:
    """Columns present and of their types; flags as True/False/None (object), numbers as floats."""
    missing = [c for c in ("sample_id", "method") if c not in frame.columns]
    if missing:
        cols = ", ".join(map(str, list(frame.columns)[:6]))
        raise ReportInputError(f"{path}: not a PlateBench results table: no column {missing[0]!r} "
                               f"(columns: {cols or 'none'})")
    frame = frame.copy()
    for c in frame.columns:
        col = frame[c]
        known = col.notna()
        if c in FLAG_COLUMNS or (c not in NUMBER_COLUMNS and c not in TEXT_COLUMNS and known.any()
                                  and col[known].map(lambda v: isinstance(v, (bool, np.bool_))).all()):
            bad = known & ~col.map(lambda v: isinstance(v, (bool, np.bool_)))
            if bad.any():
                raise _bad_cell(path, frame, c, bad, "true or false")
            frame[c] = col.astype(object).where(known, None).map(lambda v: None if v is None else bool(v))
        elif c in NUMBER_COLUMNS or (c not in TEXT_COLUMNS and pd.api.types.is_numeric_dtype(col)):
            num = pd.to_numeric(col, errors="coerce")
            bad = known & num.isna()
            if bad.any() or pd.api.types.is_bool_dtype(col):
                raise _bad_cell(path, frame, c, bad if bad.any() else known, "a number")
            frame[c] = num.astype(float)
        elif c in TEXT_COLUMNS:
            frame[c] = col.astype(object).where(known, None).map(lambda v: None if v is None else str(v))
    return frame


def _bad_cell(path: Path, frame: pd.DataFrame, column: str, bad: pd.Series, allowed: str) -> ReportInputError:
    i = int(np.flatnonzero(bad.to_numpy())[0])
    where = f"line {i + 2}" if path.suffix == ".csv" else f"row {i + 1}"
    return ReportInputError(f"{path}: {where}, column {column!r}: {frame[column].iloc[i]!r} is not {allowed}")


def sample_folder(dataset: Path, sample_id, where: str = "") -> Path:
    """``DATASET/samples/<sample_id>`` after checking that the id names a folder inside the
    dataset's own ``samples/`` (a plain name: no separator, no ``..``, not absolute, and no link
    that leads out). Raises ReportInputError naming the id and ``where`` it came from."""
    base = Path(dataset) / SAMPLES
    sid = sample_id if isinstance(sample_id, str) else None
    bad = (sid is None or sid in ("", ".", "..") or any(c in sid for c in "/\\\x00")
           or Path(sid).is_absolute())
    if not bad:
        path = base / sid
        try:
            bad = not path.resolve().is_relative_to(base.resolve())
        except (OSError, RuntimeError):  # a link loop
            bad = True
    if bad:
        raise ReportInputError(f"{where or dataset}: sample_id {sample_id!r} is not the name of a folder inside "
                               f"{base} (allowed: a plain folder name, no '/', no '..', no absolute path, no link "
                               "leading out of the dataset)")
    return path


def load_results(dataset: Path) -> tuple[pd.DataFrame | None, str]:
    """The dataset's results table (``results.parquet``, else ``results.csv``) as a typed frame, and
    the file name it came from; (None, "") when the dataset has no table yet.

    Flags are True/False/None (object columns), numbers floats (NaN missing), text str/None. Every
    sample_id is checked with ``sample_folder`` here, before anything opens a sample's files."""
    d = Path(dataset)
    path = next((d / n for n in (RESULTS_PARQUET, RESULTS_CSV) if (d / n).is_file()), None)
    if path is None:
        return None, ""
    try:
        verify_table(path)
    except DatasetError as e:
        raise ReportInputError(str(e)) from None
    frame = _check_table(_read_table(path), path)
    for i, sid in enumerate(frame["sample_id"]):
        where = f"{path}: {'line' if path.suffix == '.csv' else 'row'} {i + 2 if path.suffix == '.csv' else i + 1}"
        sample_folder(d, sid, where)
    return frame.reset_index(drop=True), path.name


# ----------------------------------------------------------------------------- study
def load_study(study_dir: Path) -> dict:
    """study.json (a JSON object whose ``rows`` is a list of objects), else the rows of study.csv,
    with ``source`` naming the file read. A damaged file is a ReportInputError."""
    d = Path(study_dir)
    if (d / "study.json").is_file():
        path = d / "study.json"
        doc = _read_dict(path, "study")
        rows = doc.get("rows", [])
        if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
            raise ReportInputError(f"{path}: 'rows' must be a list of objects")
        return {**doc, "rows": rows, "source": "study.json"}
    path = d / "study.csv"
    frame = _read_csv(path, ("direction", "status", "error", "family", "cure_error"))
    if "bend_deg" not in frame.columns:
        raise ReportInputError(f"{path}: not a study table: no column 'bend_deg'")
    return {"rows": records(frame), "source": "study.csv"}


def load_sensing(sensing_dir: Path) -> dict:
    """sensing.json as a dict (must hold ``steps`` as a list and ``final`` as an object)."""
    path = Path(sensing_dir) / "sensing.json"
    doc = _read_dict(path, "sensing record")
    if not isinstance(doc.get("steps", []), list) or not isinstance(doc.get("final", {}), dict):
        raise ReportInputError(f"{path}: 'steps' must be a list and 'final' an object")
    return doc


def load_recon(recon_dir: Path) -> tuple[dict, dict | None]:
    """(recon.json or {} for another method's output, score.json or None when not scored yet)."""
    d = Path(recon_dir)
    meta = _read_dict(d / "recon.json", "reconstruction summary") if (d / "recon.json").is_file() else {}
    score = _read_dict(d / "score.json", "score") if (d / "score.json").is_file() else None
    return meta, score


def load_sample_meta(sample_dir: Path) -> dict:
    return _read_dict(Path(sample_dir) / "sample.json", "sample description")


def load_compare(path: Path) -> dict:
    return _read_dict(path, "comparison")
