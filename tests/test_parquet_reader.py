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
PRODUCT = ("plates", "scenes", "reconstruction", "evaluation", "bench")
SCANNER_CALLS = {"read_table", "read_parquet", "ParquetDataset", "dataset"}


def scanner_reads(tree: ast.AST) -> list[int]:
    """Lines of ``tree`` that call a Parquet reader that may use Arrow's scanner."""
    return [n.lineno for n in ast.walk(tree)
            if isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute) and n.func.attr in SCANNER_CALLS
            and isinstance(n.func.value, ast.Name) and n.func.value.id in {"pq", "pd", "pandas", "ds", "pa"}]


def test_the_product_reads_parquet_only_through_read_parquet():
    found = []
    for d in PRODUCT:
        for p in (REPO / d).rglob("*.py"):
            if p == REPO / "bench" / "io" / "parquet.py":
                continue
            found += [f"{p.relative_to(REPO)}:{line}" for line in scanner_reads(ast.parse(p.read_text()))]
    assert found == [], f"read Parquet with bench.io.parquet.read_parquet: {found}"


def test_the_rule_finds_a_planted_scanner_read():
    planted = "import pyarrow.parquet as pq\nimport pandas as pd\nt = pq.read_table('x')\nf = pd.read_parquet('y')\n"
    assert scanner_reads(ast.parse(planted)) == [3, 4]


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
