"""Results folders in and out, and the leaderboard made from one or more of them.

A *results folder* (``write_results`` is its one writer) holds ``results.parquet`` and
``results.csv`` (the same ``BenchmarkRow`` rows, sorted by method and sample), ``sparse.csv``
(``SparseRow`` rows) where some method gave sparse points, and ``benchmark-results.json``:
``{"format": "platebench-benchmark-results", "version", "split", "split_sha256", "methods",
"samples", "rows", "tables": {file name: sha256 of its bytes}}`` (and what the writer was told:
``sources``, method -> where its results came from). ``read_results`` scores nothing it cannot
trust: a table missing, changed since it was written (its sha256), not listed, with rows of another
split or of an unlisted method, with a (sample, method) pair twice or without every (sample,
method) pair of the methods listed (a half-scored run) is refused with one line naming the file
(``ResultsTableError``). ``merge`` joins folders of one split (for example one computed on a GPU
machine, one on a laptop).

The ranking rule: methods are ranked by their *primary* figure, the mean of ``bad_2mm_pct`` over
every sample of the split (a failed or missing row counts 100: every plate pixel bad), ascending;
methods whose primary figures lie within ``tol.rank_tie_pct`` of each other (chained along the
ascending order) are tied, and a tie is broken by the mean ``bad_0_5mm_pct`` (ascending), then by
the method's name. Beside the primary figure the ranking shows the mean ``coverage_frac`` (0 for a
failed or missing row), the median ``depth_rms_mm`` over the method's ok rows and the counts of
ok, failed and missing rows; they never change the order.

Breakdowns: the mean primary figure and the mean coverage of each method per realism preset,
family, bend bin and ground-truth false boundary (``BreakdownRow``).

``write_leaderboard(table, OUT)`` writes ``OUT/leaderboard.csv`` and ``OUT/leaderboard.parquet``
(the ranking, one ``MethodRank`` per method), ``OUT/breakdown.csv`` (long form, one
``BreakdownRow`` per method and group), ``OUT/leaderboard.md`` (Markdown tables for a paper),
``OUT/leaderboard.html`` (a self-contained page: the tables, and plots embedded as PNG data URIs,
also kept in ``OUT/plots/``; one colour per method in every plot), ``OUT/leaderboard.json`` (the
folder's marker and the ranking) and the merged results as a results folder, ``OUT/results/``.
Results folders and leaderboards follow the output rule (``bench.io.outputs``): staged and renamed
into place, never written into their inputs. Units: percent 0..100 (``_pct`` and the primary
figure), fractions 0..1 (``_frac``), millimetres (``_mm``).
"""
from __future__ import annotations

import csv
import datetime as _dt
import hashlib
import io
import json
import math
import os
from dataclasses import dataclass, fields, replace
from importlib import metadata
from pathlib import Path
from typing import Iterable, Mapping, Sequence

import numpy as np
import pandas as pd

from platebench.bench.benchmark.records import BEND_BINS, PRIMARY, STATUSES, BenchmarkRow, SparseRow
from platebench.bench.benchmark.records import COLUMNS as C
from platebench.bench.files import JSON_MAX_BYTES, TABLE_MAX_BYTES, read_capped, require_dir
from platebench.bench.io.atomic import write_bytes, write_json, write_text
from platebench.bench.io.images import DatasetError
from platebench.bench.io.layout import RESULTS_CSV, RESULTS_PARQUET
from platebench.bench.io.outputs import canonical, output_dir
from platebench.bench.io.records import Record
from platebench.bench.report.colours import method_colours
from platebench.errors import UserValueError
from platebench.tolerances import tol

__all__ = ["ResultsTable", "ResultsTableError", "MethodRank", "BreakdownRow", "write_results", "read_results",
           "merge", "ranking", "breakdowns", "method_colours", "error_by_bend_figure", "coverage_accuracy_figure",
           "leaderboard_markdown", "write_leaderboard", "RESULTS_FORMAT", "RESULTS_JSON", "SPARSE_CSV",
           "BREAKDOWNS", "RANKING_RULE", "LEADERBOARD_JSON", "LEADERBOARD_FORMAT", "GENERATOR"]

RESULTS_FORMAT = "platebench-benchmark-results"
RESULTS_VERSION = 1
RESULTS_JSON = "benchmark-results.json"
SPARSE_CSV = "sparse.csv"
TABLES = (RESULTS_PARQUET, RESULTS_CSV, SPARSE_CSV)
LEADERBOARD_JSON = "leaderboard.json"  # a leaderboard folder's marker (bench.io.outputs.KINDS)
LEADERBOARD_FORMAT = "platebench-leaderboard"
LEADERBOARD_CSV, LEADERBOARD_PARQUET, BREAKDOWN_CSV = "leaderboard.csv", "leaderboard.parquet", "breakdown.csv"
LEADERBOARD_MD, LEADERBOARD_HTML = "leaderboard.md", "leaderboard.html"
MERGED_RESULTS = "results"  # a leaderboard folder's merged results folder
GENERATOR = "platebench leaderboard"  # leaderboard.html: <meta name="generator" content="...">
BREAKDOWNS = ("realism", "family", "bend_bin", "false_boundary_gt")
BREAKDOWN_TITLES = {"realism": "realism preset", "family": "family", "bend_bin": "bend bin (deg)",
                    "false_boundary_gt": "false boundary (ground truth)"}
REALISM_ORDER = ("ideal", "modern", "1995")
_LEGEND_IN = 1.4  # inches beside the panels for the methods' legend
FAILED_PCT = 100.0  # a failed or missing row's bad_*_pct: every plate pixel bad
RANKING_RULE = ("Ranked by the mean bad-2mm percentage over every sample of the split (failed and missing rows "
                "count 100), ascending; methods within {tie:g} percentage points of each other are tied, and ties "
                "are broken by the mean bad-0.5mm percentage, then by name. Coverage is shown beside it and never "
                "changes the order.").format(tie=tol.rank_tie_pct)


