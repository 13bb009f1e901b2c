"""The CPU model's fast paths (docs/fast-paths.md): a lone handler on an idle CPU runs without
the general path's dispatch (firmware_model/mcu/cpu.py, ``alone=True``), and the bytes of a
good frame come late while the receiver's CPU has nothing else to do (hil/sim/air.py,
``Reception.quiet``). Against the general path (``Cpu.fuse = False``, every byte at its tick):
the same ticks, effects and figures whatever else asks for the CPU meanwhile, and whole rings
give the same trace, event for event.
"""
from __future__ import annotations

import pytest

from firmware_model.cycle_costs import DEFAULT_COSTS
from firmware_model.mcu.cpu import Cpu, Vector
from firmware_model.mcu.scheduler import PlacedScheduler, Scheduler

RX = Vector("rx", level=1, number=37)
TOP = Vector("top", level=0, number=5)
SAME = Vector("same", level=1, number=38)
LOW = Vector("low", level=4, number=11)

BODY = 160
"""The lone handler's body (cycles): entry 24 + 160 + RETI 11 = 195 cycles in all."""


def _figures(cpu: Cpu) -> dict:
    cpu.settle()
    return {s.name: (s.calls, s.busy, sorted(s.latency.items()), sorted(s.response.items()),
                     s.worst_latency, s.worst_response) for s in cpu.stats.values()}


class _Deferred:
    """The owner of a request the CPU takes without an event (``Cpu.defer``): its effects
    noted as ``_run``'s lone handler notes them."""

    def __init__(self, sched: Scheduler, seen: list) -> None:
        self.sched, self.seen = sched, seen

    def enter(self) -> None:
        pass

    def fn(self) -> None:
        self.seen.append(("rx effect", self.sched.now))

    def ran_alone(self, due: int) -> None:
        self.seen.append(("rx effect", due))


def _run(fuse: bool, other: Vector | None, at: int, task: bool = False,
         extend: int = 0, ask_in_fn: bool = False,
         defer: bool = False) -> tuple[list, dict, int]:
    """A lone handler requested at tick 1000 and, ``at`` ticks later, another request of
    ``other`` (or a main-loop task): what happened when, each handler's figures, busy.
    ``defer``: the lone handler's request taken without an event (``Cpu.defer``)."""
    sched = PlacedScheduler()      # (the CPU model's: lone handlers stand in)
    cpu = Cpu(sched, DEFAULT_COSTS)
    cpu.fuse = fuse
    seen: list[tuple[str, int]] = []
    reg = []
    if defer:
        owner = _Deferred(sched, seen)

        def take() -> None:
            assert cpu.defer(RX, BODY, owner)
            assert not cpu.quiescent(sched.now)
        sched.at(1000, take)

    def enter():
        reg.append(sched.now)

    def body():
        seen.append(("rx effect", sched.now))
        if extend:
            cpu.extend(extend)
        if ask_in_fn:
            cpu.irq(LOW, 30, lambda: seen.append(("asked by rx", sched.now)))

    if not defer:
        sched.at(1000, lambda: cpu.irq(RX, BODY, body, enter=enter, alone=True))
    if task:
        sched.at(1000 + at, lambda: cpu.task("main", 50, lambda: seen.append(("task",
                                                                              sched.now))))
    elif other is not None:
        sched.at(1000 + at, lambda: cpu.irq(other, 40, lambda: seen.append((other.name,
                                                                            sched.now))))
    sched.at(1000 + at, lambda: seen.append(("idle?", int(cpu.idle))))
    sched.run_until(5000)
    seen.append(("idle at end", int(cpu.idle)))
    return seen, _figures(cpu), cpu.busy


OFFSETS = sorted({0, 1, 12, 23, 24, 25, 100, 183, 184, 185, 190, 194, 195, 196, 400})
"""Ticks after the lone handler's request: in its entry (0-23), body (24-183), RETI (184-194)
and after it (195 on), with each boundary and its neighbours."""


