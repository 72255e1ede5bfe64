"""Sweep dataset layout: manifest, per-sample results, results table (CSV + Parquet), resume.

Layout (format ``platebench-sweep`` version 1)::

    DATASET/manifest.json          spec (parsed + its TOML text + sha256), package versions, executor,
                                   counts, and per sample: id, axis values, config sha256, status,
                                   error, worker, result.json / sample.json / score.json checksums
                                   and the image checksums
    DATASET/spec.toml              the spec file as given
    DATASET/results.csv            one row per sample and method (``COLUMNS``); units in the names
    DATASET/results.parquet        the same table (pyarrow), typed
    DATASET/samples/<id>/sample/   the rendered sample (layout version 1, see bench/io/layout.py)
    DATASET/samples/<id>/recon/<method>/   the method's reconstruction + score.json
    DATASET/samples/<id>/result.json       status, error, metrics per method, timings, worker,
                                   the sha256 of EVERY file of the sample directory
    DATASET/../.DATASET.lock       the dataset lock while a sweep writes it (bench.io.atomic.OutputLock)

Results columns: the sample's parameters as rendered (bend_deg, axis_deg in degrees, sizes
in metres, pixels, ...; ``params_json`` holds the spec's axis values), then the metrics
(``METRIC_COLUMNS``, units in the names, empty when a method does not produce them or
failed), timings and the worker. ``coverage_frac``, for every method: the share of the left
view's plate pixels with an estimate (``evaluation.pixel_coverage``; for "paper" those whose true
ray hits its interpolated surface). ``time_render_s`` is the sample's render (+ the method's own
pattern sequence for peers), ``time_total_s`` the whole sample task.

One writer per sample: a worker makes a sample in its own attempt directory
(``samples/.tmp-<id>~HOST~PID~R``, ``make_attempt_dir``) and returns its result; only the
sweep process commits it (``commit_sample``: every file's checksum verified, ``result.json``
written, the directory renamed to ``samples/<id>`` in one step). A sample directory with a
``result.json`` is therefore complete; an attempt nobody committed (a lost worker, a worker
that outlived its scheduler) is swept by the next run. The manifest and the tables are
derived from the committed ``result.json`` files, written atomically after each result (at
most every ``flush_every_s`` when writing them gets slow) and rebuilt by every run, so a
kill -9 loses nothing. A sample counts as done when ``validate_result`` accepts it: right
sample id and configuration, and every file its result and the manifest list still has the
listed checksum (a truncated image, a deleted points.csv: the sample is redone).
``read_manifest`` reports a "running" manifest whose writer is gone as "interrupted".
"""
from __future__ import annotations

import csv
import datetime as _dt
import hashlib
import io
import json
import math
import os
import secrets
import shutil
from dataclasses import replace
from importlib import metadata
from pathlib import Path

from platebench.bench.config.axes import PARAMETERS
from platebench.bench.io.atomic import (
    HOST,
    OutputLock,
    is_temp_name,
    owner_alive,
    swap_in,
    sweep_stale,
    temp_owner,
    write_bytes,
    write_json,
    write_text,
)
from platebench.bench.io.table_checksums import write_table_checksums
from platebench.bench.io.layout import (  # noqa: F401  (re-exported: the dataset's names)
    FORMAT,
    MANIFEST,
    RESULT,
    RESULT_FORMAT,
    RESULTS_CHECKSUMS,
    RESULTS_CSV,
    RESULTS_PARQUET,
    SAMPLES,
    SPEC_COPY,
    VERSION,
)
from platebench.bench.io.codecs import encode
from platebench.bench.io.dataset_state import dataset_lock, live_state  # noqa: F401  (re-exported)
from platebench.bench.io.sweep_records import SampleResult, table_rows
from platebench.bench.io.outputs import file_sha256, foreign_entries, guard_output
from platebench.errors import UserValueError
from platebench.evaluation.metrics_row import METRIC_FIELDS, METRIC_NAMES

STATUSES = ("ok", "failed")

# (column, type) of the results table; "str", "int", "float", "bool"; None where unknown
COLUMNS = (
    ("sample_id", "str"), ("index", "int"), ("method", "str"), ("status", "str"), ("error", "str"),
    *((p.name, p.kind) for p in PARAMETERS),
    *((name, f.metadata["kind"]) for name, f in METRIC_FIELDS.items()),
    ("time_render_s", "float"), ("time_recon_s", "float"), ("time_eval_s", "float"), ("time_total_s", "float"),
    ("variant", "str"), ("worker", "str"), ("worker_maxrss_mb", "float"), ("params_json", "str"),
)
COLUMN_NAMES = tuple(c for c, _ in COLUMNS)
METRIC_COLUMNS = METRIC_NAMES


