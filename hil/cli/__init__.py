"""The ``rprs`` command line, one module per command (as cantools and python-can lay out
theirs): ``sim``, ``demo``, ``encode``/``decode`` (codec), ``child``/``submodules``/``father``
(robots), ``radio-hub`` (hub), ``inject``, ``bench``, ``conformance``, ``plot``, ``monitor``,
``soak``, ``listing``. Option
types and shared options live in ``common``; ``trace_digests`` holds seeded ``rprs sim`` runs
whose traces must not change by accident (tests/hil/sim/test_trace_digests.py).

A user mistake (bad option value, unreadable file, malformed input) prints one line starting
``rprs: error:`` and exits with status 2; it never shows a traceback. Ctrl-C ends a command
with ``rprs: interrupted`` and status 130, SIGTERM with ``rprs: terminated`` and status 143,
SIGHUP (its terminal closed) with ``rprs: hung up`` (if the terminal is still there) and 129.
A standard output whose reader went away (``| head -1``) ends every command alike, as the
Python docs recommend for SIGPIPE: no traceback, nothing more on stderr, stdout pointed at
/dev/null, status 1 (``common.stdout_gone``, called here only); a bench process (``child``,
``father``) first stops as cleanly as on Ctrl-C and gives its closing line on stderr
(``common.run_until_stopped``).
"""
from __future__ import annotations

import argparse
import importlib
import io
import logging
import os
import signal
import sys
import time
from typing import Sequence

from ..bench.stdout import GuardedStdout, StdoutFailed
from .common import READ_FILES, Parser, Terminated, UserError, say_closing, stdout_gone

EXTRA_OF = {"matplotlib": "plot", "textual": "ui", "dask": "campaign", "distributed": "campaign",
            "numpy": "campaign", "pyarrow": "campaign"}
"""The libraries the core install leaves out (pyproject.toml), by the extra that brings each:
the firmware model, the simulator, the bench and the captures need none of them."""


def missing_extra(exc: ModuleNotFoundError, command: str | None) -> str | None:
    """The one line for a command that needs a library of an extra not installed, or None
    when the missing module is none of those (a real error, raised as it is)."""
    top = (exc.name or "").split(".")[0]
    extra = EXTRA_OF.get(top)
    if extra is None:
        return None
    what = f"'rprs {command}'" if command else "this command"
    return (f"{what} needs {top}, which comes with the '{extra}' extra: "
            f"pip install 'rprs[{extra}]' (in a checkout: pip install -e '.[{extra}]'; "
            f"'all' for every extra)")

__all__ = ["build_parser", "main", "UserError"]

COMMANDS = ("sim", "demo", "robots", "plot", "monitor", "soak", "campaign", "hub", "inject",
            "bench", "capture", "conformance", "codec", "wireshark", "listing")
"""The command modules; each adds its subcommands in this order (the order of ``rprs --help``)."""

MODULE_OF = {"sim": "sim", "demo": "demo", "child": "robots", "submodules": "robots",
             "father": "robots", "plot": "plot", "monitor": "monitor", "soak": "soak",
             "campaign": "campaign", "radio-hub": "hub", "inject": "inject", "bench": "bench",
             "capture": "capture",
             "conformance": "conformance", "encode": "codec", "decode": "codec",
             "wireshark": "wireshark", "listing": "listing"}
"""The module that adds each command: ``rprs NAME ...`` imports that module only, so that a
light command (``encode``, ``decode``, ``--version``) does not pay for the simulator's imports
(python-can, cantools: about 0.4 s)."""


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    from firmware_model.radio import PROTOCOL_VERSION
    try:
        mine = version("rprs")
    except PackageNotFoundError:          # run from a checkout that was never installed
        mine = "(not installed)"
    return f"rprs {mine}, radio protocol {PROTOCOL_VERSION}"


def build_parser(modules: Sequence[str] = COMMANDS) -> argparse.ArgumentParser:
    """The parser with the commands of ``modules`` (all of them by default)."""
    p = Parser(prog="rprs", description="RPRS child firmware model, rotational TDMA radio "
               "MAC simulator and HIL bench")
    p.add_argument("--version", action="version", version=_version())
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    for name in modules:
        importlib.import_module(f"{__name__}.{name}").add(sub)
    _add_logging_options(p)
    return p


