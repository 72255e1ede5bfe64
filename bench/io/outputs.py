"""The output rule: where a command may write, and what it may replace. One place, every command.

Every command checks its output path here before any work (``check_output``; directories are
then made with ``output_dir``, which stages them, ``bench.io.atomic``):

1. **Never replaced, whatever the flags**: the file-system root, the working directory, the home
   directory or a folder holding either; a symbolic link (the link is not what the user meant);
   an input of the command (``inputs``), a folder holding one, or a path inside one, except the
   input's own output slot (``slots``: a dataset's ``report/``, a sample's ``compare/``, a
   reconstruction's ``score.json``).
2. **An existing path is replaced only with** ``--overwrite``, and then only when it is what
   PlateBench wrote, of the kind the command writes (``KINDS``): a directory whose marker file
   (``sample.json``, ``recon.json``, ``manifest.json``, the report's ``index.html`` stamp,
   ``export.json``, ...) holds that kind, and which holds nothing PlateBench did not write; or
   an empty directory. Anything else is refused with one line naming what is there.
3. **What PlateBench wrote**: a directory output lists its files (with their sha256) in its stamp,
   ``.platebench-output.json``, written when the output is complete (``write_stamp``); a sweep
   dataset lists them in its samples' ``result.json``. A file no stamp lists (a user's note put in
   a sample folder) makes the directory foreign, except PlateBench outputs added later (a stamped
   folder such as ``compare/`` or ``report/``, a score JSON of ``platebench evaluate``) and the
   temporary names and locks of ``bench.io.atomic``. A listed file counts as PlateBench's only while
   it still has the sha256 listed for it: a file edited since (or replaced by a link or a folder)
   is the user's, and ``--overwrite`` refuses to replace the output, naming the file.

Messages name the path as the user gave it. Paths are compared after resolving symbolic links
and ``..`` (``canonical``), so a relative, absolute, trailing-slash or linked spelling of the same
place is the same place.
"""
from __future__ import annotations

import contextlib
import json
import os
import stat
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterable

from platebench.bench.files import JSON_MAX_BYTES, file_kind, file_sha256, open_regular, read_capped  # noqa: F401
from platebench.bench.io.atomic import (
    OutputExistsError,
    is_temp_name,
    staged_output,
    target_of_temp,
    write_json,
)
from platebench.bench.io.layout import (
    FORMAT,
    MANIFEST,
    RESULT,
    RESULTS_CHECKSUMS,
    RESULTS_CSV,
    RESULTS_PARQUET,
    SAMPLES,
    SPEC_COPY,
)
from platebench.bench.io.table_checksums import recorded_table_checksums

__all__ = ["STAMP", "KINDS", "OutputKind", "OutputRefusedError", "canonical", "check_output", "guard_output",
           "check_replace", "output_dir", "write_stamp", "read_stamp", "foreign_entries", "unowned_entries",
           "recognise", "describe_path", "file_sha256", "GENERATOR_REPORT"]

STAMP = ".platebench-output.json"
STAMP_FORMAT = "platebench-output"
GENERATOR_REPORT = "platebench report"  # the report's index.html: <meta name="generator" content="...">
_MAX_NAMED = 3  # entries named in a refusal


class OutputRefusedError(OutputExistsError):
    """An output path the rule refuses (one line naming it and why)."""


# ----------------------------------------------------------------------------- kinds
def _json(path: Path):
    """The JSON document of the regular file ``path``, or None when it is not one."""
    try:
        return json.loads(read_capped(path, JSON_MAX_BYTES, "JSON file"))
    except (OSError, ValueError):  # unreadable, not JSON, not a regular file (InputFileError is a ValueError)
        return None


def _dict_with(path: Path, *keys: str, **values) -> bool:
    d = _json(path)
    return isinstance(d, dict) and all(k in d for k in keys) and all(d.get(k) == v for k, v in values.items())