@pytest.mark.parametrize("other", [TOP, SAME, LOW], ids=lambda v: v.name)
@pytest.mark.parametrize("at", OFFSETS)
def test_a_request_while_a_lone_handler_runs_is_taken_as_on_the_general_path(other, at):
    fused = _run(True, other, at)
    assert fused == _run(False, other, at)
    assert ("rx effect", 1000 + 24 + BODY) in fused[0] or other is TOP


@pytest.mark.parametrize("at", OFFSETS)
def test_a_task_while_a_lone_handler_runs_waits_as_on_the_general_path(at):
    assert _run(True, None, at, task=True) == _run(False, None, at, task=True)


@pytest.mark.parametrize("other", [TOP, SAME, LOW, None], ids=lambda v: getattr(v, "name",
                                                                               "task"))
@pytest.mark.parametrize("at", OFFSETS)
def test_a_request_taken_without_an_event_is_counted_as_on_the_general_path(other, at):
    """``Cpu.defer``: touched in its entry, body or RETI it goes on as a lone handler from
    its tick; touched after its RETI it was counted run alone; either way the general
    path's ticks, effects and figures."""
    deferred = _run(True, other, at, task=other is None, defer=True)
    assert deferred == _run(False, other, at, task=other is None)
    assert ("rx effect", 1000 + 24 + BODY) in deferred[0] or other is TOP


def test_a_request_is_not_taken_without_an_event_where_something_may_meet_it():
    sched = PlacedScheduler()      # (the CPU model's: lone handlers stand in)
    cpu = Cpu(sched, DEFAULT_COSTS)
    owner = _Deferred(sched, [])
    sched.at(100, lambda: cpu.irq(RX, BODY, lambda: None, alone=True))
    sched.run_until(150)
    assert not cpu.defer(LOW, 40, owner)            # a lone handler runs
    sched.run_until(1000)
    cpu.late_clear = lambda now, until: until < 1100
    assert not cpu.defer(LOW, 80, owner)            # a byte handed over late at 1100 would
    #                                                 meet it (RETI done at 1000 + 115)
    assert cpu.defer(LOW, 20, owner)                # over by then: 1000 + 55
    assert not cpu.defer(LOW, 20, owner)            # the first still runs
    cpu.fuse = False
    sched.run_until(2000)
    assert not cpu.defer(LOW, 20, owner)            # every handler on the general path


@pytest.mark.parametrize("at", [0, 100, 184, 200, 240, 260, 400])
@pytest.mark.parametrize("ask", [False, True])
def test_a_lone_handler_that_extends_itself_or_asks_for_the_cpu(at, ask):
    """``extend`` from its body (the MAC's bookkeeping on a frame's End) makes the body longer,
    preemptible by a higher level; a request made by its body waits for its RETI."""
    for other in (TOP, LOW):
        assert _run(True, other, at, extend=60, ask_in_fn=ask) == \
            _run(False, other, at, extend=60, ask_in_fn=ask)


def test_a_lone_handler_alone_costs_what_the_general_path_says():
    seen, figures, busy = _run(True, None, 10_000)
    assert seen[:1] == [("rx effect", 1184)]
    assert figures["rx"] == (1, 195, [(0, 1)], [(184, 1)], 0, 184)
    assert busy == 195


@pytest.mark.parametrize("fuse", [True, False])
def test_busy_counts_a_lone_handler_once_its_reti_event_would_have_run(fuse):
    """Readers scheduled before the body ended see the handler running at the tick its RETI
    ends (the general path's RETI event comes after them); after that tick it is counted."""
    sched = PlacedScheduler()      # (the CPU model's: lone handlers stand in)
    cpu = Cpu(sched, DEFAULT_COSTS)
    cpu.fuse = fuse
    cpu.irq(RX, BODY, lambda: None, alone=True)
    marks = []
    for t in (100, 194, 195, 196):
        sched.at(t, lambda: marks.append((sched.now, cpu.busy, cpu.idle)))
    sched.run_until(1000)
    assert marks == [(100, 0, False), (194, 0, False), (195, 0, False), (196, 195, True)]


