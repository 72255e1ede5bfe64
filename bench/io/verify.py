"""Readers verify: a dataset's files are what its records say, and nothing in it leads out of it.

``sample_checksums(sample_dir)``: the sha256 of every file of a sample as recorded when it was
written, from the first of: the sweep manifest of the dataset holding it (``files_sha256`` of its
entry), the sample's ``result.json`` (a committed sweep sample), the sample's own stamp
(``bench.io.outputs.STAMP``, written by ``platebench render``). ``verify_sample`` compares the
files with them: a file changed, truncated or swapped with another sample's is refused, naming
the sample and the file. ``refuse_links`` refuses a symbolic link anywhere under a dataset (a
sample folder or an image replaced by a link could lead out of it). ``verify_inputs`` is what a
command that reads some of a sample's files checks before its work (``platebench reconstruct``):
none of them is a link (``refuse_linked_inputs``, checked before any is opened), and each still
has its recorded checksum.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

from platebench.bench.files import JSON_MAX_BYTES, read_capped
from platebench.bench.io.atomic import is_temp_name
from platebench.bench.io.images import DatasetError
from platebench.bench.io.layout import FORMAT, MANIFEST, RESULT, SAMPLE, SAMPLES
from platebench.bench.io.outputs import STAMP, file_sha256, read_stamp

__all__ = ["Checksums", "sample_checksums", "stamp_checksums", "verify_reconstruction", "verify_sample",
           "verify_inputs", "refuse_linked_inputs", "refuse_links",
           "find_links", "file_sha256", "dataset_manifest"]


@dataclass(frozen=True)
class Checksums:
    """The recorded sha256 of a sample's files: ``files`` (path relative to the sample -> hex) and
    where they come from (``source``: 'the manifest of DATASET', 'result.json', 'its stamp')."""

    files: dict
    source: str
    sample_id: str


def _json(path: Path):
    try:
        return json.loads(read_capped(path, JSON_MAX_BYTES, "JSON record"))
    except (OSError, ValueError):  # unreadable, not JSON, not a regular file (InputFileError is a ValueError)
        return None


def dataset_manifest(dataset: Path) -> dict | None:
    """The sweep manifest of ``dataset`` (a dict of format ``platebench-sweep``), or None."""
    m = _json(Path(dataset) / MANIFEST)
    return m if isinstance(m, dict) and m.get("format") == FORMAT else None


def sample_checksums(sample_dir: Path, manifest: dict | None = None) -> Checksums | None:
    """The recorded checksums of ``sample_dir``'s files (module doc), or None when nothing records
    them. ``manifest``: the dataset's manifest when the caller has read it already."""
    d = Path(sample_dir)
    if d.name == SAMPLE and d.parent.parent.name == SAMPLES:  # DATASET/samples/<id>/sample
        sid, dataset = d.parent.name, d.parent.parent.parent
        m = manifest if manifest is not None else dataset_manifest(dataset)
        entry = next((e for e in (m or {}).get("samples", []) if isinstance(e, dict) and e.get("id") == sid), None)
        files = (entry or {}).get("files_sha256")
        if isinstance(files, dict) and files:
            return Checksums(_under(files, SAMPLE), f"the manifest of {dataset}", sid)
        res = _json(d.parent / RESULT)
        if isinstance(res, dict) and isinstance(res.get("files"), dict) and res["files"]:
            return Checksums(_under(res["files"], SAMPLE), f"{d.parent / RESULT}", sid)
    return stamp_checksums(d, "sample")


def stamp_checksums(directory: Path, kind: str) -> Checksums | None:
    """The checksums the stamp of ``directory`` records (``bench.io.outputs.STAMP``: ``platebench render``
    writes a "sample" stamp, ``platebench reconstruct`` a "reconstruction" one), or None when it has no
    stamp of that ``kind``."""
    d = Path(directory)
    st = read_stamp(d)
    if st is not None and st.get("kind") == kind:
        return Checksums({k: v for k, v in st["files"].items() if isinstance(k, str)}, f"{d / STAMP}", d.name)
    return None


