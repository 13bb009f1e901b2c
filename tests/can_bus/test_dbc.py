"""can_bus/rprs.dbc and can_bus.dbc: the frame contract of docs/can.md."""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import can
import cantools
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from budgets import quick_and_thorough

import can_bus
from can_bus import dbc
from can_bus.frames import CanFrame

DBC = Path(can_bus.__file__).parent / "rprs.dbc"

# signal: (start bit, length, signed, scale, unit)
U8 = lambda start, unit=None: (start, 8, False, 1, unit)  # noqa: E731
EVENT = {"kind": U8(0), "seq": U8(8), "code": U8(16)}
JOINT_CMD = {"angle": (0, 16, True, 0.01, "deg"), "speed": (16, 16, False, 0.1, "deg/s"),
             "seq": U8(32), "mode": U8(40)}
JOINT_STATUS = {"angle": (0, 16, True, 0.01, "deg"), "speed": (16, 16, True, 0.1, "deg/s"),
                "state": U8(32), "seq": U8(40)}
SUBS = ["JOINT1", "JOINT2", "JOINT3", "JOINT4", "WHEEL", "PAW"]

# name: (id, dlc, sender, receivers, signals) -- docs/can.md
EXPECTED: dict[str, tuple[int, int, str, list[str], dict]] = {
    "ESTOP": (0x010, 1, "MCU", SUBS, {"reason": U8(0)}),
    "WHEEL_CMD": (0x105, 7, "MCU", ["WHEEL"], {"speed": (0, 16, True, 1, "mm/s"),
                                               "distance": (16, 32, True, 1, "mm"),
                                               "seq": U8(48)}),
    "PAW_CMD": (0x106, 3, "MCU", ["PAW"], {"action": U8(0), "force": U8(8, "%"), "seq": U8(16)}),
    "WHEEL_STATUS": (0x185, 8, "WHEEL", ["MCU"], {"speed": (0, 16, True, 1, "mm/s"),
                                                  "odometer": (16, 32, True, 1, "mm"),
                                                  "state": U8(48), "seq": U8(56)}),
    "PAW_STATUS": (0x186, 4, "PAW", ["MCU"], {"opening": U8(0, "%"), "grip": U8(8),
                                              "state": U8(16), "seq": U8(24)}),
}
for _n in range(1, 7):
    EXPECTED[f"EVENT{_n}"] = (0x0C0 + _n, 3, SUBS[_n - 1], ["MCU"], EVENT)
for _n in range(1, 5):
    EXPECTED[f"JOINT{_n}_CMD"] = (0x100 + _n, 6, "MCU", [f"JOINT{_n}"], JOINT_CMD)
    EXPECTED[f"JOINT{_n}_STATUS"] = (0x180 + _n, 6, f"JOINT{_n}", ["MCU"], JOINT_STATUS)

CHOICES = {
    "state": {0: "idle", 1: "moving", 2: "holding", 3: "stalled", 4: "fault"},
    "kind": {1: "done", 2: "fault", 3: "refused"},
    "mode": {0: "move", 1: "hold", 2: "relax"},
    "action": {0: "close", 1: "open"},
}


