"""Versions of the packages a result depends on (recorded in sample.json, the manifest and ``info``)."""
from __future__ import annotations

import platform
from importlib import metadata

PACKAGES = ("platebench", "mitsuba", "drjit", "numpy", "scipy", "trimesh", "opencv-contrib-python-headless")


def package_versions(extra: tuple[str, ...] = ()) -> dict:
    """Python's and each package's installed version (None if not installed)."""
    out = {"python": platform.python_version()}
    for name in PACKAGES + tuple(extra):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


