"""Versions of the packages a result depends on (recorded in sample.json, the manifest and ``info``),
and the installed environment against the lock file (``requirements.lock`` at the repository root,
made by pip-tools' ``pip-compile`` from pyproject.toml; see README "Set-up").

A version here is that of the copy Python imports (``find_installed``): a distribution's metadata
folders (``NAME-VERSION.dist-info``) are found in the order of the Python path, and the first one is
what ``importlib.metadata.version`` reads, but ``import`` takes the package from the first folder of
the path that holds the package itself. So for each distribution the module Python would import is
looked up (its top-level names from ``importlib.metadata.packages_distributions``; an imported one's
``__spec__``, else ``importlib.util.find_spec``, which runs nothing for a top-level name), and the copy
whose file list (RECORD) holds that module's file gives the version. A copy that comes first but is
not that one (a stray ``numpy-99.0.dist-info`` on PYTHONPATH), or a module file that no copy's list
holds while a copy lists the module elsewhere, is "shadowed": an error of ``info --check-lock``.
"""
from __future__ import annotations

import functools
import importlib.util
import os
import platform
import re
import sys
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

PACKAGES = ("platebench", "mitsuba", "drjit", "numpy", "scipy", "trimesh", "opencv-contrib-python-headless")
LOCK_NAME = "requirements.lock"
_PIN = re.compile(r"^\s*([A-Za-z0-9][A-Za-z0-9._-]*)\s*==\s*([^\s;#]+)\s*(?:;\s*([^#]+?))?\s*(?:#.*)?$")


def package_versions(extra: tuple[str, ...] = ()) -> dict:
    """Python's and each package's version as imported (``find_installed``; None if not installed)."""
    names = PACKAGES + tuple(extra)
    return {"python": platform.python_version(), **dict(zip(names, _imported_versions(names, tuple(sys.path))))}


@functools.lru_cache(maxsize=8)
def _imported_versions(names: tuple, path: tuple) -> tuple:
    """The imported version of each of ``names`` (``find_installed``); ``path``, the Python path, keys the cache."""
    found = find_installed(names)
    return tuple(found[normalize(n)].version for n in names)


@dataclass(frozen=True)
class Installed:
    """One distribution as this Python has it: ``copies`` (version, metadata folder) of each copy in the
    order of the path; ``version`` that of the copy Python imports (the first copy's when the module cannot
    tell); ``module`` and ``module_file`` the module looked at (None: none); ``owner`` the index in ``copies``
    of the copy whose file list holds ``module_file`` (None: none does, or none lists files); ``foreign``
    whether a copy lists ``module`` at another place than ``module_file``."""

    name: str
    copies: tuple = ()
    module: str | None = None
    module_file: str | None = None
    owner: int | None = None
    foreign: bool = False

    @property
    def version(self) -> str | None:
        if not self.copies:
            return None
        return self.copies[self.owner if self.owner is not None else 0][0]

    @property
    def shadowed(self) -> str | None:
        """Why what Python imports is not what the first copy's metadata says (one line), or None."""
        if not self.copies:
            return None
        first_version, first_path = self.copies[0]
        if self.owner is not None and self.owner > 0 and first_version != self.version:
            own_path = self.copies[self.owner][1]
            return (f"Python imports {self.module} {self.version} from {self.module_file} ({own_path}), but "
                    f"{first_path} comes first on the path and reads as {self.name} {first_version}")
        if self.foreign:
            return (f"Python imports {self.module} from {self.module_file}, which no installed copy holds "
                    f"({self.name} {first_version} is installed at {first_path})")
        return None


def _copies() -> dict:
    """normalised name -> [Distribution, ...] in the order of the Python path."""
    out: dict = {}
    for d in metadata.distributions():
        name = d.metadata["Name"]
        if name:
            out.setdefault(normalize(name), []).append(d)
    return out


@functools.lru_cache(maxsize=1)
def _module_names() -> dict:
    """normalised distribution name -> its top-level import names (``packages_distributions``)."""
    out: dict = {}
    for top, dists in metadata.packages_distributions().items():
        for d in dists:
            out.setdefault(normalize(d), []).append(top)
    return out


def _module_file(top: str) -> str | None:
    """The real path of the file Python imports for top-level module ``top`` (None: not found, or no file)."""
    mod = sys.modules.get(top)
    try:
        spec = getattr(mod, "__spec__", None) if mod is not None else importlib.util.find_spec(top)
    except (ImportError, ValueError, AttributeError):
        return None
    origin = getattr(spec, "origin", None) if spec is not None and getattr(spec, "has_location", False) else None
    return os.path.realpath(origin) if isinstance(origin, str) else None


