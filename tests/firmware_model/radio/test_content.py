"""Content command table, parser and formatter (docs/protocol.md §3.3)."""
from __future__ import annotations

import math

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from firmware_model.radio.content import (
    COMMANDS,
    Command,
    CommandSpec,
    Param,
    cmd,
    format_content,
    format_number,
    parse_content,
    split_layers,
)
from firmware_model.radio.errors import ContentError, FrameError, WireError

SETTINGS = settings(max_examples=200, deadline=None)


def test_table_exact():
    app = {"movex", "movey", "movez", "moveto", "joint", "wheel", "paw", "act", "stop", "status",
           "fail", "done"}
    mac = {"ack", "poll", "ring", "crc"}
    assert set(COMMANDS) == app | mac
    assert {n for n, s in COMMANDS.items() if s.layer == "app"} == app
    assert {n for n, s in COMMANDS.items() if s.layer == "mac"} == mac
    for name, spec in COMMANDS.items():
        assert isinstance(spec, CommandSpec) and spec.name == name and spec.doc
        assert all(isinstance(p, Param) and p.kind in ("int", "num") and p.unit
                   for p in spec.params)
    sig = {n: [(p.name, p.kind, p.lo, p.hi) for p in s.params] for n, s in COMMANDS.items()}
    assert sig["moveto"] == [("x", "num", None, None), ("y", "num", None, None),
                             ("z", "num", None, None)]
    assert sig["joint"] == [("index", "int", 1, 4), ("angle", "num", None, None)]
    assert sig["act"] == [("action", "int", 0, 99), ("phase", "int", 0, 1)]
    assert sig["ack"] == [("src", "int", 0, 6), ("num", "int", 0, 99)]
    assert sig["poll"] == [("id", "int", 0, 6), ("mask", "int", 0, 127)]
    assert sig["ring"] == [("mask", "int", 0, 127)]
    assert sig["crc"] == [("value", "int", 0, 65535)]
    assert sig["fail"] == [("code", "int", 0, 999)]
    assert sig["stop"] == sig["status"] == sig["done"] == []
    assert [p.unit for p in COMMANDS["movex"].params] == ["mm"]
    assert COMMANDS["joint"].params[1].unit == "deg" and COMMANDS["wheel"].params[0].unit == "mm/s"


def test_paper_example():
    cs = parse_content(b"movex(10)moveto(1.5,-2,0)")
    assert cs == (cmd("movex", 10), cmd("moveto", 1.5, -2, 0))
    assert [type(a) for a in cs[1].args] == [float, int, int]
    assert type(cs[0].args[0]) is int
    assert format_content(cs) == b"movex(10)moveto(1.5,-2,0)"
    assert cs[1].text() == "moveto(1.5,-2,0)" and cs[1].spec is COMMANDS["moveto"]


def test_empty_and_str_input():
    assert parse_content(b"") == () and parse_content("") == ()
    assert format_content(()) == b""
    assert parse_content("stop()status()") == (cmd("stop"), cmd("status"))


@pytest.mark.parametrize(
    "value, text",
    [(10, "10"), (-2, "-2"), (1.5, "1.5"), (0.125, "0.125"), (-0.5, "-0.5"), (2.0, "2"),
     (0.1234, "0.123"), (-0.0, "0"), (-0.0004, "0"), (100.10, "100.1")],
)
def test_number_format(value, text):
    assert format_number(value) == text
    assert cmd("movex", value).text() == f"movex({text})"


def test_floats_are_rounded_to_wire_resolution():
    c = cmd("movex", 0.1234)
    assert c.args == (0.123,)
    assert parse_content(format_content([c])) == (c,)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_rejected(bad):
    with pytest.raises(ContentError):
        cmd("movex", bad)
    with pytest.raises(ContentError):
        format_number(bad)


@pytest.mark.parametrize(
    "args, match",
    [
        (("nope",), "unknown command 'nope'"),
        (("movex",), r"movex takes 1 parameter \(dx\), got 0"),
        (("moveto", 1, 2), r"moveto takes 3 parameters \(x, y, z\), got 2"),
        (("stop", 1), "stop takes no parameters, got 1"),
        (("paw", 2), "outside 0..1"),
        (("joint", 0, 10), "outside 1..4"),
        (("joint", 1.0, 10), "must be an integer"),
        (("movex", True), "must be a number"),
        (("movex", "10"), "must be a number"),
        (("movex", 10**12), "longer than 12"),
        (("crc", 65536), "outside 0..65535"),
    ],
)
def test_cmd_validation(args, match):
    with pytest.raises(ContentError, match=match) as ei:
        cmd(*args)
    assert ei.value.offset is None


