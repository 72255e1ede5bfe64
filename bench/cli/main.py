"""``platebench``: the command line. Each sub-command lives in its own ``bench.cli.<name>`` module
(argparse and printing only; the work is in ``bench.run``, ``bench.sweep``, ``bench.report``).

Errors a user can fix (``platebench.errors.PlateBenchError``: bad flags, bad files, bad
configurations) and file-system errors (a path missing, existing, unreadable or unwritable)
print one line ``platebench: error: ...`` and exit with status 2; nothing half-written is left
behind. Anything else is a bug and keeps its traceback. PLATEBENCH_DEBUG=1 shows the traceback
of user errors too.

Ctrl-C and SIGTERM end every command with status 130 and 143 (``bench.interrupts``: the handlers
are installed before any command module is imported, and a signal swallowed by a library on the
way still sets the status); completed outputs are kept, partial ones removed.
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys
from pathlib import Path

from platebench.bench import interrupts
from platebench.errors import PlateBenchError

# name -> module exposing HELP (its line in 'platebench --help'), add_parser(subparsers) and run(args) -> int.
# A command module imports only what its parser needs at the top; the work's modules (renderer, pipeline,
# trimesh, SciPy, pandas, ...) are imported where they are used, so --help and a bad flag or file answer
# in a fraction of a second.
COMMANDS = {name: f"platebench.bench.cli.{name}" for name in (
    "render", "reconstruct", "evaluate", "compare", "sense", "study", "sweep", "calibrate", "report", "demo",
    "perf", "info", "export")}


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The parser. With ``argv``, only the commands named in it get their whole sub-parser (their
    ``add_parser``, which may import what the command's defaults come from); the others get their name
    and ``HELP`` only, which is all that 'platebench --help' and the 'invalid choice' error show: argparse
    hands arguments to a sub-parser only when a token of ``argv`` is exactly its name."""
    parser = argparse.ArgumentParser(
        prog="platebench",
        description="Test bench for passive + active stereo measurement of deformed plates "
                    "(Chen & Zheng 1995): render bent plates with Mitsuba 3, reconstruct them with the "
                    "paper's pipeline and peer methods, score against exact ground truth.",
        epilog="Units: metres and radians in files; flags say when they take mm or degrees. "
               "Run 'platebench COMMAND --help' for each command. Exit status: 0 done, 2 a user error "
               "(one line on stderr), 130 interrupted (Ctrl-C), 143 terminated (SIGTERM).")
    parser.add_argument("--version", action=_Version, help="show the installed version and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True, help="what to do (below)")
    for name, modname in COMMANDS.items():
        module = importlib.import_module(modname)
        if argv is None or name in argv:
            module.add_parser(sub)
        else:
            sub.add_parser(name, help=module.HELP)
    return parser


class _Version(argparse.Action):
    """``--version``: the package metadata is read only when asked (it costs every other command 30-50 ms)."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS, help=None):
        super().__init__(option_strings, dest, nargs=0, default=default, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        from platebench.version import __version__  # noqa: PLC0415
        print(f"platebench {__version__}")  # on stdout, as argparse's own version action prints it
        parser.exit()


def _one_line(e: BaseException) -> str:
    if isinstance(e, OSError) and e.filename is not None and e.strerror:
        from platebench.bench.io.atomic import target_of_temp  # noqa: PLC0415  (loaded after the handlers)
        name = target_of_temp(Path(os.fsdecode(e.filename)))  # the user's path, never a staging name
        return f"{name}: {e.strerror[0].lower() + e.strerror[1:]}"
    text = str(e).strip()
    return text.splitlines()[0] if text else type(e).__name__


def _interrupted(e: KeyboardInterrupt | None) -> int:
    status = interrupts.exit_status() or (143 if isinstance(e, interrupts.Terminated) else 130)
    what = "terminated (SIGTERM)" if status == 143 else "interrupted"
    print(f"platebench: {what}; completed outputs are kept, partial ones removed", file=sys.stderr)
    return status


def main(argv: list[str] | None = None) -> int:
    """Run one command. ``argv`` None: this process's command line (the handlers of ``bench.interrupts`` stay
    to its very end: ``finish``); a list: a call from Python, which gets its own handlers back."""
    whole_process = argv is None
    interrupts.install(whole_process)  # first: a signal at any later moment ends the command with 130 / 143
    try:
        return _run(sys.argv[1:] if argv is None else list(argv),
                    interrupts.finish if whole_process else (lambda status: status))
    finally:
        if not whole_process:
            interrupts.uninstall()


def _run(argv: list[str], done) -> int:
    """The command's exit status, passed through ``done`` as soon as it is known."""
    try:
        parser = build_parser(argv)
        args = parser.parse_args(argv)
        status = int(args.run(args) or 0)
        interrupts.check()  # a signal that a library swallowed on the way
        return done(status)
    except KeyboardInterrupt as e:
        return done(_interrupted(e))
    except BaseException as e:
        if interrupts.received() is not None:  # an error on the way out of an interrupt
            return done(_interrupted(None))
        if not isinstance(e, (PlateBenchError, OSError)) or os.environ.get("PLATEBENCH_DEBUG"):
            raise  # argparse's exits (--help, a bad flag), and bugs: their traceback
        print(f"platebench: error: {_one_line(e)}", file=sys.stderr)
        return done(2)


if __name__ == "__main__":
    sys.exit(main())