class ResultsTableError(DatasetError):
    """A results folder that cannot be scored (one line naming the file and what is wrong)."""


# ----------------------------------------------------------------------------- records of the leaderboard
@dataclass(frozen=True)
class MethodRank(Record):
    """One method's place on the leaderboard (module doc: the ranking rule). ``primary``: mean
    bad_2mm_pct over the split's samples, percent; ``coverage_frac``: mean coverage, 0..1;
    ``bad_0_5mm_pct``: mean, percent; ``median_depth_rms_mm``: median depth RMS over the ok rows
    (None: no ok row has one); counts of the method's rows."""

    rank: int
    method: str
    primary: float
    coverage_frac: float
    bad_0_5mm_pct: float
    median_depth_rms_mm: float | None
    n_samples: int
    n_ok: int
    n_failed: int
    n_missing: int


@dataclass(frozen=True)
class BreakdownRow(Record):
    """A method's mean primary figure (percent) and mean coverage (0..1) over the ``n`` samples of
    one ``group`` (a value, as text) of the column ``by`` (one of ``BREAKDOWNS``)."""

    method: str
    by: str
    group: str
    primary: float
    coverage_frac: float
    n: int


@dataclass(frozen=True, eq=False)
class ResultsTable:
    """The rows of one or more results folders of one split: ``rows`` (a frame of ``BenchmarkRow``
    columns, every (sample, method) pair of ``methods`` once, sorted by method and sample),
    ``sparse`` (``SparseRow`` columns, or None), the split's name and the sha256 of its definition,
    and the folders read (``sources``)."""

    rows: pd.DataFrame
    sparse: pd.DataFrame | None
    split: str
    split_sha256: str
    methods: tuple[str, ...]
    sources: tuple[Path, ...] = ()

    @property
    def samples(self) -> tuple[str, ...]:
        """The split's sample ids, sorted."""
        return tuple(sorted(set(self.rows["sample_id"])))


# ----------------------------------------------------------------------------- typed tables
def _columns(cls) -> tuple[tuple[str, str, bool], ...]:
    """(name, kind, nullable) of a record class's fields; kind: "str", "int", "float" or "bool"."""
    out = []
    for f in fields(cls):
        parts = [p.strip() for p in str(f.type).split("|")]
        kind = next(p for p in parts if p != "None")
        if kind not in ("str", "int", "float", "bool"):
            raise TypeError(f"{cls.__name__}.{f.name}: a table column of type {f.type} is not supported")
        out.append((f.name, kind, "None" in parts))
    return tuple(out)


def _cell(v, name: str, kind: str, nullable: bool, where: str):
    """``v`` as the plain Python value of a ``kind`` cell (None: no value); ValueError naming ``where``."""
    if v is None or (isinstance(v, (float, np.floating)) and math.isnan(v)):
        if nullable:
            return None
        raise ValueError(f"{where}: {name} has no value (allowed: a {kind})")
    if kind == "bool":
        if isinstance(v, (bool, np.bool_)):
            return bool(v)
    elif kind == "int":
        if isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_)):
            return int(v)
    elif kind == "float":
        if isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_)):
            x = float(v)
            if math.isfinite(x):
                return x
            raise ValueError(f"{where}: {name} = {x} (allowed: a finite number)")
    elif isinstance(v, str):
        return v
    raise ValueError(f"{where}: {name} = {v!r} (allowed: a {kind})")


def _record_cells(cls, records: Sequence, what: str) -> list[tuple]:
    cols = _columns(cls)
    out = []
    for i, r in enumerate(records):
        if not isinstance(r, cls):
            raise UserValueError(f"{what} {i}: a {type(r).__name__}, allowed a {cls.__name__}")
        try:
            out.append(tuple(_cell(getattr(r, n), n, k, nl, f"{what} {i}") for n, k, nl in cols))
        except ValueError as e:
            raise UserValueError(str(e)) from None
    return out


