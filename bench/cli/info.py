"""``platebench info``: which libLLVM and Mitsuba variant this machine uses, and the installed package
versions against the lock file."""
from __future__ import annotations

import json
import sys

from platebench.errors import PlateBenchError

HELP = "show the renderer set-up (libLLVM, Mitsuba variant) and versions vs the lock"


class LockMismatch(PlateBenchError):
    """Installed packages differ from the lock file (``info --check-lock``)."""


def add_parser(sub) -> None:
    p = sub.add_parser("info", help=HELP,
                       description="Print the libLLVM drjit will use, its version, the Mitsuba variant platebench "
                                   "picks, package versions, and every package of requirements.lock against the "
                                   "installed version (JSON on stdout; differences flagged on stderr).")
    p.add_argument("--check-lock", action="store_true",
                   help="exit with status 2 (one line) if an installed package differs from requirements.lock")
    p.set_defaults(run=run)


def run(args) -> int:
    from platebench.bench.io.versions import check_lock, package_versions  # noqa: PLC0415
    from platebench.scenes.render import runtime  # noqa: PLC0415
    lock = check_lock()
    print(json.dumps({"renderer": runtime.describe(), "packages": package_versions(), "lock": lock.to_dict()},
                     indent=2))
    if lock.path is None:
        print("platebench: note: no requirements.lock beside this installation: versions not checked",
              file=sys.stderr)
        return 0
    for name, locked, have, status in lock.problems:
        print(f"platebench: lock: {name} {status}: locked {locked}, installed {have or 'none'}", file=sys.stderr)
    if lock.problems:
        msg = (f"{len(lock.problems)} of {len(lock.rows)} packages differ from {lock.path}: reinstall with "
               f"'pip install -r {lock.path.name}' (see README, Set-up)")
        if args.check_lock:
            raise LockMismatch(msg)
        print(f"platebench: note: {msg}", file=sys.stderr)
    else:
        print(f"platebench: lock: all {len(lock.rows)} packages match {lock.path}", file=sys.stderr)
    return 0
