"""The fuzz targets' properties (fuzz/, docs/fuzzing.md) under hypothesis, short atheris runs,
and regression tests for the bugs the fuzzers found.

(a) The same checks the atheris targets run (fuzz/fuzz_*.py: ``check_deframer``,
    ``check_content``, ``check_station``), fed by hypothesis draws instead of fuzzer bytes,
    with a bounded budget.
(b) Each atheris target for a bounded number of runs in a subprocess (skipped without atheris).
(c) The findings (docs/fuzzing.md), each reduced to a fixed input.
"""
from __future__ import annotations

import os
import subprocess
import sys

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from budgets import quick_and_thorough
from paths import ROOT

from firmware_model.radio.content import Command, format_content
from firmware_model.radio.frame import Frame
from firmware_model.radio.mac import MacConfig, RotationalMac, Transmit
from firmware_model.timing import CHILD_BYTE_TICKS

FUZZ = ROOT / "fuzz"
sys.path.insert(0, str(FUZZ))  # the targets import each other's helpers by module name

import fuzz_content  # noqa: E402
import fuzz_deframer  # noqa: E402
import fuzz_station  # noqa: E402

BT = CHILD_BYTE_TICKS
BUDGET = settings(
    max_examples=300,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
QUICK = settings(BUDGET, max_examples=60)
"""The fast tier's budget for the three costliest properties; the slow tier runs each with
``BUDGET`` too (``_quick_and_thorough``)."""


def _quick_and_thorough(make):
    return quick_and_thorough(make, QUICK, BUDGET)


class HypSource:
    """The fuzz targets' decision source (int/bool/pick/bytes/more), drawn by hypothesis."""

    def __init__(self, data, continue_odds: int = 5) -> None:
        self.data = data
        self.odds = continue_odds

    def int(self, lo: int, hi: int) -> int:
        return self.data.draw(st.integers(lo, hi))

    def bool(self) -> bool:
        return self.data.draw(st.booleans())

    def pick(self, seq):
        return self.data.draw(st.sampled_from(list(seq)))

    def bytes(self, max_len: int) -> bytes:
        return self.data.draw(st.binary(max_size=max_len))

    def more(self) -> bool:
        return self.data.draw(st.integers(0, self.odds - 1)) > 0


# ------------------------------------------------------------------ (a) hypothesis versions


def _deframer_bulk_equals_bytewise_and_frames_reencode(data):
    max_content, chunks = fuzz_deframer.draw_plan(HypSource(data))
    fuzz_deframer.check_deframer(max_content, chunks)


test_deframer_bulk_equals_bytewise_and_frames_reencode, \
    test_deframer_bulk_equals_bytewise_and_frames_reencode_thoroughly = _quick_and_thorough(
        lambda budget: budget(given(st.data())(_deframer_bulk_equals_bytewise_and_frames_reencode)))


@BUDGET
@given(st.lists(st.tuples(st.binary(max_size=80), st.integers(1, 3 * BT), st.integers(1, BT),
                          st.booleans()), max_size=8),
       st.sampled_from(fuzz_deframer.MAX_CONTENTS))
def test_deframer_on_raw_chunks(chunks, max_content):
    fuzz_deframer.check_deframer(max_content, chunks)


@BUDGET
@given(st.binary(max_size=200))
def test_content_raises_only_content_error_and_round_trips(data):
    fuzz_content.check_content(data)


def _content_from_tokens(data):
    fuzz_content.check_content(fuzz_content.draw_tokens(HypSource(data, continue_odds=12)))


test_content_from_tokens, test_content_from_tokens_thoroughly = _quick_and_thorough(
    lambda budget: budget(given(st.data())(_content_from_tokens)))


@BUDGET
@given(st.lists(st.sampled_from(fuzz_content.TOKENS), max_size=30))
def test_content_token_lists(tokens):
    fuzz_content.check_content(b"".join(tokens))


def _station_never_raises_keeps_deadline_and_delivers_only_received_frames(checksum, data):
    # raw=True: half the plans let bytes reach the UART while the station transmits too
    robot, _, deaf, late, events = fuzz_station.draw_station_plan(HypSource(data), raw=True)
    fuzz_station.check_station(robot, checksum, deaf, late, events)


test_station_never_raises_keeps_deadline_and_delivers_only_received_frames, \
    test_station_never_raises_keeps_deadline_and_delivers_only_received_frames_thoroughly = \
    _quick_and_thorough(lambda budget: budget(pytest.mark.parametrize(
        "checksum", [False, True], ids=["plain", "checksum"])(given(data=st.data())(
            _station_never_raises_keeps_deadline_and_delivers_only_received_frames))))


def _poll_frame(robot: int, by: int, checksum: bool) -> bytes:
    body = Command("poll", (robot, (1 << robot) | (1 << by))).text().encode()
    if checksum:
        return fuzz_station.seal(robot, by, 0, 3, body).encode()
    return Frame(dst=robot, src=by, num=0, type=3, content=body).encode()


@pytest.mark.parametrize("checksum", [False, True], ids=["plain", "checksum"])
def test_station_plan_reaches_delivery(checksum):
    """The harness itself: an invitation, then a message for the station, is delivered once."""
    msg = format_content([Command("movex", (12,))])
    if checksum:
        frame = fuzz_station.seal(1, 2, 7, 2, msg).encode()
    else:
        frame = Frame(dst=1, src=2, num=7, type=2, content=msg).encode()
    if checksum:  # movex(92) under movex(12)'s checksum: refused
        bad = bytearray(fuzz_station.seal(1, 2, 8, 2, msg).encode())
        bad[18] = ord("9")
    else:         # another message, Number 8
        bad = Frame(dst=1, src=2, num=8, type=2, content=b"movex(92)").encode()
    events = [
        ("rx", 1000, _poll_frame(1, 2, checksum), BT, None),
        ("rx", 900_000, frame, BT, None),  # after the station's own turn
        ("rx", 900_000, bytes(bad), BT, None),
    ]
    res = fuzz_station.check_station(1, checksum, True, False, events)
    assert res["sent"] >= 2
    assert res["delivered"] == (1 if checksum else 2)


# ------------------------------------------------------------------ (b) atheris, bounded

try:
    import atheris  # noqa: F401
    HAVE_ATHERIS = True
except ImportError:
    HAVE_ATHERIS = False

ATHERIS_RUNS = {"fuzz_deframer.py": 20000, "fuzz_content.py": 20000, "fuzz_station.py": 2000}


@pytest.mark.skipif(not HAVE_ATHERIS, reason="atheris not installed (wheels for CPython "
                    "3.11-3.13 on x86-64 Linux; elsewhere pip install -e .[fuzz] builds it "
                    "with clang)")
@pytest.mark.parametrize("target", [pytest.param(t, marks=pytest.mark.slow)
                                    if t != "fuzz_content.py" else t for t in sorted(ATHERIS_RUNS)])
def test_atheris_target_runs_clean(target, tmp_path):
    env = dict(os.environ)
    env.pop("RPRS_FUZZ_RAW", None)
    (tmp_path / "corpus").mkdir()
    proc = subprocess.run(
        [sys.executable, str(FUZZ / target), f"-atheris_runs={ATHERIS_RUNS[target]}",
         "-seed=1", f"-artifact_prefix={tmp_path}/", str(tmp_path / "corpus")],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600,
    )
    tail = "\n".join((proc.stdout + proc.stderr).splitlines()[-40:])
    assert proc.returncode == 0, tail
    assert f"Done {ATHERIS_RUNS[target]} in" in proc.stderr, tail


# ------------------------------------------------------------------ (c) findings


def test_garbage_never_sets_a_past_deadline():
    """Finding 1 (fuzz_station): a member waits for robot 2. A stray 0x0F is held by the
    deframer as a partial Header; the next byte comes 5 byte-times later (robot 2's frame), so
    only then is the 0x0F reported as Garbage. on_garbage used to set the deadline to
    last + quiet_gap, already past."""
    mac = RotationalMac(1)
    mac.power_on(0)
    poll = Frame(dst=1, src=2, num=0, type=3, content=b"poll(1,6)")
    end = 5_000_000
    mac.on_frame(poll, end - (poll.nbytes - 1) * BT, end, end)   # invited: my turn
    t_send = mac.deadline
    acts = mac.on_timer(t_send)
    sent = [a for a in acts if isinstance(a, Transmit)]
    assert len(sent) == 1
    tx_end = t_send + len(sent[0].data) * BT
    mac.on_tx_done(tx_end)                                        # WAIT for robot 2
    assert mac.owner == 2 and mac.deadline == tx_end + MacConfig().tmax
    stray = tx_end + 200_000                                      # the 0x0F
    now = stray + 5 * BT                                          # the next byte
    mac.on_garbage(stray, stray, now)
    assert mac.deadline is None or mac.deadline >= now, (mac.phase, mac.deadline, now)


def test_garbage_never_sets_a_past_deadline_through_station():
    """Finding 1 end to end, every byte handed over at its own tick: after its turn the
    station waits for robot 2; a stray 0x0F, then 2's frame 5 byte-times later."""
    hb = Frame(dst=7, src=2, num=1, type=3).encode()
    events = [
        ("rx", 1000, _poll_frame(1, 2, False), BT, None),
        ("rx", 600_000, b"\x0f", BT, None),
        ("rx", 4 * BT, hb, BT, None),
    ]
    fuzz_station.check_station(1, False, True, False, events)


def test_frame_heard_while_sending_is_ignored():
    """Finding 2 (fuzz_station with RPRS_FUZZ_RAW=1; a PTR2000 is deaf while it transmits,
    so only raw input gets here): a frame reaching the UART while the station's own frame was
    on air handed the turn back, and the MAC sent again with UART0 still busy
    (RuntimeError 'transmitter busy')."""
    hb = Frame(dst=7, src=2, num=1, type=3).encode()
    events = [
        ("rx", 1000, _poll_frame(1, 2, False), BT, None),
        ("rx", 80_000 + 2 * BT, hb, 1, None),   # while the station's Boot frame is on air
    ]
    fuzz_station.check_station(1, False, False, False, events)
