"""The F2MC-16LX CPU model (firmware_model/mcu/cpu.py) and the cycle-cost table.

Expected ticks are worked by hand from the manual's rules (entry 24, RETI 11 cycles; a higher
level preempts a body, nothing preempts the entry sequence or RETI; one level waits, the lower
interrupt number first), not taken from the model's constants.
"""
from __future__ import annotations

import json
import math
import subprocess
import sys

import pytest

from firmware_model import kinematics
from firmware_model.cycle_costs import (
    DEFAULT_COSTS, FORWARD_OPS, INVERSE_OPS, Cost, load_costs, message_cycles, replace,
)
from firmware_model.isa.listing import count
from firmware_model.mcu.cpu import Cpu, Vector
from firmware_model.mcu.scheduler import Scheduler
from firmware_model.radio.content import cmd
from firmware_model.timing import CHILD_BYTE_TICKS, PC_BYTE_TICKS
from paths import ROOT

HIGH = Vector("high", level=1, number=1)
MID = Vector("mid", level=3, number=2)
LOW_A = Vector("low a", level=4, number=3)
LOW_B = Vector("low b", level=4, number=4)
OFF = Vector("off", level=7, number=9)


def make():
    sched = Scheduler()
    return sched, Cpu(sched, DEFAULT_COSTS)


def test_one_handler_costs_entry_body_and_reti():
    sched, cpu = make()
    seen = []
    cpu.irq(LOW_A, 100, lambda: seen.append(("effect", sched.now)),
            enter=lambda: seen.append(("enter", sched.now)))
    sched.run_until(1000)
    assert seen == [("enter", 24), ("effect", 124)]
    assert cpu.stats["low a"].busy == 24 + 100 + 11
    assert cpu.busy == 135 and cpu.idle


def test_a_higher_level_preempts_a_body_and_the_lower_finishes_later():
    sched, cpu = make()
    seen = []
    cpu.irq(LOW_A, 1000, lambda: seen.append(("low", sched.now)))
    sched.at(100, lambda: cpu.irq(HIGH, 50, lambda: seen.append(("high", sched.now))))
    sched.run_until(5000)
    # high: accepted at 100 (low's entry ended at 24), effect at 100 + 24 + 50 = 174, RETI
    # to 185; low had done 76 of its 1000 body cycles: effect at 185 + 924 = 1109
    assert seen == [("high", 174), ("low", 1109)]
    assert cpu.stats["high"].worst_latency == 0
    assert cpu.stats["low a"].worst_response == 1109


def test_nothing_preempts_the_entry_sequence_or_reti():
    sched, cpu = make()
    seen = []
    cpu.irq(LOW_A, 100, lambda: seen.append(("low", sched.now)))
    sched.at(10, lambda: cpu.irq(HIGH, 10, lambda: seen.append(("high", sched.now))))
    # a request during low's RETI (169..180, see below) waits for it
    sched.at(175, lambda: cpu.irq(MID, 10, lambda: seen.append(("mid", sched.now))))
    sched.run_until(5000)
    # high accepted at 24 (end of low's entry): effect 24 + 24 + 10 = 58, RETI to 69;
    # low's body then runs 69..169, effect 169, RETI to 180; mid accepted at 180 -> 214
    assert seen == [("high", 58), ("low", 169), ("mid", 214)]
    assert cpu.stats["high"].worst_latency == 14
    assert cpu.stats["mid"].worst_latency == 5


def test_one_level_waits_and_the_lower_interrupt_number_goes_first():
    sched, cpu = make()
    seen = []
    cpu.irq(MID, 200, lambda: seen.append(("mid", sched.now)))
    sched.at(50, lambda: cpu.irq(LOW_B, 10, lambda: seen.append(("b", sched.now))))
    sched.at(60, lambda: cpu.irq(LOW_A, 10, lambda: seen.append(("a", sched.now))))
    sched.at(70, lambda: cpu.irq(MID, 10, lambda: seen.append(("mid2", sched.now))))
    sched.run_until(5000)
    # mid: effect 224, RETI to 235; then mid2 (level 3 before level 4): 235+34 = 269, to 280;
    # then a (number 3 before b's 4): 280+34 = 314, to 325; b: 325+34 = 359
    assert seen == [("mid", 224), ("mid2", 269), ("a", 314), ("b", 359)]