def test_cmd_hands_out_one_value_for_the_same_name_and_typed_arguments():
    """Commands are immutable values, so ``cmd`` remembers those it made; an argument of
    another type (1.0 for 1, True for 1) is another command, validated on its own."""
    assert cmd("joint", 1, 20) is cmd("joint", 1, 20)
    assert type(cmd("movex", 20.0).args[0]) is float and type(cmd("movex", 20).args[0]) is int
    with pytest.raises(ContentError, match="must be an integer"):
        cmd("joint", 1.0, 20)
    with pytest.raises(ContentError, match="must be a number"):
        cmd("movex", True)
    with pytest.raises(ContentError, match="must be a number"):
        cmd("movex", [5])                   # unhashable: still a ContentError
    assert Command("moveto", (1.0, 2, 3)).text() == cmd("moveto", 1, 2, 3).text() == \
        "moveto(1,2,3)"


@pytest.mark.parametrize(
    "text, offset, field, match",
    [
        ("movex(10;", 8, "params", r"expected ',' or '\)' in movex\(\.\.\.\)"),
        ("moveto(1.5,-2)", 13, "params", r"moveto takes 3 parameters \(x, y, z\), got 2"),
        ("movex(1,2)", 8, "params", "got 2"),
        ("stop(1)", 5, "params", "no parameters"),
        ("foo(1)", 0, "command", "unknown command 'foo'"),
        ("movex(1)bar()", 8, "command", "unknown command 'bar'"),
        ("movex", 5, "command", "expected '\\(' after movex, got end of content"),
        ("movex 10", 5, "command", "expected '\\('"),
        ("(1)", 0, "command", "expected a command name"),
        ("movex(10) ", 9, "command", "expected a command name"),
        ("movex()", 6, "params", r"movex takes 1 parameter \(dx\), got 0"),
        ("movex(+1)", 6, "params", "expected a decimal number"),
        ("movex( 1)", 6, "params", "expected a decimal number"),
        ("movex(1e5)", 7, "params", "expected ','"),
        ("movex(1.)", 8, "params", "digit after '.'"),
        ("movex(.5)", 6, "params", "expected a decimal number"),
        ("movex(--1)", 7, "params", "expected a decimal number"),
        ("movex(0.1234)", 11, "params", "more than 3 decimals"),
        ("movex(1234567890123)", 6, "params", "longer than 12"),
        ("joint(5,1)", 6, "params", r"index=5 is outside 1\.\.4"),
        ("joint(1.5,1)", 6, "params", "must be an integer"),
        ("ack(7,0)", 4, "params", "outside 0..6"),
        ("poll(1,128)", 7, "params", "outside 0..127"),
        ("movex(10", 8, "params", "got end of content"),
        ("__import__('os')", 0, "command", "unknown command"),
        ("movex(1)\x00", 8, "command", "0x00"),
    ],
)
def test_parse_errors(text, offset, field, match):
    with pytest.raises(ContentError, match=match) as ei:
        parse_content(text.encode("latin-1"))
    err = ei.value
    assert (err.offset, err.field) == (offset, field)
    assert str(err).startswith(f"content byte {offset} ({field}): ")
    data = text.encode("latin-1")
    assert err.byte == (data[offset] if offset < len(data) else None)
    assert isinstance(err, WireError) and not isinstance(err, FrameError)


def test_non_ascii_str():
    with pytest.raises(ContentError) as ei:
        parse_content("movex(1)é")
    assert ei.value.offset == 8


def _param_values(p: Param):
    if p.kind == "int":
        lo = -(10**11) + 1 if p.lo is None else p.lo
        hi = 10**12 - 1 if p.hi is None else p.hi
        return st.integers(lo, hi)
    ints = st.integers(-(10**6), 10**6)
    decimals = st.builds(lambda i, f: float(f"{i}.{f:03d}"), ints, st.integers(0, 999))
    any_float = st.floats(-1e6, 1e6, allow_nan=False)
    return st.one_of(st.integers(-(10**11) + 1, 10**12 - 1), decimals, any_float)