def _report_index(path: Path) -> bool:
    try:
        with open_regular(path, 1 << 30, "report page") as f:  # a FIFO is refused, never read
            head = f.read(4000).decode("utf-8", "replace")
    except (OSError, ValueError):
        return False
    return f'<meta name="generator" content="{GENERATOR_REPORT}">' in head


def _score_file(path: Path) -> bool:
    """A score JSON of ``platebench evaluate`` (a reconstruction's, or another program's output's)."""
    d = _json(path)
    return isinstance(d, dict) and ({"points", "matching", "false_boundary"} <= set(d)
                                    or {"method", "kind", "score", "units"} <= set(d))


def _perf_file(path: Path) -> bool:
    return _dict_with(path, generator="platebench perf")


def _npz_names(path: Path) -> list[str]:
    """The member names of the ``.npz`` (zip) file ``path``; [] when it is none."""
    import zipfile  # noqa: PLC0415

    try:
        with zipfile.ZipFile(path) as z:
            return z.namelist()
    except (OSError, zipfile.BadZipFile, ValueError):
        return []


def _npz_images(path: Path) -> bool:
    names = _npz_names(path)
    return bool(names) and all(n.endswith(".npy") for n in names) and any(n.startswith("seed1_") for n in names)


def _error_map_file(path: Path) -> bool:
    """An error map ``platebench evaluate`` writes beside its score (``bench.io.error_map_files``)."""
    return {"kind.npy", "count.npy", "median_m.npy", "rms_m.npy"} <= set(_npz_names(path))


@dataclass(frozen=True)
class OutputKind:
    """What one command writes: ``label`` (in messages), the ``command`` that writes it, its
    ``marker`` (the file that defines it, inside a directory output; a file output is its own
    marker) and ``holds(marker_path)``, whether that file holds this kind."""

    label: str
    command: str
    marker: str
    holds: Callable[[Path], bool]
    directory: bool = True

    def recognised(self, path: Path) -> bool:
        """Whether the existing ``path`` carries this kind's marker (not whether it holds foreign files)."""
        path = Path(path)
        if self.directory:
            return path.is_dir() and not path.is_symlink() and self.holds(path / self.marker)
        return path.is_file() and not path.is_symlink() and self.holds(path)


KINDS: dict[str, OutputKind] = {k.label: k for k in (
    OutputKind("sample", "render", "sample.json", lambda p: _dict_with(p, "layout_version", "config", "images")),
    OutputKind("reconstruction", "reconstruct", "recon.json",
               lambda p: _dict_with(p, "n_points", "false_boundary", "input_checksums")),
    OutputKind("comparison", "compare", "compare.json", lambda p: _dict_with(p, "methods")),
    OutputKind("export", "export", "export.json", lambda p: _dict_with(p, "format", "samples", "shift")),
    OutputKind("calibration", "calibrate", "calibration.json", lambda p: _dict_with(p, "cameras", "stereo")),
    OutputKind("sensing run", "sense", "sensing.json", lambda p: _dict_with(p, "steps", "final")),
    OutputKind("study", "study", "study.json", lambda p: _dict_with(p, "rows")),
    OutputKind("accuracy study", "study accuracy", "accuracy.json",
               lambda p: _dict_with(p, "rows", "summary", study="accuracy")),
    OutputKind("cut-squares study", "study cut-squares", "cut_study.json",
               lambda p: _dict_with(p, "rows", "totals", kind="cut-squares study")),
    OutputKind("report", "report", "index.html", _report_index),
    OutputKind("demo output", "demo", "demo.json", lambda p: _dict_with(p, generator="platebench demo")),
    OutputKind("dataset", "sweep", MANIFEST, lambda p: _dict_with(p, format=FORMAT)),
    OutputKind("benchmark results", "benchmark score", "benchmark-results.json",
               lambda p: _dict_with(p, format="platebench-benchmark-results")),
    OutputKind("leaderboard", "benchmark leaderboard", "leaderboard.json",
               lambda p: _dict_with(p, format="platebench-leaderboard")),
    OutputKind("score", "evaluate", "", _score_file, directory=False),
    OutputKind("error map", "evaluate", "", _error_map_file, directory=False),
    OutputKind("perf figures", "perf", "", _perf_file, directory=False),
    OutputKind("perf images", "perf variants --save", "", _npz_images, directory=False),
)}