def _two_receivers(fuse: bool, how: str, a_touched: int, a_first: bool) -> tuple:
    """Two robots' CPUs, A and B, request one byte's receive handler at tick 1000 (in radio
    order: A first if ``a_first``), each ending at 1000 + 24 + BODY and its RETI at 1195;
    a request comes on A at ``a_touched`` (its body, which moves its body's end on, or its
    RETI) and one on B in its RETI (1188). B's handler is counted late on the fast paths
    (``how``: taken without an event, ``Cpu.defer``; or a byte handed over late at the
    touch, ``Cpu.lone_past``), as a sleeping CAN side's ghost or a quiet reception's byte
    is. What each CPU's request did when, in the order it was done, and the figures."""
    sched = PlacedScheduler()      # (the CPU model's: lone handlers stand in)
    a = Cpu(sched, DEFAULT_COSTS, "A", order=1 if a_first else 5)
    b = Cpu(sched, DEFAULT_COSTS, "B", order=5 if a_first else 1)
    a.fuse = b.fuse = fuse
    seen: list[tuple[str, int]] = []
    owner = _Deferred(sched, [])

    def requests() -> None:
        for cpu in sorted((a, b), key=lambda c: c.order):
            if cpu is a:
                a.irq(RX, BODY, lambda: None, alone=True)
            elif not fuse:
                b.irq(RX, BODY, owner.fn, enter=owner.enter, alone=True)
            elif how == "defer":
                assert b.defer(RX, BODY, owner)

    def on_b() -> None:
        if fuse and how == "late":
            b.lone_past(RX, BODY, 1000, 16_640, 1)     # (the UART's, as it is touched)
        b.irq(LOW, 40, lambda: seen.append(("B", sched.now)))

    sched.at(1000, requests)
    sched.at(a_touched, lambda: a.irq(LOW, 40, lambda: seen.append(("A", sched.now))))
    sched.at(1188, on_b)
    sched.run_until(5000)
    return seen, _figures(a), _figures(b)


@pytest.mark.parametrize("a_first", [True, False])
@pytest.mark.parametrize("a_touched", [1030, 1186])
@pytest.mark.parametrize("how", ["defer", "late"])
def test_handlers_of_two_cpus_ending_at_one_tick_keep_the_general_paths_order(how, a_touched,
                                                                             a_first):
    """A handler counted late (or a lone one) that a request finds in its RETI has that RETI's
    event where the general path's, made by the body's end, is among the events of its tick:
    before another CPU's RETI whose body's end a request moved on, after one requested
    before it at one tick (sleep_hunt --cpu, seed 509: two children's CAN receive handlers
    waiting for one byte's RETI, their effects at one tick in the other order)."""
    general = _two_receivers(False, how, a_touched, a_first)
    assert _two_receivers(True, how, a_touched, a_first) == general
    assert [who for who, _ in general[0]] == \
        (["B", "A"] if a_touched == 1030 or not a_first else ["A", "B"])


class _Line:
    """The UART's TX line, noting what reaches it: (tick, what, detail)."""

    def __init__(self, sched, log):
        self.sched, self.log = sched, log

    def transmit(self, data, t0, bt):
        self.log.append((self.sched.now, "on air", (len(data), t0)))

    def pause(self, now):
        self.log.append((self.sched.now, "pause", now))

    def sync(self, now):
        pass

    def rx_fall(self, after, now):
        return None