def test_level_7_is_never_accepted():
    sched, cpu = make()
    seen = []
    cpu.irq(OFF, 10, lambda: seen.append(sched.now))
    sched.run_until(1000)
    assert seen == [] and "off" not in cpu.stats


def test_main_loop_work_runs_under_every_interrupt():
    sched, cpu = make()
    seen = []
    cpu.task("main", 1000, lambda: seen.append(("task", sched.now)))
    cpu.task("main", 10, lambda: seen.append(("task2", sched.now)))
    sched.at(500, lambda: cpu.irq(LOW_A, 100, lambda: seen.append(("irq", sched.now))))
    sched.run_until(5000)
    # the task has 500 cycles done at 500; the ISR takes 500..635 (effect at 624); the task
    # resumes for its last 500: 1135; the second task follows: 1145
    assert seen == [("irq", 624), ("task", 1135), ("task2", 1145)]
    assert cpu.stats["main"].worst_latency == 1135


def test_extend_keeps_the_handler_busy_after_its_effects():
    sched, cpu = make()
    seen = []
    cpu.irq(MID, 100, lambda: cpu.extend(1000))
    sched.at(1, lambda: cpu.irq(LOW_A, 10, lambda: seen.append(sched.now)))
    sched.run_until(5000)
    # mid: 24 + 100 + 1000 + 11 = 1135 cycles; low then 1135 + 24 + 10
    assert seen == [1169]
    assert cpu.stats["mid"].busy == 1135


def test_the_ideal_cpu_takes_no_time():
    sched = Scheduler()
    cpu = Cpu(sched)
    seen = []
    sched.at(7, lambda: cpu.irq(LOW_A, 10_000, lambda: seen.append(sched.now),
                                enter=lambda: seen.append(("enter", sched.now))))
    sched.at(8, lambda: cpu.task("main", 10_000, lambda: seen.append(sched.now)))
    sched.run_until(100)
    assert seen == [("enter", 7), 7, 8] and cpu.busy == 0


def test_a_vector_level_outside_0_7_is_refused():
    with pytest.raises(ValueError, match="0-7"):
        Vector("bad", level=8, number=1)


# -- the cost table --------------------------------------------------------------------------


class _Counting:
    """math with its transcendental functions counted."""

    def __init__(self):
        self.calls = {}

    def __getattr__(self, name):
        f = getattr(math, name)
        if not callable(f):
            return f

        def counted(*a):
            self.calls[name] = self.calls.get(name, 0) + 1
            return f(*a)
        return counted


def test_the_kinematics_op_counts_match_the_code(monkeypatch):
    m = _Counting()
    monkeypatch.setattr(kinematics, "math", m)
    kinematics.forward((10.0, 45.0, -90.0, 45.0))
    assert m.calls == {"radians": 4, "sin": 4, "cos": 4, "degrees": 1}
    assert FORWARD_OPS["f_sin"] == 4 and FORWARD_OPS["f_cos"] == 4
    assert FORWARD_OPS["f_mul"] >= 5            # the 5 conversions are multiplications
    # the worst case of inverse: elbow up breaks a limit, elbow down is taken
    worst = None
    for x in range(10, 330, 10):
        for z in range(-100, 400, 10):
            m.calls = {}
            try:
                q = kinematics.inverse(float(x), 0.0, float(z), -120.0)
            except kinematics.Unreachable:
                continue
            if q[2] > 0:                        # elbow down
                worst = dict(m.calls)
                break
        if worst:
            break
    assert worst is not None, "no target needs the elbow-down solution"
    counted = {f"f_{k}": v for k, v in worst.items() if k in ("hypot", "atan2", "acos",
                                                              "sin", "cos")}
    assert counted == {k: INVERSE_OPS[k] for k in counted}
    assert set(counted) == {"f_hypot", "f_atan2", "f_acos", "f_sin", "f_cos"}
    assert INVERSE_OPS["f_mul"] >= worst["radians"] + worst["degrees"]