def verify_reconstruction(recon_dir: Path) -> None:
    """Refuse (one-line ``DatasetError`` naming the file) a file of a reconstruction directory that is
    missing, is a link or differs from the checksum its stamp records (``stamp_checksums``, kind
    "reconstruction"); a directory without such a stamp records nothing to compare. What every reader
    that scores a reconstruction checks first (``platebench evaluate``, ``platebench compare``)."""
    verify_sample(recon_dir, stamp_checksums(recon_dir, "reconstruction"), then="refusing to score it")


def _under(files: dict, folder: str) -> dict:
    pre = folder + "/"
    return {k[len(pre):]: v for k, v in files.items() if isinstance(k, str) and k.startswith(pre)}


def verify_sample(sample_dir: Path, checksums: Checksums | None, names=None, then: str = "refusing the sample") -> None:
    """Refuse (``DatasetError`` naming the sample and the file) a file of ``sample_dir`` that is missing
    or differs from its recorded checksum; ``names``: only these relative paths (default: all recorded);
    ``then``: what the reader does about it, ending the message."""
    end = f": {then}" if then else ""
    if checksums is None:
        return
    d = Path(sample_dir)
    for rel in sorted(checksums.files if names is None else [n for n in names if n in checksums.files]):
        p = d / rel
        if os.path.islink(p):
            raise DatasetError(f"{p}: is a symbolic link (to {os.readlink(p)}), not the file {checksums.source} "
                               f"records for sample {checksums.sample_id}{end}")
        if not p.is_file():
            raise DatasetError(f"{p}: is missing (sample {checksums.sample_id}; {checksums.source} lists it){end}")
        if file_sha256(p) != checksums.files[rel]:
            raise DatasetError(f"{p}: differs from the checksum {checksums.source} records for sample "
                               f"{checksums.sample_id} (changed, truncated or swapped){end}")


def refuse_linked_inputs(sample_dir: Path, names, then: str) -> None:
    """Refuse (one-line ``DatasetError`` naming it) any of the sample's files ``names`` (paths relative to
    ``sample_dir``) that is a symbolic link or lies in a linked folder of the sample; nothing is opened.
    ``then``: what the reader does about it, ending the message."""
    d = Path(sample_dir)
    for rel in names:
        parts = Path(rel).parts
        for k in range(1, len(parts) + 1):
            p = d.joinpath(*parts[:k])
            if os.path.islink(p):
                raise DatasetError(f"{p}: is a symbolic link (to {os.readlink(p)}): a sample's files are read only "
                                   f"from the sample itself: {then}")


def verify_inputs(sample_dir: Path, names, then: str) -> None:
    """Refuse (one-line ``DatasetError`` naming the file) any of the sample's files ``names`` that is a link
    (``refuse_linked_inputs``) or, where the sample's checksums are recorded (``sample_checksums``), that
    differs from its checksum (``verify_sample``)."""
    refuse_linked_inputs(sample_dir, names, then)
    verify_sample(sample_dir, sample_checksums(Path(sample_dir)), names, then=then)


def find_links(root: Path, limit: int = 1) -> list[Path]:
    """Symbolic links under ``root`` (not followed), at most ``limit``; temporary names skipped."""
    found = []
    for dirpath, dirnames, filenames in os.walk(root):
        for name in dirnames + filenames:
            p = Path(dirpath) / name
            if not is_temp_name(name) and p.is_symlink():
                found.append(p)
                if len(found) >= limit:
                    return found
        dirnames[:] = [n for n in dirnames if not is_temp_name(n) and not (Path(dirpath) / n).is_symlink()]
    return found


def refuse_links(root: Path, what: str = "dataset") -> None:
    """Refuse a symbolic link anywhere under ``root`` (one-line ``DatasetError`` naming it)."""
    links = find_links(root)
    if links:
        raise DatasetError(f"{links[0]}: is a symbolic link inside the {what} {root} (to {os.readlink(links[0])}): "
                           "refusing to follow it (a link can lead out of the dataset)")