def recognise(path: Path) -> OutputKind | None:
    """The kind of PlateBench output ``path`` is by its marker (None: none of them)."""
    return next((k for k in KINDS.values() if k.recognised(path)), None)


# ----------------------------------------------------------------------------- paths
def canonical(path) -> Path:
    """``path`` absolute, with ``.``, ``..`` and every symbolic link above its last component resolved
    (the last is kept as it is, so that an output that is a link is seen as one)."""
    p = Path(os.fspath(path))
    if p.name in ("", ".", ".."):
        return p.resolve()
    return p.parent.resolve() / p.name


def _resolved(path) -> Path:
    return Path(os.fspath(path)).resolve()


def _same(a: Path, b: Path) -> bool:
    if a == b:
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def _protected() -> list[tuple[Path, str]]:
    out = [(Path("/"), "the file-system root")]
    with contextlib.suppress(OSError):
        out.append((Path.cwd().resolve(), "the working directory"))
    with contextlib.suppress(RuntimeError, KeyError, OSError):
        home = Path.home().resolve()
        if home != Path("/"):
            out.append((home, "the home directory"))
    return out


def describe_path(path: Path) -> str:
    """What is at ``path``, for a message: 'a PlateBench reconstruction (recon.json)', 'a file',
    'a directory holding notes.txt, data/ and 2 more', 'an empty directory', 'a FIFO (named pipe)'."""
    path = Path(path)
    try:
        st = os.lstat(path)
    except OSError:
        return "nothing"
    if stat.S_ISLNK(st.st_mode):
        return f"a symbolic link to {os.readlink(path)}"
    kind = recognise(path)
    if kind is not None:
        return f"a PlateBench {kind.label}" + (f" ({kind.marker})" if kind.marker else "")
    if stat.S_ISREG(st.st_mode):
        return "a file"
    if not stat.S_ISDIR(st.st_mode):
        return file_kind(st.st_mode)
    try:
        names = sorted(e.name + ("/" if e.is_dir(follow_symlinks=False) else "") for e in os.scandir(path))
    except OSError as e:
        return f"a directory that cannot be listed ({e.strerror})"
    if not names:
        return "an empty directory"
    more = f" and {len(names) - _MAX_NAMED} more" if len(names) > _MAX_NAMED else ""
    return "a directory holding " + ", ".join(names[:_MAX_NAMED]) + more


# ----------------------------------------------------------------------------- the rule
def guard_output(target, *, inputs: Iterable = (), slots: Iterable = (), shown: str | None = None) -> Path:
    """Part 1 of the rule (module doc), whatever the flags; returns ``canonical(target)``.

    ``inputs``: the paths the command reads (files or directories); ``slots``: paths inside an
    input where this command's output belongs (a default output such as ``DATASET/report``).
    Raises ``OutputRefusedError`` naming ``shown`` (default: ``target`` as given)."""
    shown = str(target) if shown is None else shown
    t = canonical(target)
    if os.path.islink(t):
        raise OutputRefusedError(f"{shown}: is a symbolic link (to {os.readlink(t)}): an output never replaces a "
                                 "link; give the real path")
    for place, what in _protected():
        if t == place:
            raise OutputRefusedError(f"{shown}: is {what}: an output never replaces it")
        if place != Path("/") and place.is_relative_to(t):
            raise OutputRefusedError(f"{shown}: holds {what} ({place}): an output never replaces it")
    tr = _resolved(t)
    slot_set = {_resolved(s) for s in slots}
    for given in inputs:
        if given is None or not os.path.lexists(given):  # nothing there to destroy (its reader says it is missing)
            continue
        i = _resolved(given)
        if _same(tr, i):
            raise OutputRefusedError(f"{shown}: is the input {given}: an output never replaces its input")
        if i.is_relative_to(tr):
            raise OutputRefusedError(f"{shown}: holds the input {given}: an output never replaces its input")
        if tr.is_relative_to(i) and tr not in slot_set:
            raise OutputRefusedError(f"{shown}: is inside the input {given}: an output never goes into its input"
                                     + (f" (except {', '.join(sorted(map(str, slots)))})" if slot_set else ""))
    # a file above the output (render --out afile/s) is named before anything is made
    for up in t.parents:
        if os.path.lexists(up):
            if not up.is_dir():
                raise OutputRefusedError(f"{shown}: cannot be made: {up} is {describe_path(up)}, not a directory")
            break
    return t