LOG_LEVELS = ("debug", "info", "warning", "error", "critical")


def _add_logging_options(p: argparse.ArgumentParser) -> None:
    """``-v``/``--verbose`` and ``--log-level`` on ``p`` and on every command under it (before
    or after the command's name). SUPPRESS: a subcommand's unset option leaves the value its
    parent parsed."""
    g = p.add_argument_group("logging")
    g.add_argument("-v", "--verbose", action="count", default=argparse.SUPPRESS,
                   help="log more on stderr: -v info, -vv debug (python-can, the bench)")
    g.add_argument("--log-level", choices=LOG_LEVELS, default=argparse.SUPPRESS,
                   metavar="LEVEL", help=f"the log level, one of {', '.join(LOG_LEVELS)} "
                   f"(default: warning)")
    for action in p._actions:
        if isinstance(action, argparse._SubParsersAction):
            for child in set(action.choices.values()):
                _add_logging_options(child)


class _StderrHandler(logging.StreamHandler):
    """Writes to whatever ``sys.stderr`` is when a record comes: the handler outlives the
    command (``main`` called in a process that goes on, a test's captured stderr closed)."""

    @property
    def stream(self):
        return sys.stderr

    @stream.setter
    def stream(self, value) -> None:
        pass


def configure_logging(a: argparse.Namespace) -> int:
    """Python's logging, configured once for the command: to stderr, one line a record, at
    ``--log-level`` or by ``-v`` count (warning, info, debug). Returns the level."""
    name = getattr(a, "log_level", None)
    if name is not None:
        level = getattr(logging, name.upper())
    else:
        level = {0: logging.WARNING, 1: logging.INFO}.get(getattr(a, "verbose", 0),
                                                        logging.DEBUG)
    # the handler's own level too: a library's logger set lower (distributed's at INFO)
    # propagates its records to the root's handler whatever the root's level
    handler = _StderrHandler()
    handler.setLevel(level)
    logging.basicConfig(level=level, handlers=[handler],
                        format="rprs: %(levelname)s %(name)s: %(message)s", force=True)
    return level


def _parser_for(argv: Sequence[str]) -> argparse.ArgumentParser:
    """Only the named command's module for ``rprs NAME ...``; none for ``rprs --version``;
    every one otherwise (help, a mistake: the message lists every command)."""
    first = argv[0] if argv else None
    if first == "--version" and len(argv) == 1:
        return build_parser(())
    module = MODULE_OF.get(first) if first is not None else None
    return build_parser((module,)) if module is not None else build_parser()


def _stacks_on_sigusr1() -> None:
    """``kill -USR1 PID`` makes a running ``rprs`` print every thread's stack on stderr and go
    on: how to see where a bench process that has gone quiet is waiting.

    A Python-level handler, run by the main thread with the GIL held: faulthandler's own C
    handler (``faulthandler.register``) walks the threads while they run, and a child
    signalled as its threads started died of SIGSEGV (once, in a quiet loop of the fast tier;
    not seen again in 25 tries). A main thread waiting
    in a lock, a sleep or a blocking read or write is interrupted to run it (PEP 475)."""
    import faulthandler

    if not hasattr(signal, "SIGUSR1"):
        return

    def stacks(signum, frame) -> None:
        try:
            faulthandler.dump_traceback(file=sys.stderr, all_threads=True)
        except (ValueError, OSError, RuntimeError, AttributeError, io.UnsupportedOperation):
            pass                     # no usable stderr (an embedding, a closed pipe)
    try:
        signal.signal(signal.SIGUSR1, stacks)
    except ValueError:
        pass                         # not the main thread of the main interpreter


_STOPS = ("SIGTERM", "SIGHUP")
"""The signals a command ends on as on Ctrl-C (``_terminate_on_signals``)."""
_SIGHUP = getattr(signal, "SIGHUP", None)


SAME_STOP_S = 1.0
"""A second SIGTERM (SIGHUP) this soon after the first is the same stop told twice (GNU
``timeout`` signals the process, then its process group): ignored, so that the clean-up the
first began ends with its line. A later one kills."""


_STOPPING: dict[int, float] = {}
"""The stop signals taken so far (signal -> monotonic s): the command is stopping on them."""


