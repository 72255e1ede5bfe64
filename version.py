"""The installed version of PlateBench (from the package metadata; pyproject.toml is the source)."""
from __future__ import annotations

from importlib import metadata

try:
    __version__ = metadata.version("platebench")
except metadata.PackageNotFoundError:  # pragma: no cover - running from an uninstalled tree
    __version__ = "0+unknown"