def test_dbc_is_package_data_and_loads_strictly():
    assert DBC.is_file()
    db = cantools.database.load_file(str(DBC), strict=True)
    assert len(db.messages) == len(EXPECTED) == 19
    assert dbc.load() is dbc.load()  # cached
    assert dbc.dbc_path().read_text() == DBC.read_text()
    assert [n.name for n in db.nodes] == ["MCU", "JOINT1", "JOINT2", "JOINT3", "JOINT4", "WHEEL",
                                          "PAW"]
    assert all(n.comment for n in db.nodes)
    assert db.buses[0].baudrate == 500_000


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_every_frame_of_the_contract(name):
    fid, length, sender, receivers, signals = EXPECTED[name]
    m = dbc.load().get_message_by_name(name)
    assert (m.frame_id, m.length, m.is_extended_frame) == (fid, length, False)
    assert dbc.frame_id(name) == fid and dbc.frame_name(fid) == name and dbc.dlc(name) == length
    assert m.senders == [sender]
    assert m.comment
    assert {s.name for s in m.signals} == set(signals)
    for s in m.signals:
        start, size, signed, scale, unit = signals[s.name]
        assert (s.start, s.length, s.is_signed, s.scale, s.offset) == \
            (start, size, signed, scale, 0)
        assert s.byte_order == "little_endian"
        assert (s.unit or None) == unit
        assert s.receivers == receivers
        assert s.minimum is not None and s.maximum is not None
        # [min|max] fits in the raw range
        lo = -(1 << (size - 1)) if signed else 0
        hi = (1 << (size - 1)) - 1 if signed else (1 << size) - 1
        assert lo * scale - 1e-9 <= s.minimum <= s.maximum <= hi * scale + 1e-9
        assert s.comment
        if s.name in CHOICES:
            assert dict(s.choices) == CHOICES[s.name]
    if name.endswith("_STATUS"):
        assert m.cycle_time == 100


def test_name_helpers():
    assert [dbc.joint_cmd_name(n) for n in (1, 4)] == ["JOINT1_CMD", "JOINT4_CMD"]
    assert dbc.joint_status_name(2) == "JOINT2_STATUS"
    assert [dbc.event_name(n) for n in (1, 6)] == ["EVENT1", "EVENT6"]
    assert [dbc.cmd_name(n) for n in (3, 5, 6)] == ["JOINT3_CMD", "WHEEL_CMD", "PAW_CMD"]
    assert [dbc.status_name(n) for n in (4, 5, 6)] == \
        ["JOINT4_STATUS", "WHEEL_STATUS", "PAW_STATUS"]
    for bad in (0, 5, True, "1"):
        with pytest.raises(dbc.DbcError):
            dbc.joint_cmd_name(bad)
    with pytest.raises(dbc.DbcError, match="NOPE"):
        dbc.frame_id("NOPE")
    with pytest.raises(dbc.DbcError, match="0x7ff"):
        dbc.frame_name(0x7FF)


def test_little_endian_layout():
    f = dbc.encode_raw("JOINT1_CMD", angle=-2, speed=0x1234, seq=0xAB, mode=2)
    assert f == CanFrame(0x101, bytes([0xFE, 0xFF, 0x34, 0x12, 0xAB, 0x02]))
    f = dbc.encode("WHEEL_STATUS", speed=-1, odometer=0x01020304, state=1, seq=9)
    assert f.data == bytes([0xFF, 0xFF, 0x04, 0x03, 0x02, 0x01, 0x01, 0x09])
    assert dbc.encode("JOINT2_CMD", angle=12.34, speed=7.5, seq=1, mode="hold").data == \
        bytes([0xD2, 0x04, 0x4B, 0x00, 0x01, 0x01])


def _raw_signals(name: str):
    """Raw integers whose physical values lie in the DBC's [min|max]."""
    e = {}
    for s in dbc.message(name).signals:
        lo, hi = dbc.signal_range(name, s.name)
        e[s.name] = (math.ceil(round((lo - s.offset) / s.scale, 6)),
                     math.floor(round((hi - s.offset) / s.scale, 6)))
    return st.fixed_dictionaries({k: st.integers(lo, hi) for k, (lo, hi) in e.items()})


@settings(max_examples=300, deadline=None)
@given(data=st.data(), name=st.sampled_from(sorted(EXPECTED)))
def test_round_trip_raw_and_physical(data, name):
    raw = data.draw(_raw_signals(name))
    frame = dbc.encode_raw(name, **raw)
    assert frame.id == EXPECTED[name][0] and frame.dlc == EXPECTED[name][1]
    assert dbc.decode_raw(frame) == (name, raw)
    got_name, phys = dbc.decode(frame)
    assert got_name == name
    for sig, value in phys.items():
        s = dbc.message(name).get_signal_by_name(sig)
        assert math.isclose(value, raw[sig] * s.scale, abs_tol=1e-9)
    # physical values encode back to the same bytes, and python-can messages decode too
    assert dbc.encode(name, **phys) == frame
    assert dbc.decode(frame.to_message()) == (name, phys)