def _send(fuse: bool, at: int | None, level: Vector = LOW,
          ask_on_done: Vector | None = None) -> tuple[list, dict, int]:
    """A UART on the CPU model sends 8 bytes from tick 1000; at ``at`` another handler asks
    for the CPU (``ask_on_done``: one asks from the End's handler's entry, where TXEN
    falls): what reached the line, the End's handler, every handler's figures."""
    from firmware_model.interrupts import TX_END, UART0_RX, UART0_TX
    from firmware_model.mcu.uart import Uart
    sched = PlacedScheduler()      # (the CPU model's: lone handlers stand in)
    cpu = Cpu(sched, DEFAULT_COSTS)
    cpu.fuse = fuse
    log: list = []
    u = Uart(sched)
    u.line = _Line(sched, log)
    u.attach_cpu(cpu, UART0_RX, 160, UART0_TX, 48, TX_END, 200)

    def done(end):
        log.append((sched.now, "TX done", end))
        if ask_on_done is not None:
            cpu.irq(ask_on_done, 300, lambda: log.append((sched.now, "asked", None)))
    u.on_tx_done = done
    sched.at(1000, u.send, bytes(range(8)))
    if at is not None:
        sched.at(at, lambda: cpu.irq(level, 300, lambda: log.append((sched.now, level.name,
                                                                        None))))
    sched.run_until(400_000)
    return log, _figures(cpu), cpu.busy


def _tdre(k: int) -> int:
    """Tick byte k of the frame moves into the shift register (its TDRE)."""
    return 1000 + k * 16640


@pytest.mark.parametrize("at", sorted({_tdre(k) + d for k in range(8)
                                       for d in (-1, 0, 1, 23, 24, 71, 72, 82, 83, 500)}))
@pytest.mark.parametrize("level", [TOP, LOW], ids=lambda v: v.name)
def test_a_request_while_transmit_handlers_run_late_is_taken_as_on_the_general_path(at,
                                                                                   level):
    """A frame's transmit handlers (entry 24 + 48 + RETI 11 cycles each) counted late while
    the CPU is idle: a request at and around every TDRE, before and after each handler's
    effects and RETI, finds the CPU, SODR and the shift register as the general path has
    them; the line and the End's handler see the same ticks."""
    fused = _send(True, at, level)
    assert fused == _send(False, at, level)
    assert any(what == "TX done" for _, what, _ in fused[0])


def test_a_frame_sent_on_an_idle_cpu_is_counted_as_on_the_general_path():
    assert _send(True, None) == _send(False, None)


END = _tdre(8)
"""The End's stop-bit tick: TX END's request (entry 24 + 200 + RETI 11 cycles)."""


@pytest.mark.parametrize("at", [END + d for d in (-1, 0, 1, 23, 24, 25, 100, 223, 224, 225,
                                                  234, 235, 236, 300)])
@pytest.mark.parametrize("level", [TOP, SAME, LOW], ids=lambda v: v.name)
def test_the_ends_handler_alone_lowers_txen_at_its_entry_as_on_the_general_path(at, level):
    """TX END runs alone on an idle CPU, its ``enter`` (TXEN falls: others see it) at the
    entry's end as on the general path (``irq``'s ``enter_now``): a request of each level at
    and around its entry, body and RETI ends finds it as the general path has it."""
    fused = _send(True, at, level)
    assert fused == _send(False, at, level)
    assert [t for t, what, _ in fused[0] if what == "TX done"] == [END + 24] or at <= END


@pytest.mark.parametrize("level", [TOP, SAME, LOW], ids=lambda v: v.name)
def test_a_request_from_the_ends_entry_waits_for_it_as_on_the_general_path(level):
    fused = _send(True, None, ask_on_done=level)
    assert fused == _send(False, None, ask_on_done=level)
    assert any(what == "asked" for _, what, _ in fused[0])