class DatasetLayoutError(UserValueError):
    """The output directory cannot be used for this sweep (one-line message)."""


def now_utc() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")


def sample_dir(dataset: Path, sample_id: str) -> Path:
    return Path(dataset) / SAMPLES / sample_id


def text_sha256(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()


def make_attempt_dir(dataset: Path, sample_id: str) -> Path:
    """A new private directory for one attempt at a sample (``samples/.tmp-<id>~HOST~PID~R``)."""
    parent = Path(dataset) / SAMPLES
    d = parent / f".tmp-{sample_id}~{HOST}~{os.getpid()}~{secrets.token_hex(4)}"
    d.mkdir(parents=False)
    return d


def attempt_dirs(dataset: Path) -> list[tuple[str, str, int, Path]]:
    """(sample id, host, pid, path) of every uncommitted attempt directory of the dataset."""
    out = []
    root = Path(dataset) / SAMPLES
    if not root.is_dir():
        return out
    for p in root.iterdir():
        owner = temp_owner(p.name)
        if p.name.startswith(".tmp-") and owner is not None and p.is_dir():
            out.append((p.name[len(".tmp-"):].split("~", 1)[0], owner[0], owner[1], p))
    return out


def tree_checksums(root: Path) -> dict:
    """sha256 of every file under ``root`` (relative POSIX path -> hex), temporary names excluded."""
    root = Path(root)
    out = {}
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if not is_temp_name(d))
        for name in sorted(filenames):
            if is_temp_name(name):
                continue
            p = Path(dirpath) / name
            out[p.relative_to(root).as_posix()] = file_sha256(p)
    out.pop(RESULT, None)
    return out


class CommitError(RuntimeError):
    """A worker's attempt directory does not hold what its result lists (lost or corrupt in transit)."""


def commit_sample(dataset: Path, res: SampleResult) -> SampleResult:
    """Commit one sample (sweep process only): verify the attempt's files against the checksums its
    result lists, write ``result.json`` into it and rename it to ``samples/<id>`` (replacing an older
    attempt). A result without files (the task never ran) gets a directory with ``result.json`` only.
    Returns the result with ``result_sha256``. Raises ``CommitError`` if a file is missing or differs."""
    dataset = Path(dataset)
    sid = res.sample_id
    stage = Path(res.stage) if res.stage else None
    if stage is None or not stage.is_dir():
        if res.files:
            raise CommitError(f"sample {sid}: its attempt directory {stage} is gone")
        stage = make_attempt_dir(dataset, sid)
    if stage.parent.resolve() != (dataset / SAMPLES).resolve():
        raise CommitError(f"sample {sid}: attempt directory {stage} is outside {dataset / SAMPLES}")
    found = tree_checksums(stage)
    bad = sorted(k for k in set(res.files) | set(found) if found.get(k) != res.files.get(k))
    if bad:
        raise CommitError(f"sample {sid}: {stage.name}/{bad[0]} does not match its checksum "
                          f"({len(bad)} file(s) differ)")
    write_json(stage / RESULT, res.to_dict())
    swap_in(stage, sample_dir(dataset, sid))
    if stage.is_symlink():  # what stood at samples/<id> was a link: remove the link, never what it points to
        stage.unlink()
    elif stage.exists():  # the replaced older attempt
        shutil.rmtree(stage, ignore_errors=True)
    return replace(res, stage=None, result_sha256=file_sha256(sample_dir(dataset, sid) / RESULT))


def sweep_attempts(dataset: Path, force: bool = False) -> int:
    """Remove uncommitted attempt directories: all of them (``force``: under the dataset lock, at the
    start of a run) or those whose writer is gone (same host, process not running)."""
    n = 0
    for _sid, host, pid, p in attempt_dirs(dataset):
        if force or not owner_alive(host, pid):
            shutil.rmtree(p, ignore_errors=True)
            n += 1
    return n


def package_versions() -> dict:
    from platebench.bench.io.versions import package_versions as sample_versions  # noqa: PLC0415
    out = sample_versions()
    for name in ("dask", "distributed", "pyarrow", "tqdm"):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


