"""The one description of every frame on the child's CAN bus: ``can_bus/rprs.dbc`` (docs/can.md).

All encoding and decoding goes through :mod:`cantools` with that file, loaded once with strict
checks (:func:`load`). The cantools ``Message`` objects and their signal ranges are cached, so
:func:`encode` and :func:`decode` cost one dictionary look-up plus the cantools codec.

Two flavours:

* :func:`encode` / :func:`decode` use physical values (``angle`` in degrees, ``speed`` in
  deg/s, ...), as the DBC scales them; ``mode="hold"`` style choice names are accepted.
* :func:`encode_raw` / :func:`decode_raw` use the raw integers on the wire (``angle`` in
  0.01 deg, joint ``speed`` in 0.1 deg/s): what the submodule models use for exact arithmetic;
  :func:`encode_raw_values` is the same with the values in a tuple (:func:`signal_names`
  order), cheaper for a status frame sent again and again.

Every problem is a :class:`DbcError` naming the frame: unknown name or identifier, wrong data
length, remote frame, missing or unknown signal, and a value outside its range: for
:func:`encode` the DBC's [min|max], which carry the physical truth (each joint's limits, the
rated speeds, the wheel's range), e.g. ``JOINT3_CMD: signal 'angle' = -200 deg is out of
range -135..135 deg``; for :func:`encode_raw` the signal's bit width.
"""
from __future__ import annotations

from functools import lru_cache
from importlib import resources
from typing import Any, Union, cast

import can
import cantools
from cantools.database.can import Database, Message

from can_bus.frames import CanFrame

__all__ = [
    "DBC_FILE",
    "DbcError",
    "load",
    "dbc_path",
    "message",
    "encode",
    "encode_raw",
    "encode_raw_values",
    "signal_names",
    "decode",
    "decode_raw",
    "frame_id",
    "frame_name",
    "dlc",
    "signal_range",
    "ESTOP",
    "WHEEL_NUMBER",
    "PAW_NUMBER",
    "NODE_NAMES",
    "EVENT_DONE",
    "EVENT_FAULT",
    "EVENT_REFUSED",
    "FAULT_STALLED",
    "FAULT_LIMIT",
    "FAULT_OVERCURRENT",
    "REFUSED_RANGE",
    "REFUSED_BUSY",
    "REFUSED_FAULTED",
    "STATE_IDLE",
    "STATE_MOVING",
    "STATE_HOLDING",
    "STATE_STALLED",
    "STATE_FAULT",
    "MODE_MOVE",
    "MODE_HOLD",
    "MODE_RELAX",
    "ACTION_CLOSE",
    "ACTION_OPEN",
    "joint_cmd_name",
    "joint_status_name",
    "event_name",
    "cmd_name",
    "status_name",
]

DBC_FILE = "rprs.dbc"
"""Package data file of :mod:`can_bus` (declared in pyproject's package-data)."""

ESTOP = "ESTOP"
WHEEL_NUMBER = 5
PAW_NUMBER = 6
NODE_NAMES = ("MCU", "JOINT1", "JOINT2", "JOINT3", "JOINT4", "WHEEL", "PAW")
"""DBC node names, index = node number (0 = central planning module)."""

# EVENT kind / code (docs/can.md)
EVENT_DONE, EVENT_FAULT, EVENT_REFUSED = 1, 2, 3
FAULT_STALLED, FAULT_LIMIT, FAULT_OVERCURRENT = 1, 2, 3
REFUSED_RANGE, REFUSED_BUSY, REFUSED_FAULTED = 1, 2, 3
# STATUS state
STATE_IDLE, STATE_MOVING, STATE_HOLDING, STATE_STALLED, STATE_FAULT = 0, 1, 2, 3, 4
# JOINT<n>_CMD mode, PAW_CMD action
MODE_MOVE, MODE_HOLD, MODE_RELAX = 0, 1, 2
ACTION_CLOSE, ACTION_OPEN = 0, 1


class DbcError(ValueError):
    """A frame or signal that does not match ``rprs.dbc``."""


FrameLike = Union[CanFrame, can.Message]


def dbc_path():
    """A :class:`importlib.resources` traversable for ``can_bus/rprs.dbc``."""
    return resources.files("can_bus").joinpath(DBC_FILE)


@lru_cache(maxsize=1)
def load() -> Database:
    """The strictly loaded database (cached: every call returns the same object)."""
    text = dbc_path().read_text(encoding="utf-8")
    db = cantools.database.load_string(text, database_format="dbc", strict=True)
    assert isinstance(db, Database)           # a DBC file loads as a CAN database
    return db