CASES = {
    "5-ring, load 2, CAN": dict(robots=(0, 1, 2, 3, 4), duration=8.0, can=True, load=2.0,
                                seed=1),
    "radio only, byte errors": dict(robots=(1, 2, 3), duration=8.0, load=2.0, seed=3,
                                    ber=0.002),
    "idle noise": dict(robots=(1, 2, 3), duration=6.0, load=1.0, seed=4, noise=True),
    "authenticated (main-loop hashing)": dict(robots=(0, 1, 2), duration=6.0, load=1.0,
                                              seed=5, auth=True),
    "7-ring saturated, CAN": dict(robots=(0, 1, 2, 3, 4, 5, 6), duration=6.0, can=True,
                                  load="saturate", seed=9),
    "bursts, foreign frames, bus-off, lost bytes": dict(
        robots=(0, 1, 2, 3), duration=10.0, can=True, load=1.0, seed=5,
        faults=("burst@3:0.05", "foreign@4.5:40", "foreign@6:x0f0a05", "busoff:1@5",
                "drop@7-9:0.01")),
    # two children's CAN frames end at one tick, their radio bytes then come one by one:
    # each receiver's at its tick in the radios' order, not in the order their CPUs were
    # first asked for something (a user's cost table; the two submits swapped in the trace)
    "one tick's bytes on two busy CPUs, a slow RETI": dict(
        robots=(0, 1, 2, 3), duration=21.0, can=True, load=1.0, seed=51, reti=300),
    "a robot fails and recovers, a stolen turn": dict(robots=(1, 2, 3, 4), duration=12.0,
                                                      load=2.0, seed=6,
                                                      faults=("fail:2@3", "recover:2@6",
                                                              "steal:3@9")),
}


def _world(case: str, fast: bool):
    from hil.sim.faults import parse_fault
    from hil.sim.world import SimConfig, World
    kw = dict(CASES[case])
    if kw.pop("auth", False):
        from firmware_model.radio.auth import RingKey
        from firmware_model.radio.mac import MacConfig
        kw["mac"] = MacConfig(auth=RingKey(bytes(range(16))))
    kw["faults"] = tuple(parse_fault(f) for f in kw.get("faults", ()))
    costs = DEFAULT_COSTS
    if "reti" in kw:
        from dataclasses import replace
        from firmware_model.cycle_costs import Cost
        costs = replace(costs, reti=Cost(kw.pop("reti"), "a test's", "-"))
    records: list = []
    w = World(SimConfig(cpu=costs, fast_paths=fast, **kw), listeners=[records.append])
    w.run()
    return w, records


@pytest.mark.parametrize("case", list(CASES))
def test_whole_rings_on_the_cpu_model_give_the_same_trace_and_figures(case):
    """With the fast paths (lone handlers, late bytes) and without (``--every-frame``: every
    byte at its tick, every handler on the general path): the same events in the same order,
    the same summary, the same figures for every handler."""
    fast, fast_records = _world(case, True)
    slow, slow_records = _world(case, False)
    assert len(fast_records) > 100
    assert fast_records == slow_records
    assert fast.summary() == slow.summary()
    assert {r: (c.busy, _figures(c)) for r, c in fast.cpus.items()} == \
        {r: (c.busy, _figures(c)) for r, c in slow.cpus.items()}
    late = sum(st.uart.bytes_late for st in fast.stations.values())
    assert sum(st.uart.bytes_late for st in slow.stations.values()) == 0
    # late bytes need a receiver holding nothing (idle noise comes a byte at a time, and a
    # frame after noise that left no partial Header may still come late)
    assert late > 0
    # and, every radio's UART read, the same state but for the CPUs and the fast paths' forms
    from hunt import sleep_hunt
    hunt = sleep_hunt()
    for w in (fast, slow):
        hunt.looked_at(w)
    assert hunt.cpu_state(fast, forms=True) == hunt.cpu_state(slow, forms=True)


def test_the_hunts_comparison_of_the_cpu_models_fast_paths_sees_their_state(monkeypatch):
    """scripts/sleep_hunt.py --cpu compares the state too: a deframer whose known-frame door
    keeps the last frame's Header tick (a leftover nothing reads, but one the byte-by-byte path
    clears) makes a hunt world differ that is otherwise the same run."""
    from firmware_model.radio.deframer import Deframer
    from hunt import sleep_hunt
    hunt = sleep_hunt()
    cfg, cuts, _ = hunt.random_world(1)
    assert hunt.same_cpu_run(cfg, cuts)
    door = Deframer.known_frame

    def leaky(self, data, end):
        kept = self._hdr_t
        frame = door(self, data, end)
        if frame is not None:
            self._hdr_t = kept
        return frame

    monkeypatch.setattr(Deframer, "known_frame", leaky)
    assert not hunt.same_cpu_run(cfg, cuts)