@pytest.mark.parametrize("name,signal,value,rng", [
    ("JOINT1_CMD", "angle", 170.01, "-170..170 deg"),
    ("JOINT2_CMD", "angle", -10.5, "-10..120 deg"),
    ("JOINT3_CMD", "angle", -200, "-135..135 deg"),
    ("JOINT3_CMD", "speed", -0.1, "0..90 deg/s"),
    ("JOINT1_CMD", "speed", 60.1, "0..60 deg/s"),
    ("WHEEL_CMD", "speed", 301, "-300..300 mm/s"),
    ("JOINT4_CMD", "mode", 3, "0..2"),
    ("EVENT2", "kind", 0, "1..3"),
    ("PAW_CMD", "force", 101, "0..100"),
    ("PAW_STATUS", "grip", 2, "0..1"),
    ("WHEEL_CMD", "distance", 2**31, "-2147483648..2147483647"),
    ("ESTOP", "reason", 256, "0..255"),
])
def test_out_of_range_raises_dbc_error_with_signal_and_range(name, signal, value, rng):
    m = dbc.message(name)
    signals = {s.name: (s.minimum if s.minimum > 0 else 0) for s in m.signals}
    signals[signal] = value
    with pytest.raises(dbc.DbcError) as exc:
        dbc.encode(name, **signals)
    msg = str(exc.value)
    assert name in msg and repr(signal) in msg and rng in msg
    # the same out-of-limit value still goes on the wire raw (a CAN tool can send it; the
    # submodules refuse it), unless its bits cannot carry it
    s = m.get_signal_by_name(signal)
    raw = round((value - s.offset) / s.scale)
    rlo, rhi = dbc.signal_range(name, signal, raw=True)
    raw_signals = {k: round((v - m.get_signal_by_name(k).offset) / m.get_signal_by_name(k).scale)
                   for k, v in signals.items()}
    if rlo <= raw <= rhi:
        assert dbc.decode_raw(dbc.encode_raw(name, **raw_signals))[1][signal] == raw
    else:
        with pytest.raises(dbc.DbcError, match="raw signal"):
            dbc.encode_raw(name, **raw_signals)


def test_encode_errors():
    with pytest.raises(dbc.DbcError, match="missing signal.*mode"):
        dbc.encode("JOINT1_CMD", angle=0, speed=0, seq=0)
    with pytest.raises(dbc.DbcError, match="unknown signal.*bogus"):
        dbc.encode("PAW_CMD", action=0, force=0, seq=0, bogus=1)
    with pytest.raises(dbc.DbcError, match="no value named 'sideways'"):
        dbc.encode("PAW_CMD", action="sideways", force=0, seq=0)
    with pytest.raises(dbc.DbcError, match="must be an int"):
        dbc.encode_raw("PAW_CMD", action=0, force=1.5, seq=0)
    with pytest.raises(dbc.DbcError,
                       match="raw signal 'angle' = 32768 is out of range -32768..32767"):
        dbc.encode_raw("JOINT1_STATUS", angle=32768, speed=0, state=0, seq=0)
    with pytest.raises(dbc.DbcError, match="unknown frame name 'JOINT5_CMD'"):
        dbc.encode("JOINT5_CMD")


def test_decode_errors_name_the_frame():
    with pytest.raises(dbc.DbcError, match="unknown CAN id 0x200"):
        dbc.decode(CanFrame(0x200, b"\x00"))
    with pytest.raises(dbc.DbcError, match=r"JOINT1_CMD \(0x101\): expected 6 data bytes, got 5"):
        dbc.decode(CanFrame(0x101, bytes(5)))
    with pytest.raises(dbc.DbcError, match="PAW_STATUS.*expected 4 data bytes, got 8"):
        dbc.decode(can.Message(arbitration_id=0x186, is_extended_id=False, data=bytes(8)))
    with pytest.raises(dbc.DbcError, match="EVENT1.*remote"):
        dbc.decode(CanFrame(0x0C1, rtr=True, dlc=3))
    with pytest.raises(dbc.DbcError, match="extended"):
        dbc.decode(can.Message(arbitration_id=0x101, is_extended_id=True, data=bytes(6)))
    with pytest.raises(dbc.DbcError):
        dbc.decode(b"\x01\x02")