# ----------------------------------------------------------------------------- per-sample result
def validate_result(dataset: Path, sample_id: str, config_sha256: str | None = None,
                    manifest_files: dict | None = None) -> SampleResult | None:
    """The sample's result.json (a ``SampleResult``) if it exists and is valid (see module doc), else None.

    ``manifest_files``: the checksums the manifest lists for the sample; they must agree too."""
    d = sample_dir(dataset, sample_id)
    if d.is_symlink():  # a sample is a folder of the dataset, never a link to elsewhere
        return None
    path = d / RESULT
    try:
        res = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(res, dict) or res.get("format") != RESULT_FORMAT or res.get("version") != VERSION:
        return None
    if res.get("sample_id") != sample_id or res.get("status") not in STATUSES:
        return None
    if config_sha256 is not None and res.get("config_sha256") != config_sha256:
        return None
    if not isinstance(res.get("rows"), list) or not res["rows"]:
        return None
    files = res.get("files")
    if not isinstance(files, dict) or (res["status"] == "ok" and not files):
        return None
    if manifest_files and any(files.get(k) != v for k, v in manifest_files.items()):
        return None
    for rel, digest in files.items():
        p = d / rel
        try:
            if not p.resolve().is_relative_to(d.resolve()) or file_sha256(p) != digest:
                return None
        except OSError:
            return None
    return SampleResult.from_dict(res)


# ----------------------------------------------------------------------------- table rows
def _cell(v, kind: str):
    if v is None:
        return None
    if kind == "float":
        v = float(v)
        return v if math.isfinite(v) else None
    if kind == "int":
        return int(v)
    if kind == "bool":
        return bool(v)
    return str(v)


def columns_of(rows: list[dict]) -> tuple:
    """(name, kind) of the table's columns: ``COLUMNS``, then the methods' own metrics (``extra`` of
    their ``MetricsRow``; bool or float, in sorted order) after the shared metric columns."""
    known = set(COLUMN_NAMES)
    extra: dict = {}
    for r in rows:
        for k, v in r.items():
            if k not in known and v is not None:
                extra[k] = "bool" if isinstance(v, bool) and extra.get(k, "bool") == "bool" else "float"
            elif k not in known:
                extra.setdefault(k, "float")
    cut = COLUMN_NAMES.index(METRIC_COLUMNS[-1]) + 1
    return COLUMNS[:cut] + tuple(sorted(extra.items())) + COLUMNS[cut:]


def table_columns(rows: list[dict], columns: tuple | None = None) -> dict:
    """Column name -> list of typed cells (None = missing)."""
    return {name: [_cell(r.get(name), kind) for r in rows] for name, kind in (columns or columns_of(rows))}


def csv_text(rows: list[dict]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    columns = columns_of(rows)
    w.writerow([name for name, _ in columns])
    cols = table_columns(rows, columns)
    for i in range(len(rows)):
        line = []
        for name, kind in columns:
            v = cols[name][i]
            line.append("" if v is None else (repr(v) if kind == "float" else str(v).lower() if kind == "bool"
                                              else str(v)))
        w.writerow(line)
    return buf.getvalue()


def parquet_bytes(rows: list[dict]) -> bytes:
    import pyarrow as pa  # noqa: PLC0415
    import pyarrow.parquet as pq  # noqa: PLC0415
    types = {"str": pa.string(), "int": pa.int64(), "float": pa.float64(), "bool": pa.bool_()}
    columns = columns_of(rows)
    cols = table_columns(rows, columns)
    schema = pa.schema([(name, types[kind]) for name, kind in columns])
    table = pa.table({name: pa.array(cols[name], type=types[kind]) for name, kind in columns}, schema=schema)
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink)
    return sink.getvalue().to_pybytes()


def write_results(dataset: Path, results: list[SampleResult]) -> list[dict]:
    """Write results.csv and results.parquet (atomically) from the samples' results, then their sha256
    (``bench.io.table_checksums``); returns the rows."""
    rows = [r for res in sorted(results, key=lambda x: x.index or 0) for r in table_rows(res)]
    tables = {RESULTS_CSV: csv_text(rows).encode(), RESULTS_PARQUET: parquet_bytes(rows)}
    for name, data in tables.items():
        write_bytes(Path(dataset) / name, data)
    write_table_checksums(Path(dataset), tables)
    return rows


def read_results(dataset: Path):
    """The results table as a pyarrow Table."""
    from platebench.bench.io.parquet import read_parquet  # noqa: PLC0415
    return read_parquet(Path(dataset) / RESULTS_PARQUET)