@pytest.mark.parametrize("case", list(CASES))
def test_the_last_bytes_of_a_frame_by_one_event_are_an_event_each(case, monkeypatch):
    """The receptions' last bytes of one transmission, one tick for all, by one event in
    radio order (hil/sim/reception.py, ``flush_ends``) and by an event each: the same run,
    event for event, figure for figure, and the same state."""
    from hil.sim.air import Air
    from hunt import sleep_hunt
    hunt = sleep_hunt()
    runs = []
    for together in (True, False):
        monkeypatch.setattr(Air, "ends_together", together)
        w, records = _world(case, True)
        runs.append((records, w.summary(), {r: (c.busy, _figures(c)) for r, c in
                                           w.cpus.items()}, hunt.cpu_state(w)))
    assert runs[0] == runs[1]


# -- a frame's late bytes given with its End (Uart._held) ------------------------------------

END_LEAD = 832
"""Ticks before a child's byte's stop bit ends at which its RDRF sets (Uart.rx_lead)."""
END_EFFECTS = DEFAULT_COSTS.entry.cycles + DEFAULT_COSTS.uart_rx_byte.cycles
"""From the End's RDRF to its handler's effects, alone: 119 cycles."""


def _ring(fast: bool, ask=None) -> tuple:
    """A ring of three children on the CPU model, 4 s; ``ask(world)`` may schedule things
    on it first. Its records, summary and every handler's figures."""
    from hil.sim.world import SimConfig, World
    records: list = []
    w = World(SimConfig(robots=(1, 2, 3), duration=4.0, seed=2, cpu=DEFAULT_COSTS,
                        fast_paths=fast), listeners=[records.append])
    if ask is not None:
        ask(w)
    w.run()
    return records, w.summary(), {r: (c.busy, _figures(c)) for r, c in w.cpus.items()}


def _an_end_at_robot_2() -> int:
    """The stop-bit tick of the End of robot 1's fourth frame, which robot 2 hears late."""
    records = _ring(True)[0]
    ends = [r.end for r in records if type(r).__name__ == "FrameOnAir" and r.src == 1]
    assert len(ends) >= 4
    return ends[3]


def test_a_frames_late_bytes_come_with_its_end_in_one_call(monkeypatch):
    """On an idle CPU a good frame's bytes but the End come late, at the End's RDRF; their
    effects wait for the End handler's, which gives the whole frame in one call: no stall
    timer is armed and stopped for it."""
    from hil.sim.world import SimConfig, World
    w = World(SimConfig(robots=(1, 2, 3), duration=4.0, seed=2, cpu=DEFAULT_COSTS))
    st = w.stations[2]
    calls: list = []
    real = st.uart.on_rx

    def spy(data, t0, dt, now=None, held=None):
        t = st.cpu.sched.now
        calls.append((len(data), held is not None, t - t0 - (len(data) - 1) * dt, t))
        return real(data, t0, dt, now, held)

    st.uart.on_rx = spy
    arms: list = []
    timer = st.stall_timer
    real_arm = type(timer).arm_at

    def arm_at(self, when, now=None):
        if self is timer:
            arms.append(self.sched.now)
        return real_arm(self, when, now)

    monkeypatch.setattr(type(timer), "arm_at", arm_at)
    w.run()
    whole = [c for c in calls if c[1]]
    assert sum(n == 14 for n, _, _, _ in whole) >= 10          # idle frames: 14 bytes
    assert {lag for _, _, lag, _ in whole} == {END_EFFECTS - END_LEAD}  # the End's effects
    # the bytes before the End were not given at its RDRF, where they came, so they armed
    # no stall timer then (it is programmed, stopped, without an event)
    assert not {t - END_EFFECTS for _, _, _, t in whole} & set(arms)
    assert not {t - END_EFFECTS for _, _, _, t in whole} & {t for _, h, _, t in calls if not h}


