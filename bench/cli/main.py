"""``platebench``: the command line. Each sub-command lives in its own ``bench.cmd_*`` module.

Errors a user can fix (bad flags, bad files) print one line ``platebench: error: ...``
and exit with status 2; nothing half-written is left behind. Set PLATEBENCH_DEBUG=1
to get the full traceback instead.
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys

from platebench.scenes.render.runtime import RendererUnavailable

# name -> module exposing add_parser(subparsers) and run(args) -> int
COMMANDS = {
    "render": "platebench.bench.cli.render",
    "reconstruct": "platebench.bench.cli.reconstruct",
    "evaluate": "platebench.bench.cli.evaluate",
    "perf": "platebench.bench.cli.perf",
    "info": "platebench.bench.cli.info",
    "demo": "platebench.bench.cli.demo",
    "sense": "platebench.bench.cli.sense",
    "study": "platebench.bench.cli.study",
    "sweep": "platebench.bench.cli.sweep",
    "compare": "platebench.bench.cli.compare",
    "calibrate": "platebench.bench.cli.calibrate",
    "report": "platebench.bench.cli.report",
}


class UserError(Exception):
    """An error the user can fix; printed as one line, exit status 2."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="platebench",
        description="Test bench for passive + active stereo measurement of deformed plates "
                    "(Chen & Zheng 1995): render bent plates with Mitsuba 3, reconstruct them with the "
                    "paper's pipeline and peer methods, score against exact ground truth.",
        epilog="Units: metres and radians in files; flags say when they take mm or degrees. "
               "Run 'platebench COMMAND --help' for each command.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, modname in COMMANDS.items():
        try:
            mod = importlib.import_module(modname)
        except ModuleNotFoundError as e:
            if e.name == modname:
                continue  # command not installed in this build
            raise
        mod.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.run(args) or 0)
    except KeyboardInterrupt:
        print("platebench: interrupted; completed outputs are kept, partial ones removed", file=sys.stderr)
        return 130
    except (UserError, ValueError, FileExistsError, FileNotFoundError, RendererUnavailable) as e:
        if os.environ.get("PLATEBENCH_DEBUG"):
            raise
        msg = str(e).splitlines()[0] if str(e) else type(e).__name__
        print(f"platebench: error: {msg}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