class _Msg:
    """Cached per-frame data: the cantools Message and the signal ranges."""

    __slots__ = ("msg", "name", "id", "length", "signals", "order", "ranges", "tolerant",
                 "raw_ranges", "units", "raw_bounds", "tolerant_bounds")

    def __init__(self, msg: Message) -> None:
        self.msg = msg
        self.name = msg.name
        self.id = msg.frame_id
        self.length = msg.length
        self.signals = frozenset(s.name for s in msg.signals)
        self.order = tuple(s.name for s in msg.signals)
        self.ranges: dict[str, tuple[float, float]] = {}
        self.tolerant: dict[str, tuple[float, float]] = {}
        self.raw_ranges: dict[str, tuple[int, int]] = {}
        self.units: dict[str, str] = {}
        for s in msg.signals:
            # every signal of rprs.dbc has [min|max]; fall back to the raw width otherwise
            if s.is_signed:
                rlo, rhi = -(1 << (s.length - 1)), (1 << (s.length - 1)) - 1
            else:
                rlo, rhi = 0, (1 << s.length) - 1
            lo = s.minimum if s.minimum is not None else s.scale * rlo + s.offset
            hi = s.maximum if s.maximum is not None else s.scale * rhi + s.offset
            # decoded floats such as 3276.7000000000003 pass, as in cantools (scale * 1e-6)
            tol = abs(s.scale) * 1e-6
            self.ranges[s.name] = (lo, hi)
            self.tolerant[s.name] = (lo - tol, hi + tol)
            self.raw_ranges[s.name] = (rlo, rhi)    # what the wire can carry
            self.units[s.name] = s.unit or ""
        # (signal, lo, hi) of every signal, for the common case of _check_signals
        self.raw_bounds = tuple((k, lo, hi) for k, (lo, hi) in self.raw_ranges.items())
        self.tolerant_bounds = tuple((k, lo, hi) for k, (lo, hi) in self.tolerant.items())


@lru_cache(maxsize=1)
def _tables() -> tuple[dict[str, _Msg], dict[int, _Msg]]:
    by_name: dict[str, _Msg] = {}
    by_id: dict[int, _Msg] = {}
    for m in load().messages:
        e = _Msg(m)
        by_name[m.name] = e
        by_id[m.frame_id] = e
    return by_name, by_id


def _by_name(name: str) -> _Msg:
    try:
        return _tables()[0][name]
    except KeyError:
        raise DbcError(f"unknown frame name {name!r} (not in {DBC_FILE})") from None


def message(name: str) -> Message:
    """The cached cantools ``Message`` for a frame name."""
    return _by_name(name).msg


def frame_id(name: str) -> int:
    """CAN identifier of a frame name (DbcError if unknown)."""
    return _by_name(name).id


def frame_name(can_id: int) -> str:
    """Frame name of a CAN identifier (DbcError if unknown)."""
    try:
        return _tables()[1][can_id].name
    except KeyError:
        raise DbcError(f"unknown CAN id {can_id:#05x} (not in {DBC_FILE})") from None


def dlc(name: str) -> int:
    """Data length of a frame name."""
    return _by_name(name).length


def signal_names(name: str) -> tuple[str, ...]:
    """The signals of a frame name, in rprs.dbc's order (the order :func:`encode_raw_values`
    takes their values in)."""
    return _by_name(name).order


def signal_range(name: str, signal: str, raw: bool = False) -> tuple[float, float]:
    """Allowed (min, max) of a signal: physical, the DBC's [min|max] (a joint's limits, a
    rated speed); or raw, the integers its bits can carry on the wire."""
    e = _by_name(name)
    if signal not in e.signals:
        raise DbcError(f"{name}: no signal {signal!r} (signals: {', '.join(sorted(e.signals))})")
    return e.raw_ranges[signal] if raw else e.ranges[signal]


def _check_signals(e: _Msg, signals: dict[str, Any], raw: bool) -> dict[str, Any]:
    """``signals`` checked against frame ``e`` (choice names replaced by their numbers), or
    :class:`DbcError`. The common case first: every signal there and no other, each an ``int``
    (raw) or an ``int`` or ``float`` (physical) inside its range: that is all the checks below
    would find, so it passes as it is; anything else takes the checks below, which name it."""
    bounds = e.raw_bounds if raw else e.tolerant_bounds
    if len(signals) == len(bounds):
        for sig, lo, hi in bounds:
            value = signals.get(sig)
            t = type(value)
            # (type(value) is int or float before the bounds: None and bool are neither)
            if not (t is int or (t is float and not raw)) or \
                    not lo <= value <= hi:  # type: ignore[operator]
                break
        else:
            return signals
    return _check_signals_one_by_one(e, signals, raw)


