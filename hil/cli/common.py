"""What every ``rprs`` command shares: the one-line user error, option types that
validate as they parse, and the MAC, TXEN and real-time options of the robot commands."""
from __future__ import annotations

import argparse
import os
import sys
from typing import NoReturn, Sequence


class UserError(Exception):
    """A mistake the user can fix: printed as one line, exit status 2."""


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP (its terminal closed), raised where the command stands so that it
    ends as Ctrl-C ends it: its output files discarded, one line (if the terminal is still
    there), exit status 128 + the signal's number (143, 129)."""

    def __init__(self, signum: int = 15) -> None:
        super().__init__(signum)
        self.signum = signum


def stdout_gone() -> int:
    """A standard output whose reader has gone away (``rprs ... | head -1``): what the Python
    docs recommend for SIGPIPE (library/signal, "Note on SIGPIPE"): point the stdout file
    descriptor at /dev/null, so that what is still in its buffer is dropped without a second
    BrokenPipeError at exit ("Exception ignored ..."), and end with status 1. Every rprs
    command ends so (hil/cli/__init__.py: ``main``, the only caller); nothing is said on
    stderr. Returns the exit status."""
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, ValueError, OSError):   # not a real file (a test's capture)
        return 1
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, fd)
    finally:
        os.close(devnull)
    return 1


class Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line, status 2, no usage dump
        raise UserError(f"{message} (see '{self.prog} --help')")

    def _print_message(self, message, file=None) -> None:
        """argparse's, but a stdout closed by its reader (``rprs --help | head -1``) ends the
        command as it ends any other (argparse swallowed the error, and the exit said 0)."""
        if not message:
            return
        file = file or sys.stderr
        try:
            file.write(message)
            file.flush()
        except BrokenPipeError:
            if file is sys.stdout:
                raise
        except (AttributeError, OSError):
            pass


def output_file(path: str, what: str) -> str:
    """``path``, checked before a run that ends by writing ``what`` there: a directory or a
    missing parent directory is a UserError now, not an error after the run."""
    if os.path.isdir(path):
        raise UserError(f"cannot write {what} {path}: it is a directory")
    d = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(d):
        raise UserError(f"cannot write {what} {path}: no directory {d}")
    return path


def file_name(text: str) -> str:
    """A file or directory an option names (``--log``, ``--db``, ``--plots`` ...): an empty
    name, which ran as if the option were not given and wrote nothing, is refused."""
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty name: give the file (or directory)")
    return text


def output_path(text: str) -> str:
    """The file an output option (``--trace``, ``--vcd``, ``--pcap``) writes. An empty name
    (which wrote nothing, and said nothing) and ``-`` (standard output to the radio hub; a
    file named ``-`` here) are refused."""
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty file name: give the file to write")
    if text == "-":
        raise argparse.ArgumentTypeError("'-' is not taken for standard output here: give a "
                                         "file name")
    return text


def distinct_outputs(**paths: str | None) -> None:
    """Two output options naming one file would overwrite each other (the later writer wins,
    or the two renames of PATH.PID.partial fail after the run): a UserError before anything runs.
    ``paths``: option name (``_`` for ``-``) -> the path given, or None."""
    seen: dict[str, str] = {}
    for opt, path in paths.items():
        if not path or path == "-":
            continue
        key, name = os.path.realpath(path), opt.replace("_", "-")
        if key in READ_FILES:
            raise UserError(f"--{name} {path} is the file --{READ_FILES[key]} reads: give the "
                            f"output another name (it would be overwritten)")
        if is_terminal(path):
            raise UserError(f"--{name} {path} is a terminal or a serial port: what is written "
                            f"there would be sent (a radio on it would transmit it); give a "
                            f"file, or '-' where standard output is taken")
        if key in seen:
            raise UserError(f"--{seen[key]} and --{name} name the same file {path}: give each "
                            f"its own")
        seen[key] = name
    # each is written to PATH.PID.partial first and renamed at the end (trace.py)
    from hil.sim.trace import partial_name
    for key, name in list(seen.items()):
        other = seen.get(partial_name(key))
        if other is not None:
            raise UserError(f"--{name}'s file, written as {partial_name(key)} first, is "
                            f"--{other}'s: give each a name of its own")


