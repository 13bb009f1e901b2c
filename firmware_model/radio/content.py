"""Content commands: the one table both the encoder and the dispatcher use (docs/protocol.md §3.3).

Content is ``<command>(<params>)`` repeated with nothing in between, e.g.
``movex(10)moveto(1.5,-2,0)`` (paper §IV, Fig. 8). Parameters are decimal numbers: an 'int'
parameter is ``-?[0-9]+``, a 'num' parameter ``-?[0-9]+(\\.[0-9]{1,3})?`` (resolution 0.001 of its
unit, no exponent, no '+', no spaces), at most 12 characters each. Content is tokenised by hand
here and never evaluated as code.

Bounds in :data:`COMMANDS` are syntactic (what may appear on the wire); physical limits (joint
ranges, top speeds) belong to the dispatcher.
"""
from __future__ import annotations

import math
import numbers
import re
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Iterable

from firmware_model.radio.errors import ContentError, describe_byte

__all__ = [
    "Param",
    "CommandSpec",
    "COMMANDS",
    "Command",
    "cmd",
    "parse_content",
    "format_content",
    "format_number",
    "split_layers",
    "MAX_PARAM_CHARS",
    "MAX_DECIMALS",
]

MAX_PARAM_CHARS = 12
"""Longest parameter text, sign and decimal point included."""
MAX_DECIMALS = 3
"""Most digits after the decimal point of a 'num' parameter (0.001 of its unit)."""


@dataclass(frozen=True)
class Param:
    """One parameter: ``kind`` 'int' or 'num', hard syntactic bounds ``lo``/``hi`` (None: only
    the 12-character limit), ``unit`` for documentation (e.g. 'mm', 'deg', 'mm/s', 'robot id')."""

    name: str
    kind: str
    lo: int | float | None = None
    hi: int | float | None = None
    unit: str = ""

    def __post_init__(self) -> None:
        if self.kind not in ("int", "num"):
            raise ValueError(f"Param kind must be 'int' or 'num', got {self.kind!r}")


@dataclass(frozen=True)
class CommandSpec:
    """A Content command: its parameters in wire order, its ``layer`` ('mac' or 'app') and a doc
    line."""

    name: str
    params: tuple[Param, ...]
    layer: str
    doc: str

    @property
    def arity(self) -> int:
        return len(self.params)

    def signature(self) -> str:
        """``moveto(x, y, z)``."""
        return f"{self.name}({', '.join(p.name for p in self.params)})"


def _spec(name: str, layer: str, doc: str, *params: Param) -> CommandSpec:
    return CommandSpec(name=name, params=tuple(params), layer=layer, doc=doc)


_SPECS = (
    # ---- application layer: handed to the dispatcher (paper §IV + project additions) ----
    _spec("movex", "app", "Move along x by dx (paper).", Param("dx", "num", unit="mm")),
    _spec("movey", "app", "Move along y by dy (paper).", Param("dy", "num", unit="mm")),
    _spec("movez", "app", "Move along z by dz (paper).", Param("dz", "num", unit="mm")),
    _spec(
        "moveto",
        "app",
        "Move to the absolute position (x, y, z) (paper).",
        Param("x", "num", unit="mm"),
        Param("y", "num", unit="mm"),
        Param("z", "num", unit="mm"),
    ),
    _spec(
        "joint",
        "app",
        "Set joint executive submodule `index` (1-4) to `angle`.",
        Param("index", "int", 1, 4, unit="joint no."),
        Param("angle", "num", unit="deg"),
    ),
    _spec("wheel", "app", "Drive the wheel submodule at `speed`.",
          Param("speed", "num", unit="mm/s")),
    _spec("paw", "app", "Paw submodule: 1 open, 0 close.", Param("open", "int", 0, 1, unit="flag")),
    _spec(
        "act",
        "app",
        "Action-sequence notice: sequence `action`, phase 0 start, 1 done.",
        Param("action", "int", 0, 99, unit="action id"),
        Param("phase", "int", 0, 1, unit="0 start / 1 done"),
    ),
    _spec("stop", "app", "Stop every submodule now."),
    _spec("status", "app", "Ask for (or announce) the robot's status."),
    _spec(
        "fail",
        "app",
        "Failure reason code, carried in Type '4' (failure information) frames.",
        Param("code", "int", 0, 999, unit="reason code"),
    ),
    _spec("done", "app", "Completion notice: the order after it has finished (Type '3', to "
          "the order's sender; protocol 2.1)."),
    # ---- MAC layer: consumed by the rotational MAC (docs/protocol.md §4) ----
    _spec(
        "ack",
        "mac",
        "Acknowledge the message (Source `src`, Number `num`) (docs/protocol.md §4.7, clause 47).",
        Param("src", "int", 0, 6, unit="robot id"),
        Param("num", "int", 0, 99, unit="frame number"),
    ),
    _spec(
        "poll",
        "mac",
        "Join invitation: robot `id` is invited; `mask` = bitmask of current ring members "
        "(bit i = ID i).",
        Param("id", "int", 0, 6, unit="robot id"),
        Param("mask", "int", 0, 127, unit="bitmask"),
    ),
    _spec(
        "ring",
        "mac",
        "The sender's view of the ring: `mask` = bitmask of its members (bit i = ID i) "
        "(docs/protocol.md §4.4, clause 51, rule R-view).",
        Param("mask", "int", 0, 127, unit="bitmask"),
    ),
    _spec(
        "crc",
        "mac",
        "Opt-in frame checksum extension (docs/protocol.md §3.4), last command of the Content.",
        Param("value", "int", 0, 65535, unit="CRC-16"),
    ),
)

