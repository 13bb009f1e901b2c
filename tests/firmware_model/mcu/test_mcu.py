"""MB90F549 peripheral models, tick-exact: scheduler, reload timer, UART, GPIO pin, PTR2000."""
from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware_model.mcu.gpio import OutputPin
from firmware_model.mcu.ptr2000 import Ptr2000
from firmware_model.mcu.reload_timer import PRESCALERS, ReloadTimer, plan_delay
from firmware_model.mcu.scheduler import Scheduler
from firmware_model.mcu.uart import BAUD_DIVISORS, Uart
from firmware_model.timing import (
    CHILD_BYTE_TICKS, PC_BYTE_TICKS, PTR2000_RX_READY_TICKS, PTR2000_TX_READY_TICKS, TICK_HZ,
    TTRANS_TICKS, UART_BIT_TICKS_9600,
)

# ---------------------------------------------------------------------------------------------
# Scheduler
# ---------------------------------------------------------------------------------------------


def test_same_tick_events_run_fifo():
    s = Scheduler()
    out = []
    for i in range(20):
        s.at(100, out.append, i)
    s.at(50, out.append, "early")
    s.run_until(100)
    assert out == ["early"] + list(range(20))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(0, 50), min_size=1, max_size=60))
def test_events_run_in_tick_then_insertion_order(times):
    s = Scheduler()
    out = []
    for i, t in enumerate(times):
        s.at(t, lambda i=i, t=t: out.append((t, i, s.now)))
    s.run_until(max(times))
    assert [(t, i) for t, i, _ in out] == sorted((t, i) for i, t in enumerate(times))
    assert all(now == t for t, _, now in out)      # now is the event's tick while it runs


def test_event_scheduled_at_current_tick_during_run_runs_after_queued_ones():
    s = Scheduler()
    out = []

    def first():
        out.append("first")
        s.at(s.now, out.append, "added-now")
        s.after(0, out.append, "added-after0")

    s.at(10, first)
    s.at(10, out.append, "second")
    s.run_until(10)
    assert out == ["first", "second", "added-now", "added-after0"]


def test_scheduling_in_the_past_raises():
    s = Scheduler()
    s.run_until(1000)
    with pytest.raises(ValueError, match="999"):
        s.at(999, lambda: None)
    with pytest.raises(ValueError):
        s.after(-1, lambda: None)
    s.at(1000, lambda: None)                         # now itself is allowed


def test_cancel_prevents_the_call():
    s = Scheduler()
    out = []
    ev = s.at(5, out.append, "cancelled")
    s.at(5, out.append, "kept")
    ev.cancel()
    assert len(s) == 1
    s.run_until(10)
    assert out == ["kept"]


def test_run_until_leaves_now_at_end():
    s = Scheduler()
    s.run_until(12345)
    assert s.now == 12345
    out = []
    s.at(20000, out.append, 1)
    s.at(20001, out.append, 2)
    s.run_until(20000)                               # inclusive end
    assert out == [1] and s.now == 20000
    s.run_until(30000)
    assert out == [1, 2] and s.now == 30000


def test_after_is_relative_to_now():
    s = Scheduler(start=700)
    out = []
    s.after(300, lambda: out.append(s.now))
    s.run_until(2000)
    assert out == [1000]


def test_next_time_skips_cancelled():
    s = Scheduler()
    assert s.next_time() is None
    a = s.at(10, lambda: None)
    b = s.at(20, lambda: None)
    s.at(30, lambda: None)
    assert s.next_time() == 10
    a.cancel()
    assert s.next_time() == 20
    b.cancel()
    assert s.next_time() == 30


def test_step_runs_next_live_event_and_reports_empty():
    s = Scheduler()
    out = []
    s.at(7, out.append, "a").cancel()
    s.at(9, out.append, "b")
    assert s.step() is True
    assert out == ["b"] and s.now == 9
    assert s.step() is False


# ---------------------------------------------------------------------------------------------
# Reload timer
# ---------------------------------------------------------------------------------------------