def _check_signals_one_by_one(e: _Msg, signals: dict[str, Any], raw: bool) -> dict[str, Any]:
    if signals.keys() != e.signals:
        missing = e.signals - signals.keys()
        extra = signals.keys() - e.signals
        parts = []
        if missing:
            parts.append(f"missing signal(s) {', '.join(sorted(missing))}")
        if extra:
            parts.append(f"unknown signal(s) {', '.join(sorted(extra))}")
        raise DbcError(f"{e.name}: {'; '.join(parts)} (signals: {', '.join(sorted(e.signals))})")
    ranges = e.raw_ranges if raw else e.ranges
    tlo = e.tolerant
    out = signals
    for sig, value in signals.items():
        if isinstance(value, str) and not raw:
            sd = e.msg.get_signal_by_name(sig)
            try:
                num = sd.conversion.choice_to_number(value)
            except (KeyError, NotImplementedError, AttributeError):
                num = None
            if num is None:
                choices = ", ".join(str(c) for c in (sd.choices or {}).values())
                raise DbcError(f"{e.name}: signal {sig!r} has no value named {value!r} ({choices})")
            if out is signals:
                out = dict(signals)
            out[sig] = num * sd.scale + sd.offset
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise DbcError(f"{e.name}: signal {sig!r} must be a number, got {value!r}")
        if raw and not isinstance(value, int):
            raise DbcError(f"{e.name}: raw signal {sig!r} must be an int, got {value!r}")
        lo, hi = ranges[sig]
        if not (lo <= value <= hi if raw else tlo[sig][0] <= value <= tlo[sig][1]):
            unit = "" if raw or not e.units[sig] else f" {e.units[sig]}"
            what = "raw signal" if raw else "signal"
            raise DbcError(
                f"{e.name}: {what} {sig!r} = {value}{unit} is out of range {lo}..{hi}{unit}"
            )
    return out


_ENCODED: dict[tuple, CanFrame] = {}
_DECODED: dict[tuple, tuple[str, dict[str, Any]]] = {}
_CACHE_MAX = 4096
"""Encoding and decoding are pure functions of their inputs; periodic status frames repeat
the same values, so the results are memoised (bounded; decoded dicts are copied out). An
encoding's key holds the values' types too: ``True`` and ``1.0`` equal ``1`` but are refused
where ``1`` is taken, whatever was encoded before."""


def _encode(name: str, signals: dict[str, Any], raw: bool) -> CanFrame:
    key: tuple[Any, ...] | None
    try:
        key = (name, raw, tuple(signals.items()), tuple(map(type, signals.values())))
        hit = _ENCODED.get(key)
    except TypeError:               # an unhashable value: let the checks below report it
        key = hit = None
    if hit is not None:
        return hit
    frame = _encode_uncached(name, signals, raw)
    if key is not None:
        if len(_ENCODED) >= _CACHE_MAX:
            _ENCODED.clear()
        _ENCODED[key] = frame
    return frame


def _encode_uncached(name: str, signals: dict[str, Any], raw: bool) -> CanFrame:
    e = _by_name(name)
    signals = _check_signals(e, signals, raw)
    try:
        # raw values were checked against their bit width only (a frame any CAN tool can
        # send); physical ones against the DBC's [min|max] with cantools' strict tolerance
        # (|scale| * 1e-6), every signal and none else, choice names already numbers: all that
        # cantools' strict mode would check again (tests/can_bus/test_dbc.py holds it to that),
        # and one more: a choice signal's value must be whole (cantools rounds 1.4 to 1)
        data = e.msg.encode(signals, scaling=not raw, strict=False)
    except (cantools.database.EncodeError, KeyError, ValueError, OverflowError) as exc:
        raise DbcError(f"{name}: cannot encode {signals!r}: {exc}") from exc
    return CanFrame(e.id, data)


def encode(name: str, **signals: Any) -> CanFrame:
    """Encode physical signal values (every signal of the frame, none else) into a CanFrame.

    Strict: a value outside the signal's DBC ``[min|max]`` raises :class:`DbcError` naming the
    frame, the signal and its range. Choice names (``mode="hold"``) are accepted.
    """
    return _encode(name, signals, False)


def encode_raw(name: str, **signals: int) -> CanFrame:
    """Like :func:`encode` with raw integers (no scaling), checked only against what each
    signal's bits can carry: any frame a CAN tool could put on the bus, an out-of-limit
    command included (the submodules refuse those)."""
    return _encode(name, signals, True)


_BY_VALUES: dict[tuple[str, tuple[int, ...]], CanFrame] = {}