COMMANDS: dict[str, CommandSpec] = {s.name: s for s in _SPECS}
"""Every Content command by name: declared once, used by the encoder and the dispatcher."""


# --------------------------------------------------------------------------------------------
# Numbers
# --------------------------------------------------------------------------------------------


def format_number(v: int | float) -> str:
    """Wire text of a parameter: ints as is, floats with '.3f' minus trailing zeros and dot.

    NaN and infinities raise :class:`ContentError`; ``-0`` is written ``0``.
    """
    if isinstance(v, int):
        return str(v)
    if not math.isfinite(v):
        raise ContentError(f"{v!r} cannot be sent: parameters are finite decimals", field="params")
    s = f"{v:.3f}".rstrip("0").rstrip(".")
    return "0" if s == "-0" else s


def _normalise(spec: CommandSpec, p: Param, v: object) -> tuple[int | float | None, str]:
    """(value, '') or (None, reason) for Python value ``v`` of parameter ``p``."""
    if type(v) is int:                  # the common case, without the numbers ABCs
        return _check_value(spec, p, v)
    if isinstance(v, bool):
        return None, f"{spec.name} parameter {p.name} must be a number, got {v!r}"
    t = type(v)
    if t is not float and isinstance(v, numbers.Integral):
        v = int(v)
    elif p.kind == "num" and (t is float or isinstance(v, numbers.Real)):
        # a float or a numbers.Real (which has __float__, unseen by mypy through the ABC)
        v = float(v)  # type: ignore[arg-type]
        if not math.isfinite(v):
            return None, f"{spec.name} parameter {p.name} must be finite, got {v!r}"
        v = float(f"{v:.3f}") + 0.0  # wire resolution 0.001; '+ 0.0' turns -0.0 into 0.0
    else:
        what = "an integer" if p.kind == "int" else "a number"
        return None, f"{spec.name} parameter {p.name} must be {what}, got {v!r}"
    return _check_value(spec, p, v)


def _check_value(spec: CommandSpec, p: Param, v: int | float) -> tuple[int | float | None, str]:
    text = format_number(v)
    if len(text) > MAX_PARAM_CHARS:
        return None, (f"{spec.name} parameter {p.name}={text} is longer than {MAX_PARAM_CHARS} "
                      "characters")
    if (p.lo is not None and v < p.lo) or (p.hi is not None and v > p.hi):
        lo = "" if p.lo is None else p.lo
        hi = "" if p.hi is None else p.hi
        return None, f"{spec.name} parameter {p.name}={text} is outside {lo}..{hi} ({p.unit})"
    return v, ""


def _arity_reason(spec: CommandSpec, got: int) -> str:
    n = spec.arity
    names = ", ".join(p.name for p in spec.params)
    if n == 0:
        return f"{spec.name} takes no parameters, got {got}"
    word = "parameter" if n == 1 else "parameters"
    return f"{spec.name} takes {n} {word} ({names}), got {got}"


# --------------------------------------------------------------------------------------------
# Command
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Command:
    """One Content command: ``name`` from :data:`COMMANDS` and ``args`` in wire order.

    'int' parameters hold ints; 'num' parameters hold an int (no '.') or a float rounded to
    0.001. Construction validates name, arity, kinds and hard bounds (:class:`ContentError`).
    """

    name: str
    args: tuple = ()
    wire: str = field(init=False, repr=False, compare=False)
    """The wire text (:meth:`text`), made once with the command (a saturated sender formats
    the same 31 orders for every message)."""

    def __post_init__(self) -> None:
        spec = COMMANDS.get(self.name)
        if spec is None:
            raise ContentError(f"unknown command {self.name!r}", field="command")
        args = tuple(self.args)
        if len(args) != spec.arity:
            raise ContentError(_arity_reason(spec, len(args)), field="params")
        out = []
        for p, v in zip(spec.params, args):
            value, reason = _normalise(spec, p, v)
            if reason:
                raise ContentError(reason, field="params")
            out.append(value)
        args = tuple(out)
        object.__setattr__(self, "args", args)
        object.__setattr__(self, "wire",
                           f"{self.name}({','.join(format_number(a) for a in args)})")

    @property
    def spec(self) -> CommandSpec:
        return COMMANDS[self.name]

    @property
    def layer(self) -> str:
        """'mac' or 'app'."""
        return COMMANDS[self.name].layer

    def text(self) -> str:
        """Wire text, e.g. ``moveto(1.5,-2,0)`` (equal commands have the same text: ``1`` and
        ``1.0`` are both written ``1``)."""
        return self.wire

    def __str__(self) -> str:
        return self.text()


