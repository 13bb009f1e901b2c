"""``rprs monitor``: a live terminal view of the ring, like the paper's simulator (Fig. 9).

The paper's Fig. 9 shows one list box per robot with the messages it received, an edit box with
the messages waiting to be sent and the total number of channel occupations. This is the same
view, live, in a textual TUI:

* a header with the ring (the robots in it, as the live members see it), who owns the turn now
  (the source of the frame on air, else the last sender), the channel occupations, collisions,
  the time and the speed;
* one pane per robot: its mode (member/listen) and radio state, the frames it sent, the
  messages it received (source, Number, Content), its queue (pending messages) and the turns
  it missed;
* a line of recent events (faults, drops, joins, collisions, failed messages).

Two sources:

:class:`SimMonitorApp` owns a :class:`hil.sim.world.World` and advances it from a textual timer by
``speed`` x the wall time elapsed (speed 1 = real time; space pauses, ``+``/``-`` double or halve
the speed). A slice of wall time the simulator cannot keep up with is dropped rather than owed,
so the view stays responsive; the header then shows the speed actually achieved. Keys:
``k`` then a digit kills that robot's radio, ``r`` then a digit revives it (both through
``World.inject``, so they are the same faults as ``--fail``/``--recover``), ``s`` then a digit
makes that robot steal the turn (a forced collision, the ``steal`` fault), ``n`` toggles idle
noise on the air (``Air.noise``, with the air's idle bookkeeping restarted so that listening
radios hear noise from now on / stop hearing it now), ``q`` quits.

:class:`RadioMonitorApp` opens a serial port (a USB radio, or one node of the pty radio hub) as
a passive listener (:class:`hil.bench.scripts.Sniffer`, it never transmits) and shows what it hears:
frames per robot with their Content, the inferred ring (robots heard in the last
``window`` seconds), the owner of the turn (the last source heard), occupations (frames heard,
good or failed) and inferred missed turns (a gap of about Tmax or more between two frames is
charged to the ring members the turn skipped). Kill/revive/steal/noise keys do nothing there.

Both refresh at ``rate`` Hz (10 by default): a textual interval timer calls :meth:`MonitorApp.tick`
(step the source, then redraw). The timer belongs to the app's screen (:class:`MonitorView`), the
node that holds every widget it draws into, so its lifetime is the view's: textual stops a node's
timers when it starts removing the node, before it removes any child, hence no refresh can run
while the widgets are being taken down (a timer on the app itself kept ticking until after they
were gone). The widgets are looked up once, at mount, not on every refresh; once the view is gone
a direct ``refresh_view()`` only keeps the model. Wall time is read through ``app.clock``
(``time.monotonic``), so a test can pause ``app.refresh_timer``, replace the clock and drive
``tick()`` itself. ``advance(seconds)`` on the simulator app runs the world synchronously by that
much simulated time and refreshes (the tests use it).

Over 500 lines on purpose: one textual application: its widgets, key bindings and the world it
drives.
"""
from __future__ import annotations

import time
from collections import Counter, deque
from dataclasses import dataclass, replace
from typing import IO, Any, Callable, Iterable

from rich.text import Text
from textual.app import App, ComposeResult
from textual.binding import Binding
from textual.containers import Grid
from textual.screen import Screen
from textual.timer import Timer
from textual.widgets import Footer, Static

from firmware_model.radio.content import format_content
from firmware_model.radio.frame import BROADCAST
from firmware_model.radio.mac import Deliver, RotationalMac
from firmware_model.timing import PC_BYTE_TICKS, TICK_HZ, TMAX_TICKS, s_to_ticks

from ...bench.scripts import HeardFrame, Sniffer
from ...sim.pcap import PcapWriter
from ...sim.world import SimConfig, World

