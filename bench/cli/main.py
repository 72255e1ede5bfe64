"""``platebench``: the command line. Each sub-command lives in its own ``bench.cli.<name>`` module
(argparse and printing only: its flags are checked and its configuration built in ``bench.config``, the
work is in ``bench.run``, ``bench.sweep``, ``bench.benchmark``, and the text it prints about a result in
``bench.report.text``). A command module imports no other command module; the argument groups several
commands share are in ``bench.cli._args`` (tests/test_layers.py holds these rules).

Exit status, the same for every command, so that a script can trust it:

* 0: all well: every sample and every method of the run gave its result.
* 1: some work failed and was recorded (a sweep's failed samples in its results, a comparison's
  failed methods in compare.json); also a run that produced no result at all, or in which every
  sample or every method failed. One summary line ``platebench: ...`` goes to stderr.
* 2: refused: a bad flag, file, configuration or input. Errors a user can fix
  (``platebench.errors.PlateBenchError``) and file-system errors (a path missing, existing,
  unreadable or unwritable) print one line ``platebench: error: ...``; nothing half-written is
  left behind. argparse's own usage errors exit 2 as well. PLATEBENCH_DEBUG=1 shows the traceback
  of user errors too. Anything else is a bug and keeps its traceback (status 1, Python's).
* An installed package's extension (an entry point of ``platebench.families``, ``platebench.metrics``
  or ``platebench.cure_rules``, ``bench.run.extensions``) that cannot be loaded refuses every command
  with one line naming it and its group, status 2.
* An argument that is not UTF-8 text (a file name's bytes that decode to no characters) is refused
  with status 2 before any work: every output records its names as UTF-8 text.
* Printing never changes the status: text the terminal's encoding cannot show is printed with
  backslash escapes (``\\xe9``), and when standard output cannot be written (a full disk, a closed
  pipe) the command's outputs are still completed and kept, its status stays what the work gave, and
  one line ``platebench: note: ...`` on stderr says that its summary was not printed.
* 130 and 143: interrupted by Ctrl-C or terminated by SIGTERM (``bench.interrupts``: the handlers
  are installed before any command module is imported, and a signal swallowed by a library on the
  way still sets the status); completed outputs are kept, partial ones removed.

A working directory that no longer exists (deleted under the shell) is refused with one line
before any command runs. Python itself may stop before PlateBench's code runs at all: when the
working directory is gone and ``PYTHONPATH`` names a relative folder, the interpreter fails while
building its import path ("Fatal Python error: error evaluating path"); only the interpreter's
own status can be reported then.
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
EXIT_OK, EXIT_FAILED, EXIT_REFUSED = 0, 1, 2  # the exit statuses of the module doc (and 130 / 143)

COMMANDS = {name: f"platebench.bench.cli.{name}" for name in (
    "render", "reconstruct", "evaluate", "compare", "sense", "study", "sweep", "calibrate", "report", "demo",
    "perf", "info", "export", "benchmark")}


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
               "Run 'platebench COMMAND --help' for each command. Exit status: 0 all well; 1 some work failed "
               "(failed samples or methods are recorded; also when the run produced no result or every sample "
               "or method failed; a summary line on stderr); 2 refused: bad input (one line on stderr); "
               "130 interrupted (Ctrl-C), 143 terminated (SIGTERM).")
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
    """``--version``: the package metadata is read only when asked (not at every command's start-up)."""

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
    to its very end: ``finish``); a list: a call from Python, which gets its own handlers and its own
    ``sys.stdout`` back. Printing never fails the command (module doc, ``_GuardedStdout``)."""
    whole_process = argv is None
    interrupts.install(whole_process)  # first: a signal at any later moment ends the command with 130 / 143
    if whole_process:
        _escape_unprintable(sys.stderr)
    previous = sys.stdout
    guard = None if previous is None else _GuardedStdout(previous, whole_process)  # None: no console at all
    if guard is not None:
        sys.stdout = guard
    try:
        status = _run(sys.argv[1:] if argv is None else list(argv),
                      interrupts.finish if whole_process else (lambda status: status))
        if guard is not None:
            guard.flush()
        if guard is not None and guard.failure is not None:
            why = guard.failure.strerror or type(guard.failure).__name__
            print(f"platebench: note: the summary was not printed (standard output: {why}); the command's "
                  "outputs are complete and kept", file=sys.stderr)
        return status
    finally:
        if not whole_process:
            sys.stdout = previous
            interrupts.uninstall()


def _escape_unprintable(stream) -> None:
    """``stream`` (a text stream) writes characters its encoding cannot hold as backslash escapes, never
    raising UnicodeEncodeError (a name like 'sé' printed under ``LC_ALL=C PYTHONIOENCODING=ascii``)."""
    reconfigure = getattr(stream, "reconfigure", None)
    if reconfigure is not None:
        try:
            reconfigure(errors="backslashreplace")
        except (ValueError, OSError, TypeError):  # a stream that cannot change its error handler keeps it
            pass


class _GuardedStdout:
    """``sys.stdout`` while a command runs: characters the stream's encoding cannot hold are written as
    backslash escapes, and the first write or flush that fails (``OSError``: a full disk, a closed pipe)
    is kept in ``failure`` and never raised; nothing is written after it. In the whole process the
    file descriptor is then pointed at the null device, so that the interpreter's own flush at exit
    does not fail either. Every other attribute is the stream's."""

    def __init__(self, stream, whole_process: bool):
        self._stream = stream
        self._whole_process = whole_process
        self.failure: OSError | None = None
        if whole_process:
            _escape_unprintable(stream)

    def write(self, text: str) -> int:
        if self.failure is None:
            try:
                return self._stream.write(text)
            except UnicodeEncodeError:  # a stream whose error handler could not be changed
                enc = getattr(self._stream, "encoding", None) or "utf-8"
                return self.write(text.encode(enc, "backslashreplace").decode(enc))
            except OSError as e:
                self._failed(e)
        return len(text)

    def flush(self) -> None:
        if self.failure is None:
            try:
                self._stream.flush()
            except OSError as e:
                self._failed(e)

    def _failed(self, e: OSError) -> None:
        self.failure = e
        if not self._whole_process:
            return
        try:
            fd = self._stream.fileno()
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, fd)
            os.close(null)
        except (OSError, ValueError, AttributeError):
            pass

    def __getattr__(self, name):
        return getattr(self._stream, name)