@settings(max_examples=200, deadline=None)
@given(st.integers(1, 500_000_000))
def test_plan_delay_reproduces_every_even_delay(half):
    ticks = 2 * half
    pre, first, full = plan_delay(ticks)
    assert pre == 2
    assert 0 <= first <= 0xFFFF
    assert full >= 0
    assert ((first + 1) + full * 65536) * pre == ticks


@settings(max_examples=200, deadline=None)
@given(st.sampled_from(PRESCALERS), st.integers(1, 10**9 // 32))
def test_plan_delay_other_prescalers(pre, n):
    pre_out, first, full = plan_delay(n * pre, pre)
    assert pre_out == pre and 0 <= first <= 0xFFFF
    assert ((first + 1) + full * 65536) * pre == n * pre


@pytest.mark.parametrize("ticks,expected", [
    (2, (2, 0, 0)),
    (131072, (2, 0xFFFF, 0)),        # exactly one full period
    (131074, (2, 0, 1)),             # one count more: first period 1, then one full
    (9_600_000, (2, 15871, 73)),        # Tmax: 73 full periods + 15872 counts
])
def test_plan_delay_boundaries(ticks, expected):
    assert plan_delay(ticks) == expected
    pre, first, full = expected
    assert ((first + 1) + full * 65536) * pre == ticks


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 500_000_000))
def test_plan_delay_rejects_odd(half):
    with pytest.raises(ValueError, match="not a positive whole number"):
        plan_delay(2 * half + 1)


@pytest.mark.parametrize("ticks", [0, -2, -1])
def test_plan_delay_rejects_zero_and_negative(ticks):
    with pytest.raises(ValueError):
        plan_delay(ticks)


def test_plan_delay_rejects_bad_prescaler_and_non_multiple():
    with pytest.raises(ValueError, match="prescaler"):
        plan_delay(64, 4)
    with pytest.raises(ValueError):
        plan_delay(12, 8)


def _timer(start=0):
    s = Scheduler(start)
    fired = []
    t = ReloadTimer(s, fired.append)
    return s, t, fired


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 10**6), st.integers(1, 10**8).map(lambda h: 2 * h))
def test_timer_fires_exactly_at_armed_tick(start, delay):
    s, t, fired = _timer(start)
    t.arm_at(start + delay)
    assert t.expiry == start + delay
    s.run_until(start + delay - 1)
    assert fired == []
    s.run_until(start + delay + 10**6)
    assert fired == [start + delay]
    assert t.expiry is None
    pre, first, full = t.registers
    assert ((first + 1) + full * 65536) * pre == delay


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 10**6), st.integers(1, 10**7), st.integers(0, 10**5),
       st.one_of(st.none(), st.integers(1, 10**7)))
def test_a_timer_programmed_and_stopped_without_an_event_is_as_armed_then_stopped(
        start, delay, later, pending):
    """``programmed(when, at)``, given later than the tick the firmware programmed it at
    (bytes whose handler armed it, given with the next byte's, which stopped it): the
    registers and state ``arm_at(when, at)`` then ``stop()`` leave, and nothing fires."""
    runs = []
    for way in ("arm and stop", "programmed"):
        s, t, fired = _timer(start)
        if pending is not None:
            t.arm_at(start + pending)            # armed before, for later or sooner
        s.run_until(start + later)
        at = start + later // 2                  # the firmware's tick, before now
        when = start + later + delay             # later than both (arm_at's contract)
        if way == "arm and stop":
            t.arm_at(when, at)
            t.stop()
        else:
            t.programmed(when, at)
        s.run_until(start + later + 2 * 10**7)
        runs.append((t.delay, t.expiry, t.registers if t.delay >= 2 else None, fired))
    assert runs[0] == runs[1]
    assert runs[0][1] is None                                 # stopped: no expiry
    # nothing fires after it was stopped (an earlier arming may have fired before)
    assert all(f <= start + later for f in runs[0][3]) and (pending or not runs[0][3])