# ----------------------------------------------------------------------------- manifest
def manifest_dict(spec, results: dict, executor: dict | None, started: str, state: str,
                  packages: dict | None = None) -> dict:
    """The manifest: ``results`` maps sample id -> ``SampleResult`` (completed samples only)."""
    samples = []
    counts = {"total": len(spec.samples), "ok": 0, "failed": 0, "pending": 0}
    for plan in spec.samples:
        res = results.get(plan.sample_id)
        entry = {"id": plan.sample_id, "index": plan.index, "params": plan.params,
                 "config_sha256": plan.config_sha256, "pose": plan.pose}
        if res is None:
            entry["status"] = "pending"
            counts["pending"] += 1
        else:
            entry["status"] = res.status
            counts[res.status] += 1
            entry["error"] = res.error
            entry["methods"] = {r.method: {"status": r.status, "error": r.error} for r in res.rows}
            entry["result_sha256"] = res.result_sha256
            entry["files_sha256"] = res.files
            entry["images_sha256"] = res.images
            w = res.worker or {}
            entry["worker"] = f"{w.get('host')}:{w.get('pid')}" if w else None
        samples.append(entry)
    return {"format": FORMAT, "version": VERSION, "state": state, "writer": {"host": HOST, "pid": os.getpid()},
            "created_utc": started,
            "updated_utc": now_utc(), "spec": encode(spec), "spec_text": spec.text,
            "packages": packages if packages is not None else package_versions(), "executor": executor or {},
            "counts": counts,
            "layout": {"samples": f"{SAMPLES}/<id>/sample", "recon": f"{SAMPLES}/<id>/recon/<method>",
                       "result": f"{SAMPLES}/<id>/{RESULT}", "results": [RESULTS_CSV, RESULTS_PARQUET]},
            "samples": samples}