def _listed(dist) -> tuple[str, set] | None:
    """(real path of the folder ``dist``'s file list is relative to, the listed paths), None without a list."""
    try:
        files = dist.files
    except Exception:  # noqa: BLE001  (an unreadable RECORD)
        return None
    if files is None:
        return None
    return os.path.realpath(str(dist.locate_file(""))), {Path(str(f)).as_posix() for f in files}


def _inspect(name: str, dists: list) -> Installed:
    copies = tuple((d.version, str(getattr(d, "_path", "") or d.locate_file(""))) for d in dists)
    lists = [_listed(d) for d in dists]
    for top in sorted(_module_names().get(name, ()), key=lambda t: (t.startswith("_"), t != name.replace("-", "_"))):
        path = _module_file(top)
        if path is None:
            continue
        foreign = False
        for i, listed in enumerate(lists):
            if listed is None:
                continue
            base, files = listed
            rel = Path(os.path.relpath(path, base)).as_posix()
            if rel in files:
                return Installed(name, copies, top, path, i)
            foreign = foreign or any(f == f"{top}.py" or f.startswith(f"{top}/") for f in files)
        return Installed(name, copies, top, path, None, foreign)
    return Installed(name, copies)


def find_installed(names) -> dict:
    """normalised name -> ``Installed`` for each of ``names`` (module doc)."""
    copies = _copies()
    return {normalize(n): _inspect(normalize(n), copies.get(normalize(n), [])) for n in names}


def normalize(name: str) -> str:
    """PEP 503 name: lower case, runs of -_. as one -."""
    return re.sub(r"[-_.]+", "-", name).lower()


def lock_path() -> Path | None:
    """The lock file of the checkout this package runs from (None for an installed wheel without one)."""
    root = Path(__file__).resolve().parents[2]
    p = root / LOCK_NAME
    return p if p.is_file() else None


def read_lock(path: Path) -> dict:
    """name (normalised) -> (version, environment marker or None) of every ``name==version`` line."""
    out = {}
    for line in Path(path).read_text().splitlines():
        m = _PIN.match(line)
        if m:
            out[normalize(m.group(1))] = (m.group(2), m.group(3))
    return out


@dataclass(frozen=True)
class LockCheck:
    """The installed environment against the lock: ``rows`` are (name, locked, installed, status) with
    ``installed`` the version Python imports (``find_installed``) and status "ok", "differs", "missing",
    "shadowed" (the first metadata on the path is not the copy Python imports: ``shadows`` says how, one
    line each) or "not for this platform"."""

    path: Path | None
    rows: tuple
    shadows: tuple = ()  # (name, why), one per "shadowed" row

    @property
    def problems(self) -> list:
        return [r for r in self.rows if r[3] in ("differs", "missing", "shadowed")]

    def problem_lines(self) -> list[str]:
        """One line per problem, naming the package and both versions (and the folders, for a shadowed one)."""
        why = dict(self.shadows)
        out = []
        for name, locked, have, status in self.problems:
            if status == "shadowed":
                out.append(f"{name} shadowed: {why[name]}; locked {locked}")
            else:
                out.append(f"{name} {status}: locked {locked}, installed {have or 'none'}")
        return out

    def to_dict(self) -> dict:
        why = dict(self.shadows)
        return {"file": str(self.path) if self.path else None, "packages": len(self.rows),
                "ok": sum(r[3] == "ok" for r in self.rows),
                "differs": {r[0]: {"locked": r[1], "installed": r[2]} for r in self.rows if r[3] == "differs"},
                "shadowed": {r[0]: {"locked": r[1], "imported": r[2], "why": why.get(r[0])} for r in self.rows
                             if r[3] == "shadowed"},
                "missing": [r[0] for r in self.rows if r[3] == "missing"]}


def check_lock(path: Path | None = None) -> LockCheck:
    """Compare every pin of the lock file with the version Python imports of it (module doc)."""
    path = path or lock_path()
    if path is None:
        return LockCheck(None, ())
    try:
        from packaging.markers import Marker  # noqa: PLC0415
    except ImportError:  # pragma: no cover
        Marker = None
    pins = read_lock(path)
    found = find_installed(pins)
    rows, shadows = [], []
    for name, (version, marker) in sorted(pins.items()):
        inst = found[name]
        have = inst.version
        if marker and Marker is not None and not Marker(marker).evaluate():
            rows.append((name, version, have, "not for this platform"))
            continue
        why = inst.shadowed
        if have is None:
            status = "missing"
        elif why is not None:
            status = "shadowed"
            shadows.append((name, why))
        else:
            status = "ok" if have == version else "differs"
        rows.append((name, version, have, status))
    return LockCheck(path, tuple(rows), tuple(shadows))


def renderer_setup() -> dict:
    """The renderer's set-up on this machine: the libLLVM drjit uses, its version, and the Mitsuba
    variant chosen (``scenes.render.runtime.describe``)."""
    from platebench.scenes.render import runtime  # noqa: PLC0415

    return runtime.describe()