def cmd(name: str, *args: int | float) -> Command:
    """``cmd('moveto', 1.5, -2, 0)``: a validated :class:`Command` (raises :class:`ContentError`).

    Commands are immutable values, so one made before with the same name and arguments (of
    the same types) is handed out again instead of being validated anew: the simulator's load
    and the dispatcher's failure replies make the same few commands over and over."""
    try:
        return _made(name, *args)
    except TypeError:                  # an unhashable argument: let the validation say why
        return Command(name, args)


@lru_cache(maxsize=4096, typed=True)
def _made(name: str, *args: int | float) -> Command:
    return Command(name, args)


# --------------------------------------------------------------------------------------------
# Tokeniser
# --------------------------------------------------------------------------------------------

_NAME_START = frozenset(b"abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ_")
_NAME_REST = _NAME_START | frozenset(b"0123456789")
_DIGITS = frozenset(b"0123456789")


def _got(data: bytes, i: int) -> str:
    return "end of content" if i >= len(data) else describe_byte(data[i])


def _err(data: bytes, i: int, field: str, reason: str) -> ContentError:
    return ContentError(reason, field=field, offset=i, byte=data[i] if i < len(data) else None)


def _scan_number(data: bytes, i: int, ctx: str) -> tuple[int, bool]:
    """End offset of the number starting at ``i`` and whether it has a decimal point."""
    n = len(data)
    j = i
    if j < n and data[j] == 0x2D:  # '-'
        j += 1
    k = j
    while j < n and data[j] in _DIGITS:
        j += 1
    if j == k:
        raise _err(data, j, "params", f"expected a decimal number in {ctx}, got {_got(data, j)}")
    dotted = j < n and data[j] == 0x2E  # '.'
    if dotted:
        j += 1
        k = j
        while j < n and data[j] in _DIGITS:
            j += 1
        if j == k:
            raise _err(data, j, "params",
                       f"expected a digit after '.' in {ctx}, got {_got(data, j)}")
        if j - k > MAX_DECIMALS:
            raise _err(
                data, k + MAX_DECIMALS, "params", f"more than {MAX_DECIMALS} decimals in {ctx}"
            )
    if j - i > MAX_PARAM_CHARS:
        raise _err(data, i, "params", f"number longer than {MAX_PARAM_CHARS} characters in {ctx}")
    return j, dotted


def parse_content(data: bytes | str) -> tuple[Command, ...]:
    """Content bytes -> commands (docs/protocol.md §3.3, clause 16). Empty content -> ().

    Raises :class:`ContentError` whose offset is the Content byte where parsing stopped: bad
    character, unknown command name, wrong arity, bad number, parameter outside its hard bound.

    A command whose bytes have the shape of one (:data:`_SHAPE`) is taken from
    :func:`_known` (the same text is read once: a saturated sender repeats its commands);
    anything else, and any command :func:`_known` refuses, is read by :func:`_parse_one` where
    it stands, which gives the error and its offset.
    """
    if isinstance(data, str):
        try:
            data = data.encode("ascii")
        except UnicodeEncodeError as exc:
            raise ContentError(
                f"{data[exc.start]!r} is not ASCII", field="command", offset=exc.start
            ) from None
    elif not isinstance(data, bytes):
        data = bytes(data)
    n = len(data)
    out: list[Command] = []
    match = _SHAPE.match
    i = 0
    while i < n:
        m = match(data, i)
        if m is not None:
            c = _known(m.group())
            if c is not None:
                out.append(c)
                i = m.end()
                continue
        c, i = _parse_one(data, i)
        out.append(c)
    return tuple(out)


_SHAPE = re.compile(rb"[A-Za-z_][A-Za-z0-9_]*\((?:-?[0-9]+(?:\.[0-9]+)?"
                    rb"(?:,-?[0-9]+(?:\.[0-9]+)?)*)?\)")
"""The bytes :func:`_parse_one` reads as one command, before its checks (a name, '(', numbers
separated by ',', ')'): a match ends where that command ends."""


