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

The rooms: ``app`` (the view both share: its screen, widgets, timer, keys and quit signals),
``sim`` (the simulator's app, which drives a world), ``radio`` (the listening port's app).
"""
from __future__ import annotations

from typing import IO, Any, Iterable

from ...sim.events import Listener
from ...sim.world import SimConfig, World
from .app import SPEED_MAX, SPEED_MIN, MonitorApp, _speed_text, quit_signals
from .radio import MonitorSniffer, RadioMonitorApp
from .sim import SimMonitorApp

# ---------------------------------------------------------------------------------------------
# Entry points for the CLI


def run_monitor_sim(config: SimConfig, speed: float = 1.0, trace: Any = None,
                    listeners: Iterable[Listener] = (),
                    capture: IO[bytes] | None = None) -> tuple[int, World]:
    """``rprs monitor [sim options] [--speed X]``: run the TUI on a simulated world until q.
    The world stops at ``config.duration`` (the header then says FINISHED). Returns the exit
    status and the world as it was when the view closed. An output that could not be written
    during the run ends the view, and its OSError is raised once the terminal is back."""
    app = SimMonitorApp(config, speed=speed, trace=trace, listeners=listeners, capture=capture)
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


__all__ = ["SPEED_MAX", "SPEED_MIN", "_speed_text", "quit_signals", "MonitorApp",
           "SimMonitorApp", "RadioMonitorApp", "MonitorSniffer", "run_monitor_sim",
           "run_monitor_radio"]