def is_terminal(path: str) -> bool:
    """Is ``path`` a terminal, a pty or a serial port (a tty device), told from its device
    number without opening it (opening a serial port raises DTR, which may key a radio's
    TXEN)? Unix98 pty slaves are majors 136-143 (Linux devices.txt); every other tty device
    has ``tty`` for its sysfs subsystem."""
    import stat
    try:
        st = os.stat(path)
    except OSError:
        return False
    if not stat.S_ISCHR(st.st_mode):
        return False
    major, minor = os.major(st.st_rdev), os.minor(st.st_rdev)
    if 136 <= major <= 143:
        return True
    subsystem = f"/sys/dev/char/{major}:{minor}/subsystem"
    return os.path.exists(subsystem) and os.path.basename(os.path.realpath(subsystem)) == "tty"


def robot_list(text: str) -> tuple[int, ...]:
    try:
        ids = tuple(int(x) for x in text.split(",") if x.strip() != "")
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a comma-separated list of robot IDs such as 1,2,3,4") from None
    bad = [i for i in ids if not 0 <= i <= 6]
    if bad:
        raise argparse.ArgumentTypeError(
            f"robot ID {bad[0]} is out of range: IDs are 0 (father) and 1-6 (children)")
    if not ids:
        raise argparse.ArgumentTypeError("the robot list is empty")
    if len(set(ids)) != len(ids):
        raise argparse.ArgumentTypeError(f"robot IDs repeat in {text!r}")
    return ids


def id_at(text: str) -> tuple[int, float]:
    rid, sep, when = text.partition("@")
    try:
        r, t = int(rid), float(when)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not ID@SECONDS, e.g. 1@5.5") from None
    if not sep:
        raise argparse.ArgumentTypeError(f"{text!r} is not ID@SECONDS, e.g. 1@5.5")
    if not 0 <= r <= 6:
        raise argparse.ArgumentTypeError(f"robot ID {r} in {text!r} is not 0-6")
    if not t >= 0 or t != t or t == float("inf"):
        raise argparse.ArgumentTypeError(f"time in {text!r} must be a finite number >= 0")
    return r, t