commands = st.sampled_from(sorted(COMMANDS)).flatmap(
    lambda name: st.tuples(*(_param_values(p) for p in COMMANDS[name].params)).map(
        lambda args, name=name: Command(name, args)
    )
)


@SETTINGS
@given(st.lists(commands, max_size=8))
def test_round_trip(cs):
    cs = tuple(cs)
    data = format_content(cs)
    assert data.isascii()
    assert parse_content(data) == cs
    assert format_content(parse_content(data)) == data  # canonical text is a fixed point
    for c in cs:
        for p, a in zip(c.spec.params, c.args):
            assert type(a) is int if p.kind == "int" else type(a) in (int, float)


@SETTINGS
@given(st.binary(max_size=40))
def test_parse_never_raises_anything_else(data):
    try:
        parse_content(data)
    except ContentError as err:
        assert err.offset is not None and 0 <= err.offset <= len(data)


@SETTINGS
@given(st.text(alphabet="movextjinlpawckfsu(),.-0123456789", max_size=30))
def test_parse_near_miss_text(text):
    try:
        cs = parse_content(text)
    except ContentError:
        return
    assert parse_content(format_content(cs)) == cs


def test_split_layers():
    cs = parse_content("ack(2,17)movex(1)poll(5,13)stop()crc(4660)")
    mac, app = split_layers(cs)
    assert [c.name for c in mac] == ["ack", "poll", "crc"]
    assert [c.name for c in app] == ["movex", "stop"]
    assert split_layers(()) == ((), ())
    assert cs[0].layer == "mac" and cs[1].layer == "app"


def _one_at_a_time(data: bytes):
    """The reader before the remembered fast path: every command read where it stands."""
    from firmware_model.radio.content import _parse_one
    out, i = [], 0
    while i < len(data):
        c, i = _parse_one(data, i)
        out.append(c)
    return tuple(out)


def _outcome(fn, data: bytes):
    try:
        return "ok", fn(data)
    except ContentError as exc:
        return "error", (str(exc), exc.field, exc.offset, exc.byte)


_PIECES = st.sampled_from([
    b"movex(", b"moveto(", b"joint(", b"ack(", b"fail(", b"status(", b"paw(", b"crc(",
    b"bogus(", b"wheel(", b")", b",", b"-", b".", b"0", b"1", b"12", b"123456789",
    b"1.5", b"1.2345", b"4", b"-7", b"300", b"999999999999999", b"x", b" ", b"(", b"_a(",
])


_WHOLE = st.sampled_from([
    b"movex(1)", b"movex(123456789)", b"moveto(1.5,-2,0)", b"joint(2,150)", b"ack(3,17)",
    b"status()", b"done()", b"joint(9,1)", b"movex(1.2345)", b"bogus(1)", b"movex(1,2)",
    b"ack(3)", b"paw(1.5)", b"movex(9999999999999)",
])
"""Whole commands, good and bad, for the pieces to fall between."""


@settings(max_examples=500, deadline=None)
@given(st.lists(st.one_of(_WHOLE, _WHOLE, _PIECES), max_size=14).map(b"".join)
       | st.binary(max_size=40))
@example(b"movex(1),")
@example(b"movex(1)joint(9,1)status()")
@example(b"ack(3,17)movex(1.2345)")
@example(b"movex(1)movex(1)(")
def test_the_fast_path_reads_content_as_the_command_by_command_reader(data):
    """parse_content takes well-shaped commands from a memo: commands, errors, their fields
    and offsets must be what reading every command where it stands gives, twice over (the
    second time from the memo)."""
    want = _outcome(_one_at_a_time, data)
    assert _outcome(parse_content, data) == want
    assert _outcome(parse_content, data) == want


def test_a_remembered_command_is_read_once_and_errors_keep_their_offsets():
    from firmware_model.radio.content import _known
    _known.cache_clear()
    content = b"movex(123456789)" * 14 + b"ack(3,17)"
    assert parse_content(content) == (cmd("movex", 123456789),) * 14 + (cmd("ack", 3, 17),)
    assert _known.cache_info().misses == 2 and _known.cache_info().hits == 13
    # a well-shaped command the checks refuse is read where it stands: the offset is there
    with pytest.raises(ContentError) as ei:
        parse_content(b"movex(1)joint(9,10)")
    assert ei.value.offset == 14 and ei.value.field == "params"