@pytest.mark.parametrize("offset", [-1, 0, 1, 23, 24, 25, 60, 118, 119, 120, 130, 800, 1400])
@pytest.mark.parametrize("how", ["request", "read", "sync"])
def test_a_look_before_the_end_handlers_effects_gets_the_late_bytes_first(offset, how):
    """Something asks robot 2's CPU for something (a request of another level), reads it, or
    its firmware reads the UART, ``offset`` ticks after the End's RDRF of a frame whose bytes
    came late: it finds the frame's bytes before the End taken, as every byte at its tick
    has them; the run is the general path's, event for event and figure for figure."""
    end = _an_end_at_robot_2()
    seen: list = []

    def ask(w):
        st = w.stations[2]

        def look():
            d = st.deframer
            seen.append((w.sched.now, d.in_frame, d.last_tick))
            if how == "request":
                st.cpu.irq(LOW, 300, lambda: seen.append(("low", w.sched.now)))
            elif how == "read":
                seen.append(("busy", st.cpu.busy))
            else:
                st.uart.sync(w.sched.now)
            seen.append(("then", d.in_frame, d.last_tick))
        w.sched.at(end - END_LEAD + offset, look)

    fast = _ring(True, ask)
    fast_seen, seen[:] = list(seen), []
    slow = _ring(False, ask)
    assert fast == slow
    # what the look saw once it asked, as every byte at its tick has it: the bytes before
    # the End taken, or, once the End's handler has had its effects (the look comes first
    # at their tick), the whole frame
    then = [x for x in fast_seen if x[0] == "then"]
    assert then == [x for x in seen if x[0] == "then"]
    assert then == [("then", True, end - 16640) if offset <= END_EFFECTS else
                    ("then", False, end)]



def _a_frame_from_robot_1() -> tuple[int, int]:
    """(first bit, End's stop bit) of robot 1's fourth frame, which robot 2 hears."""
    records = _ring(True)[0]
    frames = [r for r in records if type(r).__name__ == "FrameOnAir" and r.src == 1]
    assert len(frames) >= 4
    return frames[3].start, frames[3].end


@pytest.mark.parametrize("before", [1, 100, 1_500])
@pytest.mark.parametrize("lasts", [2_000, 40_000, 120_000])
def test_a_reception_that_begins_while_the_main_loop_works_comes_late_once_it_is_done(
        before, lasts, monkeypatch):
    """Robot 2's main loop has ``lasts`` cycles of work from ``before`` ticks before robot
    1's frame begins: its bytes come at their ticks while the work runs, and late from the
    first byte that finds the CPU idle (Uart.late_once_idle); the run is the general path's,
    event for event and figure for figure."""
    from firmware_model.mcu.uart import Uart
    start, end = _a_frame_from_robot_1()
    chosen: list = []
    real = Uart.late_once_idle

    def spy(self, data, dt, now):
        ok = real(self, data, dt, now)
        if now == start:
            chosen.append(ok)
        return ok

    monkeypatch.setattr(Uart, "late_once_idle", spy)
    late: list = []

    def ask(w):
        st = w.stations[2]
        w.sched.at(start - before, st.cpu.task, "work", lasts, lambda: None)
        for t in (start - before - 1, end + 1):
            w.sched.at(t, lambda: late.append(st.uart.bytes_late))

    fast = _ring(True, ask)
    fast_late, late[:] = list(late), []
    slow = _ring(False, ask)
    assert fast == slow
    assert chosen[0] is True             # robot 2's reception began on a busy CPU ...
    # ... and the 14-byte frame's bytes after the work (not its End) came late
    after = (lasts - before) // 16640 + 1
    assert fast_late[1] - fast_late[0] >= 13 - after - 1
    assert late == [0, 0]                # (every byte at its tick on the general path)