RATE_HZ = 10.0
"""Display refresh (and simulator pacing) rate."""
KEEP = 200
"""Received messages / heard frames remembered per robot (the pane shows what fits)."""
SPEED_MIN, SPEED_MAX = 1 / 64, 4096.0
BUDGET_S = 0.06
"""Wall time one refresh may spend simulating (of the 0.1 s between refreshes)."""
CHUNK_TICKS = s_to_ticks(0.02)
"""Simulated time run between two looks at the wall-clock budget."""
QUIT_SIGNALS = ("SIGTERM", "SIGHUP")
"""Signals that quit the view as ``q`` does."""


class HeldQuitSignals:
    """``QUIT_SIGNALS`` held while the view is not up to take them: from when ``rprs monitor``
    opens its outputs until it has closed them. One that comes before the view is mounted
    quits the view as soon as it is (``seen``); one that comes after the view is gone is
    noted and changes nothing: the outputs are being finished anyway. (Such a signal used to
    kill the process between the two, its trace and capture left ``.partial``.)"""

    def __init__(self) -> None:
        self.seen = False
        self.active = False
        self._old: dict[int, Any] = {}

    def note(self, *_: Any) -> None:
        self.seen = True

    def arm(self) -> None:
        """Take the signals (again: ``loop.remove_signal_handler`` leaves them at default)."""
        import signal
        for sig in (getattr(signal, n, None) for n in QUIT_SIGNALS):
            if sig is None:
                continue
            try:
                old = signal.signal(sig, self.note)
            except ValueError:          # not the main thread
                return
            self._old.setdefault(sig, old)

    def __enter__(self) -> "HeldQuitSignals":
        self.seen, self.active = False, True
        self.arm()
        return self

    def __exit__(self, *exc: Any) -> None:
        import signal
        self.active = False
        for sig, old in self._old.items():
            signal.signal(sig, old)
        self._old.clear()


quit_signals = HeldQuitSignals()
"""The one ``rprs monitor`` holds (hil/cli/monitor.py) and the view takes over."""
TYPE_NAMES = {0: "help", 1: "invite", 2: "instr", 3: "info", 4: "failure", 5: "boot"}


def _ids(robots: Iterable[int]) -> str:
    return " ".join(str(r) for r in robots) or "-"


def _dst(d: int | None) -> str:
    if d is None:
        return "?"
    return "all" if d == BROADCAST else str(d)


def _cut(s: str, width: int) -> str:
    if width <= 1:
        return s[:max(width, 0)]
    return s if len(s) <= width else s[:width - 1] + "…"


def _fault_line(ev: dict) -> str:
    """An events line for a world's ``fault`` event: the monitor's own keys in words, any
    other ``--fault`` by its spec as it starts and by its kind and robot as it ends."""
    kind, robot = ev["kind"], ev["robot"]
    if ev.get("phase") == "end":
        return f"fault {kind}{'' if robot is None else f' on robot {robot}'} ends"
    own = {"fail": "radio of robot {} killed", "recover": "radio of robot {} revived",
           "steal": "robot {} steals the turn"}.get(kind)
    return own.format(robot) if own else f"fault {ev.get('spec', kind)} starts"


def _speed_text(speed: float) -> str:
    """×4, ×1/8 (a whole fraction), else ×0.75 (``--speed 0.75`` used to show ×1/1)."""
    if speed < 1 and (1 / speed).is_integer():
        return f"×1/{round(1 / speed):d}"
    return f"×{speed:g}"


@dataclass
class Received:
    """One line of a robot's received list (Fig. 9's list box)."""

    t: int           # tick it was delivered / heard
    src: int
    num: int
    dst: int
    type: int
    content: str
    repeat: int = 1   # identical heartbeats heard in a row (radio monitor)


# ---------------------------------------------------------------------------------------------
# The common TUI


class MonitorView(Screen):
    """The monitor's (default) screen: :meth:`MonitorApp.compose`'s widgets live on it and so does
    the refresh timer. Textual removes a screen by first closing the screen itself (which stops
    its timers) and only then its children, so a refresh never races with the widgets being
    unmounted. When the screen is unmounted the app stops drawing."""

    def on_unmount(self) -> None:
        app = self.app
        if isinstance(app, MonitorApp):
            app._view_gone()