def read_manifest(dataset: Path) -> dict | None:
    """The manifest, or None. A manifest left "running" by a sweep that is gone (killed: nobody holds
    the dataset lock) reads as "interrupted" (``live_state``)."""
    try:
        m = json.loads((Path(dataset) / MANIFEST).read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(m, dict) or m.get("format") != FORMAT:
        return None
    return live_state(m, dataset)


def check_dataset(out: Path, spec, resume: bool, overwrite: bool) -> dict | None:
    """Check that ``out`` can take this sweep, before anything is written; returns its manifest
    (None for a new dataset). Call it holding the dataset lock.

    A dataset whose ``manifest.json`` is lost or damaged is still a dataset by its samples (their own
    ``result.json`` files): ``--overwrite`` replaces it, and ``--resume`` continues it from a manifest
    rebuilt from them (``recover_manifest``: marked ``"recovered"``), when every committed sample belongs
    to this spec."""
    out = Path(out)
    if overwrite:  # the output rule (bench.io.outputs): never the root, the working directory, a link
        guard_output(out)
    if os.path.lexists(out) and not out.is_dir():
        raise DatasetLayoutError(f"{out} exists and is not a directory")
    if not (out.is_dir() and any(out.iterdir())):
        return None  # new, or an empty folder (a mount point made for the dataset): nothing there to lose
    manifest = read_manifest(out)
    if manifest is None and (overwrite or resume):
        manifest = recover_manifest(out, spec if resume else None)
    if overwrite:
        if manifest is None:
            foreign = sorted(p.name for p in out.iterdir() if p.name not in _DATASET_NAMES and not is_temp_name(p.name))
            raise DatasetLayoutError(f"{out} is not empty and holds no sweep manifest"
                                     + (f" but {foreign[0]!r}, which no sweep writes" if foreign else
                                        " and no committed sample") + ": refusing to replace it")
        foreign = foreign_entries(out, "dataset") or []
        if foreign:
            raise DatasetLayoutError(f"{out}: holds {foreign[0]}, which PlateBench did not write: refusing to replace "
                                     "it (move it out, or choose another --out)")
        return manifest
    if resume:
        if manifest is None and _started_skeleton(out, spec):
            return None  # a sweep killed before its first manifest: nothing committed to keep, start it
        if manifest is None:
            raise DatasetLayoutError(f"{out}: no valid {MANIFEST} to resume from (is it a sweep dataset?)")
        old = (manifest.get("spec") or {}).get("sha256")
        if old != spec.sha256:
            raise DatasetLayoutError(f"{out} was made from a different spec (sha256 {str(old)[:12]} vs "
                                     f"{spec.sha256[:12]}): use another --out, or --overwrite")
        return manifest
    raise DatasetLayoutError(f"{out} already exists (use --resume to continue it or --overwrite to replace it)")


_DATASET_NAMES = (MANIFEST, SPEC_COPY, RESULTS_CSV, RESULTS_PARQUET, RESULTS_CHECKSUMS, SAMPLES, "report")


def _result_doc_of(d: Path) -> dict | None:
    """A sample folder's result.json if it is one (format and version), else None (checksums not checked)."""
    try:
        doc = json.loads((d / RESULT).read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(doc, dict) or doc.get("format") != RESULT_FORMAT or doc.get("version") != VERSION \
            or doc.get("sample_id") != d.name:
        return None
    return doc


def recover_manifest(out: Path, spec=None) -> dict | None:
    """A manifest rebuilt from the samples' own ``result.json`` files, for a dataset whose manifest.json is
    lost or damaged; None when ``out`` is not a sweep dataset by its samples. A dataset by its samples holds
    only the names a sweep writes (``_DATASET_NAMES``, temporary names) and at least one committed sample
    (``samples/<id>/result.json`` of this format). With ``spec`` (``--resume``), every committed sample must
    be one of the spec's (same id and configuration), else ``DatasetLayoutError``; the samples' checksums
    are verified later, as for any resume (``validate_result``): what cannot be verified is made again."""
    out = Path(out)
    if any(p.name not in _DATASET_NAMES and not is_temp_name(p.name) for p in out.iterdir()):
        return None
    root = out / SAMPLES
    if not root.is_dir() or root.is_symlink():
        return None
    docs = {p.name: _result_doc_of(p) for p in sorted(root.iterdir())
            if p.is_dir() and not p.is_symlink() and not is_temp_name(p.name)}
    found = {k: v for k, v in docs.items() if v is not None}
    if not found:
        return None
    if spec is not None:
        plans = {s.sample_id: s.config_sha256 for s in spec.samples}
        alien = sorted(k for k, v in found.items() if plans.get(k) != v.get("config_sha256"))
        if alien:
            raise DatasetLayoutError(f"{out}: its {MANIFEST} is lost or damaged, and sample {alien[0]} "
                                     f"({len(alien)} in all) is not one of this spec's: use another --out, or "
                                     "--overwrite")
    samples = [{"id": k, "status": v.get("status"), "files_sha256": v.get("files") or {}} for k, v in found.items()]
    return {"format": FORMAT, "version": VERSION, "state": "interrupted", "recovered": True,
            "recovered_samples": len(found), "unreadable_samples": sorted(k for k, v in docs.items() if v is None),
            "spec": {"sha256": spec.sha256 if spec is not None else None}, "samples": samples}


def make_stage_dataset(out: Path) -> Path:
    """A staging directory beside ``out`` for an ``--overwrite`` sweep (swapped in once complete)."""
    out = Path(out)
    d = out.parent / f".tmp-{out.name}~{HOST}~{os.getpid()}~{secrets.token_hex(4)}"
    d.mkdir()
    return d


def _started_skeleton(out: Path, spec) -> bool:
    """``out`` holds only what a sweep of this spec makes before its first manifest (``samples/`` with
    uncommitted attempts, ``spec.toml`` of the same text, tables, temporary files)."""
    for p in Path(out).iterdir():
        if is_temp_name(p.name):
            continue
        if p.name == SPEC_COPY and p.is_file():
            if spec.text and p.read_text(errors="replace") != spec.text:
                return False
        elif p.name == SAMPLES and p.is_dir():
            if any(not is_temp_name(q.name) for q in p.iterdir()):
                return False
        elif p.name not in (RESULTS_CSV, RESULTS_PARQUET, RESULTS_CHECKSUMS, MANIFEST):  # tables of no sample, a damaged
            return False                                                 # manifest (read_manifest said so)
    return True


def prepare_dataset(out: Path, spec) -> None:
    """Make the dataset directory and sweep every leftover of earlier runs (call it holding the lock)."""
    out = Path(out)
    (out / SAMPLES).mkdir(parents=True, exist_ok=True)
    sweep_stale(out)
    sweep_attempts(out, force=True)  # nobody commits them: their run is over
    sweep_stale(out / SAMPLES)
    for p in (out / SAMPLES).iterdir():
        if p.is_dir() and not is_temp_name(p.name):
            for dirpath, dirnames, _files in os.walk(p):
                sweep_stale(Path(dirpath))
    if spec.text and not (out / SPEC_COPY).exists():
        write_text(out / SPEC_COPY, spec.text)


def write_manifest(dataset: Path, manifest: dict) -> None:
    write_json(Path(dataset) / MANIFEST, manifest)


def stale_files(dataset: Path) -> list[Path]:
    """Temporary leftovers anywhere under ``dataset`` (what ``sweep_stale`` removes), for checks."""
    out = []
    for root, dirs, files in os.walk(dataset):
        for name in dirs + files:
            if name.startswith((".tmp-", ".old-")) or (name.startswith(".") and name.endswith(".tmp")):
                out.append(Path(root) / name)
    return out