def test_a_move_costs_more_than_a_joint_order():
    move = message_cycles((cmd("movex", 10),))
    joint = message_cycles((cmd("joint", 1, 20),))
    trig = (FORWARD_OPS["f_sin"] * DEFAULT_COSTS.f_sin.cycles
            + FORWARD_OPS["f_cos"] * DEFAULT_COSTS.f_cos.cycles)
    assert move > joint + trig        # the float library's trigonometry alone


def test_a_cost_file_overrides_rows(tmp_path):
    p = tmp_path / "costs.toml"
    p.write_text("[costs]\nuart_rx_byte = 300\nf_sin = 900\n")
    c = load_costs(p)
    assert c.uart_rx_byte.cycles == 300 and c.f_sin.cycles == 900
    assert c.entry == DEFAULT_COSTS.entry
    assert f"was {DEFAULT_COSTS.uart_rx_byte.cycles}" in c.uart_rx_byte.source


def test_a_cost_file_takes_a_listing_of_your_own(tmp_path):
    (tmp_path / "enter.asm").write_text("MOV RP, #1\n")
    (tmp_path / "rx.asm").write_text(".include enter\nMOV A, I:SIDR0\nMULUW A\n")
    p = tmp_path / "costs.toml"
    p.write_text('[costs]\nf_sin = 900\n[listings]\nuart_rx_byte = "rx.asm"\n')
    c = load_costs(p)
    assert c.uart_rx_byte.cycles == 2 + 3 + 11 and c.f_sin.cycles == 900
    assert c.uart_rx_byte.source.startswith("listing: rx.asm, 3 instructions (was ")
    assert c.can_rx == DEFAULT_COSTS.can_rx


@pytest.mark.parametrize("text, words", [
    ('[listings]\nuart_rx_byte = "nowhere.asm"\n', "no listing nowhere.asm"),
    ('[listings]\nuart_rx_byte = 3\n', "must name a listing"),
    ('[listings]\nuart_rx = "a.asm"\n', "no cost named 'uart_rx'"),
    ('[costs]\nuart_rx_byte = 3\n[listings]\nuart_rx_byte = "a.asm"\n', "under [costs] and"),
    ('[listings]\nuart_rx_byte = "bad.asm"\n', "bad.asm:1: BNE x: BNE is a conditional"),
    ("[costs]\nuart_rx = 3\n", "no cost named 'uart_rx'"),
    ("[costs]\nentry = -1\n", "whole number of cycles"),
    ("[costs]\nentry = 2.5\n", "whole number of cycles"),
    ("entry = 3\n", "[costs] table"),
    ("[costs\n", "not TOML"),
])
def test_a_bad_cost_file_says_what_is_wrong(tmp_path, text, words):
    (tmp_path / "bad.asm").write_text("BNE x\n")
    p = tmp_path / "c.toml"
    p.write_text(text)
    with pytest.raises(ValueError, match=None) as exc:
        load_costs(p)
    assert words in str(exc.value)


def test_a_missing_cost_file_is_a_clear_error(tmp_path):
    with pytest.raises(ValueError, match="cannot read the cost table"):
        load_costs(tmp_path / "none.toml")


def test_every_row_names_its_source():
    for name, row in DEFAULT_COSTS.rows():
        assert isinstance(row, Cost) and row.cycles >= 0
        assert row.source.split(":")[0] in ("manual", "listing", "estimate"), name
        assert row.good_for, name


# -- the child on the CPU model -----------------------------------------------------------------


def _world(costs, on_event=None, **kw):
    from hil.sim.world import SimConfig, World
    return World(SimConfig(robots=kw.pop("robots", (0, 1, 2)), duration=kw.pop("duration", 8),
                           cpu=costs, keep_records=True, **kw), on_event=on_event)


