"""A study's journal: each finished plate's row, kept on disk as it arrives, so that an interrupted
study (Ctrl-C, SIGTERM, a crash, a power cut) loses none of the plates it finished.

The study's output folder appears complete or not at all (``staged_output``); the journal lives
beside it, ``OUT.journal.jsonl``: a header line (the study's settings, the package version and a
hash of its source, ``code_digest``),
then one line per finished plate (its key and its row), each appended, flushed and fsync'ed. A
half-written last line (the process killed mid-write) is ignored. ``platebench study ... --resume``
reuses the rows whose key matches a plate still to run, and the journal is removed once the study's
output is in place. Settings that differ from the journal's are refused (its rows belong to
another study), as is a journal left behind when neither ``--resume`` nor ``--overwrite`` is given.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

from platebench.bench.io.atomic import json_default
from platebench.errors import UserValueError

JOURNAL_SUFFIX = ".journal.jsonl"
CODE_DIRS = ("plates", "scenes", "reconstruction", "evaluation", "bench")  # the package's code (code_digest)


def journal_path(out: Path) -> Path:
    """Where the study writing ``out`` keeps its journal: beside it, ``OUT.journal.jsonl``."""
    out = Path(out)
    return out.parent / f"{out.name}{JOURNAL_SUFFIX}"


def code_digest() -> str:
    """A hash of the package's Python source (its top-level modules and every ``*.py`` under
    ``CODE_DIRS``, by relative path and content):
    a journal written by other code is not resumed, whatever the version number says."""
    root = Path(__file__).resolve().parents[2]  # the package: bench/run/journal.py -> platebench
    files = list(root.glob("*.py")) + [f for d in CODE_DIRS for f in (root / d).rglob("*.py")]
    h = hashlib.sha1()
    for f in sorted(files):
        h.update(str(f.relative_to(root)).encode())
        h.update(f.read_bytes())
    return h.hexdigest()


def case_key(*parts) -> str:
    """A plate run's identity: a hash of the reprs of ``parts`` (its case and its full config)."""
    h = hashlib.sha1()
    for p in parts:
        h.update(repr(p).encode())
    return h.hexdigest()


class StudyJournal:
    """The journal of the study writing ``out`` (module doc). ``header``: what must match for rows
    to be reused (settings, version; JSON-able)."""

    def __init__(self, out: Path, header: dict):
        self.path = journal_path(out)
        self.header = json.loads(json.dumps(header, default=json_default))
        self._file = None

    def read(self) -> tuple[dict | None, dict[str, dict]]:
        """(the header, key -> row) of the journal on disk ((None, {}) when there is none)."""
        if not self.path.exists():
            return None, {}
        header, rows = None, {}
        with open(self.path, encoding="utf-8", errors="replace") as f:
            for k, line in enumerate(f):
                try:
                    rec = json.loads(line)
                except json.JSONDecodeError:
                    continue  # the line a killed process was writing
                if k == 0:
                    header = rec.get("header") if isinstance(rec, dict) else None
                elif isinstance(rec, dict) and "key" in rec and "row" in rec:
                    rows[rec["key"]] = rec["row"]
        return header, rows

    def start(self, resume: bool, overwrite: bool) -> dict[str, dict]:
        """Open the journal for this run and return the rows it may reuse (key -> row): those of an
        interrupted run of the same study with ``resume``, none otherwise. A journal left behind is
        refused unless ``resume`` (same settings only) or ``overwrite`` (started again)."""
        if os.path.islink(self.path) or (os.path.lexists(self.path) and not self.path.is_file()):
            raise UserValueError(f"{self.path}: is not a regular file where this study's journal goes: refusing to "
                                 "use it (move it away, or choose another --out)")
        header, rows = self.read()
        if header is None and not rows and self.path.exists() and self.path.stat().st_size:
            raise UserValueError(f"{self.path}: is not a study journal (no header line), where this study's journal "
                                 "goes: refusing to write over it (move it away, or choose another --out)")
        if header is not None or rows:
            if resume:
                if header is not None and {k: v for k, v in header.items() if k != "code"} == \
                        {k: v for k, v in self.header.items() if k != "code"} and header != self.header:
                    raise UserValueError(f"--resume: {self.path} was written by other code (the package's source "
                                         "has changed since): allowed the same code, or --overwrite to start again")
                if header != self.header:
                    raise UserValueError(f"--resume: {self.path} is the journal of a study with other settings "
                                         f"({_difference(header, self.header)}): allowed the same settings, or "
                                         "--overwrite to start again")
            elif overwrite:
                rows = {}
            else:
                raise UserValueError(f"{self.path} holds {len(rows)} finished plates of an interrupted study: "
                                     "allowed --resume to finish it or --overwrite to start again")
        else:
            rows = {}
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if not rows:  # a new journal: the header first
            tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
            tmp.write_text(json.dumps({"header": self.header}) + "\n", encoding="utf-8")
            os.replace(tmp, self.path)
        self._file = open(self.path, "a", encoding="utf-8")
        if _ends_torn(self.path):  # a half-written last line: end it, so the next row stands alone
            self._file.write("\n")
        return rows

    def record(self, key: str, row: dict) -> None:
        """Append one finished plate's row (flushed and fsync'ed before returning)."""
        self._file.write(json.dumps({"key": key, "row": row}, default=json_default) + "\n")
        self._file.flush()
        os.fsync(self._file.fileno())

    def close(self, remove: bool) -> None:
        """Close the journal; ``remove``: delete it (the study's output is in place)."""
        if self._file is not None:
            self._file.close()
            self._file = None
        if remove:
            self.path.unlink(missing_ok=True)


def _ends_torn(path: Path) -> bool:
    """The file is not empty and its last byte is not a newline."""
    with open(path, "rb") as f:
        size = f.seek(0, os.SEEK_END)
        if size == 0:
            return False
        f.seek(size - 1)
        return f.read(1) != b"\n"


def _difference(a: dict | None, b: dict) -> str:
    a = a or {}
    keys = [k for k in sorted(set(a) | set(b)) if a.get(k) != b.get(k)]
    return ", ".join(f"{k}: {a.get(k)!r} there, {b.get(k)!r} now" for k in keys[:3]) or "no header"