def test_cantools_cli_decodes_a_candump_log(tmp_path):
    frames = [
        dbc.encode("JOINT2_CMD", angle=12.5, speed=30, seq=17, mode="move"),
        dbc.encode("EVENT2", kind="done", seq=17, code=0),
        dbc.encode("EVENT3", kind="fault", seq=4, code=1),
        dbc.encode("WHEEL_STATUS", speed=-150, odometer=1234, state=1, seq=3),
    ]
    lines = [f"  can0  {f.id:03X}   [{f.dlc}]  " + " ".join(f"{b:02X}" for b in f.data)
             for f in frames]
    log = "\n".join(lines) + "\n"
    out = subprocess.run(
        [sys.executable, "-m", "cantools", "decode", str(DBC)],
        input=log, capture_output=True, text=True, timeout=120, check=True,
    ).stdout
    assert "JOINT2_CMD(" in out and "angle: 12.5 deg" in out and "mode: move" in out
    assert "EVENT2(" in out and "kind: done" in out and "code: none" in out
    assert "EVENT3(" in out and "kind: fault" in out and "code: stalled(fault)" in out
    assert "WHEEL_STATUS(" in out and "odometer: 1234 mm" in out and "state: moving" in out


def test_the_dbc_carries_the_physical_truth():
    """Each joint's limits, its rated and default speeds, and the wheel's range are in
    rprs.dbc, and they are what the firmware's kinematics and the submodules use: cantools
    alone refuses a command the submodule would refuse (it once encoded -200 deg for joint 3)."""
    import cantools

    from can_bus.submodules import JOINT_DEFAULT_SPEED_DPS, JOINT_DEFAULTS, WHEEL_MAX_SPEED_MM_S
    from firmware_model.kinematics import JOINT_LIMITS, WHEEL_MAX_SPEED
    db = cantools.database.load_file(str(DBC), strict=True)
    for n, (lo, hi) in JOINT_LIMITS.items():
        cmd = db.get_message_by_name(f"JOINT{n}_CMD")
        angle, speed = cmd.get_signal_by_name("angle"), cmd.get_signal_by_name("speed")
        assert (angle.minimum, angle.maximum) == (lo, hi)
        assert JOINT_DEFAULTS[n]["limits"] == (lo, hi)
        assert speed.maximum == JOINT_DEFAULTS[n]["max_speed_dps"]
        assert f"0 = the joint's default speed, {JOINT_DEFAULT_SPEED_DPS[n]:g} deg/s" in \
            speed.comment
        status = db.get_message_by_name(f"JOINT{n}_STATUS").get_signal_by_name("angle")
        assert (status.minimum, status.maximum) == (lo, hi)
        with pytest.raises(cantools.database.EncodeError):
            cmd.encode({"angle": lo - 0.01, "speed": 0, "seq": 0, "mode": 0})
    wheel = db.get_message_by_name("WHEEL_CMD").get_signal_by_name("speed")
    assert (wheel.minimum, wheel.maximum) == (-WHEEL_MAX_SPEED, WHEEL_MAX_SPEED)
    assert WHEEL_MAX_SPEED_MM_S == WHEEL_MAX_SPEED


def test_event_codes_have_a_value_table():
    """The code of an EVENT is named, for the kind it comes with (fault or refused)."""
    import cantools
    db = cantools.database.load_file(str(DBC), strict=True)
    for n in range(1, 7):
        m = db.get_message_by_name(dbc.event_name(n))
        names = {int(k): str(v) for k, v in m.get_signal_by_name("code").choices.items()}
        assert names[0] == "none"
        assert names[dbc.FAULT_STALLED].startswith("stalled(fault)")
        assert names[dbc.REFUSED_RANGE].endswith("out_of_range(refused)")
        assert names[dbc.FAULT_OVERCURRENT] == "overcurrent(fault)/faulted(refused)"
        assert dbc.REFUSED_FAULTED == dbc.FAULT_OVERCURRENT and dbc.REFUSED_BUSY == dbc.FAULT_LIMIT