def test_timer_rearm_later_moves_expiry_and_fires_once():
    s, t, fired = _timer()
    t.arm_at(1000)
    s.run_until(400)
    t.arm_at(5000)
    s.run_until(4999)
    assert fired == []
    s.run_until(100_000)
    assert fired == [5000]


def test_timer_rearm_earlier_fires_at_earlier_tick_once():
    s, t, fired = _timer()
    t.arm_at(5000)
    s.run_until(400)
    t.arm_at(1000)
    s.run_until(100_000)
    assert fired == [1000]


def test_timer_stop_prevents_firing():
    s, t, fired = _timer()
    t.arm_at(1000)
    s.run_until(500)
    t.stop()
    assert t.expiry is None
    s.run_until(100_000)
    assert fired == []
    # stop after a lazy re-arm (pending event earlier than the expiry) too
    t.arm_at(200_000)
    s.run_until(150_000)
    t.arm_at(300_000)
    t.stop()
    s.run_until(1_000_000)
    assert fired == []


@pytest.mark.parametrize("delay", [1, 3, 12345, 9_600_001])
def test_timer_odd_delay_rounded_up_one_tick(delay):
    s, t, fired = _timer(start=1000)
    t.arm_at(1000 + delay)
    assert t.expiry == 1000 + delay + 1
    s.run_until(1000 + delay)
    assert fired == []
    s.run_until(1000 + delay + 10)
    assert fired == [1000 + delay + 1]


def test_timer_can_be_rearmed_from_its_own_expiry():
    s = Scheduler()
    fired = []

    def on_expiry(now):
        fired.append(now)
        if len(fired) < 3:
            t.arm_at(now + 100)

    t = ReloadTimer(s, on_expiry)
    t.arm_at(100)
    s.run_until(10_000)
    assert fired == [100, 200, 300]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 300_000),
                          st.one_of(st.none(), st.integers(1, 400_000))),
                min_size=1, max_size=12))
def test_timer_matches_reference_model_under_rearm_and_stop(ops):
    """Random re-arms/stops: fires exactly once per arming not overridden, at the last armed
    (even-rounded) tick; the reference is the obvious eager model."""
    s, t, fired = _timer()
    expected = []
    pending = None
    for advance, delay in ops:
        target = s.now + advance
        if pending is not None and pending <= target:
            expected.append(pending)
            pending = None
        s.run_until(target)
        if delay is None:
            t.stop()
            pending = None
        else:
            pending = s.now + delay + (delay & 1)
            t.arm_at(s.now + delay)
            assert t.expiry == pending
        assert fired == expected
    s.run_until(s.now + 10**6)
    if pending is not None:
        expected.append(pending)
    assert fired == expected


# ---------------------------------------------------------------------------------------------
# UART
# ---------------------------------------------------------------------------------------------


class LineRecorder:
    def __init__(self):
        self.sent = []
        self.synced = []

    def transmit(self, data, t0, byte_ticks):
        self.sent.append((bytes(data), t0, byte_ticks))

    def sync(self, now):
        self.synced.append(now)


def test_uart_9600_timing():
    u = Uart(Scheduler())
    assert u.bit_ticks == 1664 == UART_BIT_TICKS_9600
    assert u.byte_ticks == 16640 == CHILD_BYTE_TICKS
    assert u.baud == pytest.approx(9615.38, abs=0.005)
    assert u.baud == TICK_HZ / 1664


@pytest.mark.parametrize("baud", sorted(BAUD_DIVISORS))
def test_uart_supported_bauds(baud):
    u = Uart(Scheduler(), baud=baud)
    assert u.byte_ticks == 10 * u.bit_ticks
    # the real rate is within 0.2 % of nominal for every supported setting
    assert abs(u.baud - baud) / baud < 0.002


@pytest.mark.parametrize("baud", [9601, 115200, 0, 300])
def test_uart_unsupported_baud_raises_clear_error(baud):
    with pytest.raises(ValueError) as exc:
        Uart(Scheduler(), baud=baud)
    msg = str(exc.value)
    assert str(baud) in msg and "9600" in msg and "38400" in msg