def port_name(text: str) -> str:
    """A serial port, pty or pyserial URL as given; an empty one is refused (it used to mean
    "no radio" to some commands and a port to others)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty port name: give a serial port, a pty or a "
                                         "pyserial URL")
    return text


def positive(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not v > 0 or v == float("inf"):
        raise argparse.ArgumentTypeError(f"{text!r} must be a positive finite number")
    return v


def probability(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not 0.0 <= v < 1.0:
        raise argparse.ArgumentTypeError(f"{text!r} must be a probability in [0, 1)")
    return v




def load_spec(text: str, words: bool = True) -> str | float:
    """``--load``: idle, saturate or a rate in messages/s per robot (``words`` False: a rate
    only, and the errors offer nothing else)."""
    from hil.sim.config import LOAD_MAX
    if words and text in ("idle", "saturate"):
        return text
    try:
        v = float(text)
    except ValueError:
        v = -1.0
    if not v > 0 or v == float("inf"):
        raise argparse.ArgumentTypeError(
            f"{text!r} is not {'idle, saturate or ' if words else ''}a positive rate in "
            f"messages/s per robot")
    if v > LOAD_MAX:
        far = ("so any rate far above that is 'saturate' (which runs as fast; a rate costs "
               "the simulator each message it offers)" if words else
               "so any rate far above that only costs the simulator each message it offers")
        raise argparse.ArgumentTypeError(
            f"{text} messages/s per robot is more than {LOAD_MAX:g}: the channel carries a few "
            f"dozen short messages a second in all, {far}")
    return v


def load_rate(text: str) -> float:
    """A load given as a rate only (``rprs soak --rate``): positive, at most LOAD_MAX."""
    v = load_spec(text, words=False)
    assert isinstance(v, float)
    return v


def digit(lo: int, hi: int, what: str):
    def conv(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{what} {text!r} is not a whole number") from None
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f"{what} must be {lo}-{hi}, got {v}")
        return v
    return conv


def fault_spec(text: str):
    from ..sim.faults import FaultError, parse_fault
    try:
        return parse_fault(text)
    except FaultError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def profile_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--profile", choices=("rprs", "paper"), default="rprs",
                   help="rprs: the whole protocol (docs/protocol.md); paper: only the paper's "
                   "rules, to share a ring with robots that implement only the paper (a static "
                   "ring of the team, no BOOT/JOIN/poll/ring/ack/crc, messages sent once and "
                   "never acknowledged; docs/protocol.md §9)")


def checked_mac_config(**kw):
    """A MacConfig, or a UserError naming the options that do not go together."""
    from firmware_model.radio.mac import MacConfig
    try:
        return MacConfig(**kw)
    except ValueError as exc:
        if kw.get("profile", "rprs") != "paper":
            raise UserError(f"--auth-key: {exc}") from None
        raise UserError(f"--profile {kw.get('profile', 'rprs')}: {exc}") from None


def auth_key(text: str):
    """``--auth-key FILE``: the ring key (firmware_model.radio.auth), or one line saying what is
    wrong with the file."""
    from firmware_model.radio.auth import KeyFileError, load_key
    try:
        key = load_key(text)
    except KeyFileError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    READ_FILES[os.path.realpath(text)] = "auth-key"
    return key


READ_FILES: dict[str, str] = {}
"""Files this command reads (real path -> its option, without ``--``), which no output of it
may name (:func:`distinct_outputs`): ``--trace k.key`` overwrote the ring key it was given.
Emptied as each command starts (hil/cli/__init__.py, ``main``)."""


def auth_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--auth-key", type=auth_key, metavar="FILE", default=None,
                   help="the opt-in authenticated profile with this ring key file (a line "
                   "'key = ' and 32 hex digits; every robot must have the same): every frame "
                   "carries a freshness value and a truncated HMAC-SHA256 tag, and forged or "
                   "replayed frames are refused (docs/protocol.md §4.11)")


def mac_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--team", type=robot_list, metavar="IDS",
                   help="the robot IDs that may ever join (default: 0-6); a small team forms "
                   "its ring sooner (claim after |team| x Tmax)")
    p.add_argument("--checksum", action="store_true",
                   help="the opt-in crc() integrity extension (every robot must agree)")
    auth_option(p)
    p.add_argument("--idle-noise", action="store_true",
                   help="the radio outputs noise without a carrier (a bare PTR2000, or "
                   "'rprs radio-hub --noise'): the channel never falls quiet, so do not wait "
                   "for quiet after an uncertain turn (docs/mac.md, R-stagger)")
    profile_option(p)


def mac_config(a: argparse.Namespace, own: int):
    """The MAC configuration of a bench station whose ID is ``own`` (a child's ``--id``, the
    father's 0). A ``--team`` without ``own`` is refused: the station claimed the channel
    and formed a ring all the same, outside the team it was told."""
    kw = {"checksum": a.checksum, "quiet_channel": not a.idle_noise, "profile": a.profile,
          "auth": a.auth_key}
    if a.team:
        if own not in a.team:
            raise UserError(f"--team {','.join(map(str, sorted(a.team)))} leaves out this "
                            f"robot's own ID {own}: give the team it belongs to")
        kw["team"] = frozenset(a.team)
    if getattr(a, "standby", False):
        kw["standby"] = True
    if getattr(a, "pc", None) is not None:
        kw["paired"] = True           # --pc: one of a pair (build_father sets it too)
    return checked_mac_config(**kw)


def txen_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--txen", choices=("none", "rts", "dtr"), default="none",
                   help="serial line wired to the radio's TXEN (default: none, for the pty hub "
                   "and self-switching modules)")


def realtime_options(p: argparse.ArgumentParser, events: bool = False) -> None:
    """``--duration``, and ``--events`` where the command has MAC events to print (the child;
    the father prints its station's with ``--json``, the submodules have no MAC)."""
    p.add_argument("--duration", type=positive, metavar="SECONDS",
                   help="stop after this long (default: until Ctrl-C or SIGTERM)")
    if events:
        p.add_argument("--events", action="store_true",
                       help="print MAC events as JSON lines on stdout")


def can_notes(command: str, spec: str | None) -> list[str]:
    """What is worth saying of ``--can SPEC`` though it is no mistake: python-can's
    ``virtual`` bus lives inside one process, so no other process (the robot's other half,
    candump, cansend) ever sees its frames; a user would wait for them."""
    if not spec or spec.partition(":")[0] != "virtual":
        return []
    other = "rprs submodules" if command == "child" else "rprs child"
    return [f"rprs {command}: note: {spec} is python-can's in-process bus: no other process "
            f"({other}, candump, cansend) can reach it; to share a bus between processes use "
            f"rprs_unix:DIR or socketcan:vcan0"]


def run_until_stopped(runner, a: argparse.Namespace, describe: str, summary,
                      notes: Sequence[str] = ()) -> int:
    """Run a bench process to its end; exit status 1 if it went on through troubles (each
    said in its own line as it happened: ``Runner.warn``) or stopped by itself (its radio
    port went away), else 0. Standard output closed by its reader (``| head -1``) stops the
    process as cleanly as Ctrl-C does: the runner has closed its ports, and the summary still
    goes to stderr (the ``--events`` printer stops the runner itself and says so in
    ``runner.stdout_closed``; this catches any other writer); then BrokenPipeError goes on to
    ``main``, which ends every rprs command so (status 1, nothing more said). ``notes``:
    lines said right after the ``describe`` line (which stays the first: scripts wait for
    it)."""
    def ready() -> None:
        print(describe, file=sys.stderr, flush=True)
        for line in notes:
            print(line, file=sys.stderr, flush=True)
    closed = False
    try:
        runner.run(a.duration, ready=ready)
    except BrokenPipeError:
        closed = True             # Runner.run closed everything on its way out
    say_closing(summary())
    code = stopped_by_itself(runner)
    n = getattr(runner, "troubles", 0)
    if n and not code:
        say_closing(f"rprs: {n} trouble{'s' if n > 1 else ''} during the run (above): "
                    "exit status 1")
        code = 1
    if closed or getattr(runner, "stdout_closed", False):
        raise BrokenPipeError("standard output closed by its reader")
    return code


def say_closing(line: str) -> None:
    """A closing line on stderr; none if the terminal it was has gone (closed: SIGHUP
    stopped the process, and a write there fails with EIO): nobody is left to read it, and
    the stop was clean."""
    try:
        print(line, file=sys.stderr, flush=True)
    except OSError:
        pass


def stopped_by_itself(runner) -> int:
    """1 and one line ``rprs: error: ...`` if ``runner`` stopped by itself, else 0."""
    if getattr(runner, "failure", None) is None:
        return 0
    say_closing(f"rprs: error: {runner.failure}")
    return 1


def progress_bar(total: float, label: str):
    """A progress bar on a terminal, nothing otherwise; returns (update, close)."""
    updates, close = progress_bars(total, [label])
    return (updates[0] if updates is not None else (lambda x: None)), close


def progress_bars(total: float, labels: list[str]):
    """Progress bars on a terminal, one per label, each going to ``total``; returns
    (updates, close): ``updates[i](x)`` moves bar i. Not on a terminal: (None, close), so
    that the caller can run without progress calls at all (a soak then runs in longer
    stretches, hil/sim/soak.py)."""
    if not sys.stderr.isatty():
        return None, (lambda: None)
    from rich.progress import BarColumn, Progress, TextColumn
    bar = Progress(TextColumn("{task.description}"), BarColumn(),
                   TextColumn("{task.completed:.0f}/{task.total:.0f}"), transient=True,
                   console=stderr_console())
    tasks = [bar.add_task(label, total=total) for label in labels]
    bar.start()
    return [(lambda x, t=t: bar.update(t, completed=x)) for t in tasks], bar.stop


NOT_A_TERMINAL_WIDTH = 100_000
"""Columns of a rich console on a stdout that is not a terminal: no line is wrapped (a table
is as wide as its cells)."""


class _TrimmedLines:
    """A text stream that writes to ``out`` each line without the spaces at its end (a rich
    table pads every cell of its last column to the widest one: hundreds of spaces a line in
    a file); a line not ended yet is held until it is, or until ``flush``."""

    def __init__(self, out) -> None:
        self.out = out
        self._line = ""

    def write(self, text: str) -> int:
        *done, self._line = (self._line + text).split("\n")
        if done:
            self.out.write("".join(line.rstrip(" ") + "\n" for line in done))
        return len(text)

    def flush(self) -> None:
        if self._line:
            self.out.write(self._line)
            self._line = ""
        self.out.flush()

    def isatty(self) -> bool:
        return False

    def fileno(self) -> int:
        return self.out.fileno()


def stdout_console(**kw):
    """A rich console on stdout whose reader going away ends the command as any other write
    to a closed stdout does (``main``: ``stdout_gone``), not by rich's own SystemExit.

    On a stdout that is not a terminal (a pipe, a file) nothing is wrapped and nothing is
    coloured, whatever ``COLUMNS`` or ``FORCE_COLOR`` say: ``rprs sim | grep "duplicate
    deliveries 1"`` finds its line (rich wrapped at 80 columns there); and no line ends in
    spaces."""
    from rich.console import Console

    class StdoutConsole(Console):
        def on_broken_pipe(self) -> None:
            self.quiet = True
            raise BrokenPipeError("standard output closed by its reader")
    out = sys.stdout
    if not (hasattr(out, "isatty") and out.isatty()):
        kw.update(width=NOT_A_TERMINAL_WIDTH, soft_wrap=True, color_system=None,
                  force_terminal=False, file=_TrimmedLines(out))
    return StdoutConsole(**kw)


def stderr_console():
    from rich.console import Console
    return Console(stderr=True)

