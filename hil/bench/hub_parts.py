"""The radio hub's parts that are not its threads (hil/bench/radio_hub.py): the bounds and
parsing of its settings, the raw mode its ptys are kept in, a node's radio on the air, and the
air's idle noise as a hub plays it."""
from __future__ import annotations

import os
import termios
from typing import TYPE_CHECKING, Any, Iterable

from firmware_model.timing import BITS_PER_BYTE_8N1, TICK_HZ

from ..sim.air import Air, AirRadio

if TYPE_CHECKING:
    from .radio_hub import RadioHub


MAX_NODES = 7
"""Robot IDs 0-6: at most seven radios share the channel."""

MAX_BURST = 1024
"""Bytes put on air in one Transmission; longer backlogs continue back to back."""

BACKLOG_LIMIT = 4096
"""Bytes a node may have waiting for the air before the hub stops reading its pty."""

MIN_BAUD = 1
"""Slowest air the hub plays: one bit a second, a byte in 10 s."""

MAX_BAUD = TICK_HZ
"""Fastest air, 16,000,000 baud: a bit lasts one tick of the 16 MHz time base, a byte 10 ticks.
Faster, a byte's time rounds towards 0 ticks (at 1e9 baud a byte of 0 ticks made the Air's
rate check divide by zero)."""

MAX_SECONDS = 10_000_000
"""Latest time, in seconds after the hub starts, of a ``--drop`` window or a ``--fault``
(about 116 days): finite, and a whole number of ticks far from any float or timeout limit."""

READ_SIZE = 4096
POLL_S = 0.02
"""The reader thread re-checks backlogs, the stop flag, which nodes a program has open and
that every node is still raw at least this often."""

_RAW_IFLAG_OFF = (termios.IGNBRK | termios.BRKINT | termios.IGNPAR | termios.PARMRK
                  | termios.INPCK | termios.ISTRIP | termios.INLCR | termios.IGNCR
                  | termios.ICRNL | termios.IXON | termios.IXANY | termios.IXOFF
                  | getattr(termios, "IUCLC", 0))
_RAW_OFLAG_OFF = termios.OPOST
_RAW_LFLAG_OFF = (termios.ECHO | termios.ECHONL | termios.ICANON | termios.ISIG
                  | termios.IEXTEN)


def raw_attrs(attrs: list) -> list:
    """``attrs`` (``termios.tcgetattr``) in raw mode, as cfmakeraw makes it: no echo, no line
    editing or signals, no CR/LF translation, no XON/XOFF, 8 bits. The line's speed and its
    VMIN/VTIME (how a program's reads return) are the program's, and stay as they are."""
    iflag, oflag, cflag, lflag = attrs[:4]
    return [iflag & ~_RAW_IFLAG_OFF, oflag & ~_RAW_OFLAG_OFF,
            (cflag & ~(termios.CSIZE | termios.PARENB)) | termios.CS8,
            lflag & ~_RAW_LFLAG_OFF] + list(attrs[4:])


def byte_ticks_for(baud: float) -> int:
    """Ticks one 8N1 byte occupies the air at ``baud`` (16667 at 9600)."""
    return round(BITS_PER_BYTE_8N1 * TICK_HZ / baud)


def check_args(nodes: int, baud: float, ber: float, drops: Iterable[Any] = ()) -> None:
    """Raise ValueError (one line) for arguments the hub cannot run with (each of ``drops``
    must be ``(node, start s, end s)``)."""
    if isinstance(nodes, bool) or not isinstance(nodes, int) or not 1 <= nodes <= MAX_NODES:
        raise ValueError(f"nodes must be an integer from 1 to {MAX_NODES} (robot IDs 0-6), "
                         f"got {nodes!r}")
    if isinstance(baud, bool) or not isinstance(baud, (int, float)) \
            or not MIN_BAUD <= baud <= MAX_BAUD:
        raise ValueError(_baud_range(baud))
    if isinstance(ber, bool) or not isinstance(ber, (int, float)) or not 0.0 <= ber < 1.0:
        raise ValueError(f"byte error rate must be in [0, 1), got {ber!r}")
    for d in drops:
        try:
            node, start, end = d
        except (TypeError, ValueError):
            raise ValueError(f"a drop is (node, start_s, end_s), got {d!r}") from None
        if isinstance(node, bool) or not isinstance(node, int) or not 0 <= node < nodes:
            raise ValueError(f"drop node {node!r} is not one of the hub's nodes 0-{nodes - 1}")
        if not (isinstance(start, (int, float)) and isinstance(end, (int, float))
                and 0 <= start < end <= MAX_SECONDS):
            raise ValueError(f"drop window {start!r}-{end!r} s of node {node} must satisfy "
                             f"0 <= start < end <= {MAX_SECONDS} (seconds)")