def test_rdrf_comes_at_the_stop_bits_sample_half_a_bit_before_it_ends():
    """The UART samples each bit in the middle of its own bit time from the start edge
    (MAME's f2mc16_uart.cpp), and sets RDRF at the stop bit's sample: 9.5 of its bits after
    the edge, 15 808 ticks for a child. So a byte from a child is taken 832 ticks (half a bit)
    before its stop bit ends, one from the father (a PC at exact 9600 baud) 859 ticks before;
    the firmware is still given the stop bit's end (docs/protocol.md §2). On an idle CPU the
    handler's effects come entry + body after RDRF."""
    from firmware_model.mcu.uart import Uart
    from firmware_model.mcu.scheduler import Scheduler
    u = Uart(Scheduler())
    assert u.rx_lead(CHILD_BYTE_TICKS) == 0             # the ideal CPU: at the stop bit's end
    w = _world(DEFAULT_COSTS, robots=(0, 1, 2), duration=5)
    u = w.stations[2].uart
    assert u.rx_lead(CHILD_BYTE_TICKS) == CHILD_BYTE_TICKS // 20 == 832
    assert u.rx_lead(PC_BYTE_TICKS) == PC_BYTE_TICKS - 19 * CHILD_BYTE_TICKS // 20 == 859
    seen: dict[int, list[int]] = {CHILD_BYTE_TICKS: [], PC_BYTE_TICKS: []}
    real = u.on_rx

    def spy(data, t0, dt, now=None, held=None):
        at = w.sched.now if now is None else now
        seen[dt].append(at - (t0 + (len(data) - 1) * dt))    # effects less the last date
        return real(data, t0, dt, now, held)

    u.on_rx = spy
    w.run()
    handler = DEFAULT_COSTS.entry.cycles + u.rx_cycles
    for dt, lead in ((CHILD_BYTE_TICKS, 832), (PC_BYTE_TICKS, 859)):
        assert len(seen[dt]) > 20
        assert min(seen[dt]) == handler - lead       # the earliest: an idle CPU


def test_dispatcher_latency_is_the_radio_handler_then_the_main_loop():
    """A joint order: the End byte's receive handler (entry + body), its MAC bookkeeping
    (extend) and RETI, then the main loop's parse and plan; then the CAN frame's SOF. The
    handler starts at RDRF, the End's stop-bit sample: 9.5 of the child's bits after the
    start edge, 859 ticks before the father's (9600-exact) stop bit ends, where the latency
    is counted from."""
    w = _world(DEFAULT_COSTS, can=True, duration=6)
    w.sched.at(4 * 16_000_000, lambda: w.submit(0, 1, [cmd("joint", 1, 20)]))
    w.run()
    c = DEFAULT_COSTS
    lead = PC_BYTE_TICKS - 19 * CHILD_BYTE_TICKS // 20
    assert lead == 859 == w.stations[1].uart.rx_lead(PC_BYTE_TICKS)
    floor = (c.entry.cycles + c.uart_rx_byte.cycles + c.mac_frame.cycles + c.reti.cycles +
             message_cycles((cmd("joint", 1, 20),))) - lead
    lat = [s - e for r, e, s in w.dispatch_latency if r == 1]
    assert lat, "the order produced no CAN frame"
    # the bus may be busy with a status frame (<= 135 bits at 2 us = 4320 ticks) at that tick
    assert floor <= lat[0] <= floor + 4320


def test_the_ideal_cpu_dispatches_on_the_tick():
    w = _world(None, can=True, duration=6)
    w.sched.at(4 * 16_000_000, lambda: w.submit(0, 1, [cmd("joint", 1, 20)]))
    w.run()
    lat = [s - e for r, e, s in w.dispatch_latency if r == 1]
    assert lat and max(lat) <= 4320          # only the CAN bus can make it wait


def test_a_ring_on_the_cpu_model_keeps_every_member_and_delivers():
    w = _world(DEFAULT_COSTS, robots=(0, 1, 2, 3), duration=12, load=1.0)
    w.run()
    s = w.summary()
    assert all(v["mode"] == "member" for v in s["robots"].values())
    assert s["delivered"] >= s["submitted"] - 3 and s["failed"] == 0
    assert s["collisions"] == 0
    assert all(v == 0 for v in s["cpu_overruns"].values())
    assert all(v == 0 for v in s["cpu_tx_gaps"].values())
    assert all(0 < v < 0.05 for v in s["cpu_load"].values())