def check_replace(target, kind: str, overwrite: bool, shown: str | None = None) -> None:
    """Part 2 of the rule (module doc): nothing at ``target``; or, with ``overwrite``, an empty
    directory or a PlateBench output of ``kind`` holding nothing else. ``target``: canonical."""
    shown = str(target) if shown is None else shown
    t = Path(target)
    if not os.path.lexists(t):
        return
    if not overwrite:
        raise OutputRefusedError(f"{shown}: already exists (use --overwrite to replace it)")
    k = KINDS[kind]
    if os.path.islink(t):
        raise OutputRefusedError(f"{shown}: is a symbolic link (to {os.readlink(t)}): an output never replaces a "
                                 "link; give the real path")
    if k.directory and not t.is_dir():
        raise OutputRefusedError(f"{shown}: exists and is not a directory ({describe_path(t)}): refusing to "
                                 f"replace it with a {k.label} directory")
    if not k.directory and t.is_dir():
        raise OutputRefusedError(f"{shown}: is a directory: refusing to replace it with a {k.label} file")
    if k.directory and not any(os.scandir(t)):
        return  # an empty directory: nothing to lose
    if not k.recognised(t):
        raise OutputRefusedError(f"{shown}: is {describe_path(t)}, not a PlateBench {k.label}: refusing to replace "
                                 f"it (--overwrite replaces only what 'platebench {k.command}' wrote)")
    if k.directory:
        unowned = unowned_entries(t, kind, limit=1)
        if unowned is None:
            raise OutputRefusedError(f"{shown}: is a PlateBench {k.label} without the {STAMP} that lists what "
                                     "PlateBench wrote in it (made by hand or by an older version): what else it "
                                     "holds cannot be told, so it is not replaced; remove it yourself or choose "
                                     "another --out")
        if unowned:
            rel, changed = unowned[0]
            if changed:
                raise OutputRefusedError(f"{shown}: holds {rel}, which was changed after PlateBench wrote it (it no "
                                         "longer has the sha256 recorded for it): refusing to replace it (copy your "
                                         "edit elsewhere, or choose another --out)")
            raise OutputRefusedError(f"{shown}: holds {rel}, which PlateBench did not write: refusing to "
                                     "replace it (move it out, or choose another --out)")


def check_output(target, kind: str, *, overwrite: bool = False, inputs: Iterable = (), slots: Iterable = (),
                 shown: str | None = None) -> Path:
    """The whole rule for the output ``target`` of ``kind`` (a key of ``KINDS``), before any work;
    returns its canonical path (module doc)."""
    shown = str(target) if shown is None else shown
    inputs, slots = list(inputs), list(slots)
    t = guard_output(target, inputs=inputs, slots=slots, shown=shown)
    check_replace(t, kind, overwrite, shown)
    return t