class MonitorApp(App):
    """Header, one pane per robot, recent events, a hint line and the key footer."""

    CSS = """
    Screen { layout: vertical; }
    #header, .pane, #events, #hint { text-wrap: nowrap; text-overflow: ellipsis; }
    #header { height: 4; border: round $primary; padding: 0 1; }
    #panes { height: 1fr; grid-gutter: 0 1; }
    .pane { border: round $secondary; padding: 0 1; height: 1fr; overflow: hidden hidden; }
    .pane.dead { border: round $error; }
    .pane.listen { border: round $warning; }
    .pane.silent { border: round $panel; }
    #events { height: 5; border: round $panel; padding: 0 1; }
    #hint { height: 1; padding: 0 1; background: $boost; }
    """

    TITLE = "RPRS monitor"
    BINDINGS = [Binding("q", "quit", "quit"),
                # Ctrl-C stops it, as it stops every rprs process (textual's own ctrl+c only
                # said "Press ctrl+q to quit")
                Binding("ctrl+c", "quit", "quit", show=False, priority=True),
                Binding("space", "pause", "pause/run"),
                # textual binds no key to its suspend: Ctrl-Z was a key the view ignored (the
                # terminal is raw), so a shell's Ctrl-Z / fg did nothing
                Binding("ctrl+z", "suspend_process", "suspend", show=False)]

    def get_driver_class(self):
        """textual's driver, sized by the terminal drawn on and quiet once it closed
        (hil/view/terminal.py)."""
        from ..terminal import driver_for
        return driver_for(super().get_driver_class())

    def __init__(self, robots: Iterable[int], rate: float = RATE_HZ) -> None:
        super().__init__()
        self.robots = tuple(sorted(robots))
        self.rate = rate
        self.paused = False
        self.events: deque[str] = deque(maxlen=50)
        self.hint = ""
        self._hint_until = 0.0
        self._texts: dict[str, str] = {}
        self._widgets: dict[str, Static] = {}
        """'#header', '#robot-N', '#events', '#hint' -> the widget, while the view is mounted."""
        self.clock = time.monotonic
        """The wall clock the app paces by and expires hints with (tests may replace it)."""
        self.refresh_timer: Timer | None = None
        """The textual timer calling :meth:`tick` at ``rate`` Hz (owned by the view)."""

    # -- layout ----------------------------------------------------------------------------

    def get_default_screen(self) -> Screen:
        return MonitorView(id="_default")

    def compose(self) -> ComposeResult:
        yield Static(id="header")
        with Grid(id="panes"):
            for r in self.robots:
                p = Static(id=f"robot-{r}", classes="pane")
                p.border_title = self.pane_title(r)
                yield p
        yield Static(id="events")
        yield Static(id="hint")
        yield Footer()

    def on_mount(self) -> None:
        view = self.default_screen
        n = len(self.robots)
        cols = n if n <= 4 else (n + 1) // 2
        grid = view.query_one("#panes", Grid)
        grid.styles.grid_size_columns = max(1, cols)
        grid.styles.grid_size_rows = 1 if n <= 4 else 2
        self._widgets = {sel: view.query_one(sel, Static) for sel in
                         ("#header", *(f"#robot-{r}" for r in self.robots), "#events", "#hint")}
        self._widgets["#events"].border_title = "events"
        self._texts.clear()            # nothing drawn into these widgets yet
        self.refresh_view()
        # On the view, not on the app: textual stops it before it removes any of the widgets.
        self.refresh_timer = view.set_interval(1 / self.rate, self.tick, name="monitor refresh")
        self._quit_on_signals(True)
        if quit_signals.active and quit_signals.seen:   # it came while the view started
            self.exit()

    def _quit_on_signals(self, on: bool) -> None:
        """SIGTERM and SIGHUP quit like ``q``: the terminal restored, the trace and summary
        written (they used to kill the process in the alternate screen, the trace left
        ``.partial``). Only where the app's loop can take signals (the main thread)."""
        import asyncio
        import signal
        loop = asyncio.get_running_loop()
        for sig in (getattr(signal, n, None) for n in QUIT_SIGNALS):
            if sig is None:
                continue
            try:
                if on:
                    loop.add_signal_handler(sig, self.exit)
                else:
                    loop.remove_signal_handler(sig)
            except (ValueError, RuntimeError, NotImplementedError):
                return                   # not the main thread, or no signals on this platform

    def _view_gone(self) -> None:
        """The view is unmounted (its timer already stopped): draw nothing from now on."""
        self._widgets = {}
        self.refresh_timer = None
        self._quit_on_signals(False)
        if quit_signals.active:          # until the outputs are closed (hil/cli/monitor.py)
            quit_signals.arm()

    @property
    def view_ready(self) -> bool:
        """Whether the widgets are mounted (the refresh draws into them)."""
        return bool(self._widgets)

    def tick(self) -> None:
        """One refresh period: what the timer calls (tests may call it themselves)."""
        self.step()
        self.refresh_view()

    # -- what the subclasses provide -------------------------------------------------------

    def step(self) -> None:
        """Advance the source (simulator) or collect what arrived (radio)."""

    def pane_title(self, r: int) -> str:
        return f"robot {r}" + (" (father)" if r == 0 else "")

    def header_text(self) -> Text:
        raise NotImplementedError

    def pane_text(self, r: int, width: int, height: int) -> tuple[Text, str]:
        """The pane's content and its state class ('', 'dead', 'listen', 'silent')."""
        raise NotImplementedError

    def default_hint(self) -> str:
        return ""

    # -- refresh ---------------------------------------------------------------------------

    def flash(self, text: str, seconds: float = 3.0) -> None:
        """Show ``text`` in the hint line for a while."""
        self.hint = text
        self._hint_until = self.clock() + seconds
        self._set("#hint", Text(text))

    def refresh_view(self) -> None:
        if not self._widgets:
            return
        self._set("#header", self.header_text())
        for r in self.robots:
            pane = self._widgets[f"#robot-{r}"]
            size = pane.content_size
            w = size.width if size.width > 0 else 40
            h = size.height if size.height > 0 else 12
            text, state = self.pane_text(r, w, h)
            self._set(f"#robot-{r}", text)
            for cls in ("dead", "listen", "silent"):
                pane.set_class(cls == state, cls)
        ev = self._widgets["#events"]
        h = ev.content_size.height or 3
        w = ev.content_size.width or 80
        self._set("#events", Text("\n".join(_cut(e, w) for e in list(self.events)[-h:])))
        if self.hint and self.clock() > self._hint_until:
            self.hint = ""
        self._set("#hint", Text(self.hint or self.default_hint()))

    def _set(self, selector: str, text: Text) -> None:
        widget = self._widgets.get(selector)
        if widget is None:               # not mounted yet, or gone: nothing to draw into
            return
        plain = text.plain
        if self._texts.get(selector) == plain:
            return
        self._texts[selector] = plain
        widget.update(text)

    def shown(self, selector: str) -> str:
        """The plain text last put in a widget ('#header', '#robot-N', '#events', '#hint')."""
        return self._texts.get(selector, "")

    # -- keys ------------------------------------------------------------------------------

    def action_pause(self) -> None:
        self.paused = not self.paused
        self.refresh_view()


