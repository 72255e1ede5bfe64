"""The sha256 of a sweep dataset's results tables (``results.csv``, ``results.parquet``), recorded in
``results.sha256.json`` beside them when the sweep writes them, so that a reader (the report,
``platebench.results()``) and ``--overwrite`` can tell a table edited since.

File format: a JSON object ``{"format": "platebench-results-checksums", "sha256": {NAME: HEX}}``, one
entry per table written. A table read without its entry, or whose bytes do not give it, is refused
(``DatasetError``) with the table's path."""
from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Mapping

from platebench.bench.files import file_sha256
from platebench.bench.io.atomic import write_text
from platebench.bench.io.images import DatasetError
from platebench.bench.io.layout import RESULTS_CHECKSUMS

FORMAT = "platebench-results-checksums"


def write_table_checksums(dataset: Path, tables: Mapping[str, bytes]) -> None:
    """Record (atomically) in ``dataset`` the sha256 of each table, given as name -> the bytes written
    to ``dataset / name``."""
    doc = {"format": FORMAT, "sha256": {n: hashlib.sha256(b).hexdigest() for n, b in tables.items()}}
    write_text(Path(dataset) / RESULTS_CHECKSUMS, json.dumps(doc, indent=1) + "\n")


def recorded_table_checksums(dataset: Path) -> dict[str, str] | None:
    """The recorded sha256 per table name, or None when the record is missing or not one."""
    try:
        doc = json.loads((Path(dataset) / RESULTS_CHECKSUMS).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT or not isinstance(doc.get("sha256"), dict):
        return None
    return {k: v for k, v in doc["sha256"].items() if isinstance(k, str) and isinstance(v, str)}


def verify_table(path: Path) -> None:
    """Refuse (``DatasetError``) the results table ``path`` unless its bytes give the sha256 recorded
    beside it."""
    path = Path(path)
    recorded = recorded_table_checksums(path.parent)
    if recorded is None:
        raise DatasetError(f"{path}: its dataset has no readable {RESULTS_CHECKSUMS}: the table cannot be told "
                           "from an edited one (run the sweep again with --resume to write both)")
    if path.name not in recorded:
        raise DatasetError(f"{path}: not listed in {path.parent / RESULTS_CHECKSUMS}: refusing a table the sweep "
                           "did not write")
    if file_sha256(path) != recorded[path.name]:
        raise DatasetError(f"{path}: changed after the sweep wrote it (its sha256 is not the one in "
                           f"{RESULTS_CHECKSUMS}): refusing an edited results table")