@pytest.mark.parametrize("bad", [True, 1.0])
def test_a_remembered_encoding_does_not_accept_what_encoding_refuses(bad):
    """encode_raw(speed=1) is remembered; speed=True (not a number) and speed=1.0 (not an int)
    equal 1 as dict keys, and must still be refused, whatever was encoded before."""
    good = dbc.encode_raw("WHEEL_CMD", speed=1, distance=0, seq=1)
    assert dbc.encode_raw("WHEEL_CMD", seq=1, distance=0, speed=1) == good   # any order
    with pytest.raises(dbc.DbcError, match="speed"):
        dbc.encode_raw("WHEEL_CMD", speed=bad, distance=0, seq=1)
    with pytest.raises(dbc.DbcError, match="must be a number"):
        dbc.encode("WHEEL_CMD", speed=True, distance=0, seq=1)


def _value(signal) -> st.SearchStrategy:
    """Any value a caller might give one signal: numbers on and around both ends of its
    physical and raw ranges (cantools' tolerance |scale| * 1e-6 included), its choice names and
    a bogus one, and things that are not numbers."""
    lo, hi = signal.minimum, signal.maximum
    tol = abs(signal.scale) * 1e-6
    raw_bits = 1 << (signal.length - 1 if signal.is_signed else signal.length)
    rlo, rhi = (-raw_bits, raw_bits - 1) if signal.is_signed else (0, raw_bits - 1)
    edges = [lo, hi, lo - tol, hi + tol, rlo, rhi, rlo - 1, rhi + 1]
    near = [e + d for e in edges for d in (-tol / 2, tol / 2, -2 * tol, 2 * tol, -1e-12, 1e-12)]
    near += [math.nextafter(e, s) for e in (lo - tol, hi + tol) for s in (-math.inf, math.inf)]
    return st.one_of(
        st.integers(rlo - 3, rhi + 3),
        st.floats(lo - 1, hi + 1),
        st.sampled_from(edges + near + [int(lo), int(hi)]),
        st.sampled_from([True, False, math.nan, math.inf, -math.inf, "bogus", None, [1], b"1"]),
        st.sampled_from([str(v) for v in (signal.choices or {}).values()] or [0]),
    )


@st.composite
def _signals(draw, name: str | None = None):
    """(frame name, a dict of values for its signals, now and then one missing or one more)."""
    name = name or draw(st.sampled_from(sorted(EXPECTED)))
    m = dbc.message(name)
    out = {s.name: draw(_value(s)) for s in m.signals}
    odd = draw(st.integers(0, 9))
    if odd == 0:
        out.pop(draw(st.sampled_from(sorted(out))))
    elif odd == 1:
        out["bogus"] = 0
    return name, out


def _outcome(fn, *args):
    try:
        return "ok", fn(*args)
    except dbc.DbcError as exc:
        return "error", str(exc)


THOROUGH = settings(max_examples=1000, deadline=None)
QUICK = settings(THOROUGH, max_examples=150)
"""The four properties below: 150 examples in the fast tier, 1000 in the slow tier."""


def _the_quick_check_says_what_the_one_by_one_check_says(case, raw):
    """_check_signals' common case (every signal an int or float in range) gives what the
    signal-by-signal checks give, value for value and error for error."""
    name, signals = case
    e = dbc._by_name(name)
    quick = _outcome(dbc._check_signals, e, signals, raw)
    full = _outcome(dbc._check_signals_one_by_one, e, signals, raw)
    assert quick == full
    if quick[0] == "ok":
        assert all(type(a) is type(b) for a, b in zip(quick[1].values(), full[1].values()))


(test_the_quick_check_says_what_the_one_by_one_check_says,
 test_the_quick_check_says_what_the_one_by_one_check_says_thoroughly) = quick_and_thorough(
    lambda budget: budget(given(case=_signals(), raw=st.booleans())(
        _the_quick_check_says_what_the_one_by_one_check_says)),
    QUICK, THOROUGH)