def _csv_bytes(cls, cells: Sequence[tuple]) -> bytes:
    """The CSV form of typed cells: a header of field names; no value is an empty cell, floats in
    their shortest exact form (``repr``), flags ``true``/``false``."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow([n for n, _, _ in _columns(cls)])
    for row in cells:
        w.writerow(["" if v is None else ("true" if v else "false") if isinstance(v, bool)
                    else repr(v) if isinstance(v, float) else str(v) for v in row])
    return buf.getvalue().encode("utf-8")


def _parquet_bytes(cls, cells: Sequence[tuple]) -> bytes:
    import pyarrow as pa  # noqa: PLC0415
    import pyarrow.parquet as pq  # noqa: PLC0415
    types = {"str": pa.string(), "int": pa.int64(), "float": pa.float64(), "bool": pa.bool_()}
    cols = _columns(cls)
    schema = pa.schema([pa.field(n, types[k], nullable=nl) for n, k, nl in cols])
    table = pa.table({n: pa.array([r[j] for r in cells], type=types[k]) for j, (n, k, _) in enumerate(cols)},
                     schema=schema)
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink)
    return sink.getvalue().to_pybytes()


def _parse_text(s: str, name: str, kind: str, nullable: bool, where: str):
    if s == "" and kind != "str":
        if nullable:
            return None
        raise ValueError(f"{where}: {name} has no value (allowed: a {kind})")
    try:
        if kind == "float":
            x = float(s)
            if not math.isfinite(x):
                raise ValueError
            return x
        if kind == "int":
            return int(s)
        if kind == "bool":
            return {"true": True, "false": False}[s]
    except (ValueError, KeyError):
        raise ValueError(f"{where}: {name} = {s!r} (allowed: a {kind})") from None
    return s


def _csv_cells(cls, data: bytes, path: Path) -> list[tuple]:
    """The typed cells of a CSV table of ``cls`` (its header exactly the field names)."""
    cols = _columns(cls)
    try:
        lines = list(csv.reader(io.StringIO(data.decode("utf-8"), newline="")))
    except (UnicodeDecodeError, csv.Error) as e:
        raise ResultsTableError(f"{path}: not a readable CSV table ({e})") from None
    names = [n for n, _, _ in cols]
    if not lines or lines[0] != names:
        raise ResultsTableError(f"{path}: its header is not the {cls.__name__} columns ({', '.join(names[:4])}, ...)")
    out = []
    for i, line in enumerate(lines[1:], start=2):
        if len(line) != len(cols):
            raise ResultsTableError(f"{path}: line {i} has {len(line)} cells, allowed {len(cols)}")
        try:
            out.append(tuple(_parse_text(s, n, k, nl, f"line {i}") for s, (n, k, nl) in zip(line, cols)))
        except ValueError as e:
            raise ResultsTableError(f"{path}: {e}") from None
    return out


def _parquet_cells(cls, data: bytes, path: Path) -> list[tuple]:
    import pyarrow as pa  # noqa: PLC0415
    from platebench.bench.io.parquet import read_parquet  # noqa: PLC0415
    cols = _columns(cls)
    try:
        table = read_parquet(data)
    except (pa.ArrowException, OSError, ValueError) as e:
        raise ResultsTableError(f"{path}: not a readable Parquet table ({str(e).splitlines()[0][:200]})") from None
    names = [n for n, _, _ in cols]
    if table.column_names != names:
        raise ResultsTableError(f"{path}: its columns are not the {cls.__name__} columns ({', '.join(names[:4])}, ...)")
    out = []
    for i, row in enumerate(table.to_pylist()):
        try:
            out.append(tuple(_cell(row[n], n, k, nl, f"row {i + 1}") for n, k, nl in cols))
        except ValueError as e:
            raise ResultsTableError(f"{path}: {e}") from None
    return out


def _frame_cells(cls, frame: pd.DataFrame) -> list[tuple]:
    """The typed cells of a frame made by ``_frame`` (NaN back to None)."""
    cols = _columns(cls)
    return [tuple(_cell(r[n], n, k, nl, "row") for n, k, nl in cols) for r in frame.to_dict("records")]


def _frame(cls, cells: Sequence[tuple]) -> pd.DataFrame:
    """A frame of typed cells: floats float64 (NaN: no value), ints int64, flags bool, text str."""
    data = {}
    for j, (n, k, _) in enumerate(_columns(cls)):
        values = [r[j] for r in cells]
        if k == "float":
            data[n] = pd.Series([np.nan if v is None else v for v in values], dtype="float64")
        elif k == "int":
            data[n] = pd.Series(values, dtype="int64")
        elif k == "bool":
            data[n] = pd.Series(values, dtype="bool")
        else:
            data[n] = pd.Series(values, dtype=str)
    return pd.DataFrame(data)


# ----------------------------------------------------------------------------- checks of the rows
def _check_rows(cells: list[tuple], path: Path, split: str, methods: Sequence[str]) -> None:
    """Every rule of a results table (module doc) on its typed cells; ResultsTableError naming ``path``."""
    idx = {n: j for j, (n, _, _) in enumerate(_columns(BenchmarkRow))}
    if not cells:
        raise ResultsTableError(f"{path}: holds no rows")
    listed = set(methods)
    pairs: set = set()
    for i, r in enumerate(cells, start=1):
        what = f"{path}: row {i} ({r[idx['sample_id']]}, {r[idx['method']]})"
        if r[idx["split"]] != split:
            raise ResultsTableError(f"{what} is of split {r[idx['split']]!r}, not the folder's {split!r}")
        if r[idx["method"]] not in listed:
            raise ResultsTableError(f"{what} is of a method {RESULTS_JSON} does not list ({', '.join(methods)})")
        if r[idx["status"]] not in STATUSES:
            raise ResultsTableError(f"{what}: status {r[idx['status']]!r} (allowed: {', '.join(STATUSES)})")
        for name, hi in ((PRIMARY, FAILED_PCT), ("bad_0_5mm_pct", FAILED_PCT), ("coverage_frac", 1.0)):
            if not 0.0 <= r[idx[name]] <= hi:
                raise ResultsTableError(f"{what}: {name} = {r[idx[name]]} (allowed: 0 to {hi:g})")
        key = (r[idx["sample_id"]], r[idx["method"]])
        if key in pairs:
            raise ResultsTableError(f"{what} is there twice: one row per (sample, method)")
        pairs.add(key)
    samples = {s for s, _ in pairs}
    expected = len(samples) * len(listed)
    if len(pairs) < expected:
        gap = next((s, m) for m in methods for s in sorted(samples) if (s, m) not in pairs)
        raise ResultsTableError(f"{path}: {expected - len(pairs)} of the {expected} (sample, method) pairs of "
                                f"{len(samples)} samples and {len(listed)} methods have no row (a half-scored run; "
                                f"the first: sample {gap[0]}, method {gap[1]}): not scored")


def _check_sparse(cells: list[tuple], path: Path, split: str, methods: Sequence[str]) -> None:
    idx = {n: j for j, (n, _, _) in enumerate(_columns(SparseRow))}
    seen: set = set()
    for i, r in enumerate(cells, start=1):
        what = f"{path}: row {i} ({r[idx['sample_id']]}, {r[idx['method']]})"
        if r[idx["split"]] != split:
            raise ResultsTableError(f"{what} is of split {r[idx['split']]!r}, not the folder's {split!r}")
        if r[idx["method"]] not in methods:
            raise ResultsTableError(f"{what} is of a method {RESULTS_JSON} does not list ({', '.join(methods)})")
        key = (r[idx["sample_id"]], r[idx["method"]], r[idx["points"]])
        if key in seen:
            raise ResultsTableError(f"{what} is there twice: one row per (sample, method, points)")
        seen.add(key)


def _sorted_rows(cells: list[tuple], cls) -> list[tuple]:
    names = [n for n, _, _ in _columns(cls)]
    keys = [names.index(k) for k in ("method", "sample_id", "points") if k in names]
    return sorted(cells, key=lambda r: tuple(r[k] for k in keys))


# ----------------------------------------------------------------------------- the writer
def _fill_results(d: Path, cells: list[tuple], sparse: list[tuple] | None, split: str, split_sha256: str,
                  methods: Sequence[str], extra: dict | None) -> None:
    """The tables and ``benchmark-results.json`` (last) of checked, sorted cells, written into ``d``."""
    tables = {RESULTS_PARQUET: _parquet_bytes(BenchmarkRow, cells), RESULTS_CSV: _csv_bytes(BenchmarkRow, cells)}
    if sparse is not None:
        tables[SPARSE_CSV] = _csv_bytes(SparseRow, sparse)
    doc = {"format": RESULTS_FORMAT, "version": RESULTS_VERSION, "split": split, "split_sha256": split_sha256,
           "methods": list(methods), "samples": len({r[1] for r in cells}), "rows": len(cells),
           "tables": {name: hashlib.sha256(data).hexdigest() for name, data in tables.items()}}
    clash = sorted(set(extra or {}) & set(doc))
    if clash:
        raise UserValueError(f"extra key {clash[0]!r} of {RESULTS_JSON}: it is one the writer defines")
    doc.update(extra or {})
    for name, data in tables.items():
        write_bytes(d / name, data)
    write_json(d / RESULTS_JSON, doc)


def write_results(folder, rows: Sequence[BenchmarkRow], sparse_rows: Sequence[SparseRow] | None, split: str,
                  split_sha256: str, methods: Sequence[str] | None = None, extra: dict | None = None, *,
                  sources: Mapping[str, str] | None = None, overwrite: bool = False, inputs: Iterable = (),
                  leaderboard: bool = False) -> ResultsTable:
    """Write the results folder ``folder`` (module doc) and return it as ``read_results`` reads it;
    the one writer of results folders.

    ``rows``: one ``BenchmarkRow`` per (sample, method), every sample for every method, all of
    ``split``; ``sparse_rows``: ``SparseRow`` rows or None (no ``sparse.csv``); ``methods``: the
    methods scored (default: those of ``rows``, sorted by name); ``extra``: more keys for
    ``benchmark-results.json`` (never the ones it defines); ``sources``: method -> where its
    results came from (recorded as ``sources``); ``leaderboard``: the leaderboard's files
    (``write_leaderboard``'s, without its ``leaderboard.json``) go into the folder too. The rows
    are checked as ``read_results`` checks them (UserValueError, one line) before anything is
    written. The folder follows the output rule (``bench.io.outputs``, kind "benchmark results";
    ``inputs``: the paths the results were made from, never replaced): it is new, or replaced only
    with ``overwrite``; it is staged and renamed into place, so it appears complete or not at all."""
    folder = Path(folder)
    rows, sparse_rows = list(rows), None if sparse_rows is None else list(sparse_rows)
    methods = tuple(methods) if methods is not None else tuple(sorted({r.method for r in rows if
                                                                        isinstance(r, BenchmarkRow)}))
    if len(set(methods)) != len(methods) or not all(isinstance(m, str) and m for m in methods):
        raise UserValueError(f"methods {list(methods)}: allowed distinct non-empty names")
    cells = _sorted_rows(_record_cells(BenchmarkRow, rows, "results row"), BenchmarkRow)
    _check_rows(cells, folder / RESULTS_CSV, split, methods)
    sparse = None
    if sparse_rows is not None:
        sparse = _sorted_rows(_record_cells(SparseRow, sparse_rows, "sparse row"), SparseRow)
        _check_sparse(sparse, folder / SPARSE_CSV, split, methods)
    if sources is not None:
        extra = {**(extra or {}), "sources": {str(k): str(v) for k, v in sources.items()}}
    with output_dir(folder, "benchmark results", overwrite=overwrite, inputs=inputs) as stage:
        _fill_results(stage, cells, sparse, split, split_sha256, methods, extra)
        if leaderboard:
            table = ResultsTable(rows=_frame(BenchmarkRow, cells), sparse=None if sparse is None else
                                 _frame(SparseRow, sparse), split=split, split_sha256=split_sha256, methods=methods,
                                 sources=(canonical(folder),))
            _leaderboard_files(table, stage, canonical(folder))
    return read_results(folder)


# ----------------------------------------------------------------------------- the reader
def _read_doc(folder: Path) -> dict:
    path = folder / RESULTS_JSON
    data = read_capped(path, JSON_MAX_BYTES, "results document", ResultsTableError,
                       missing=f"{RESULTS_JSON} is missing: not a benchmark results folder")
    try:
        doc = json.loads(data)
    except (ValueError, UnicodeDecodeError) as e:
        raise ResultsTableError(f"{path}: not a readable JSON document ({e})") from None
    if not isinstance(doc, dict) or doc.get("format") != RESULTS_FORMAT:
        raise ResultsTableError(f"{path}: its format is not {RESULTS_FORMAT!r}: not a benchmark results document")
    for key in ("split", "split_sha256"):
        if not isinstance(doc.get(key), str) or not doc[key]:
            raise ResultsTableError(f"{path}: {key} is {doc.get(key)!r} (allowed: a non-empty string)")
    methods = doc.get("methods")
    if not isinstance(methods, list) or not methods or not all(isinstance(m, str) and m for m in methods) \
            or len(set(methods)) != len(methods):
        raise ResultsTableError(f"{path}: methods is {methods!r} (allowed: a list of distinct method names)")
    tables = doc.get("tables")
    if not isinstance(tables, dict) or not all(isinstance(v, str) for v in tables.values()):
        raise ResultsTableError(f"{path}: tables is {tables!r} (allowed: file name -> sha256)")
    unknown = sorted(set(tables) - set(TABLES))
    if unknown:
        raise ResultsTableError(f"{path}: lists the table {unknown[0]!r} (allowed: {', '.join(TABLES)})")
    for name in (RESULTS_PARQUET, RESULTS_CSV):
        if name not in tables:
            raise ResultsTableError(f"{path}: lists no sha256 of {name}: its tables cannot be trusted")
    return doc


def _table_bytes(folder: Path, name: str, sha256: str) -> bytes:
    path = folder / name
    data = read_capped(path, TABLE_MAX_BYTES, "results table", ResultsTableError,
                       missing=f"is missing (listed in {RESULTS_JSON})")
    if hashlib.sha256(data).hexdigest() != sha256.lower():
        raise ResultsTableError(f"{path}: its sha256 differs from the one in {RESULTS_JSON} (changed after it was "
                                "written): not scored")
    return data


def read_results(folder) -> ResultsTable:
    """The results folder ``folder`` (module doc) as a ``ResultsTable``, every table verified
    against its sha256 and every rule checked; ResultsTableError (one line naming the file)
    otherwise."""
    folder = require_dir(Path(folder), "benchmark results folder", ResultsTableError)
    doc = _read_doc(folder)
    split, methods, tables = doc["split"], tuple(doc["methods"]), doc["tables"]
    if SPARSE_CSV not in tables and os.path.lexists(folder / SPARSE_CSV):
        raise ResultsTableError(f"{folder / SPARSE_CSV}: is not listed in {RESULTS_JSON}: not scored")
    pq_cells = _parquet_cells(BenchmarkRow, _table_bytes(folder, RESULTS_PARQUET, tables[RESULTS_PARQUET]),
                              folder / RESULTS_PARQUET)
    csv_cells = _csv_cells(BenchmarkRow, _table_bytes(folder, RESULTS_CSV, tables[RESULTS_CSV]), folder / RESULTS_CSV)
    if pq_cells != csv_cells:
        raise ResultsTableError(f"{folder / RESULTS_CSV}: does not hold the rows of {RESULTS_PARQUET} (both are "
                                "written from the same rows): not scored")
    _check_rows(pq_cells, folder / RESULTS_PARQUET, split, methods)
    if isinstance(doc.get("rows"), int) and doc["rows"] != len(pq_cells):
        raise ResultsTableError(f"{folder / RESULTS_PARQUET}: holds {len(pq_cells)} rows, {RESULTS_JSON} says "
                                f"{doc['rows']}: not scored")
    n_samples = len({r[1] for r in pq_cells})
    if isinstance(doc.get("samples"), int) and doc["samples"] != n_samples:
        raise ResultsTableError(f"{folder / RESULTS_PARQUET}: holds {n_samples} samples, {RESULTS_JSON} says "
                                f"{doc['samples']}: not scored")
    sparse = None
    if SPARSE_CSV in tables:
        s_cells = _csv_cells(SparseRow, _table_bytes(folder, SPARSE_CSV, tables[SPARSE_CSV]), folder / SPARSE_CSV)
        _check_sparse(s_cells, folder / SPARSE_CSV, split, methods)
        sparse = _frame(SparseRow, _sorted_rows(s_cells, SparseRow))
    return ResultsTable(rows=_frame(BenchmarkRow, _sorted_rows(pq_cells, BenchmarkRow)), sparse=sparse, split=split,
                        split_sha256=doc["split_sha256"], methods=methods, sources=(folder,))


# ----------------------------------------------------------------------------- merging
def _name(t: ResultsTable) -> str:
    return ", ".join(str(s) for s in t.sources) or "a results table"


def merge(tables: Iterable[ResultsTable]) -> ResultsTable:
    """One ``ResultsTable`` of several of one split (the same split name and ``split_sha256``) and
    the same samples: the union of their methods. A method in more than one is taken once, and only
    when its rows (and sparse rows) are identical in each; otherwise ResultsTableError (one line)."""
    tables = list(tables)
    if not tables:
        raise UserValueError("merge: no results tables given (allowed: one or more)")
    first = tables[0]
    for t in tables[1:]:
        if (t.split, t.split_sha256) != (first.split, first.split_sha256):
            raise ResultsTableError(f"{_name(t)}: split {t.split} (sha256 {t.split_sha256[:12]}) is not the split of "
                                    f"{_name(first)}, {first.split} (sha256 {first.split_sha256[:12]}): results of "
                                    "different splits are never merged")
        if t.samples != first.samples:
            extra = sorted(set(t.samples) ^ set(first.samples))
            raise ResultsTableError(f"{_name(t)}: its samples differ from those of {_name(first)} ({len(extra)} in "
                                    f"one only, the first {extra[0]}): results of different samples are never merged")
    owner: dict[str, ResultsTable] = {}
    for t in tables:
        for m in t.methods:
            if m not in owner:
                owner[m] = t
                continue
            if not (_method_rows(owner[m].rows, m).equals(_method_rows(t.rows, m))
                    and _same_sparse(owner[m], t, m)):
                raise ResultsTableError(f"method {m!r} is scored in both {_name(owner[m])} and {_name(t)} with "
                                        "different rows: a method's results are merged only when identical")
    methods = tuple(owner)
    rows = pd.concat([_method_rows(owner[m].rows, m) for m in methods], ignore_index=True)
    parts = [_method_rows(owner[m].sparse, m) for m in methods if owner[m].sparse is not None]
    sparse = pd.concat(parts, ignore_index=True) if parts else None
    sources = tuple(dict.fromkeys(s for t in tables for s in t.sources))
    return ResultsTable(rows=rows, sparse=sparse, split=first.split, split_sha256=first.split_sha256,
                        methods=methods, sources=sources)


def _method_rows(frame: pd.DataFrame, method: str) -> pd.DataFrame:
    keys = [k for k in ("sample_id", "points") if k in frame.columns]
    return frame[frame["method"] == method].sort_values(keys, kind="stable").reset_index(drop=True)


def _same_sparse(a: ResultsTable, b: ResultsTable, method: str) -> bool:
    sa = None if a.sparse is None else _method_rows(a.sparse, method)
    sb = None if b.sparse is None else _method_rows(b.sparse, method)
    sa = None if sa is not None and sa.empty else sa
    sb = None if sb is not None and sb.empty else sb
    return (sa is None and sb is None) or (sa is not None and sb is not None and sa.equals(sb))


# ----------------------------------------------------------------------------- ranking and breakdowns
def _effective(frame: pd.DataFrame) -> pd.DataFrame:
    """The rows as the figures count them: a failed or missing row has every pixel bad, coverage 0."""
    out = frame.copy()
    bad = out["status"] != "ok"
    out.loc[bad, PRIMARY] = FAILED_PCT
    out.loc[bad, C.bad_0_5mm_pct] = FAILED_PCT
    out.loc[bad, C.coverage_frac] = 0.0
    return out


def _mean(values) -> float:
    v = [float(x) for x in values]
    return math.fsum(v) / len(v)


def _rank_order(stats: list["MethodRank"]) -> list["MethodRank"]:
    """The ranking rule (module doc) on unranked ``MethodRank`` records."""
    by_primary = sorted(stats, key=lambda s: (s.primary, s.bad_0_5mm_pct, s.method))
    groups: list[list[MethodRank]] = []
    for s in by_primary:
        if groups and s.primary - groups[-1][-1].primary <= tol.rank_tie_pct:
            groups[-1].append(s)
        else:
            groups.append([s])
    return [s for g in groups for s in sorted(g, key=lambda s: (s.bad_0_5mm_pct, s.method))]


def ranking(table: ResultsTable) -> tuple[MethodRank, ...]:
    """Every method of ``table`` in leaderboard order (module doc: the ranking rule), ranks 1, 2, ..."""
    eff = _effective(table.rows)
    stats = []
    for m in table.methods:
        g = eff[eff["method"] == m]
        ok = g[g["status"] == "ok"]
        rms = ok[C.depth_rms_mm].dropna()
        stats.append(MethodRank(rank=0, method=m, primary=_mean(g[PRIMARY]), coverage_frac=_mean(g[C.coverage_frac]),
                                bad_0_5mm_pct=_mean(g[C.bad_0_5mm_pct]),
                                median_depth_rms_mm=float(np.median(rms)) if len(rms) else None, n_samples=len(g),
                                n_ok=len(ok), n_failed=int((g["status"] == "failed").sum()),
                                n_missing=int((g["status"] == "missing").sum())))
    return tuple(replace(s, rank=i + 1) for i, s in enumerate(_rank_order(stats)))


def _group_text(v) -> str:
    return ("true" if v else "false") if isinstance(v, (bool, np.bool_)) else str(v)


def _group_order(by: str, groups: Iterable[str]) -> list[str]:
    """Groups in reading order: presets ideal, modern, 1995; bend bins by angle; the rest by name."""
    groups = set(groups)
    first = {"realism": REALISM_ORDER, "bend_bin": tuple(b[2] for b in BEND_BINS) + ("none",),
             "false_boundary_gt": ("false", "true")}.get(by, ())
    return [g for g in first if g in groups] + sorted(groups - set(first))


def breakdowns(table: ResultsTable, by: Sequence[str] = BREAKDOWNS) -> tuple[BreakdownRow, ...]:
    """Mean primary figure and coverage of every method per group of each column of ``by`` (a
    failed or missing row counts 100 and coverage 0), ordered by ``by``, group, then the ranking."""
    unknown = [b for b in by if b not in table.rows.columns]
    if unknown:
        raise UserValueError(f"breakdown by {unknown[0]!r}: allowed {', '.join(BREAKDOWNS)}")
    eff = _effective(table.rows)
    order = [r.method for r in ranking(table)]
    out = []
    for b in by:
        text = eff[b].map(_group_text)
        for g in _group_order(b, set(text)):
            sub = eff[text == g]
            for m in order:
                s = sub[sub["method"] == m]
                if len(s):
                    out.append(BreakdownRow(method=m, by=b, group=g, primary=_mean(s[PRIMARY]),
                                            coverage_frac=_mean(s[C.coverage_frac]), n=len(s)))
    return tuple(out)


# ----------------------------------------------------------------------------- plots
def _grid(n: int, w: float, h: float, legend_in: float = 0.0, per_row: int = 3):
    """A figure of ``n`` panels of ``w`` x ``h`` inches, ``per_row`` to a row, ``legend_in`` inches
    on the right kept for a legend; returns (figure, the n axes)."""
    from platebench.bench.report.plots import _figure  # noqa: PLC0415
    cols = min(n, per_row)
    rows = -(-n // cols)
    fig = _figure(w * cols + legend_in, h * rows + 0.6)
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    for ax in axes[n:]:
        ax.remove()  # never an empty panel
    return fig, axes[:n]


def error_by_bend_figure(table: ResultsTable, by: str, colours: dict[str, str]):
    """A matplotlib Figure of the mean primary figure (percent) against bend bin, one panel per group
    of ``by`` (``"realism"`` or ``"family"``) that has rows, one line per method in its colour of
    ``colours``; None when there is nothing to show."""
    eff = _effective(table.rows)
    text = eff[by].map(_group_text)
    panels = [(g, eff[text == g]) for g in _group_order(by, set(text))]
    panels = [(g, s) for g, s in panels if len(s)]
    if not panels:
        return None
    fig, axes = _grid(len(panels), 4.0, 3.2, legend_in=_LEGEND_IN)
    order = [r.method for r in ranking(table)]
    for ax, (g, sub) in zip(axes, panels):
        bins = _group_order("bend_bin", set(sub["bend_bin"]))
        x = {b: i for i, b in enumerate(bins)}
        for m in order:
            s = sub[sub["method"] == m]
            if not len(s):
                continue
            means = s.groupby("bend_bin")[PRIMARY].apply(_mean)
            pts = sorted((x[b], v) for b, v in means.items() if b != "none")
            ax.plot([p[0] for p in pts], [p[1] for p in pts], "-o", color=colours[m], ms=4, lw=1.5, label=m)
            if "none" in means.index:  # no bend angle: a point of its own, never joined to the bends
                ax.plot([x["none"]], [means["none"]], "o", color=colours[m], ms=4, label="_" + m)
        ax.set_xticks(range(len(bins)), bins)
        ax.set_xlim(-0.5, len(bins) - 0.5)
        ax.set_title(f"{BREAKDOWN_TITLES.get(by, by)}: {g}", fontsize=10)
        ax.set_xlabel("bend bin (deg)")
        ax.set_ylabel("bad 2 mm (%)")
        ax.set_ylim(bottom=0.0)
        ax.grid(True, alpha=0.3)
    lines = {h.get_label(): h for ax in axes for h in ax.get_lines()}
    handles = [lines[m] for m in order if m in lines]
    fig.legend(handles, [h.get_label() for h in handles], loc="center right", fontsize=8)
    fig.tight_layout(rect=(0, 0, 1 - _LEGEND_IN / fig.get_figwidth(), 1))
    return fig


def coverage_accuracy_figure(ranks: Sequence[MethodRank], colours: dict[str, str]):
    """A matplotlib Figure of accuracy against mean coverage, one point per method in its colour:
    a panel of the median depth RMS (mm; methods that have one) and a panel of the primary figure
    (percent); None when there is no method."""
    panels = []
    with_rms = [(r.method, r.coverage_frac, r.median_depth_rms_mm) for r in ranks if r.median_depth_rms_mm is not None]
    if with_rms:
        panels.append(("median depth RMS over ok rows (mm)", with_rms))
    if ranks:
        panels.append(("bad 2 mm (%)", [(r.method, r.coverage_frac, r.primary) for r in ranks]))
    if not panels:
        return None
    fig, axes = _grid(len(panels), 4.4, 3.6)
    for ax, (label, pts) in zip(axes, panels):
        for m, xv, yv in pts:
            ax.plot([xv], [yv], "o", color=colours[m], ms=7, label=m)
            ax.annotate(m, (xv, yv), textcoords="offset points", xytext=(5, 4), fontsize=7)
        ax.set_xlabel("mean coverage (fraction of plate pixels)")
        ax.set_ylabel(label)
        ax.set_xlim(-0.05, 1.05)
        ax.grid(True, alpha=0.3)
    fig.suptitle("Coverage against accuracy (one point per method)", fontsize=10)
    fig.tight_layout()
    return fig


# ----------------------------------------------------------------------------- Markdown
def _pct(v) -> str:
    return "–" if v is None else f"{v:.2f}"


def _frac(v) -> str:
    return "–" if v is None else f"{v:.3f}"


def _md_table(header: list[str], rows: list[list[str]], right_from: int = 1) -> list[str]:
    out = ["| " + " | ".join(header) + " |",
           "|" + "|".join(":---" if i < right_from else "---:" for i in range(len(header))) + "|"]
    out += ["| " + " | ".join(r) + " |" for r in rows]
    return out


def _wide(rows: Sequence[BreakdownRow], by: str):
    """(groups, {method: {group: BreakdownRow}}) of one breakdown."""
    mine = [r for r in rows if r.by == by]
    groups = _group_order(by, {r.group for r in mine})
    cells: dict = {}
    for r in mine:
        cells.setdefault(r.method, {})[r.group] = r
    return groups, cells


def leaderboard_markdown(table: ResultsTable, ranks: Sequence[MethodRank] | None = None,
                         rows: Sequence[BreakdownRow] | None = None, sources: Sequence[str] = ()) -> str:
    """Markdown for a paper: the ranking (primary figure and coverage side by side), then one table
    per breakdown (methods as rows, a column per group; each cell "primary (coverage)"). Percent
    to 2 decimals, fractions to 3, millimetres to 3; counts as integers."""
    ranks = ranking(table) if ranks is None else ranks
    rows = breakdowns(table) if rows is None else rows
    lines = [f"# PlateBench leaderboard: split {table.split}", "",
             f"Split sha256 `{table.split_sha256}`; {len(table.samples)} samples, {len(ranks)} methods."
             + (f" Results folders: {', '.join(sources)}." if sources else ""), "", RANKING_RULE, "",
             "## Ranking", ""]
    lines += _md_table(["rank", "method", "bad 2 mm (%)", "coverage", "bad 0.5 mm (%)", "median depth RMS (mm)",
                        "ok", "failed", "missing"],
                       [[str(r.rank), r.method, _pct(r.primary), _frac(r.coverage_frac), _pct(r.bad_0_5mm_pct),
                         _frac(r.median_depth_rms_mm), str(r.n_ok), str(r.n_failed), str(r.n_missing)]
                        for r in ranks], right_from=2)
    for by in BREAKDOWNS:
        groups, cells = _wide(rows, by)
        if not groups:
            continue
        lines += ["", f"## By {BREAKDOWN_TITLES[by]}", "", "Each cell: bad 2 mm (%) (coverage).", ""]
        def cell(m: str, g: str) -> str:
            c = cells.get(m, {}).get(g)
            return "–" if c is None else f"{_pct(c.primary)} ({_frac(c.coverage_frac)})"
        lines += _md_table(["method", *groups], [[r.method, *(cell(r.method, g) for g in groups)] for r in ranks])
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------- the output
def _version() -> str:
    try:
        return metadata.version("platebench")
    except metadata.PackageNotFoundError:
        return "?"


def _html_tables(ranks: Sequence[MethodRank], rows: Sequence[BreakdownRow]) -> tuple[dict, list[dict]]:
    ranking_table = {"title": "", "caption": "bad 2 mm and bad 0.5 mm: % of plate pixels (no estimate counts as "
                     "bad); coverage: fraction of plate pixels with an estimate; depth RMS in mm", "groups": [],
                     "columns": ["rank", "method", "bad 2 mm (%)", "coverage", "bad 0.5 mm (%)",
                                 "median depth RMS (mm)", "samples", "ok", "failed", "missing"],
                     "rows": [[r.rank, r.method, _pct(r.primary), _frac(r.coverage_frac), _pct(r.bad_0_5mm_pct),
                               _frac(r.median_depth_rms_mm), r.n_samples, r.n_ok, r.n_failed, r.n_missing]
                              for r in ranks]}
    tables = []
    for by in BREAKDOWNS:
        groups, cells = _wide(rows, by)
        if not groups:
            continue
        tables.append({"anchor": f"by_{by}", "nav": f"by {BREAKDOWN_TITLES[by]}",
                       "heading": f"By {BREAKDOWN_TITLES[by]}", "title": "",
                       "caption": "bad 2 mm (%) and coverage of each method over the group's samples (n)",
                       "groups": [{"label": "", "span": 1}] + [{"label": g, "span": 3} for g in groups],
                       "columns": ["method"] + ["bad 2 mm (%)", "coverage", "n"] * len(groups),
                       "rows": [[r.method] + [x for g in groups for x in
                                              ((_pct(cells[r.method][g].primary),
                                                _frac(cells[r.method][g].coverage_frac), cells[r.method][g].n)
                                               if g in cells.get(r.method, {})
                                               else (None, None, None))] for r in ranks]})
    return ranking_table, tables


def _leaderboard_files(table: ResultsTable, stage: Path, final: Path) -> tuple[MethodRank, ...]:
    """Write the leaderboard's tables, Markdown, page and plots of ``table`` into ``stage``, the
    staging directory of ``final`` (links are relative to ``final``); returns the ranking."""
    from platebench.bench.report.html import render_page  # noqa: PLC0415
    from platebench.bench.report.page import Page  # noqa: PLC0415
    from platebench.bench.report.plots import _save  # noqa: PLC0415

    ranks = ranking(table)
    rows = breakdowns(table)
    colours = method_colours(table.methods)
    page = Page(stage=stage, out=final, root=final)
    # the results folders the leaderboard reads, but not the folder it is written into (a results folder's own)
    sources = [page.link(s) for s in table.sources if canonical(s) != final and canonical(s) != canonical(stage)]
    rank_cells = _record_cells(MethodRank, ranks, "rank")
    write_bytes(stage / LEADERBOARD_CSV, _csv_bytes(MethodRank, rank_cells))
    write_bytes(stage / LEADERBOARD_PARQUET, _parquet_bytes(MethodRank, rank_cells))
    write_bytes(stage / BREAKDOWN_CSV, _csv_bytes(BreakdownRow, _record_cells(BreakdownRow, rows, "breakdown")))
    write_text(stage / LEADERBOARD_MD, leaderboard_markdown(table, ranks, rows, sources))
    figures = []
    for by in ("realism", "family"):
        fig = error_by_bend_figure(table, by, colours)
        if fig is not None:
            path = _save(fig, page.plot_dir / f"error_by_bend_per_{by}.png")
            figures.append(page.figure(path, f"Mean bad 2 mm (%) against bend bin, one panel per "
                                             f"{BREAKDOWN_TITLES[by]} (failed and missing rows count 100)."))
    fig = coverage_accuracy_figure(ranks, colours)
    if fig is not None:
        path = _save(fig, page.plot_dir / "coverage_accuracy.png")
        figures.append(page.figure(path, "Mean coverage against accuracy, one point per method."))
    ranking_table, tables = _html_tables(ranks, rows)
    html = render_page("leaderboard.html", generator=GENERATOR, split=table.split, split_sha256=table.split_sha256,
                       n_samples=len(table.samples), n_methods=len(ranks), sources=sources, rule=RANKING_RULE,
                       ranking=ranking_table, breakdowns=tables, figures=figures, version=_version(),
                       generated=_dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"))
    write_text(stage / LEADERBOARD_HTML, html)
    return ranks


def write_leaderboard(table: ResultsTable, out_dir, overwrite: bool = False) -> tuple[MethodRank, ...]:
    """Write the leaderboard of ``table`` into the folder ``out_dir`` (module doc) and return its
    ranking. Beside the leaderboard's files: ``leaderboard.json`` (its marker: format
    "platebench-leaderboard", the split, the ranking, the results folders read) and the merged
    results as a results folder of their own in ``results/`` (``read_results`` reads it; a later
    leaderboard can merge it again).

    The output rule (``bench.io.outputs``, kind "leaderboard"): ``out_dir`` is never one of
    ``table.sources``, a folder holding one or inside one; an existing ``out_dir`` is replaced only
    with ``overwrite`` and only when empty or an earlier leaderboard. It is staged and renamed into
    place. Paths on the page and in the Markdown are relative to ``out_dir``."""
    final = canonical(out_dir)
    with output_dir(out_dir, "leaderboard", overwrite=overwrite, inputs=list(table.sources)) as stage:
        ranks = _leaderboard_files(table, stage, final)
        sources = [Path(os.path.relpath(Path(s).resolve(), final.resolve())).as_posix() for s in table.sources]
        write_json(stage / LEADERBOARD_JSON, {"format": LEADERBOARD_FORMAT, "version": RESULTS_VERSION,
                                              "split": table.split, "split_sha256": table.split_sha256,
                                              "sources": sources, "ranking": [r.to_dict() for r in ranks]})
        (stage / MERGED_RESULTS).mkdir()
        _fill_results(stage / MERGED_RESULTS, _frame_cells(BenchmarkRow, table.rows),
                      None if table.sparse is None else _frame_cells(SparseRow, table.sparse), table.split,
                      table.split_sha256, table.methods, {"merged_from": sources})
    return ranks