@contextlib.contextmanager
def output_dir(target, kind: str, *, overwrite: bool = False, inputs: Iterable = (), slots: Iterable = (),
               lock: bool = True, note=None):
    """Yield the staging directory of the output directory ``target`` of ``kind``: the rule is
    checked before any work and again, under the output's lock, before the finished output (with its
    stamp, ``write_stamp``) replaces ``target`` (``bench.io.atomic.staged_output``)."""
    shown = str(target)
    inputs, slots = list(inputs), list(slots)
    t = check_output(target, kind, overwrite=overwrite, inputs=inputs, slots=slots, shown=shown)

    def again(_path: Path) -> None:
        check_output(t, kind, overwrite=overwrite, inputs=inputs, slots=slots, shown=shown)

    kwargs = {} if note is None else {"note": note}
    try:
        with staged_output(t, overwrite=overwrite, what=KINDS[kind].label, lock=lock, check=again, **kwargs) as stage:
            yield stage
            write_stamp(stage, kind)
    except OSError as e:  # name the user's path, never a staging name
        name = os.fsdecode(e.filename) if e.filename is not None else None
        if name and e.errno is not None and target_of_temp(Path(name)) != Path(name):
            raise type(e)(e.errno, e.strerror, str(target_of_temp(Path(name)))) from None
        raise


# ----------------------------------------------------------------------------- stamps
def _files(root: Path) -> dict[str, str]:
    out = {}
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if not is_temp_name(d))
        for name in sorted(filenames):
            if is_temp_name(name) or (dirpath == str(root) and name == STAMP):
                continue
            p = Path(dirpath) / name
            if p.is_file() and not p.is_symlink():
                out[p.relative_to(root).as_posix()] = file_sha256(p)
    return out


def write_stamp(directory: Path, kind: str) -> None:
    """Write ``directory/.platebench-output.json``: the output's kind and the sha256 of every file in
    it (what PlateBench wrote there). Called on the finished staging directory."""
    write_json(Path(directory) / STAMP, {"format": STAMP_FORMAT, "kind": kind, "files": _files(Path(directory))})


def read_stamp(directory: Path) -> dict | None:
    """The stamp of ``directory`` ({"kind", "files": {relative path: sha256}}), or None."""
    d = _json(Path(directory) / STAMP)
    if not isinstance(d, dict) or d.get("format") != STAMP_FORMAT or not isinstance(d.get("files"), dict):
        return None
    return d


def _dataset_listing(root: Path) -> dict[str, str | None] | None:
    """Every file a sweep dataset's manifest and committed samples list (relative path -> its recorded
    sha256, None for the dataset's own records, which a sweep rewrites)."""
    if not _dict_with(root / MANIFEST, format=FORMAT):
        return None
    listed: dict[str, str | None] = dict.fromkeys((MANIFEST, SPEC_COPY, RESULTS_CSV, RESULTS_PARQUET,
                                                   RESULTS_CHECKSUMS))
    listed.update((name, sha) for name, sha in (recorded_table_checksums(root) or {}).items()
                  if name in (RESULTS_CSV, RESULTS_PARQUET))  # an edited table is the user's now
    samples = root / SAMPLES
    with contextlib.suppress(OSError):
        for e in os.scandir(samples):
            if is_temp_name(e.name) or not e.is_dir(follow_symlinks=False):
                continue
            res = _json(Path(e.path) / RESULT)
            if isinstance(res, dict) and isinstance(res.get("files"), dict):
                listed[f"{SAMPLES}/{e.name}/{RESULT}"] = None
                listed.update((f"{SAMPLES}/{e.name}/{rel}", _sha(v)) for rel, v in res["files"].items()
                              if isinstance(rel, str))
    return listed


def _sha(v) -> str | None:
    return v if isinstance(v, str) else None


