"""The monitor of a simulated ring (hil.view.monitor): it advances a world by the wall time
elapsed times the speed, and injects the keys' faults through ``World.inject``."""
from __future__ import annotations

from collections import Counter, deque
from dataclasses import replace
from typing import IO, Any, Iterable

from rich.text import Text
from textual.binding import Binding

from firmware_model.radio.content import format_content
from firmware_model.radio.mac import Deliver, RotationalMac
from firmware_model.timing import TICK_HZ, s_to_ticks

from ...sim import events as E
from ...sim.events import Listener
from ...sim.pcap import PcapWriter
from ...sim.world import SimConfig, World

from .app import (BUDGET_S, CHUNK_TICKS, KEEP, MonitorApp, RATE_HZ, Received, SPEED_MAX, SPEED_MIN,
                  _cut, _dst, _fault_line, _ids, _speed_text)


class SimMonitorApp(MonitorApp):
    """The monitor driving a simulated world (see the module docstring for the keys)."""

    BINDINGS = MonitorApp.BINDINGS + [
        Binding("k", "prefix('kill')", "kill radio N"),
        Binding("r", "prefix('revive')", "revive N"),
        Binding("s", "prefix('steal')", "steal turn N"),
        Binding("n", "noise", "noise on/off"),
        Binding("plus,equals_sign", "speed(2)", "faster"),
        Binding("minus", "speed(0.5)", "slower"),
        Binding("escape", "prefix('')", "cancel", show=False),
    ] + [Binding(str(d), f"digit({d})", str(d), show=False) for d in range(10)]

    def __init__(self, config: SimConfig, speed: float = 1.0, paused: bool = False,
                 rate: float = RATE_HZ, keep: int = KEEP, trace: Any = None,
                 listeners: Iterable[Listener] = (),
                 capture: IO[bytes] | None = None) -> None:
        """``trace`` (a TraceWriter) and ``listeners`` also get the world's events, and
        ``capture`` (a binary file) its traffic as pcapng (hil/sim/pcap.py), as in ``rprs
        sim`` (the caller closes them)."""
        if config.realtime:
            config = replace(config, realtime=False)   # the monitor paces the world itself
        self.world = World(config, trace, listeners=[*listeners, self._on_event])
        if capture is not None:
            self.world.capture(PcapWriter(capture, *self.world.capture_interfaces()))
        super().__init__(config.robots, rate)
        self.sub_title = "simulator"
        self.speed = min(SPEED_MAX, max(SPEED_MIN, float(speed)))
        self.paused = paused
        self.prefix = ""
        self.received: dict[int, deque[Received]] = {r: deque(maxlen=keep)
                                                     for r in self.robots}
        self.last_sender: int | None = None
        self._seen: set[tuple] = set()
        self._wall = self.clock()
        self._rate_log: deque[tuple[float, int]] = deque(maxlen=int(rate * 2) + 1)
        self.write_error: OSError | None = None
        """What stopped the run when one of its outputs could not be written (a full disk):
        :func:`run_monitor_sim` raises it once the terminal is restored."""
        for st in self.world.stations.values():
            st.add_observer(self._received_by, first=True)

    def on_mount(self) -> None:
        self._wall = self.clock()            # wall time before the first refresh is not owed
        super().on_mount()

    # -- the world's side ------------------------------------------------------------------

    def _received_by(self, st, a, now: int) -> None:
        """Every message delivered, for the robot's pane (told before the world's own)."""
        if type(a) is Deliver:
            text = format_content(a.commands).decode("ascii", "replace")
            self.received[st.id].append(Received(now, a.src, a.num, a.dst, a.type, text))

    def _on_event(self, ev: E.TraceEvent) -> None:
        """The world's events that make the log pane's lines (typed: hil/sim/events.py)."""
        if isinstance(ev, E.FrameOnAir):
            self.last_sender = ev.src
            return
        t = ev.t / TICK_HZ
        if isinstance(ev, (E.Disable, E.Join, E.Rejoin)):
            key = (ev.t, ev.KIND, ev.robot)
            if key in self._seen:
                return
            self._seen.add(key)
            if len(self._seen) > 1000:
                self._seen.clear()
            verb = {"disable": "dropped from the ring", "join": "joined the ring",
                    "rejoin": "rejoined the ring"}[ev.KIND]
            line = f"robot {ev.robot} {verb} (first seen by {ev.by})"
        elif isinstance(ev, E.Mode):
            line = f"robot {ev.robot}{' PC2' if ev.pc else ''} -> {ev.mode} ({ev.reason})"
        elif isinstance(ev, E.FaultEdge):
            line = _fault_line(ev)
        elif isinstance(ev, E.Collision):
            line = f"collision between robots {_ids(ev.robots)}"
        elif isinstance(ev, E.Failed):
            line = f"message {ev.src}#{ev.num:02d}->{_dst(ev.dst)} failed: {ev.reason}"
        elif isinstance(ev, E.Power):
            line = f"robot {ev.robot}{' PC2' if ev.pc else ''} powered on"
        elif isinstance(ev, E.BadContent):
            line = f"robot {ev.to}: bad Content from {ev.src}: {ev.reason}"
        else:
            return
        self.events.append(f"{t:9.3f} s  {line}")

    # -- time ------------------------------------------------------------------------------

    @property
    def finished(self) -> bool:
        return self.world.now >= self.world.end_tick

    def advance(self, seconds: float) -> None:
        """Run the world ``seconds`` of simulated time now (synchronously) and refresh."""
        self.world.run(self.world.now + s_to_ticks(seconds))
        self.refresh_view()

    def step(self) -> None:
        clock = self.clock
        now = clock()
        dt, self._wall = now - self._wall, now
        w = self.world
        if self.paused or self.finished:
            self._rate_log.clear()
            return
        target = min(w.end_tick, w.now + int(min(dt, 1.0) * self.speed * TICK_HZ))
        deadline = now + BUDGET_S
        try:
            while w.now < target and clock() < deadline:
                w.run(min(target, w.now + CHUNK_TICKS))
        except OSError as exc:           # an output (trace, waveform, capture) cannot be written
            self.write_error = exc
            self.paused = True
            self.exit(return_code=2)
        # Time the simulator could not keep up with is dropped, not owed.
        self._rate_log.append((clock(), w.now))

    def actual_speed(self) -> float | None:
        log = self._rate_log
        if len(log) < 3:
            return None
        (t0, k0), (t1, k1) = log[0], log[-1]
        return (k1 - k0) / TICK_HZ / (t1 - t0) if t1 > t0 else None

    # -- what the view shows ---------------------------------------------------------------

    def alive(self, r: int) -> bool:
        return bool(self.world.radios[r].alive)

    def ring(self) -> tuple[tuple[int, ...], bool]:
        """The ring as most live members see it, and whether every live member agrees."""
        views = Counter(st.mac.ring for r, st in self.world.stations.items()
                        if self.alive(r) and st.mac.mode == "member")
        if not views:
            return (), True
        ring, _ = views.most_common(1)[0]
        return ring, len(views) == 1

    def owner(self) -> tuple[str, bool]:
        """Who owns the turn (the source on air, else the last sender), and whether on air."""
        on_air = sorted({tx.radio.robot for tx in self.world.air.active if not tx.aborted})
        if len(on_air) > 1:
            return f"{'+'.join(map(str, on_air))} COLLIDING", True
        if on_air:
            return str(on_air[0]), True
        return ("-" if self.last_sender is None else str(self.last_sender)), False

    def header_text(self) -> Text:
        w = self.world
        ring, agree = self.ring()
        owner, on_air = self.owner()
        t = Text(no_wrap=True, overflow="ellipsis")
        t.append("ring ", "bold")
        t.append(f"[{_ids(ring)}]", "bold green" if ring else "bold red")
        if not agree:
            t.append(" (views differ)", "yellow")
        out = [r for r in self.robots if r not in ring]
        if out:
            t.append(f"  out: {_ids(out)}", "red")
        t.append("   turn: ", "bold")
        t.append(owner, "bold red" if "COLL" in owner else "bold cyan")
        t.append(" (on air)" if on_air else " (last sender)", "dim")
        t.append("\n")
        t.append("occupations ", "bold")
        t.append(f"{w.air.occupations}")
        t.append("   collisions ", "bold")
        t.append(f"{w.collisions}", "red" if w.collisions else "")
        pend = sum(st.mac.pending for st in w.stations.values())
        t.append(f"   pending {pend}")
        t.append(f"   t = {w.now / TICK_HZ:.3f} s", "bold")
        t.append(f"   speed {_speed_text(self.speed)}")
        act = self.actual_speed()
        if act is not None and not self.paused and act < 0.9 * self.speed:
            t.append(f" (achieved ×{act:.2g})", "yellow")
        state = "FINISHED" if self.finished else "PAUSED" if self.paused else "running"
        t.append(f"   {state}", "bold yellow" if state != "running" else "green")
        t.append("   noise " + ("ON" if w.air.noise else "off"),
                 "bold magenta" if w.air.noise else "dim")
        return t

    def pane_text(self, r: int, width: int, height: int) -> tuple[Text, str]:
        w = self.world
        st = w.stations[r]
        mac = st.mac
        alive = self.alive(r)
        stats = w.stats[r]
        t = Text(no_wrap=True, overflow="ellipsis")
        if not alive:
            t.append("RADIO OFF", "bold red")
            t.append(f"  ({mac.mode})", "dim")
            state = "dead"
        else:
            t.append(mac.mode, "bold green" if mac.mode == "member" else "bold yellow")
            state = "" if mac.mode == "member" else "listen"
        t.append(f"  view [{_ids(mac.ring)}]\n", "dim")
        t.append(f"sent {w.air.sent.get(r, 0)}  recv {stats.received}  ")
        t.append(f"missed {stats.missed}\n", "red" if stats.missed else "")
        assert isinstance(mac, RotationalMac)   # (the monitor refuses the peer MACs)
        outbox = mac.outbox
        inflight = getattr(mac, "inflight", None)
        lines_left = height - 2
        t.append(f"queue {mac.pending}", "bold")
        t.append(f"  ok {stats.delivered} failed {stats.failed}\n", "dim")
        lines_left -= 1
        shown_q = [(m, "sent" if m is inflight else "") for m in outbox]
        qmax = min(len(shown_q), max(1, lines_left // 3))
        for m, how in shown_q[:qmax]:
            c = m.content.decode("ascii", "replace")
            tag = f" [try {m.attempts}]" if how else ""
            t.append(_cut(f" #{m.num:02d}→{_dst(m.dst)}{tag} {c}", width) + "\n", "cyan")
            lines_left -= 1
        if len(shown_q) > qmax:
            t.append(f" … {len(shown_q) - qmax} more\n", "dim cyan")
            lines_left -= 1
        rec = self.received[r]
        t.append(f"received {stats.received}", "bold")
        t.append("\n")
        lines_left -= 1
        n = max(0, lines_left)
        items = list(rec)[-n:] if n else []
        for got in items:
            t.append(_cut(f" {got.src}#{got.num:02d}→{_dst(got.dst)} {got.content}", width)
                     + "\n")
        t.rstrip()
        return t, state

    def default_hint(self) -> str:
        if self.prefix:
            return f"{self.prefix} which robot? press its digit "\
                   f"({_ids(self.robots)}), Esc cancels"
        return "k N kill radio · r N revive · s N steal the turn (collision) · " \
               "n noise · space pause · +/- speed · q quit"

    # -- keys ------------------------------------------------------------------------------

    def action_prefix(self, what: str) -> None:
        self.prefix = what
        self.hint = ""
        self.refresh_view()

    def action_digit(self, d: int) -> None:
        what, self.prefix = self.prefix, ""
        if not what:
            self.refresh_view()
            return
        self.fault(what, d)

    def _over(self) -> bool:
        """Has the run finished? Then a fault key says so and does nothing (the trace and
        the summary end at the run's end)."""
        if self.finished:
            self.flash("the run has finished: nothing more can happen in it")
        return self.finished

    def fault(self, what: str, r: int) -> bool:
        """'kill', 'revive' or 'steal' robot ``r`` now (the keys k/r/s then a digit); not
        once the run has finished (the trace and the summary end at its end)."""
        if self._over():
            return False
        if r not in self.world.stations:
            self.flash(f"robot {r} is not in this simulation (robots {_ids(self.robots)})")
            return False
        kind = {"kill": "fail", "revive": "recover", "steal": "steal"}[what]
        w = self.world
        if kind == "fail" and not self.alive(r):
            self.flash(f"the radio of robot {r} is already off")
            return False
        if kind == "recover" and self.alive(r):
            self.flash(f"the radio of robot {r} is already on")
            return False
        w.inject(kind, r, w.now)
        w.run(w.now)                 # apply it at this tick, so the view shows it at once
        self.refresh_view()
        return True

    def action_noise(self) -> None:
        self.set_noise(not self.world.air.noise)

    def set_noise(self, on: bool) -> None:
        """Idle noise on the air on/off from now (radios hearing a frame or garbage are not
        disturbed; they start hearing noise when it ends)."""
        air, now = self.world.air, self.world.now
        if self._over():
            return
        if air.noise == on:
            return
        air.set_noise(on)
        self.events.append(f"{now / TICK_HZ:9.3f} s  idle noise {'ON' if on else 'off'}")
        self.refresh_view()

    def action_speed(self, factor: float) -> None:
        self.speed = min(SPEED_MAX, max(SPEED_MIN, self.speed * factor))
        self._rate_log.clear()
        self.refresh_view()


# ---------------------------------------------------------------------------------------------
# Attached to a radio (USB, or a node of the pty radio hub)