def _loads(events) -> dict[int, dict[int, float]]:
    """CpuLoad events (or their records): robot -> {second's end (s) -> load}."""
    from hil.sim import events as E
    out: dict[int, dict[int, float]] = {}
    for ev in events:
        if isinstance(ev, dict):
            if ev.get("ev") != "cpu":
                continue
            ev = E.from_record(ev)
        if type(ev) is E.CpuLoad:
            assert ev.t % 16_000_000 == 0
            out.setdefault(ev.robot, {})[ev.t // 16_000_000] = ev.load
    return out


def test_each_second_traced_is_the_cpu_load_over_it_and_a_late_listener_gets_whole_seconds():
    """Listened from the start: one CpuLoad a child a second, which add up to its busy
    cycles. A listener added at 2.5 s gets the seconds from the fourth on, the same figures;
    nobody listening, no clock ticks the seconds (it would keep an idle ring from leaping)."""
    seen: list = []
    w = _world(DEFAULT_COSTS, on_event=seen.append, duration=6)
    w.run()
    full = _loads(seen)
    assert sorted(full) == [1, 2] and all(sorted(v) == [1, 2, 3, 4, 5, 6] for v in full.values())
    for r, per in full.items():
        assert min(per[s] for s in (3, 4, 5, 6)) > 0          # (joined by the third)
        assert abs(sum(per.values()) * 16_000_000 - w.cpus[r].busy) < 16_000_000 * 1e-5
    late: list = []
    w2 = _world(DEFAULT_COSTS, duration=6)
    w2.run(until=40_000_000)
    assert w2._cpu_clock is None
    w2.add_listener(late.append)
    w2.run()
    got = _loads(late)
    assert {r: sorted(v) for r, v in got.items()} == {1: [4, 5, 6], 2: [4, 5, 6]}
    assert got == {r: {s: v for s, v in per.items() if s >= 4} for r, per in full.items()}
    w2.remove_listener(late.append)
    assert w2._cpu_clock is None


def test_a_receive_handler_slower_than_a_byte_overruns_and_loses_bytes():
    slow = replace(DEFAULT_COSTS, uart_rx_byte=Cost(20_000, "test", "test"))
    w = _world(slow, robots=(0, 1), duration=6)
    w.run()
    s = w.summary()
    assert s["cpu_overruns"][1] > 0
    assert s["robots"][1]["mode"] == "listen" or s["robots"][1]["received"] == 0


def test_idle_noise_on_the_cpu_model_is_an_interrupt_a_byte_and_overruns_nothing():
    """A PTR2000 with no carrier outputs noise, a byte every 16 640 ticks: on the part each
    is a receive interrupt of 130 cycles, far inside a byte. Handed over in bursts, a second
    of noise queued a request a byte at once and the frame byte after it overran."""
    w = _world(DEFAULT_COSTS, robots=(1, 2, 3, 4), duration=20, noise=True, seed=0)
    w.run()
    assert w.summary()["cpu_overruns"] == {1: 0, 2: 0, 3: 0, 4: 0}
    for r, st in w.stations.items():
        rx = w.cpus[r].stats["UART0 RX"]
        assert st.uart.bytes_received > 20 * 500               # mostly noise
        assert rx.calls == st.uart.bytes_received
        assert max(rx.latency) < st.uart.byte_ticks           # no backlog


def test_a_transmit_handler_slower_than_a_byte_stretches_every_frame_it_sends():
    # 20 000 cycles a TDRE handler: each byte waits for the last one's handler, so every
    # frame a child sends has a gap after each byte; the father, a PC, sends back to back
    slow = replace(DEFAULT_COSTS, uart_tx_byte=Cost(20_000, "test", "test"))
    w = _world(slow, robots=(0, 1), duration=6)
    w.run()
    s = w.summary()
    u = w.stations[1].uart
    assert s["cpu_tx_gaps"][1] > 0 and u.gaps == s["cpu_tx_gaps"][1]
    # each gap: the handler's 24 + 20 000 cycles less the byte time, and more when it had to
    # wait for the previous handler's RETI (11) or a higher level
    assert u.gap_ticks >= u.gaps * (24 + 20_000 - u.byte_ticks)


def test_the_cpu_model_is_deterministic():
    traces = []
    for _ in range(2):
        evs = []
        _world(DEFAULT_COSTS, robots=(0, 1, 2), duration=6, can=True, load=1.0,
               on_event=evs.append).run()
        traces.append(evs)
    assert traces[0] == traces[1]
    assert any(e["ev"] == "cpu" for e in traces[0])


# -- the command line --------------------------------------------------------------------------


def rprs(*args):
    return subprocess.run([sys.executable, "-m", "hil.cli", *args], capture_output=True,
                          text=True, timeout=120)


def test_cpu_report_as_json():
    p = rprs("sim", "--robots", "0,1", "--duration", "5", "--can", "--load", "1",
             "--cpu-report", "--json", "--no-progress")
    assert p.returncode == 0, p.stderr
    summary = report = json.loads(p.stdout)         # one JSON document (json.load reads it)
    assert "cpu_load" in summary
    names = [h["handler"] for h in report["cpu_report"]["1"]["handlers"]]
    assert "UART0 RX" in names and "CAN0 RX" in names
    uart = next(h for h in report["cpu_report"]["1"]["handlers"] if h["handler"] == "UART0 RX")
    assert uart["worst_case_us"] < uart["deadline_us"]
    # the worst case adds what is not simulated: the instruction under way, and the fetch and
    # CAN buffer waits its listings count in their worst case
    extra = DEFAULT_COSTS.uart_rx_byte.worst_extra + DEFAULT_COSTS.mac_frame.worst_extra
    assert extra == (count("uart_rx_byte").worst - count("uart_rx_byte").cycles
                     + count("mac_frame").worst - count("mac_frame").cycles) > 0
    unsimulated = (DEFAULT_COSTS.sample_wait_max.cycles + extra) / 16
    assert abs(uart["worst_case_us"] - uart["response_us"][2] - unsimulated) <= 0.1
    # each handler's vector, ICR and the cost rows its cycles come from, with their sources
    assert (uart["vector"], uart["icr"]) == (37, 13)
    assert uart["costs"] == {
        "uart_rx_byte": {"cycles": DEFAULT_COSTS.uart_rx_byte.cycles, "source": "listing"},
        "mac_frame": {"cycles": DEFAULT_COSTS.mac_frame.cycles, "source": "listing"}}
    main = next(h for h in report["cpu_report"]["1"]["handlers"] if h["handler"] == "main loop")
    assert main["vector"] is None and main["costs"]["mul16"]["source"] == "manual"
    assert main["costs"]["f_sin"]["source"] == "listing"
    assert main["worst_case_us"] == main["response_us"][2]      # no instruction to wait for


def test_cpu_options_refuse_nonsense(tmp_path):
    p = rprs("sim", "--cpu", "ideal", "--cpu-report", "--no-progress")
    assert p.returncode == 2 and "Traceback" not in p.stderr
    assert "--cpu estimated" in p.stderr
    p = rprs("sim", "--cpu-costs", str(tmp_path / "none.toml"), "--no-progress")
    assert p.returncode == 2 and "cannot read the cost table" in p.stderr
    assert "Traceback" not in p.stderr


def test_docs_show_the_table_in_use():

    from firmware_model.cycle_costs import markdown_table
    doc = (ROOT / "docs" / "cpu.md").read_text()
    assert markdown_table() in doc


def test_report_quantiles_from_counted_values_match_a_sorted_list():
    import random
    from collections import Counter

    from hil.view.cpu_report import _pct
    rng = random.Random(4)
    values = [rng.choice((0, 0, 0, 16, 184, 1200, 61963)) for _ in range(1001)]
    for q in (0.0, 0.5, 0.99, 1.0):
        ref = sorted(values)[min(len(values) - 1, int(q * len(values)))]
        assert _pct(Counter(values), q) == ref
    assert _pct(Counter(), 0.5) == 0


# ---------------------------------------------------------------- UART transmission: TDRE
class _Line:
    """What a UART's TX pin drives, logged: bursts started and pauses."""

    def __init__(self):
        self.log = []

    def transmit(self, data, t0, bt):
        self.log.append(("burst", t0, bytes(data)))

    def pause(self, now):
        self.log.append(("pause", now))

    def sync(self, now):
        pass

    def rx_fall(self, after, now):
        return None


def _tx_rig(tx_byte):
    from firmware_model.interrupts import TX_END, UART0_RX, UART0_TX
    from firmware_model.mcu.uart import Uart
    sched = Scheduler()
    cpu = Cpu(sched, DEFAULT_COSTS)
    u = Uart(sched)
    u.line = _Line()
    done = []
    u.on_tx_done = lambda end: done.append((end, sched.now))
    u.attach_cpu(cpu, UART0_RX, 160, UART0_TX, tx_byte, TX_END, 200)
    return sched, cpu, u, done


def test_each_byte_is_a_transmit_interrupt_and_a_quick_handler_sends_back_to_back():
    sched, cpu, u, done = _tx_rig(48)
    assert u.byte_ticks == 16640
    u.send(b"\x01\x02\x03\x04\x05")
    sched.run_until(200_000)
    # byte k moves to the shift register at 16640 k: a TDRE request each; each handler writes
    # the next byte 24 + 48 cycles later, long before the byte shifting out ends
    assert u.line.log == [("burst", 0, b"\x01\x02\x03\x04\x05")]
    assert cpu.stats["UART0 TX"].calls == 5
    assert (u.gaps, u.gap_ticks) == (0, 0)
    # the last TDRE (at 4 x 16640 = 66560) arms the End's timer one byte time on: 83200;
    # its handler lowers TXEN when its entry ends, 24 cycles later
    assert done == [(83200, 83224)]
    assert cpu.stats["TX END"].calls == 1


def test_a_transmit_handler_slower_than_a_byte_leaves_gaps_worked_by_hand():
    body = 16640 + 1000
    sched, cpu, u, done = _tx_rig(body)
    u.send(b"\xAA\xBB\xCC")
    sched.run_until(200_000)
    # byte 0: 0..16640. Its TDRE handler: entry to 24, writes byte 1 at 24 + 17640 = 17664,
    # RETI to 17675. The shift register ran dry at 16640: a gap of 1024 ticks.
    # byte 1: 17664..34304; its TDRE waits for that RETI: accepted 17675, entry to 17699,
    # writes byte 2 at 17699 + 17640 = 35339 (gap from 34304: 1035), RETI to 35350.
    # byte 2: 35339..51979; its handler: accepted 35350, entry to 35374, no byte left: the
    # End's timer at 35374 - 24 + 16640 = 51990 (11 late: the RETI it waited for), armed at
    # the body's end, 35374 + 17640 = 53014, already past: the TX END request at 53014,
    # accepted after that handler's RETI at 53025, TXEN low at 53049.
    assert u.line.log == [("burst", 0, b"\xAA\xBB\xCC"), ("pause", 16640),
                          ("burst", 17664, b"\xBB\xCC"), ("pause", 34304),
                          ("burst", 35339, b"\xCC")]
    assert (u.gaps, u.gap_ticks) == (2, 1024 + 1035)
    assert done == [(51990, 53049)]


def test_the_ideal_cpu_path_still_sends_one_burst_and_ends_on_the_tick():
    from firmware_model.mcu.uart import Uart
    sched = Scheduler()
    u = Uart(sched)
    u.line = _Line()
    done = []
    u.on_tx_done = lambda end: done.append((end, sched.now))
    u.send(b"\x01\x02")
    sched.run_until(100_000)
    assert u.line.log == [("burst", 0, b"\x01\x02")] and done == [(33280, 33280)]


def test_a_lone_handler_on_the_cpu_models_scheduler_is_one_event():
    """A handler alone on an idle CPU, its ``enter`` for its body only: one event, at its
    body's end, on the scheduler that keeps places (the CPU model's worlds); two (the
    entry's end, then the body's) on the plain kernel. The same effects either way."""
    from firmware_model.mcu.scheduler import PlacedScheduler
    runs = []
    for sched in (PlacedScheduler(), Scheduler()):
        cpu = Cpu(sched, DEFAULT_COSTS)
        seen: list = []
        ran = 0
        cpu.irq(LOW_A, 100, lambda s=sched, seen=seen: seen.append(("effect", s.now)),
                enter=lambda s=sched, seen=seen: seen.append(("enter", s.now)), alone=True)
        while sched.step():
            ran += 1
        sched.run_until(1000)          # (its RETI, counted when next asked, is over)
        runs.append((ran, seen, cpu.busy))
    assert runs[0] == (1, [("enter", 124), ("effect", 124)], 135)
    assert runs[1] == (2, [("enter", 124), ("effect", 124)], 135)