def _listing(root: Path, kind: str | None) -> dict[str, str | None] | None:
    """What PlateBench wrote in ``root`` (relative path -> the sha256 recorded for it, None where none is):
    its stamp's files (of ``kind`` when given), or a dataset's."""
    if kind == "dataset" or (kind is None and not (root / STAMP).is_file()):
        return _dataset_listing(root)
    st = read_stamp(root)
    if st is None or (kind is not None and st.get("kind") != kind):
        return None
    return {STAMP: None, **{k: _sha(v) for k, v in st["files"].items() if isinstance(k, str)}}


def _is_lock(path: Path) -> bool:
    name = path.name
    return name.startswith(".") and name.endswith(".lock") and _dict_with(path, "pid", "host")


def foreign_entries(root: Path, kind: str | None = None, limit: int = _MAX_NAMED) -> list[str] | None:
    """Paths under ``root`` (relative, POSIX) that are not what PlateBench wrote (module doc, 3: not
    listed, or changed since), at most ``limit``; None when nothing lists what it wrote there (no stamp
    of ``kind``, no dataset manifest). Symbolic links are never followed."""
    found = unowned_entries(root, kind, limit)
    return None if found is None else [rel for rel, _ in found]


def unowned_entries(root: Path, kind: str | None = None, limit: int = _MAX_NAMED) -> list[tuple[str, bool]] | None:
    """``foreign_entries`` with the reason: (relative path, changed), ``changed`` True for a file PlateBench
    listed whose bytes no longer have the recorded sha256 (or that is now a link or a folder), False for
    a path PlateBench never wrote."""
    root = Path(root)
    listed = _listing(root, kind)
    if listed is None:
        return None
    found: list[tuple[str, bool]] = []
    _walk(root, "", listed, found, limit)
    return found


def _changed(p: Path, entry: os.DirEntry, sha: str | None) -> bool:
    """Whether the listed path ``p`` is no longer the file PlateBench recorded with ``sha``."""
    if sha is None:
        return False
    if not entry.is_file(follow_symlinks=False):
        return True
    try:
        return file_sha256(p) != sha
    except OSError:
        return True


def _walk(d: Path, rel: str, listed: dict, found: list, limit: int, dirs: set[str] | None = None) -> None:
    if dirs is None:  # every folder on the way to a listed file ("a/", "a/b/")
        dirs = {p.rsplit("/", k)[0] + "/" for p in listed for k in range(1, p.count("/") + 1)}
    try:
        entries = sorted(os.scandir(d), key=lambda e: e.name)
    except OSError:
        found.append((rel or "./", False))
        return
    for e in entries:
        if len(found) >= limit:
            return
        r = rel + e.name
        p = Path(e.path)
        if is_temp_name(e.name):
            continue
        if r in listed:
            if _changed(p, e, listed[r]):
                found.append((r, True))
            continue
        if e.is_dir(follow_symlinks=False):
            own = _listing(p, None)
            if own is not None:  # a PlateBench output added inside (compare/, report/, a dataset)
                sub: list[tuple[str, bool]] = []
                _walk(p, "", own, sub, limit - len(found))
                found += [(r + "/" + s, changed) for s, changed in sub]
            elif r + "/" in dirs:
                _walk(p, r + "/", listed, found, limit, dirs)
            else:
                first = _first_file(p)
                if first is not None:  # an empty folder holds nothing to lose
                    found.append((f"{r}/{first}", False))
        elif e.is_file(follow_symlinks=False) and (_score_file(p) or _is_lock(p)):
            continue  # a score of 'platebench evaluate' beside an output, a lock of a finished writer
        else:
            found.append((r, False))


def _first_file(d: Path) -> str | None:
    """The first file (or link) under ``d``, relative to it; None when it holds none."""
    for dirpath, dirnames, filenames in os.walk(d):
        dirnames.sort()
        names = sorted(filenames) + sorted(n for n in dirnames if os.path.islink(os.path.join(dirpath, n)))
        if names:
            return (Path(dirpath) / names[0]).relative_to(d).as_posix()
    return None
