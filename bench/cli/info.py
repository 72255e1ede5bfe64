"""``platebench info``: which libLLVM and Mitsuba variant this machine uses, and why."""
from __future__ import annotations

import json


def add_parser(sub) -> None:
    p = sub.add_parser("info", help="show the renderer set-up (libLLVM, Mitsuba variant, versions)",
                       description="Print the libLLVM drjit will use, its version, the Mitsuba variant "
                                   "platebench picks, and package versions, as JSON.")
    p.set_defaults(run=run)


def run(args) -> int:
    from platebench.bench.io.versions import package_versions  # noqa: PLC0415
    from platebench.scenes.render import runtime  # noqa: PLC0415
    print(json.dumps({"renderer": runtime.describe(), "packages": package_versions()}, indent=2))
    return 0