# ---------------------------------------------------------------------------------------------
# Attached to the simulator


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
                 on_event: Callable[[dict], None] | None = None,
                 capture: IO[bytes] | None = None) -> None:
        """``trace`` (a TraceWriter) and ``on_event`` also get the world's events, and
        ``capture`` (a binary file) its traffic as pcapng (hil/sim/pcap.py), as in ``rprs
        sim`` (the caller closes them)."""
        if config.realtime:
            config = replace(config, realtime=False)   # the monitor paces the world itself
        self._also = on_event
        self.world = World(config, trace, on_event=self._on_event)
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
            st.observer = self._chain(st.observer)

    def on_mount(self) -> None:
        self._wall = self.clock()            # wall time before the first refresh is not owed
        super().on_mount()

    # -- the world's side ------------------------------------------------------------------

    def _chain(self, prev):
        received = self.received

        def observe(st, a, now):
            if type(a) is Deliver:
                text = format_content(a.commands).decode("ascii", "replace")
                received[st.id].append(Received(now, a.src, a.num, a.dst, a.type, text))
            if prev is not None:
                prev(st, a, now)
        return observe

    def _on_event(self, ev: dict) -> None:
        if self._also is not None:
            self._also(ev)
        k = ev["ev"]
        if k == "frame":
            self.last_sender = ev["src"]
            return
        if k in ("txen", "deliver", "submit", "delivered", "miss", "can", "duplicate",
                 "meta", "action"):
            return
        t = ev.get("t", 0) / TICK_HZ
        if k in ("disable", "join", "rejoin"):
            key = (ev["t"], k, ev["robot"])
            if key in self._seen:
                return
            self._seen.add(key)
            if len(self._seen) > 1000:
                self._seen.clear()
            verb = {"disable": "dropped from the ring", "join": "joined the ring",
                    "rejoin": "rejoined the ring"}[k]
            line = f"robot {ev['robot']} {verb} (first seen by {ev['by']})"
        elif k == "mode":
            line = f"robot {ev['robot']}{' PC2' if ev.get('pc') else ''} -> {ev['mode']} " \
                   f"({ev['reason']})"
        elif k == "fault":
            line = _fault_line(ev)
        elif k == "collision":
            line = f"collision between robots {_ids(ev['robots'])}"
        elif k == "fail":
            line = f"message {ev['src']}#{ev['num']:02d}->{_dst(ev['dst'])} failed: " \
                   f"{ev['reason']}"
        elif k == "power":
            line = f"robot {ev['robot']}{' PC2' if ev.get('pc') else ''} powered on"
        elif k == "bad_content":
            line = f"robot {ev['to']}: bad Content from {ev['src']}: {ev['reason']}"
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