def _not_utf8_argument(argv: list[str]) -> str | None:
    """The one-line refusal of the first argument that is not UTF-8 text (bytes passed through
    ``os.fsdecode`` as lone surrogates), else None."""
    for arg in argv:
        try:
            arg.encode("utf-8")
        except UnicodeEncodeError:
            shown = os.fsencode(arg).decode("utf-8", "backslashreplace")
            return (f"argument '{shown}' is not UTF-8 text: allowed names and values are UTF-8 characters "
                    "(every output records them as UTF-8): rename the file or folder")
    return None


def _working_directory_error() -> str | None:
    """The one-line refusal when the working directory no longer exists, else None."""
    try:
        os.getcwd()
    except FileNotFoundError:
        return ("the working directory no longer exists (it was removed while the shell was in it): "
                "change to an existing directory and run the command again")
    except OSError as e:
        return f"the working directory cannot be read ({e.strerror}): change to another directory"
    return None


def _run(argv: list[str], done) -> int:
    """The command's exit status, passed through ``done`` as soon as it is known."""
    refusal = _working_directory_error() or _not_utf8_argument(argv)
    if refusal is not None:
        print(f"platebench: error: {refusal}", file=sys.stderr)
        return done(EXIT_REFUSED)
    try:
        parser = build_parser(argv)
        args = parser.parse_args(argv)
        from platebench.bench.run.extensions import load_extensions  # noqa: PLC0415  (loaded after the handlers)
        load_extensions()  # the families, metrics and cure rules of installed packages (entry points)
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
        return done(EXIT_REFUSED)


if __name__ == "__main__":
    sys.exit(main())
