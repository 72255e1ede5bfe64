"""The one base class of every error a user can fix (bad flags, files, configurations, inputs).

Every layer's user-facing error derives from ``PlateBenchError`` (and from ``ValueError`` where
a bad value is the cause, for code that catches that). The command line catches this class
and the file-system errors (missing, existing, unreadable or unwritable paths) and prints one
line, exit status 2; anything else is a bug and keeps its traceback. Messages are one line
naming the bad value (or file, or key) and what is allowed.
"""
from __future__ import annotations

__all__ = ["PlateBenchError", "UserValueError", "RegistrationError", "SamplesFailedError", "WorkerImportError"]


class PlateBenchError(Exception):
    """An error the user can fix; its message is one line naming the value and what is allowed."""


class UserValueError(PlateBenchError, ValueError):
    """A bad value (a flag, a key, an argument): one line naming it and the allowed range."""


class RegistrationError(UserValueError):
    """A name given to a registry (``plates.spec.register_family``, ``evaluation.metrics_row.register_metric``,
    ``reconstruction.strategy.cures.register_cure_rule``) that is registered already or not allowed."""


class SamplesFailedError(PlateBenchError):
    """A sweep finished, but some of its samples failed (``platebench.sweep`` with ``check=True``).

    ``summary`` is the sweep's ``SweepSummary`` (``failed``, ``results`` with each sample's error);
    the dataset keeps every sample, the failed ones with status "failed"."""

    def __init__(self, message: str, summary):
        super().__init__(message)
        self.summary = summary


class WorkerImportError(PlateBenchError, RuntimeError):
    """A facade function was called while a spawned worker process imported the main script: the
    script's top-level code runs again in every worker unless it sits under
    ``if __name__ == "__main__":``."""