def encode_raw_values(name: str, values: tuple[int, ...]) -> CanFrame:
    """``encode_raw(name, **dict(zip(signal_names(name), values)))``, with its checks and
    errors, for callers that send the same values again and again (a submodule's status): the
    values come as a tuple in :func:`signal_names` order and the frame is remembered by them
    alone, no keyword dict and no key of their types, the ``int`` type being asked of each
    value instead (``True`` and ``1.0`` equal ``1`` and are refused by :func:`encode_raw`)."""
    try:
        hit = _BY_VALUES.get((name, values))
    except TypeError:               # an unhashable value: the checks below report it
        hit = None
    if hit is not None:
        for v in values:
            if type(v) is not int:
                break
        else:
            return hit
    order = _by_name(name).order
    if len(values) != len(order):
        raise DbcError(f"{name}: {len(values)} value(s) for the signals {', '.join(order)}")
    frame = _encode_uncached(name, dict(zip(order, values)), True)
    if len(_BY_VALUES) >= _CACHE_MAX:
        _BY_VALUES.clear()
    _BY_VALUES[(name, tuple(values))] = frame
    return frame


def _lookup(frame: FrameLike) -> tuple[_Msg, bytes]:
    if isinstance(frame, can.Message):
        if frame.is_extended_id:
            raise DbcError(f"extended id {frame.arbitration_id:#x}: {DBC_FILE} has CAN 2.0A "
                           "frames only")
        can_id, rtr, data = frame.arbitration_id, frame.is_remote_frame, bytes(frame.data or b"")
    elif isinstance(frame, CanFrame):
        can_id, rtr, data = frame.id, frame.rtr, frame.data
    else:
        raise DbcError(f"cannot decode {type(frame).__name__}: expected CanFrame or can.Message")
    e = _tables()[1].get(can_id)
    if e is None:
        raise DbcError(f"unknown CAN id {can_id:#05x} (not in {DBC_FILE})")
    if rtr:
        raise DbcError(f"{e.name} ({can_id:#05x}): remote frame carries no signals")
    if len(data) != e.length:
        raise DbcError(
            f"{e.name} ({can_id:#05x}): expected {e.length} data bytes, got {len(data)}"
        )
    return e, data


def decode(frame: FrameLike) -> tuple[str, dict[str, Any]]:
    """(frame name, {signal: physical value}) of a CanFrame or can.Message.

    Choices are not decoded (``state`` is 0..4, not ``'idle'``). Unknown id, remote frame or a
    data length other than the DBC's raise :class:`DbcError`.
    """
    if type(frame) is CanFrame:
        hit = _DECODED.get((frame.id, frame.rtr, frame.data))
        if hit is not None:
            return hit[0], dict(hit[1])
    e, data = _lookup(frame)
    try:
        # a message's decode gives its signals by name
        values = cast("dict[str, Any]", e.msg.decode(data, decode_choices=False, scaling=True))
    except Exception as exc:  # pragma: no cover - cannot happen with the length check
        raise DbcError(f"{e.name} ({e.id:#05x}): cannot decode {data.hex()}: {exc}") from exc
    if type(frame) is CanFrame:
        if len(_DECODED) >= _CACHE_MAX:
            _DECODED.clear()
        _DECODED[(frame.id, frame.rtr, frame.data)] = (e.name, dict(values))
    return e.name, values


def decode_raw(frame: FrameLike) -> tuple[str, dict[str, int]]:
    """Like :func:`decode` but the raw integers on the wire (no scaling)."""
    e, data = _lookup(frame)
    try:
        # a message's decode gives its signals by name; unscaled, the raw integers
        values = cast("dict[str, int]", e.msg.decode(data, decode_choices=False, scaling=False))
    except Exception as exc:  # pragma: no cover
        raise DbcError(f"{e.name} ({e.id:#05x}): cannot decode {data.hex()}: {exc}") from exc
    return e.name, values


def _check_number(n: int, lo: int, hi: int, what: str) -> int:
    if isinstance(n, bool) or not isinstance(n, int) or not lo <= n <= hi:
        raise DbcError(f"{what} number must be an int in {lo}..{hi}, got {n!r}")
    return n


def joint_cmd_name(n: int) -> str:
    """``JOINT<n>_CMD`` for joint 1..4."""
    return f"JOINT{_check_number(n, 1, 4, 'joint')}_CMD"


def joint_status_name(n: int) -> str:
    """``JOINT<n>_STATUS`` for joint 1..4."""
    return f"JOINT{_check_number(n, 1, 4, 'joint')}_STATUS"


def event_name(n: int) -> str:
    """``EVENT<n>`` for node 1..6."""
    return f"EVENT{_check_number(n, 1, 6, 'node')}"


def cmd_name(n: int) -> str:
    """Command frame name of node 1..6: ``JOINT<n>_CMD``, ``WHEEL_CMD`` or ``PAW_CMD``."""
    _check_number(n, 1, 6, "node")
    return joint_cmd_name(n) if n <= 4 else f"{NODE_NAMES[n]}_CMD"


def status_name(n: int) -> str:
    """Status frame name of node 1..6: ``JOINT<n>_STATUS``, ``WHEEL_STATUS`` or ``PAW_STATUS``."""
    _check_number(n, 1, 6, "node")
    return joint_status_name(n) if n <= 4 else f"{NODE_NAMES[n]}_STATUS"
