"""A sweep dataset's state as it stands, read the same way by every reader (sweep, report, export).

The manifest a sweep writes says "running" while it works; whether it still does is known only from
its lock (``bench.io.atomic.OutputLock``, a sibling file ``.NAME.lock``): a manifest whose writer is
gone (killed with -9, its machine lost) is "interrupted".
"""
from __future__ import annotations

from pathlib import Path

from platebench.bench.io.atomic import OutputLock

__all__ = ["dataset_lock", "live_state"]


def dataset_lock(dataset: Path) -> OutputLock:
    """The lock a sweep holds on its dataset (a sibling file ``.NAME.lock``)."""
    return OutputLock(Path(dataset).absolute(), "dataset")


def live_state(manifest: dict, dataset: Path) -> dict:
    """``manifest`` with its state as it stands: "running" only while a sweep holds the dataset lock; a
    manifest whose writer is gone (killed with -9, its machine lost) is "interrupted", with a
    ``state_note`` saying so. The one rule every reader applies (sweep, report, export)."""
    if manifest.get("state") == "running" and dataset_lock(dataset).holder() is None:
        manifest = dict(manifest)
        manifest["state"] = "interrupted"
        manifest["state_note"] = "the sweep that was writing it is gone (killed); finish it with --resume"
    return manifest
