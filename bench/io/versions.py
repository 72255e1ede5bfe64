"""Versions of the packages a result depends on (recorded in sample.json, the manifest and ``info``),
and the installed environment against the lock file (``requirements.lock`` at the repository root,
made by pip-tools' ``pip-compile`` from pyproject.toml; see README "Set-up")."""
from __future__ import annotations

import platform
import re
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

PACKAGES = ("platebench", "mitsuba", "drjit", "numpy", "scipy", "trimesh", "opencv-contrib-python-headless")
LOCK_NAME = "requirements.lock"
_PIN = re.compile(r"^\s*([A-Za-z0-9][A-Za-z0-9._-]*)\s*==\s*([^\s;#]+)\s*(?:;\s*([^#]+?))?\s*(?:#.*)?$")


def package_versions(extra: tuple[str, ...] = ()) -> dict:
    """Python's and each package's installed version (None if not installed)."""
    out = {"python": platform.python_version()}
    for name in PACKAGES + tuple(extra):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


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
    status "ok", "differs", "missing" or "not for this platform"."""

    path: Path | None
    rows: tuple

    @property
    def problems(self) -> list:
        return [r for r in self.rows if r[3] in ("differs", "missing")]

    def to_dict(self) -> dict:
        return {"file": str(self.path) if self.path else None, "packages": len(self.rows),
                "ok": sum(r[3] == "ok" for r in self.rows),
                "differs": {r[0]: {"locked": r[1], "installed": r[2]} for r in self.rows if r[3] == "differs"},
                "missing": [r[0] for r in self.rows if r[3] == "missing"]}


def check_lock(path: Path | None = None) -> LockCheck:
    """Compare every pin of the lock file with what is installed."""
    path = path or lock_path()
    if path is None:
        return LockCheck(None, ())
    try:
        from packaging.markers import Marker  # noqa: PLC0415
    except ImportError:  # pragma: no cover
        Marker = None
    installed = {normalize(d.metadata["Name"]): d.version for d in metadata.distributions() if d.metadata["Name"]}
    rows = []
    for name, (version, marker) in sorted(read_lock(path).items()):
        if marker and Marker is not None and not Marker(marker).evaluate():
            rows.append((name, version, installed.get(name), "not for this platform"))
            continue
        have = installed.get(name)
        rows.append((name, version, have, "missing" if have is None else "ok" if have == version else "differs"))
    return LockCheck(path, tuple(rows))