def check_fault(f: Any, nodes: int = MAX_NODES) -> None:
    """Raise ValueError (one line) for a fault (hil.sim.faults.Fault) the hub cannot play: not
    an air fault, a node it does not have, or a time after ``MAX_SECONDS``."""
    from ..sim.faults import AIR_KINDS
    if f.kind not in AIR_KINDS:
        raise ValueError(f"the radio hub takes air faults ({', '.join(AIR_KINDS)}), "
                         f"not {f.spec()}")
    if f.robot is not None and not 0 <= f.robot < nodes:
        raise ValueError(f"fault {f.spec()}: the hub has nodes 0-{nodes - 1}")
    if not (f.at if f.until is None else f.until) <= MAX_SECONDS:   # (not a burst's end)
        raise ValueError(f"fault {f.spec()}: times must be at most {MAX_SECONDS} s after "
                         f"the hub starts")


def _baud_range(got: Any) -> str:
    return (f"baud must be a number from {MIN_BAUD} to {MAX_BAUD} (a bit lasts from 1 s down "
            f"to one 62.5 ns tick), got {got!r}")


def parse_baud(text: str) -> float:
    """``--baud``: a number from MIN_BAUD to MAX_BAUD; ValueError (one line) if not."""
    try:
        baud = float(text)
    except ValueError:
        raise ValueError(f"baud {text!r} is not a number") from None
    if not MIN_BAUD <= baud <= MAX_BAUD:
        raise ValueError(_baud_range(text))
    return baud


def parse_drop(text: str) -> tuple[int, float, float]:
    """``ID@START-END`` (seconds after the hub starts) -> (node, start, end); ValueError if not."""
    rid, sep, window = text.partition("@")
    start, sep2, end = window.partition("-")
    try:
        node, s, e = int(rid), float(start), float(end)
    except ValueError:
        node = None
    if not sep or not sep2 or node is None:
        raise ValueError(f"{text!r} is not ID@START-END, e.g. 2@5-8.5")
    if not 0 <= node < MAX_NODES:
        raise ValueError(f"node {node} in {text!r} is not 0-{MAX_NODES - 1}")
    if not (0 <= s < e <= MAX_SECONDS):
        raise ValueError(f"window in {text!r} must satisfy 0 <= START < END <= {MAX_SECONDS} "
                         f"(seconds)")
    return node, s, e


class HubError(RuntimeError):
    """The hub stopped because one of its threads failed (one line, ``RadioHub.failure()``);
    the exception itself is ``RadioHub.error`` and this error's ``__cause__``."""


def _where(exc: BaseException) -> str:
    """``path:line in function`` of the function that raised ``exc``, a generator expression
    or comprehension named by the function it is in (paths relative to the checkout when
    inside it)."""
    import traceback
    frames = traceback.extract_tb(exc.__traceback__)
    if not frames:
        return "an unknown place"
    inner = ("<genexpr>", "<listcomp>", "<dictcomp>", "<setcomp>")
    fr = next((f for f in reversed(frames) if f.name not in inner), frames[-1])
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    path = os.path.abspath(fr.filename)
    if path.startswith(root + os.sep):
        path = os.path.relpath(path, root)
    return f"{path}:{fr.lineno} in {fr.name}"


class _Uart:
    __slots__ = ("byte_ticks",)

    def __init__(self, byte_ticks: int) -> None:
        self.byte_ticks = byte_ticks


class _Node:
    """The radio-side interface hil.sim.air.Air drives (see firmware_model.mcu.ptr2000.Ptr2000):
    listening while the link is up, except while its own burst is on air and for the PTR2000's
    RX-ready delay after it ends (``rx_from``; the hub switches it, a pty having no TXEN line)."""

    __slots__ = ("hub", "robot", "idx", "alive", "rx_from", "rx", "noise_from", "uart",
                 "channel", "down")

    def __init__(self, hub: "RadioHub", robot: int, byte_ticks: int) -> None:
        self.hub = hub
        self.robot = robot
        self.idx = robot
        self.alive = True
        self.rx_from = 0
        self.rx: Any = None
        self.noise_from = 0
        self.uart = _Uart(byte_ticks)
        self.channel: Any = None
        self.down = 0                # drop windows currently open

    def listening(self, t: int) -> bool:
        return self.alive and t >= self.rx_from

    def deliver(self, data: bytes, t0: int, dt: int, late_ok: bool = False,
                lead: int = 0) -> None:
        self.hub._deliver(self.robot, data)


class _HubAir(Air):
    """The simulator's Air, counting the noise bytes it hands out (``in_noise``)."""

    def __init__(self, *args: Any, **kw: Any) -> None:
        super().__init__(*args, **kw)
        self.in_noise = False

    def _noise_upto(self, r: AirRadio, t: int) -> None:
        self.in_noise = True
        try:
            super()._noise_upto(r, t)
        finally:
            self.in_noise = False