def test_uart_explicit_byte_ticks_for_pc():
    u = Uart(Scheduler(), byte_ticks=PC_BYTE_TICKS)
    assert u.byte_ticks == 16667
    assert u.baud == pytest.approx(9600, rel=2e-5)


@pytest.mark.parametrize("n", [1, 2, 14, 576])
def test_uart_send_completes_after_n_bytes(n):
    s = Scheduler(start=1000)
    u = Uart(s)
    line = LineRecorder()
    u.line = line
    done = []
    u.on_tx_done = lambda end: done.append((end, s.now))
    data = bytes(range(256)) * 3
    end = u.send(data[:n])
    assert end == 1000 + n * 16640
    assert line.sent == [(data[:n], 1000, 16640)]
    assert u.bytes_sent == n
    s.run_until(end - 1)
    assert done == []
    s.run_until(end + 100_000)
    assert done == [(end, end)]


def test_uart_send_while_busy_raises_and_free_at_exact_end():
    s = Scheduler()
    u = Uart(s)
    u.line = LineRecorder()
    end = u.send(b"abc")
    s.run_until(end - 1)
    with pytest.raises(RuntimeError, match="busy"):
        u.send(b"x")
    s.run_until(end)
    end2 = u.send(b"xy")                              # back to back, no idle bit
    assert end2 == end + 2 * 16640
    assert u.line.sent == [(b"abc", 0, 16640), (b"xy", end, 16640)]


def test_uart_receive_and_sync():
    s = Scheduler()
    u = Uart(s)
    line = LineRecorder()
    u.line = line
    got = []
    u.on_rx = lambda d, t0, dt: got.append((d, t0, dt))
    u.receive(b"hi", 33280, 16640)
    assert got == [(b"hi", 33280, 16640)] and u.bytes_received == 2
    u.sync(5)
    assert line.synced == [5]


# ---------------------------------------------------------------------------------------------
# OutputPin + PTR2000
# ---------------------------------------------------------------------------------------------


class ChannelRecorder:
    """A fake air: records what the radio puts on it and the deafen/restart calls."""

    def __init__(self):
        self.tx = []
        self.calls = []

    def transmit(self, radio, data, t0, bt):
        self.tx.append((bytes(data), t0, bt))

    def sync(self, radio, now):
        self.calls.append(("sync", now))

    def deafen(self, radio, now):
        self.calls.append(("deafen", now))

    def rx_restart(self, radio, when):
        self.calls.append(("rx_restart", when))


def _wired(start=0):
    s = Scheduler(start)
    u = Uart(s)
    r = Ptr2000(1)
    r.uart = u
    u.line = r
    pin = OutputPin("P40/TXEN")
    pin.listeners.append(r.set_txen)
    ch = ChannelRecorder()
    r.channel = ch
    return s, u, r, pin, ch


def test_output_pin_notifies_only_on_change():
    pin = OutputPin("P40")
    seen = []
    pin.listeners.append(lambda lvl, t: seen.append((lvl, t)))
    pin.set(False, 5)
    pin.set(1, 10)
    pin.set(True, 20)
    pin.set(0, 30)
    assert seen == [(True, 10), (False, 30)]
    assert pin.level is False and pin.changed_at == 30


def test_ptr2000_switch_times_are_the_nrf401_data_sheets_not_ttrans():
    """nRF401 Table 5: data may be sent 1 ms after TXEN rises and received 3 ms after it
    falls; the protocol's Ttrans (5 ms) is a guard longer than both, not the part's figure."""
    assert (PTR2000_TX_READY_TICKS, PTR2000_RX_READY_TICKS) == (16_000, 48_000)
    assert TTRANS_TICKS == 80_000 > PTR2000_RX_READY_TICKS > PTR2000_TX_READY_TICKS
    r = Ptr2000(1)
    assert (r.tx_ready_delay, r.rx_ready_delay) == (PTR2000_TX_READY_TICKS,
                                                    PTR2000_RX_READY_TICKS)