def _terminate_on_signals() -> dict:
    """SIGTERM and SIGHUP (a closed terminal) raise :class:`Terminated` (once each: a second
    one kills, unless it comes within ``SAME_STOP_S``) while a command runs, so that it cleans
    up as on Ctrl-C (it used to die where it stood, leaving ``.partial`` files and a capture
    cut in the middle of a packet). Commands that stop cleanly on these themselves (the bench
    processes, the monitor, the hub) put their own handlers over these. Returns the handlers
    to put back (none where this is not the main thread)."""
    first = _STOPPING
    first.clear()

    def terminate(signum, frame):
        now = time.monotonic()
        if signum in first:
            if now - first[signum] < SAME_STOP_S:
                return
            signal.signal(signum, signal.SIG_DFL)
            os.kill(os.getpid(), signum)
            return
        first[signum] = now
        raise Terminated(signum)
    old = {}
    for name in _STOPS:
        sig = getattr(signal, name, None)
        if sig is None or signal.getsignal(sig) is signal.SIG_IGN:
            continue                 # (no SIGHUP on Windows; nohup: SIGHUP ignored, kept so)
        try:
            old[sig] = signal.signal(sig, terminate)
        except ValueError:           # not the main thread of the main interpreter
            return old
    return old


def main(argv: Sequence[str] | None = None) -> int:
    _stacks_on_sigusr1()
    if os.environ.get("RPRS_MAC_TABLE_GUARD") == "1":    # (the test suite's children)
        from firmware_model.radio.mac_guard import install_from_environment
        install_from_environment()
    argv = list(sys.argv[1:] if argv is None else argv)
    old_handlers = _terminate_on_signals()
    raw_stdout = sys.stdout
    READ_FILES.clear()
    if raw_stdout is not None and not isinstance(raw_stdout, GuardedStdout):
        sys.stdout = GuardedStdout(raw_stdout)       # (a full disk: one line, not a traceback)
    try:
        code = _main(argv)
    except SystemExit:      # argparse's --help and --version; rich's own broken pipe
        if not _stdout_flushed():
            raise SystemExit(1) from None
        raise
    finally:
        sys.stdout = raw_stdout
        if old_handlers:
            for sig, handler in old_handlers.items():
                # a stop in progress ignores its signal told again (SAME_STOP_S) to the end:
                # put back, the default would kill the process as it returns its status
                signal.signal(sig, signal.SIG_IGN if sig in _STOPPING else handler)
    return code if _stdout_flushed() else 1


def _stdout_flushed() -> bool:
    """Flush stdout now, so that a reader gone away is seen here and not in the interpreter's
    flush at exit ("Exception ignored ... BrokenPipeError" on stderr, status 120); False
    (stdout now at /dev/null) if it had gone."""
    try:
        sys.stdout.flush()
    except BrokenPipeError:
        stdout_gone()
        return False
    except (AttributeError, ValueError, OSError):  # no stdout, or closed: nothing to flush
        pass
    return True


def _main(argv: list[str]) -> int:
    try:
        parser = _parser_for(argv)
        a, extra = parser.parse_known_args(argv)
        if not getattr(a, "command", None):
            if extra:
                parser.error(f"unrecognized arguments: {' '.join(extra)}")
            parser.print_help()
            return 2
        if extra:              # the command's own help lists what it takes
            raise UserError(f"unrecognized arguments: {' '.join(extra)} "
                            f"(see 'rprs {a.command} --help')")
        configure_logging(a)
        return a.func(a)
    except UserError as exc:
        print(f"rprs: error: {exc}", file=sys.stderr)
        return 2
    except ModuleNotFoundError as exc:
        line = missing_extra(exc, argv[0] if argv else None)
        if line is None:
            raise
        print(f"rprs: error: {line}", file=sys.stderr)
        return 2
    except Terminated as exc:
        # after SIGHUP the terminal may be gone: then nobody reads the line (say_closing)
        say_closing("rprs: hung up" if exc.signum == _SIGHUP else "rprs: terminated")
        return 128 + exc.signum
    except KeyboardInterrupt:
        print("rprs: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return stdout_gone()
    except StdoutFailed as exc:
        print(f"rprs: error: cannot write standard output: {exc}", file=sys.stderr)
        stdout_gone()       # (what is still in its buffer dropped: no second error at exit)
        return 1

