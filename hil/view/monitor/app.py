"""The live view both ``rprs monitor`` sources share (hil.view.monitor): the screen that owns the
refresh timer, the widgets, the key bindings, the quit signals held while it starts."""
from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Iterable

from rich.text import Text
from textual.app import App, ComposeResult
from textual.binding import Binding
from textual.containers import Grid
from textual.screen import Screen
from textual.timer import Timer
from textual.widgets import Footer, Static

from firmware_model.radio.frame import BROADCAST
from firmware_model.timing import s_to_ticks

if TYPE_CHECKING:
    from ...sim.events import FaultEdge


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


def _fault_line(ev: FaultEdge) -> str:
    """An events line for a world's ``fault`` event: the monitor's own keys in words, any
    other ``--fault`` by its spec as it starts and by its kind and robot as it ends."""
    kind, robot = ev.kind, ev.robot
    if ev.phase == "end":
        return f"fault {kind}{'' if robot is None else f' on robot {robot}'} ends"
    own = {"fail": "radio of robot {} killed", "recover": "radio of robot {} revived",
           "steal": "robot {} steals the turn"}.get(kind)
    return own.format(robot) if own else f"fault {ev.spec or kind} starts"


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