def _our_physical_checks_are_at_least_as_strict_as_cantools_strict_mode(case):
    """encode() calls cantools with strict=False: whatever our checks let through, cantools'
    strict mode (every signal and none else, choice names, [min|max] with |scale| * 1e-6)
    lets through too, and encodes the same bytes either way."""
    name, signals = case
    e = dbc._by_name(name)
    verdict, checked = _outcome(dbc._check_signals, e, signals, False)
    if verdict != "ok":
        return
    e.msg.assert_signals_encodable(checked, scaling=True)       # raises if cantools refuses
    try:
        strict = e.msg.encode(checked, scaling=True, strict=True)
    except (cantools.database.EncodeError, ValueError, OverflowError) as exc:
        with pytest.raises(type(exc)):
            e.msg.encode(checked, scaling=True, strict=False)
        with pytest.raises(dbc.DbcError, match="cannot encode"):
            dbc.encode(name, **signals)
    else:
        assert e.msg.encode(checked, scaling=True, strict=False) == strict
        assert dbc.encode(name, **signals).data == strict


(test_our_physical_checks_are_at_least_as_strict_as_cantools_strict_mode,
 test_our_physical_checks_are_at_least_as_strict_as_cantools_strict_mode_thoroughly) = \
    quick_and_thorough(
    lambda budget: budget(given(case=_signals())(
        _our_physical_checks_are_at_least_as_strict_as_cantools_strict_mode)),
    QUICK, THOROUGH)


def _raw_checks_keep_what_the_bits_carry(case, first):
    """A raw value our checks let through is on the wire as given (cantools, strict=False,
    never wraps it)."""
    name, signals = case
    verdict, frame = _outcome(lambda: dbc.encode_raw(name, **signals))
    if verdict == "ok":
        assert dbc.decode_raw(frame) == (name, signals)


(test_raw_checks_keep_what_the_bits_carry,
 test_raw_checks_keep_what_the_bits_carry_thoroughly) = quick_and_thorough(
    lambda budget: budget(given(case=_signals(), first=st.booleans())(
        _raw_checks_keep_what_the_bits_carry)),
    QUICK, THOROUGH)


def _encode_raw_values_is_encode_raw(case, again):
    """encode_raw_values(name, values in signal_names order) gives encode_raw's frame or its
    error, also for values equal to remembered ones but of another type (True, 1.0)."""
    name, signals = case
    order = dbc.signal_names(name)
    assert order == tuple(s.name for s in dbc.message(name).signals)
    if signals.keys() != set(order):
        return
    values = tuple(signals[k] for k in order)
    want = _outcome(lambda: dbc.encode_raw(name, **signals))
    for _ in range(2):                                  # the second one remembered
        assert _outcome(dbc.encode_raw_values, name, values) == want
    if again is not None:
        # the first signal's value 1 remembered; then the same with True or 1.0
        ones = (1,) + values[1:]
        _outcome(dbc.encode_raw_values, name, ones)
        other = (again,) + values[1:]
        assert _outcome(dbc.encode_raw_values, name, other) == \
            _outcome(lambda: dbc.encode_raw(name, **dict(zip(order, other))))


(test_encode_raw_values_is_encode_raw,
 test_encode_raw_values_is_encode_raw_thoroughly) = quick_and_thorough(
    lambda budget: budget(given(case=_signals(), again=st.sampled_from([None, 1, True, 1.0]))(
        _encode_raw_values_is_encode_raw)),
    QUICK, THOROUGH)


def test_encode_raw_values_wants_every_signal():
    with pytest.raises(dbc.DbcError, match="3 value.*angle, speed, state, seq"):
        dbc.encode_raw_values("JOINT1_STATUS", (0, 0, 0))
    with pytest.raises(dbc.DbcError, match="unknown frame name"):
        dbc.encode_raw_values("JOINT9_STATUS", (0, 0, 0, 0))
