"""Reading a Parquet table: the one reader every PlateBench table goes through.

``read_parquet(source)`` decodes the whole file in the calling thread (``pyarrow.parquet.ParquetFile``
with ``use_threads=False``), never through Arrow's asynchronous dataset scanner that
``pyarrow.parquet.read_table`` uses. The scanner can release its last reference to the source from one
of Arrow's pool threads after the main thread has returned; when that source is memory owned by
Python (bytes read for a checksum), the release needs the interpreter's lock, and during interpreter
shutdown that aborts the whole process ("terminate called without an active exception", SIGABRT)
after its work is done and its exit status was decided (apache/arrow#34314, #36389). PlateBench's
tables are small (one row per sample and method), so a single-threaded read costs nothing.

Raises ``pyarrow.ArrowException``, ``OSError`` or ``ValueError`` for a file that is not Parquet, as
pyarrow does; callers name the file in their own one-line error.
"""
from __future__ import annotations

from pathlib import Path


def read_parquet(source: Path | bytes):
    """The table in ``source`` (a path, or the file's bytes) as a ``pyarrow.Table``, read in this thread."""
    import pyarrow as pa  # noqa: PLC0415
    import pyarrow.parquet as pq  # noqa: PLC0415
    handle = pa.BufferReader(source) if isinstance(source, (bytes, bytearray, memoryview)) else pa.OSFile(str(source))
    with handle:
        return pq.ParquetFile(handle).read(use_threads=False)