class MonitorSniffer(Sniffer):
    """A :class:`hil.bench.scripts.Sniffer` that also keeps each frame's Content, in a buffer the
    monitor drains (so memory stays bounded however long it listens)."""

    def __init__(self, port_spec: str, byte_ticks: int = PC_BYTE_TICKS) -> None:
        super().__init__(port_spec, byte_ticks)
        self._new: list[tuple[HeardFrame, bytes]] = []

    def drain(self) -> tuple[list[tuple[HeardFrame, bytes]], int, int, int]:
        """(frames heard since the last drain, failed frames, garbage bytes, bytes) so far."""
        with self._lock:
            new, self._new = self._new, []
            r = self.result
            return new, r.failed, r.garbage, r.bytes

    def _heard(self, heard: HeardFrame, frame) -> None:
        self._new.append((heard, frame.content))


class RadioMonitorApp(MonitorApp):
    """The monitor on a serial port, listening only (see the module docstring)."""

    BINDINGS = MonitorApp.BINDINGS + [
        Binding("k", "disabled", "kill/revive: disabled (listener)"),
        Binding("r,s,n", "disabled", show=False),
    ]

    def __init__(self, port: str, window: float = 3.0, rate: float = RATE_HZ,
                 keep: int = KEEP) -> None:
        super().__init__(range(7), rate)
        self.port = port
        self.window = window
        self.sub_title = f"listening on {port}"
        self.sniffer = MonitorSniffer(port)       # PortError here: nothing started yet
        self._closed = False
        self.heard: dict[int, deque[Received]] = {r: deque(maxlen=keep) for r in self.robots}
        self.count = {r: 0 for r in self.robots}
        self.missed = {r: 0 for r in self.robots}
        self.last_heard: dict[int, int] = {}
        self.last: HeardFrame | None = None
        self.occupations = 0
        self.failed = self.garbage = self.bytes = 0
        self._ring_seen: set[int] = set()
        self.lost = False
        """Whether the port went away (the header says PORT LOST)."""

    def on_mount(self) -> None:
        self.sniffer.start()
        super().on_mount()

    def on_unmount(self) -> None:
        self.close()

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self.sniffer.stop()

    def now(self) -> int:
        return self.sniffer.tick()

    def ring(self, now: int | None = None) -> tuple[int, ...]:
        """Robots heard in the last ``window`` seconds."""
        now = self.now() if now is None else now
        edge = now - s_to_ticks(self.window)
        return tuple(r for r in self.robots if r in self.last_heard and self.last_heard[r] >= edge)

    def step(self) -> None:
        frames, failed, garbage, nbytes = self.sniffer.drain()
        self.failed, self.garbage, self.bytes = failed, garbage, nbytes
        for f, content in frames:
            self.feed(f, content)
        now = self.now()
        if self.sniffer.error is not None and not self.lost:
            self.lost = True
            self.events.append(f"{now / TICK_HZ:9.3f} s  port {self.port} lost: "
                               f"{self.sniffer.error}; nothing more can be heard")
        ring = set(self.ring(now))
        for r in sorted(self._ring_seen - ring):
            self._ring_seen.discard(r)
            self.events.append(f"{now / TICK_HZ:9.3f} s  robot {r} silent for "
                               f"{self.window:g} s: out of the inferred ring")

    def feed(self, f: HeardFrame, content: bytes) -> None:
        """Account one frame heard (in arrival order)."""
        prev = self.last
        if prev is not None and f.start - prev.end >= 0.9 * TMAX_TICKS:
            ring = sorted(set(self.ring(f.start)) | {prev.src, f.src})
            if prev.src in ring and f.src in ring:
                i, j = ring.index(prev.src), ring.index(f.src)
                k = (i + 1) % len(ring)
                while k != j and ring[k] != prev.src:
                    self.missed[ring[k]] += 1
                    k = (k + 1) % len(ring)
        self.last = f
        self.last_heard[f.src] = f.end
        self.count[f.src] += 1
        heard = self.heard[f.src]
        last = heard[-1] if heard else None
        if not content and last is not None and not last.content and \
                (last.num, last.dst, last.type) == (f.num, f.dst, f.type):
            last.repeat += 1            # heartbeats in a row: one line with a count
            last.t = f.end
        else:
            heard.append(Received(f.end, f.src, f.num, f.dst, f.type,
                                  content.decode("ascii", "replace")))
        if f.src not in self._ring_seen:
            self._ring_seen.add(f.src)
            again = "again" if self.count[f.src] > 1 else "for the first time"
            self.events.append(f"{f.end / TICK_HZ:9.3f} s  robot {f.src} heard {again}")

    def header_text(self) -> Text:
        now = self.now()
        ring = self.ring(now)
        t = Text(no_wrap=True, overflow="ellipsis")
        t.append("ring ", "bold")
        t.append(f"[{_ids(ring)}]", "bold green" if ring else "bold red")
        t.append(f" (heard in the last {self.window:g} s)", "dim")
        t.append("   turn: ", "bold")
        if self.last is None:
            t.append("-", "bold cyan")
        else:
            quiet = (now - self.last.end) / TICK_HZ
            t.append(str(self.last.src), "bold cyan")
            t.append(" (last sender" + (f", quiet {quiet:.1f} s)" if quiet * TICK_HZ >
                                        TMAX_TICKS else ")"), "dim")
        t.append("\n")
        occ = sum(self.count.values()) + self.failed
        t.append("occupations ", "bold")
        t.append(f"{occ}")
        t.append(f"   failed frames {self.failed}", "red" if self.failed else "")
        t.append(f"   garbage bytes {self.garbage}   bytes {self.bytes}")
        t.append(f"   t = {now / TICK_HZ:.1f} s", "bold")
        if self.lost:
            t.append("   PORT LOST", "bold red")
        if self.paused:
            t.append("   FROZEN", "bold yellow")
        return t

    def pane_text(self, r: int, width: int, height: int) -> tuple[Text, str]:
        now = self.now()
        t = Text(no_wrap=True, overflow="ellipsis")
        if not self.count[r]:
            t.append("not heard", "dim")
            return t, "silent"
        in_ring = r in self.ring(now)
        ago = (now - self.last_heard[r]) / TICK_HZ
        t.append("in ring" if in_ring else "silent", "bold green" if in_ring else "bold red")
        t.append(f"  heard {ago:.1f} s ago\n", "dim")
        t.append(f"frames {self.count[r]}  ")
        t.append(f"missed ~{self.missed[r]}\n", "red" if self.missed[r] else "")
        t.append("heard", "bold")
        t.append("\n")
        n = max(0, height - 3)
        for m in (list(self.heard[r])[-n:] if n else []):
            body = m.content or f"({TYPE_NAMES.get(m.type, m.type)})"
            if m.repeat > 1:
                body += f" ×{m.repeat}"
            t.append(_cut(f" #{m.num:02d}→{_dst(m.dst)} {body}", width) + "\n")
        t.rstrip()
        return t, "" if in_ring else "silent"

    def default_hint(self) -> str:
        return f"passive listener on {self.port}: nothing is sent, so kill/revive/steal/noise " \
               "keys are disabled · space freezes the view · q quit"

    def action_disabled(self) -> None:
        self.flash("kill/revive/steal/noise work only on the simulator (rprs monitor without "
                   "--radio): this monitor only listens")

    def refresh_view(self) -> None:
        if self.paused:          # frozen: keep collecting, do not redraw
            if self.hint:
                self._set("#hint", Text(self.hint))
            return
        super().refresh_view()


