"""Every Parquet table PlateBench reads goes through ``bench.io.parquet.read_parquet``, which decodes in
the calling thread: Arrow's asynchronous dataset scanner (``pyarrow.parquet.read_table``,
``pandas.read_parquet``, ``pyarrow.dataset``) can free a Python-owned source from a pool thread during
interpreter shutdown and abort a finished command with SIGABRT (the module's docstring)."""
from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from platebench.bench.io.parquet import read_parquet

REPO = Path(__file__).resolve().parents[1]
SCANNED = ("plates", "scenes", "reconstruction", "evaluation", "bench", "tools")
SCANNER_READS = {"pyarrow.parquet.read_table", "pyarrow.parquet.read_pandas", "pyarrow.parquet.ParquetDataset",
                 "pandas.read_parquet", "pyarrow.dataset.dataset"}


def _dotted(node: ast.AST) -> str:
    """``a.b.c`` of a Name/Attribute chain ('' for anything else)."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    return ".".join([node.id, *reversed(parts)]) if isinstance(node, ast.Name) else ""


def scanner_reads(tree: ast.AST) -> list[int]:
    """Lines of ``tree`` that call a Parquet reader that may use Arrow's scanner (``SCANNER_READS``),
    however it was imported (``import pyarrow.parquet as pq``, ``from pyarrow import parquet``,
    ``from pyarrow.parquet import read_table``, or the full dotted name)."""
    alias = {}
    for n in ast.walk(tree):
        if isinstance(n, ast.Import):
            alias.update({a.asname or a.name.split(".")[0]: a.name if a.asname else a.name.split(".")[0]
                          for a in n.names})
        elif isinstance(n, ast.ImportFrom) and n.module:
            alias.update({a.asname or a.name: f"{n.module}.{a.name}" for a in n.names})
    lines = []
    for n in ast.walk(tree):
        if isinstance(n, ast.Call) and (name := _dotted(n.func)):
            head, _, rest = name.partition(".")
            full = ".".join(p for p in (alias.get(head, head), rest) if p)
            if full in SCANNER_READS:
                lines.append(n.lineno)
    return sorted(lines)


def test_the_package_and_its_tools_read_parquet_only_through_read_parquet():
    found = []
    for d in SCANNED:
        for p in (REPO / d).rglob("*.py"):
            if p == REPO / "bench" / "io" / "parquet.py":
                continue
            found += [f"{p.relative_to(REPO)}:{line}" for line in scanner_reads(ast.parse(p.read_text()))]
    assert found == [], f"read Parquet with bench.io.parquet.read_parquet: {found}"


@pytest.mark.parametrize("planted, lines", [
    ("import pyarrow.parquet as pq\nimport pandas as pd\nt = pq.read_table('x')\nf = pd.read_parquet('y')\n", [3, 4]),
    ("import pyarrow.parquet\nt = pyarrow.parquet.read_table('x')\n", [2]),
    ("from pyarrow.parquet import read_table as rt\nt = rt('x')\n", [2]),
    ("from pyarrow import parquet\nimport pyarrow.dataset as ds\nt = parquet.ParquetDataset('x')\nd = ds.dataset('y')\n",
     [3, 4]),
    ("import pyarrow.parquet as pq\nt = pq.ParquetFile('x').read(use_threads=False)\npq.write_table(t, 'y')\n", []),
])
def test_the_rule_finds_a_planted_scanner_read_however_it_is_imported(planted, lines):
    assert scanner_reads(ast.parse(planted)) == lines


@pytest.mark.parametrize("as_bytes", [True, False])
def test_read_parquet_gives_the_table_written(tmp_path, as_bytes):
    table = pa.table({"sample_id": ["a", "b", "c"], "depth_rms_mm": [0.1, None, 2.5],
                      "n": pa.array(np.arange(3), pa.int64())})
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink)
    data = sink.getvalue().to_pybytes()
    path = tmp_path / "t.parquet"
    path.write_bytes(data)
    got = read_parquet(data if as_bytes else path)
    assert got.equals(table)


def test_read_parquet_refuses_a_file_that_is_not_parquet(tmp_path):
    path = tmp_path / "t.parquet"
    path.write_bytes(b"sample_id,depth\n")
    with pytest.raises((pa.ArrowException, OSError, ValueError)):
        read_parquet(path)
    with pytest.raises((pa.ArrowException, OSError, ValueError)):
        read_parquet(b"PAR1")
