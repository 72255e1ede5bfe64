"""Progress bars for long commands (tqdm on stderr; silent when not a terminal unless forced)."""
from __future__ import annotations

import os
import sys

from tqdm import tqdm


def bar(total: int | None, desc: str, unit: str = "step", enabled: bool | None = None):
    """A tqdm bar with counts and ETA; disabled when stderr is not a TTY (CI logs stay clean)
    unless PLATEBENCH_PROGRESS=1."""
    if enabled is None:
        enabled = sys.stderr.isatty() or os.environ.get("PLATEBENCH_PROGRESS") == "1"
    return tqdm(total=total, desc=desc, unit=unit, disable=not enabled, dynamic_ncols=True, leave=False)


def step_callback(pbar):
    """A ``progress(step_name)`` callback that advances ``pbar`` and shows the step."""
    def step(name: str) -> None:
        if pbar.n or getattr(pbar, "_started", False):
            pbar.update(1)
        pbar._started = True
        pbar.set_postfix_str(name)
    return step