# ---------------------------------------------------------------------------------------------
# Entry points for the CLI


def run_monitor_sim(config: SimConfig, speed: float = 1.0, trace: Any = None,
                    on_event: Callable[[dict], None] | None = None,
                    capture: IO[bytes] | None = None) -> tuple[int, World]:
    """``rprs monitor [sim options] [--speed X]``: run the TUI on a simulated world until q.
    The world stops at ``config.duration`` (the header then says FINISHED). Returns the exit
    status and the world as it was when the view closed. An output that could not be written
    during the run ends the view, and its OSError is raised once the terminal is back."""
    app = SimMonitorApp(config, speed=speed, trace=trace, on_event=on_event, capture=capture)
    app.run()
    if app.write_error is not None:
        raise app.write_error
    return app.return_code or 0, app.world


def run_monitor_radio(port: str) -> int:
    """``rprs monitor --radio PORT``: the TUI on a listening serial port until q.
    Raises :class:`hil.bench.serial_radio.PortError` (one line) when the port cannot be opened.
    A port that went away while listening (PORT LOST) ends it, once the terminal is back,
    with one line ``rprs: error: the radio port PORT went away (...)`` and status 1, as a
    ``rprs bench`` listener's does (it used to end with 0, as if all had gone well)."""
    import sys
    app = RadioMonitorApp(port)
    try:
        app.run()
    finally:
        app.close()
    if app.lost:
        print(f"rprs: error: the radio port {port} went away ({app.sniffer.error}); the view "
              f"showed what was heard until then", file=sys.stderr, flush=True)
        return 1
    return app.return_code or 0


__all__ = ["MonitorApp", "SimMonitorApp", "RadioMonitorApp", "MonitorSniffer",
           "run_monitor_sim", "run_monitor_radio"]