def test_ptr2000_loses_bytes_before_its_tx_ready_delay():
    s, u, r, pin, ch = _wired()
    pin.set(True, 0)
    s.run_until(PTR2000_TX_READY_TICKS - 1)
    end = u.send(b"early")
    assert r.lost_tx == 1 and ch.tx == []
    s.run_until(end)                                  # UART still shifts them out
    assert s.now == end
    s2, u2, r2, pin2, ch2 = _wired()
    pin2.set(True, 0)
    s2.run_until(PTR2000_TX_READY_TICKS)              # 1 ms: the part sends, Ttrans or not
    u2.send(b"ok")
    assert r2.lost_tx == 0 and ch2.tx == [(b"ok", PTR2000_TX_READY_TICKS, 16640)]


def test_ptr2000_switch_times_are_set_per_module():
    """A module with its own figures (here Ttrans both ways, the model before the data
    sheet's) loses a burst the data sheet's module sends, and hears later."""
    slow = Ptr2000(2, tx_ready_delay=TTRANS_TICKS, rx_ready_delay=TTRANS_TICKS)
    s = Scheduler()
    u = Uart(s)
    slow.uart, u.line = u, slow
    ch = ChannelRecorder()
    slow.channel = ch
    slow.set_txen(True, 0)
    s.run_until(PTR2000_TX_READY_TICKS)
    u.send(b"x")
    assert slow.lost_tx == 1 and ch.tx == []
    slow.set_txen(False, 200_000)
    assert not slow.listening(200_000 + PTR2000_RX_READY_TICKS)
    assert slow.listening(200_000 + TTRANS_TICKS)
    with pytest.raises(ValueError, match="switch times"):
        Ptr2000(3, tx_ready_delay=-1)


def test_ptr2000_txen_low_loses_bytes():
    s, u, r, pin, ch = _wired()
    u.send(b"no txen")
    assert r.lost_tx == 1 and ch.tx == []


def test_ptr2000_txen_high_then_low_before_send():
    s, u, r, pin, ch = _wired()
    pin.set(True, 0)
    s.run_until(100_000)
    pin.set(False, 100_000)
    u.send(b"x")
    assert r.lost_tx == 1 and ch.tx == []


def test_ptr2000_deaf_while_txen_high_and_hears_its_rx_ready_delay_after_low():
    s, u, r, pin, ch = _wired()
    assert r.listening(0)
    pin.set(True, 1000)
    assert ("deafen", 1000) in ch.calls
    for t in (1000, 81_000, 10**9):
        assert not r.listening(t)
    s.run_until(500_000)
    pin.set(False, 500_000)
    assert ("rx_restart", 548_000) in ch.calls        # 3 ms, not Ttrans (5 ms)
    assert not r.listening(547_999)
    assert r.listening(548_000)


def test_ptr2000_retoggle_resets_switch_time():
    s, u, r, pin, ch = _wired()
    pin.set(True, 0)
    pin.set(False, 10_000)
    pin.set(True, 20_000)
    s.run_until(35_999)
    u.send(b"a")
    assert r.lost_tx == 1
    s.run_until(36_000 + 16640)
    u.send(b"b")
    assert ch.tx == [(b"b", 36_000 + 16640, 16640)]


def test_dead_ptr2000_neither_sends_nor_hears():
    s, u, r, pin, ch = _wired()
    r.alive = False
    assert not r.listening(0) and not r.listening(10**9)
    pin.set(True, 0)
    s.run_until(TTRANS_TICKS)
    u.send(b"dead")
    assert ch.tx == []


def test_ptr2000_deliver_goes_to_uart():
    s, u, r, pin, ch = _wired()
    got = []
    u.on_rx = lambda d, t0, dt: got.append((d, t0, dt))
    r.deliver(b"ab", 16640, 16640)
    assert got == [(b"ab", 16640, 16640)]