@lru_cache(maxsize=4096)
def _known(text: bytes) -> Command | None:
    """The command ``text`` (one whole command of :data:`_SHAPE`) is, or None if
    :func:`_parse_one` refuses it (an unknown name, an arity, a bound)."""
    try:
        return _parse_one(text, 0)[0]
    except ContentError:
        return None


def _parse_one(data: bytes, i: int) -> tuple[Command, int]:
    """The command starting at Content offset ``i`` and the offset after it; a
    :class:`ContentError` at the first byte that does not fit."""
    n = len(data)
    # command name
    start = i
    if data[i] not in _NAME_START:
        raise _err(data, i, "command", f"expected a command name, got {_got(data, i)}")
    i += 1
    while i < n and data[i] in _NAME_REST:
        i += 1
    name = data[start:i].decode("ascii")
    spec = COMMANDS.get(name)
    if spec is None:
        raise ContentError(
            f"unknown command {name!r}", field="command", offset=start, byte=data[start]
        )
    if i >= n or data[i] != 0x28:  # '('
        raise _err(data, i, "command", f"expected '(' after {name}, got {_got(data, i)}")
    i += 1
    ctx = f"{name}(...)"
    # parameters: number (',' number)* then ')' -- or ')' at once
    tokens: list[tuple[int, int, bool]] = []
    if i < n and data[i] == 0x29:  # ')'
        i += 1
    else:
        while True:
            j, dotted = _scan_number(data, i, ctx)
            tokens.append((i, j, dotted))
            if j < n and data[j] == 0x2C:  # ','
                i = j + 1
                continue
            if j < n and data[j] == 0x29:
                i = j + 1
                break
            raise _err(data, j, "params", f"expected ',' or ')' in {ctx}, got {_got(data, j)}")
    if len(tokens) != spec.arity:
        # too many: point at the first extra parameter; too few: at the closing ')'
        at = tokens[spec.arity][0] if len(tokens) > spec.arity else i - 1
        raise _err(data, at, "params", _arity_reason(spec, len(tokens)))
    args = []
    for p, (a, b, dotted) in zip(spec.params, tokens):
        text = data[a:b].decode("ascii")
        if p.kind == "int" and dotted:
            raise _err(data, a, "params",
                       f"{name} parameter {p.name} must be an integer, got {text}")
        v: int | float = float(text) + 0.0 if dotted else int(text)
        _, reason = _check_value(spec, p, v)
        if reason:
            raise _err(data, a, "params", reason)
        args.append(v)
    return Command(name, tuple(args)), i


def format_content(commands: Iterable[Command]) -> bytes:
    """Commands -> Content bytes (ASCII). ``parse_content(format_content(cs)) == tuple(cs)``."""
    return "".join([c.wire for c in commands]).encode("ascii")


def split_layers(commands: Iterable[Command]) -> tuple[tuple[Command, ...], tuple[Command, ...]]:
    """(MAC-layer commands, application-layer commands), each in their original order."""
    mac: list[Command] = []
    app: list[Command] = []
    for c in commands:
        (mac if COMMANDS[c.name].layer == "mac" else app).append(c)
    return tuple(mac), tuple(app)


AUTH_TAIL = re.compile(rb"auth\([0-9a-f]{8},[0-9a-f]{8}\)\Z")
"""``auth(freshness,tag)`` ending a Content (docs/protocol.md clause 52): not in the command
table (its parameters are hex), checked and taken off by the MAC before the Content is
parsed (firmware_model/radio/auth.py)."""
AUTH_TAIL_LEN = 23

FRAME_KINDS = ("heartbeat", "control", "message", "boot", "join", "unreadable")


def frame_kind(type_digit: int, content: bytes) -> str:
    """What a frame is (docs/protocol.md §3.5, clause 21), from its Type digit and Content:

    * ``boot`` (Type '5') and ``join`` (Type '6'), the project's extensions;
    * ``message``: Content holds at least one application command;
    * ``heartbeat``: empty Content (the paper's idle frame, Type '3' to '7');
    * ``control``: only MAC commands (``ack``, ``poll``, ``ring``, ``crc``, ``auth``): a
      heartbeat's place, with something for the MAC to say;
    * ``unreadable``: Content that does not parse.
    """
    if type_digit == 5:
        return "boot"
    if type_digit == 6:
        return "join"
    if not content:
        return "heartbeat"
    if AUTH_TAIL.search(content):       # the authenticated profile's last command (clause 52)
        content = content[:-AUTH_TAIL_LEN]
        if not content:
            return "control"
    try:
        _, app = split_layers(parse_content(content))
    except ContentError:
        return "unreadable"
    return "message" if app else "control"
