"""``platebench info``: which libLLVM and Mitsuba variant this machine uses, the versions of the
packages Python imports against the lock file (``bench.io.versions``: a copy whose metadata shadows the
imported one is an error of ``--check-lock``), and the extension points' registries with the entry
points of installed packages loaded into them (``bench.run.extensions``)."""
from __future__ import annotations

import json
import sys

from platebench.errors import PlateBenchError

HELP = "show the renderer set-up (libLLVM, Mitsuba variant) and versions vs the lock"


class LockMismatch(PlateBenchError):
    """The packages Python imports differ from the lock file, or a stray copy shadows one
    (``info --check-lock``)."""


def add_parser(sub) -> None:
    p = sub.add_parser("info", help=HELP,
                       description="Print the libLLVM drjit will use, its version, the Mitsuba variant platebench "
                                   "picks, package versions, every package of requirements.lock against the "
                                   "installed version, and the registered deformation families, metrics and cure "
                                   "rules with the installed packages' entry points that added them (JSON on "
                                   "stdout; differences flagged on stderr).")
    p.add_argument("--check-lock", action="store_true",
                   help="exit with status 2 (one line) if a package Python imports differs from requirements.lock, or "
                        "if another copy's metadata shadows it on the Python path")
    p.set_defaults(run=run)


def run(args) -> int:
    from platebench.bench.io.versions import check_lock, package_versions, renderer_setup  # noqa: PLC0415
    from platebench.bench.run.extensions import registry_names  # noqa: PLC0415
    lock = check_lock()
    print(json.dumps({"renderer": renderer_setup(), "packages": package_versions(), "lock": lock.to_dict(),
                      "extensions": registry_names()}, indent=2))
    if lock.path is None:
        print("platebench: note: no requirements.lock beside this installation: versions not checked",
              file=sys.stderr)
        return 0
    lines = lock.problem_lines()
    for line in lines:
        print(f"platebench: lock: {line}", file=sys.stderr)
    if lock.problems:
        msg = (f"{len(lock.problems)} of {len(lock.rows)} packages differ from {lock.path} ({lines[0]}"
               f"{'; ...' if len(lines) > 1 else ''}): reinstall with 'pip install -r {lock.path.name}' and take "
               "stray copies off the Python path (see README, Set-up)")
        if args.check_lock:
            raise LockMismatch(msg)
        print(f"platebench: note: {msg}", file=sys.stderr)
    else:
        print(f"platebench: lock: all {len(lock.rows)} packages match {lock.path}", file=sys.stderr)
    return 0
