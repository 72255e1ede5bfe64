"""Extensions declared by installed packages: the deformation families, metrics and cure rules of a
user's own package, found by entry point and imported once per process.

A distribution declares a module (or ``module:object``) in one of the groups of ``GROUPS``::

    [project.entry-points."platebench.families"]
    my_ripple = "my_package.ripple"

Importing the module runs its ``register_family`` / ``register_metric`` / ``register_cure_rule`` calls
(``plates.spec``, ``evaluation.metrics_row``, ``reconstruction.strategy.cures``), which add to that
registry; the object after ``:``, if named, is looked up and otherwise unused. ``load_extensions()``
imports every entry point of the three groups, groups in the order of ``GROUPS`` and, inside a group,
in the order of the distributions' names, then the entry points' names (so every process registers
them in the same order). It is called by the command line before it runs a command
(``bench.cli.main``), by every worker process a sweep, study or benchmark score starts
(``bench.sweep.tasks``, ``bench.run.workers.pool_worker_init``: a Dask worker at each task's start),
and by the facade functions of ``platebench.api``. It loads once per process: later calls return
what the first found.

An entry point whose module cannot be imported, raises while it is imported, or registers a name that
is registered already or not allowed (``platebench.errors.RegistrationError``) stops the caller with
``ExtensionError`` (a ``UserValueError``: one line naming the entry point, its group and its distribution;
the command line prints it and exits 2).
The same error is raised again by every later call in that process.

Peer methods have their own group, ``platebench.methods``, resolved by name without importing the
module (``bench.run.plugins``)."""
from __future__ import annotations

import threading
from dataclasses import asdict, dataclass
from importlib import metadata

from platebench.errors import RegistrationError, UserValueError

__all__ = ["GROUPS", "ExtensionError", "LoadedExtension", "load_extensions", "registry_names"]

GROUPS = ("platebench.families", "platebench.metrics", "platebench.cure_rules")


class ExtensionError(UserValueError):
    """An entry point of ``GROUPS`` could not be loaded (import failure, an error at import, or a name
    registered already or not allowed): one line naming it, its group and its distribution."""


@dataclass(frozen=True)
class LoadedExtension:
    """One entry point imported by ``load_extensions``."""

    group: str  # one of GROUPS
    name: str  # the entry point's name
    value: str  # "module" or "module:object"
    distribution: str  # the declaring distribution's name ("?" when its metadata names none)


_STATE: dict = {"loaded": None, "error": None}
_LOCK = threading.Lock()  # a Dask worker's threads may start tasks at once: one of them loads


def _distribution(ep) -> str:
    dist = getattr(ep, "dist", None)
    name = None if dist is None else dist.metadata["Name"]
    return str(name) if name else "?"


def _first_line(e: BaseException) -> str:
    text = str(e).strip()
    line = text.splitlines()[0] if text else ""
    return f"{type(e).__name__}: {line}" if line else type(e).__name__


def _failure(ep, group: str, dist: str, e: BaseException) -> ExtensionError:
    if isinstance(e, ImportError):
        what = "cannot be imported"
    elif isinstance(e, RegistrationError):
        what = "registers a name that is registered already or not allowed"
    else:
        what = "failed while it was imported"
    return ExtensionError(f"entry point '{ep.name} = {ep.value}' of group {group} (distribution {dist}) {what} "
                          f"({_first_line(e)}): fix or uninstall that distribution")


def load_extensions() -> tuple[LoadedExtension, ...]:
    """Import every entry point of ``GROUPS`` in this process, once; returns what was loaded, in order.
    Raises ``ExtensionError`` (module doc) when one cannot be loaded, at this and every later call."""
    if _STATE["loaded"] is not None:
        return _STATE["loaded"]
    with _LOCK:
        if _STATE["error"] is not None:
            raise _STATE["error"]
        if _STATE["loaded"] is None:
            _STATE["loaded"] = _load()
    return _STATE["loaded"]


def _load() -> tuple[LoadedExtension, ...]:
    found = metadata.entry_points()
    loaded = []
    for group in GROUPS:
        eps = sorted(((_distribution(ep), ep) for ep in found.select(group=group)),
                     key=lambda pair: (pair[0].lower(), pair[1].name))
        for dist, ep in eps:
            try:
                ep.load()
            except (Exception, SystemExit) as e:  # noqa: BLE001  (whatever the module does: one line)
                _STATE["error"] = _failure(ep, group, dist, e)
                raise _STATE["error"] from None
            loaded.append(LoadedExtension(group, ep.name, ep.value, dist))
    return tuple(loaded)


def registry_names() -> dict:
    """What ``platebench info`` shows of the extension points: the entry points loaded in this process
    (``load_extensions``) and the keys of each registry, in its order (built-in first)."""
    from platebench.evaluation.metrics_row import METRICS  # noqa: PLC0415
    from platebench.plates.spec import FAMILIES  # noqa: PLC0415
    from platebench.reconstruction.strategy.cures import cure_rules  # noqa: PLC0415
    return {"entry_points": [asdict(x) for x in load_extensions()], "families": list(FAMILIES),
            "metrics": list(METRICS), "cure_rules": [r.name for r in cure_rules()]}
