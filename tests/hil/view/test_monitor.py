"""``rprs monitor`` (hil/view/monitor/), headless with textual's pilot.

The simulator app starts paused and the tests advance its world with ``advance(seconds)``, so
what they check does not depend on how fast the machine is. Where the refresh timer matters the
test waits for a real tick (an event, not a sleep), then pauses ``app.refresh_timer``, gives the
app a :class:`FakeClock` and calls ``tick()`` itself, so the wall time between ticks is exact.
"""
from __future__ import annotations

import asyncio
import os
import sys
import time
from collections import deque

import pytest

pytest.importorskip("textual")

from firmware_model.cycle_costs import DEFAULT_COSTS  # noqa: E402
from firmware_model.radio.frame import Frame  # noqa: E402
from firmware_model.timing import TICK_HZ, TMAX_TICKS  # noqa: E402
from hil.bench.scripts import HeardFrame  # noqa: E402
from hil.view.monitor import RadioMonitorApp, SimMonitorApp  # noqa: E402
from hil.sim.world import SimConfig  # noqa: E402
from textual.widgets import Static  # noqa: E402
from pilots import stopped_within  # noqa: E402

SIZE = (140, 40)


def run(coro):
    return asyncio.run(coro)


def sim(robots=(1, 2, 3, 4), **kw) -> SimMonitorApp:
    return SimMonitorApp(SimConfig(robots=robots, duration=600.0, **kw), paused=True)


class FakeClock:
    """A wall clock (for ``app.clock``) that moves only when the test moves it."""

    def __init__(self, t: float = 0.0) -> None:
        self.t = t

    def __call__(self) -> float:
        return self.t

    def advance(self, dt: float) -> None:
        self.t += dt


def test_a_pane_per_robot_and_the_ring_after_advancing():
    app = sim(load=2.0)

    async def go():
        async with app.run_test(size=SIZE) as pilot:
            for r in (1, 2, 3, 4):
                assert app.query_one(f"#robot-{r}") is not None
            app.advance(5.0)
            await pilot.pause()
            head = app.shown("#header")
            assert "ring [1 2 3 4]" in head and "out:" not in head
            assert "t = 5.000 s" in head and "PAUSED" in head
            assert app.ring() == ((1, 2, 3, 4), True)
            for r in (1, 2, 3, 4):
                pane = app.shown(f"#robot-{r}")
                assert pane.startswith("member") and "missed 0" in pane
            # messages received show source, Number and Content (paper Fig. 9's list box)
            rs = [r for r in (1, 2, 3, 4) if app.received[r]]
            assert rs
            r = rs[0]
            m = app.received[r][-1]
            dst = "all" if m.dst == 7 else str(m.dst)
            assert f" {m.src}#{m.num:02d}→{dst} {m.content[:10]}" in app.shown(f"#robot-{r}")
    run(go())


def test_kill_and_revive_with_keys():
    app = sim()

    async def go():
        async with app.run_test(size=SIZE) as pilot:
            app.advance(5.0)
            occ = app.world.air.occupations
            assert "ring [1 2 3 4]" in app.shown("#header")
            await pilot.press("k")
            assert "kill which robot?" in app.shown("#hint")
            await pilot.press("1")
            assert not app.world.radios[1].alive
            assert app.shown("#robot-1").startswith("RADIO OFF")
            assert "radio of robot 1 killed" in app.shown("#events")
            app.advance(4.0)                   # 3 misses of robot 1 and more
            await pilot.pause()
            head = app.shown("#header")
            assert "ring [2 3 4]" in head and "out: 1" in head
            assert app.ring()[0] == (2, 3, 4)
            assert app.world.air.occupations > occ
            assert "robot 1 dropped from the ring" in "\n".join(app.events)
            await pilot.press("r", "1")
            assert app.world.radios[1].alive
            app.advance(6.0)
            await pilot.pause()
            assert "ring [1 2 3 4]" in app.shown("#header")
            assert app.ring() == ((1, 2, 3, 4), True)
            # a digit without k/r/s does nothing; a robot not simulated is refused
            await pilot.press("2")
            assert app.world.radios[2].alive
            await pilot.press("k", "6")
            assert "robot 6 is not in this simulation" in app.shown("#hint")
    run(go())


def test_noise_toggle_and_steal():
    app = sim(robots=(0, 1, 2))

    async def go():
        async with app.run_test(size=SIZE) as pilot:
            app.advance(4.0)
            await pilot.press("n")
            assert app.world.air.noise and "noise ON" in app.shown("#header")
            before = sum(st.garbage_bytes for st in app.world.stations.values())
            app.advance(1.0)
            after = sum(st.garbage_bytes for st in app.world.stations.values())
            assert after - before > 100          # ~200 noise bytes/s between the frames
            await pilot.press("n")               # noise heard up to now is delivered
            assert not app.world.air.noise and "noise off" in app.shown("#header")
            off = sum(st.garbage_bytes for st in app.world.stations.values())
            app.advance(1.0)
            assert sum(st.garbage_bytes for st in app.world.stations.values()) == off
            c = app.world.collisions
            await pilot.press("s", "2")          # robot 2 wrongly takes the turn
            for _ in range(10):                  # (a collision if someone else is on air)
                app.advance(0.007)
                if app.world.collisions > c:
                    break
                app.fault("steal", 2)
            assert app.world.collisions > c
            assert "collision between robots" in "\n".join(app.events)
            assert "robot 2 steals the turn" in "\n".join(app.events)
            app.advance(4.0)
            assert app.ring() == ((0, 1, 2), True)     # the ring recovers
    run(go())


def test_timer_pause_speed_and_quit(tmp_path):
    ticked = asyncio.Event()

    class Ticks(SimMonitorApp):
        def tick(self) -> None:
            super().tick()
            ticked.set()

    app = Ticks(SimConfig(robots=(1, 2, 3), duration=600.0), speed=8.0)
    clock = app.clock = FakeClock(100.0)

    async def go():
        async with app.run_test(size=SIZE) as pilot:
            await asyncio.wait_for(ticked.wait(), 10.0)   # the view's timer calls tick()
            assert app.world.now == 0                     # no wall time passed: none owed
            app.refresh_timer.pause()                     # from here the test ticks
            t0 = clock()
            for _ in range(4):
                clock.advance(0.125)
                app.tick()
            wall = clock() - t0
            assert 0.3 * 8 * wall * TICK_HZ < app.world.now <= 8 * (wall + 1.0) * TICK_HZ
            assert app.world.now == 4 * TICK_HZ           # ×8 of 0.5 s, nothing dropped
            await pilot.press("space")
            assert app.paused
            clock.advance(0.15)
            app.tick()
            t2 = app.world.now
            clock.advance(0.25)
            app.tick()
            assert app.world.now == t2 and "PAUSED" in app.shown("#header")
            await pilot.press("plus")
            assert app.speed == 16.0 and "×16" in app.shown("#header")
            await pilot.press("minus", "minus", "minus", "minus", "minus")
            assert app.speed == 0.5 and "×1/2" in app.shown("#header")
            await pilot.press("space")
            assert not app.paused
            svg = app.save_screenshot("monitor.svg", path=str(tmp_path))
            with open(svg, encoding="utf-8") as fh:
                assert "robot" in fh.read()
            await pilot.press("q")
            await pilot.pause()
        assert app.return_code == 0
    run(go())


def test_the_world_stops_at_its_duration():
    app = SimMonitorApp(SimConfig(robots=(1, 2), duration=2.0), paused=True)

    async def go():
        async with app.run_test(size=SIZE) as pilot:
            app.advance(5.0)
            await pilot.pause()
            assert app.finished and "FINISHED" in app.shown("#header")
            assert app.world.now == 2 * TICK_HZ
            # a fault key once the run is over changes nothing and says why
            events = list(app.events)
            await pilot.press("k", "1")
            assert app.world.radios[1].alive and list(app.events) == events
            assert "the run has finished" in app.shown("#hint")
            await pilot.press("n")
            assert not app.world.air.noise and list(app.events) == events
    run(go())


def test_radio_monitor_on_the_hub_shows_the_robot():
    pytest.importorskip("serial")
    from hil.bench.radio_hub import RadioHub

    with RadioHub(3) as hub:
        hub.start()
        app = RadioMonitorApp(hub.paths[0])
        fd = os.open(hub.paths[2], os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        try:
            async def go():
                async with app.run_test(size=SIZE) as pilot:
                    app.refresh_timer.pause()     # the test drains and redraws: tick()
                    for n in (7, 8):
                        os.write(fd, Frame(dst=7, src=2, num=n, type=3,
                                           content=b"movex(10)").encode())
                    end = time.monotonic() + 5.0
                    app.tick()
                    while app.count[2] < 2 and time.monotonic() < end:
                        await asyncio.sleep(0.005)   # real I/O: the sniffer thread reads
                        app.tick()
                    assert app.count[2] == 2
                    pane = app.shown("#robot-2")
                    assert pane.startswith("in ring") and "frames 2" in pane
                    assert "#08→all movex(10)" in pane
                    assert app.shown("#robot-1") == "not heard"
                    head = app.shown("#header")
                    assert "ring [2]" in head and "turn: 2" in head
                    assert "occupations 2" in head
                    assert "disabled" in app.shown("#hint")
                    await pilot.press("k")
                    assert "only listens" in app.shown("#hint")
                    await pilot.press("q")
            run(go())
        finally:
            os.close(fd)
            app.close()
    assert app.return_code == 0


def test_radio_monitor_infers_missed_turns():
    """A gap of about Tmax or more between two frames is charged to the members skipped."""
    app = RadioMonitorApp.__new__(RadioMonitorApp)       # no port: only the bookkeeping
    app.robots = tuple(range(7))
    app.window = 3.0
    app.events = deque(maxlen=10)
    app.heard = {r: deque(maxlen=10) for r in app.robots}
    app.count = {r: 0 for r in app.robots}
    app.missed = {r: 0 for r in app.robots}
    app.last_heard = {}
    app.last = None
    app._ring_seen = set()
    bt = 16667
    t = 0
    for src in (1, 2, 3, 1, 2, 3):                       # ring 1 2 3, tight turns
        app.feed(HeardFrame(src, 7, 0, 3, 14, t, t + 14 * bt), b"")
        t += 14 * bt + 80_000
    t += TMAX_TICKS                                      # robot 1 misses its turn
    app.feed(HeardFrame(2, 7, 1, 3, 14, t, t + 14 * bt), b"")
    assert app.missed == {0: 0, 1: 1, 2: 0, 3: 0, 4: 0, 5: 0, 6: 0}


def test_no_refresh_while_the_view_is_taken_down():
    """Regression (NoMatches '#robot-N' in about one run in five): the refresh timer belonged to
    the app, which textual closes only after it has removed the screen's widgets, so a tick due
    in that window looked the panes up after they were gone. A widget that holds the teardown
    open until a refresh comes (or 25 refresh periods pass) makes the window wide: no refresh may
    run once the widgets start going, and the app must close without an error."""
    rate = 50.0
    state = {"down": False, "late": 0}
    refreshed = asyncio.Event()

    class HoldOpen(Static):
        async def on_unmount(self) -> None:
            state["down"] = True
            try:
                await asyncio.wait_for(refreshed.wait(), 25 / rate)
            except asyncio.TimeoutError:
                pass

    class Probe(SimMonitorApp):
        def compose(self):
            yield from super().compose()
            yield HoldOpen()

        def refresh_view(self) -> None:
            if state["down"]:
                state["late"] += 1
                refreshed.set()
            super().refresh_view()

    app = Probe(SimConfig(robots=(1, 2, 3, 4), duration=600.0), paused=True, rate=rate)

    async def go():
        async with app.run_test(size=SIZE) as pilot:
            app.advance(1.0)
            await pilot.pause()
            assert app.shown("#robot-1").startswith(("member", "listen"))
    run(go())                                  # raised NoMatches here before the fix
    assert state["down"] and state["late"] == 0


def test_after_exit_the_world_runs_and_nothing_is_drawn():
    """Once the view is gone its timer is gone too, and a direct advance()/tick() only runs the
    model (nothing is looked up or drawn, nothing raises)."""
    app = sim(robots=(1, 2))

    async def go():
        async with app.run_test(size=SIZE) as pilot:
            assert app.view_ready and app.refresh_timer is not None
            app.advance(1.0)
            await pilot.press("q")
            await pilot.pause()
    run(go())
    assert app.return_code == 0
    assert not app.view_ready and app.refresh_timer is None
    head = app.shown("#header")
    assert "t = 1.000 s" in head
    app.advance(1.0)
    app.tick()
    assert app.world.now == 2 * TICK_HZ and app.shown("#header") == head


def test_the_monitor_writes_the_trace_and_waveform_it_shows(tmp_path):
    """``rprs monitor --trace/--vcd`` once listed the options and ignored them. The trace of
    a monitored world is the simulator's trace of the same seed, up to where the view was."""
    import json

    from hil.cli import main
    from hil.sim.trace import TraceWriter, read_trace
    from hil.view.vcd import VcdTraceWriter
    # on the CPU model, as ``rprs monitor`` and ``rprs sim`` run by default
    cfg = dict(robots=(1, 2, 3), seed=5, load=2.0, cpu=DEFAULT_COSTS)
    trace, vcd = TraceWriter(str(tmp_path / "m.jsonl")), VcdTraceWriter(str(tmp_path / "m.vcd"))
    app = SimMonitorApp(SimConfig(duration=600.0, **cfg), paused=True, trace=trace,
                        listeners=[vcd.write])

    async def go():
        async with app.run_test(size=SIZE) as pilot:
            app.advance(3.0)
            await pilot.pause()
    run(go())
    trace.close()
    vcd.close()
    assert main(["sim", "--robots", "1,2,3", "--seed", "5", "--load", "2", "--duration", "3",
                 "--trace", str(tmp_path / "s.jsonl"), "--no-progress"]) == 0
    mon = [e for e in read_trace(str(tmp_path / "m.jsonl")) if e["ev"] != "meta"]
    ref = [e for e in read_trace(str(tmp_path / "s.jsonl")) if e["ev"] != "meta"]
    end = 3 * TICK_HZ
    assert len(ref) > 100
    assert [e for e in mon if e["t"] < end] == [e for e in ref if e["t"] < end]
    assert (tmp_path / "m.vcd").read_text().startswith("$")
    assert json.loads((tmp_path / "m.jsonl").read_text().splitlines()[0])["ev"] == "meta"


def test_monitor_outputs_with_a_radio_are_refused_in_one_line(capsys):
    from hil.cli import main
    assert main(["monitor", "--radio", "/dev/null", "--trace", "x.jsonl"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--trace: only for the simulated ring" in err
    assert main(["monitor", "--no-progress"]) == 2          # no progress bar to turn off


def test_a_speed_the_keys_cannot_reach_is_refused_and_any_speed_shows_as_it_is():
    """``--speed 10000`` ran at 4096 and ``--speed 0.001`` at 1/64 without a word, and
    ``--speed 0.75`` showed as ×1/1."""
    from hil.cli import UserError, build_parser
    from hil.view.monitor import _speed_text
    parser = build_parser(("monitor",))
    for bad in ("10000", "0.001"):            # parsed only: a taken speed would run the view
        with pytest.raises(UserError, match=f"'{bad}' is outside 1/64 to 4096"):
            parser.parse_args(["monitor", "--speed", bad])
    assert parser.parse_args(["monitor", "--speed", "0.75"]).speed == 0.75
    assert [_speed_text(s) for s in (1 / 64, 0.5, 0.75, 0.3, 1, 1.5, 4096)] == \
        ["×1/64", "×1/2", "×0.75", "×0.3", "×1", "×1.5", "×4096"]


def _once_drawn(p, master: int, text: bytes, act) -> tuple[bytes, bytearray]:
    """Keep the pty's master drained (a full pty blocks the monitor's writes), wait until
    ``text`` is drawn, ``act()``, and wait for the process: (its stdout, what was drawn)."""
    import threading
    screen = bytearray()

    def read():
        while True:
            try:
                chunk = os.read(master, 65536)
            except OSError:
                return
            if not chunk:
                return
            screen.extend(chunk)
    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        deadline = time.monotonic() + 120
        while text not in screen and p.poll() is None and time.monotonic() < deadline:
            time.sleep(0.1)
        assert text in screen, bytes(screen[-500:])
        act()
        out, _ = p.communicate(timeout=120)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
        os.close(master)
        reader.join(timeout=10)
    return out, screen


def _monitor_cmd(*args):
    import sys
    return [sys.executable, "-m", "hil.cli", "monitor", *args]


def _monitor_in_pty(*args, wide: bool = False):
    """``rprs monitor ARGS`` with a pty for its terminal (stdin and stderr) and stdout a pipe:
    (the process, the pty's master). ``wide``: 200 columns (stdout is a pipe, so the size
    comes from the environment, and 80 columns cut the header's "FINISHED" short)."""
    import pty
    import subprocess
    master, slave = pty.openpty()
    env = dict(os.environ, COLUMNS="200", LINES="50") if wide else None
    p = subprocess.Popen(_monitor_cmd(*args), stdin=slave, stdout=subprocess.PIPE,
                         stderr=slave, start_new_session=True, env=env)
    os.close(slave)
    return p, master


def test_the_monitor_without_a_terminal_is_one_line(tmp_path):
    """``rprs monitor < /dev/null 2> log`` drew the screen's escape codes into the log and,
    with no ``q`` to read, never ended, even after ``--duration``. Without a terminal on stdin
    and stderr it is now one line, before any file is written."""
    import subprocess
    for args in (("--robots", "0,1", "--duration", "1", "--speed", "64", "--trace",
                  str(tmp_path / "t.jsonl")), ("--radio", "/dev/null")):
        r = subprocess.run(_monitor_cmd(*args), stdin=subprocess.DEVNULL, capture_output=True,
                           text=True, timeout=60)
        assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr[:300]
        assert r.stderr.startswith("rprs: error: rprs monitor is a live view: it needs a "
                                   "terminal on stdin and stderr")
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("signame", ["SIGTERM", "SIGHUP"])
def test_sigterm_and_sighup_quit_the_monitor_like_q(tmp_path, signame):
    """SIGTERM (``kill``, ``timeout``) or SIGHUP (the terminal closed) killed the monitor in
    the terminal's alternate screen, with the keyboard still raw, the trace left as
    ``.partial`` and no ``--json`` summary. They now quit as ``q`` does."""
    import signal
    trace = tmp_path / "t.jsonl"
    p, master = _monitor_in_pty("--robots", "0,1", "--trace", str(trace), "--json")
    out, screen = _once_drawn(p, master, b"occupations",
                              lambda: p.send_signal(getattr(signal, signame)))
    assert p.returncode == 0
    assert trace.exists() and not (tmp_path / "t.jsonl.partial").exists()
    assert b'"robots"' in out                                # the --json summary
    assert screen.rfind(b"\x1b[?1049l") > screen.rfind(b"occupations")   # screen restored


def test_a_radio_port_that_goes_away_is_said(tmp_path):
    """With the radio hub stopped (or a USB radio unplugged) under ``rprs monitor --radio``,
    the sniffer's thread ended in silence and the view went on as if listening to a quiet
    ring. The header now says the port is lost and the events line says why."""
    pytest.importorskip("serial")
    from hil.bench.radio_hub import RadioHub

    hub = RadioHub(2).start()
    app = RadioMonitorApp(hub.paths[0])
    try:
        async def go():
            async with app.run_test(size=SIZE) as pilot:
                app.refresh_timer.pause()         # the test drains and redraws: tick()
                app.tick()
                assert "PORT LOST" not in app.shown("#header")
                hub.close()
                end = time.monotonic() + 30.0     # a bound, not a timing: real I/O
                while app.sniffer.error is None and time.monotonic() < end:
                    await asyncio.sleep(0.01)
                app.tick()
                assert "PORT LOST" in app.shown("#header")
                assert f"port {hub.paths[0]} lost: " in app.shown("#events")
                await pilot.press("q")
        run(go())
    finally:
        hub.close()
        app.close()
    assert app.return_code == 0


@pytest.mark.parametrize("mac", ["aloha", "slotted", "csma"])
def test_a_peer_mac_is_refused_in_one_line(capsys, mac):
    """``rprs monitor --mac aloha`` (an option it shares with rprs sim) drew its first
    refresh into a traceback: AttributeError: 'AlohaMac' object has no attribute 'outbox'.
    The view is the rotational MAC's ring; a peer MAC is refused before anything runs."""
    from hil.cli import main
    assert main(["monitor", "--robots", "1,2,3", "--mac", mac]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--mac {mac}: the monitor shows the rotational MAC" in err


def test_every_kind_of_fault_shows_in_the_events():
    """``rprs monitor --fault drop@1-2:0.002`` (or ber, burst, busoff, stall, ...: any
    ``--fault`` but fail, recover and steal) ended in a traceback, KeyError: 'drop', when the
    fault began: the events line knew only the monitor's own three keys. Every fault now shows
    as it starts and ends."""
    from hil.sim.faults import parse_fault
    specs = ("drop@1-2:0.002", "ber@0.5-1.5:0.001", "burst@1.2:0.05", "busoff:1@1",
             "stall:2.JOINT1@1.5", "fail:3@2", "recover:3@2.5")
    app = sim(robots=(0, 1, 2, 3), can=True,
              faults=tuple(sorted((parse_fault(s) for s in specs), key=lambda f: f.at)))
    app.advance(3.0)
    shown = "\n".join(app.events)
    for line in ("fault drop@1-2:0.002 starts", "fault drop ends", "fault busoff:1@1 starts",
                 "fault stall:2.JOINT1@1.5 starts", "fault ber ends",
                 "radio of robot 3 killed", "radio of robot 3 revived"):
        assert line in shown, (line, shown)


def test_a_capture_with_a_radio_is_refused_in_one_line(tmp_path, capsys):
    from hil.cli import main
    pcap = tmp_path / "m.pcapng"
    assert main(["monitor", "--radio", "/dev/null", "--pcap", str(pcap)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--pcap: only for the simulated ring" in err, err
    assert not pcap.exists()


def test_the_monitor_captures_what_it_shows(tmp_path):
    """``rprs monitor --pcap FILE`` was refused (it once was accepted and wrote nothing).
    The capture of a monitored world is the simulator's capture of the same seed, up to
    where the view was."""
    import pcapng

    from hil.cli import main
    with open(tmp_path / "m.pcapng", "wb") as f:
        app = SimMonitorApp(SimConfig(robots=(1, 2, 3), seed=5, load=2.0, duration=600.0,
                                      can=True, cpu=DEFAULT_COSTS),
                            paused=True, capture=f)

        async def go():
            async with app.run_test(size=SIZE) as pilot:
                app.advance(3.0)
                await pilot.pause()
        run(go())
    assert main(["sim", "--robots", "1,2,3", "--seed", "5", "--load", "2", "--can",
                 "--duration", "3", "--pcap", str(tmp_path / "s.pcapng"), "--no-progress"]) == 0

    def packets(name):
        with open(tmp_path / name, "rb") as f:
            return [(b.interface_id, b.timestamp_high, b.timestamp_low, b.packet_data)
                    for b in pcapng.FileScanner(f) if isinstance(b, pcapng.blocks.EnhancedPacket)]
    mon, ref = packets("m.pcapng"), packets("s.pcapng")
    assert len(ref) > 200
    assert mon == ref


def test_the_monitor_reports_the_cpu_budget_of_what_it_ran(tmp_path):
    """``rprs monitor --cpu estimated --cpu-report --json``: the report of the world up to
    where the view was closed, inside the summary, as ``rprs sim`` gives it."""
    import json
    import subprocess
    pcap = tmp_path / "m.pcapng"
    p, master = _monitor_in_pty("--robots", "0,1", "--can", "--cpu", "estimated",
                                "--cpu-report", "--json", "--duration", "2", "--speed", "64",
                                "--pcap", str(pcap), wide=True)
    out, _ = _once_drawn(p, master, b"FINISHED", lambda: os.write(master, b"q"))
    assert p.returncode == 0
    sim = subprocess.run([sys.executable, "-m", "hil.cli", "sim", "--robots", "0,1", "--can",
                          "--cpu", "estimated", "--cpu-report", "--json", "--duration", "2",
                          "--no-progress"], capture_output=True, text=True, timeout=120)
    got, want = json.loads(out), json.loads(sim.stdout)
    # the view's own wall time and speed (it said 0.0 and null): the run paced at --speed 64
    assert got["wall_seconds"] > 0 and 0 < got["speed"] <= 64 * 1.1
    for d in (got, want):
        del d["wall_seconds"], d["speed"]
    assert want["cpu_report"]["1"]["handlers"] and want["duration_ticks"] == 2 * TICK_HZ
    assert got == want
    assert pcap.stat().st_size > 1000


def test_an_output_that_fills_the_disk_ends_the_monitor_in_one_line(tmp_path, full_device):
    """``rprs monitor --trace FILE`` on a full disk: the run's OSError was caught by the
    terminal UI, which printed a page of traceback, and the outputs were closed as if the run
    had gone well. It now ends the view and says which output, in one line, and leaves none."""
    pcap = tmp_path / "m.pcapng"
    p, master = _monitor_in_pty("--robots", "0,1,2", "--speed", "4096", "--duration", "600",
                                "--trace", str(full_device), "--pcap", str(pcap))
    _, screen = _once_drawn(p, master, b"No space left on device", lambda: None)
    assert p.returncode == 2
    assert b"Traceback" not in screen and b"locals" not in screen
    tail = screen[screen.rfind(b"\x1b[?1049l"):]          # after the screen was restored
    assert f"rprs: error: cannot write trace {full_device}: No space left on device".encode() \
        in tail, bytes(tail[-300:])
    assert not pcap.exists() and not list(tmp_path.glob("*.partial"))


@pytest.mark.parametrize("failing,kept", [("--trace", "--pcap"), ("--pcap", "--trace")])
def test_an_output_that_cannot_be_finished_leaves_the_other_whole(tmp_path, full_device,
                                                                  failing, kept):
    """As ``rprs sim`` (tests/hil/test_cli.py, the same test): a run so short that its trace (or
    capture) is written only when it is finished, on a full disk, quit with ``q`` once
    FINISHED: one line naming the output that failed, status 2, and the other output kept,
    whole, as ``rprs sim`` writes it for the same run (the code's comment said a trace that
    cannot be finished leaves no capture; it left it, and ``rprs sim`` removed a trace whose
    capture failed: both now keep every complete output)."""
    import subprocess
    import sys
    run = ["--robots", "1,2", "--duration", "0.2"]
    name = {"--trace": "t.jsonl", "--pcap": "p.pcapng"}
    whole = tmp_path / "whole" / name[kept]
    whole.parent.mkdir()
    subprocess.run([sys.executable, "-m", "hil.cli", "sim", *run, kept, str(whole)],
                   check=True, capture_output=True, timeout=120)
    out = tmp_path / name[kept]
    p, master = _monitor_in_pty(*run, "--speed", "64", kept, str(out), failing,
                                str(full_device), wide=True)
    _, screen = _once_drawn(p, master, b"FINISHED", lambda: os.write(master, b"q"))
    assert p.returncode == 2
    tail = screen[screen.rfind(b"\x1b[?1049l"):]          # after the screen was restored
    what = {"--trace": "trace", "--pcap": "capture"}[failing]
    assert f"rprs: error: cannot write {what} {full_device}: No space left on device".encode() \
        in tail, bytes(tail[-300:])
    assert out.read_bytes() == whole.read_bytes()
    assert not list(tmp_path.glob("*.partial")) and full_device.is_char_device()


class _Terminal:
    """``rprs monitor`` on a pty of ``cols`` x ``rows`` that is its controlling terminal (as a
    terminal window's or tmux's is), stdout to a pipe; ``screen`` collects what it drew."""

    def __init__(self, tmp_path, *args, cols=100, rows=30, ctty=True):
        import fcntl
        import pty
        import struct
        import subprocess
        import termios
        import threading
        self.master, slave = pty.openpty()
        self.resize(cols, rows, fd=slave)

        def controlling():                  # after setsid: the pty becomes the session's tty
            fcntl.ioctl(0, termios.TIOCSCTTY, 0)
        self.p = subprocess.Popen(_monitor_cmd(*args), stdin=slave, stdout=subprocess.PIPE,
                                  stderr=slave, start_new_session=True,
                                  preexec_fn=controlling if ctty else None)
        os.close(slave)
        self.screen = bytearray()
        self._struct = struct
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self):
        while True:
            try:
                chunk = os.read(self.master, 65536)
            except OSError:
                return
            if not chunk:
                return
            self.screen.extend(chunk)

    def resize(self, cols, rows, fd=None):
        import fcntl
        import struct
        import termios
        fcntl.ioctl(self.master if fd is None else fd, termios.TIOCSWINSZ,
                    struct.pack("HHHH", rows, cols, 0, 0))

    def wait_for(self, text: bytes, since: int = 0, timeout: float = 120,
                 plain: bool = False) -> int:
        """Wait until ``text`` is drawn after offset ``since``; its offset. ``plain``: in
        the drawing without its SGR escapes (colours, which may split a border)."""
        import re

        def find():
            screen = bytes(self.screen)
            if plain:
                screen = screen[:since] + re.sub(rb"\x1b\[[0-9;]*m", b"", screen[since:])
            return screen.find(text, since), len(self.screen)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and self.p.poll() is None:
            at, end = find()
            if at >= 0:
                return end if plain else at
            time.sleep(0.05)
        at, end = find()
        assert at >= 0, (text, bytes(self.screen[-400:]))
        return end if plain else at

    def close(self):
        if self.p.poll() is None:
            self.p.kill()
            self.p.wait()
        try:
            os.close(self.master)
        except OSError:
            pass
        self.reader.join(timeout=10)


def _top_border(cols: int) -> bytes:
    return ("╭" + "─" * (cols - 2) + "╮").encode()


def test_the_view_takes_the_size_of_its_terminal_with_stdout_in_a_file(tmp_path):
    """``rprs monitor --json > summary.json`` (docs/monitor.md) drew an 80x24 view in the
    corner of a 100x30 terminal, and kept it through every resize: textual sized the view by
    stdout, a file, and fell back to 80x24. It is now sized by the terminal it draws on, and
    follows it (a tiny one too, and back)."""
    import signal
    term = _Terminal(tmp_path, "--robots", "0,1", "--json", cols=100, rows=30)
    try:
        at = term.wait_for(_top_border(100), plain=True)
        for cols, rows in ((20, 5), (90, 30)):
            term.resize(cols, rows)
            term.p.send_signal(signal.SIGWINCH)   # what the kernel sends the foreground group
            at = term.wait_for(_top_border(cols), since=at, plain=True)
        term.p.send_signal(signal.SIGTERM)
        out, _ = term.p.communicate(timeout=60)
    finally:
        term.close()
    assert term.p.returncode == 0 and b'"robots"' in out
    assert b"Traceback" not in term.screen


def test_closing_the_terminal_ends_the_monitor_with_its_outputs_complete(tmp_path):
    """Closing the terminal under ``rprs monitor --trace ... --pcap ... --json`` (``tmux
    kill-session``, run from a shell): the view's writes to the dead terminal failed at once
    (EIO), textual's writer thread died of the first, its queue filled, and the view blocked
    for ever on its next write, so the SIGHUP that came when the shell ended never quit it: a
    process left running, the trace and capture ``.partial``, no summary. Writes to a terminal
    that has gone are now dropped, and the SIGHUP ends it as ``q`` does: status 0, every
    output complete. (Here the terminal is not the monitor's controlling terminal, so the
    hangup reaches it when the test says, as the shell's exit passes it on.)"""
    import signal
    trace, pcap = tmp_path / "t.jsonl", tmp_path / "t.pcapng"
    term = _Terminal(tmp_path, "--robots", "0,1,2", "--load", "1", "--trace", str(trace),
                     "--pcap", str(pcap), "--json", ctty=False)
    try:
        term.wait_for(b"occupations")
        os.close(term.master)                 # the terminal goes: every write fails (EIO)
        time.sleep(4)                         # 40 refreshes: more than textual's queue holds
        term.p.send_signal(signal.SIGHUP)     # the hangup, passed on as the shell ends
        out, _ = term.p.communicate(timeout=60)
    finally:
        term.close()
    assert term.p.returncode == 0
    assert b'"robots"' in out                 # the --json summary, on stdout
    assert trace.exists() and pcap.exists() and not list(tmp_path.glob("*.partial"))
    assert trace.read_text().endswith("\n")


def test_ctrl_z_suspends_the_monitor_and_it_comes_back(tmp_path):
    """Ctrl-Z reached the view as a key it ignored (the terminal is raw), so a shell's Ctrl-Z
    and ``fg`` did nothing. It now suspends the process, the terminal restored; on SIGCONT
    (``fg``) the view is drawn again and ``q`` still quits with the trace whole."""
    import signal
    trace = tmp_path / "t.jsonl"
    term = _Terminal(tmp_path, "--robots", "0,1", "--trace", str(trace))

    def state():
        with open(f"/proc/{term.p.pid}/stat") as f:
            return f.read().rpartition(")")[2].split()[0]
    try:
        at = term.wait_for(b"occupations")
        os.write(term.master, b"\x1a")                     # Ctrl-Z
        deadline = time.monotonic() + 60
        while state() != "T" and time.monotonic() < deadline:
            time.sleep(0.05)
        assert state() == "T"
        left = term.wait_for(b"\x1b[?1049l", since=at)     # the normal screen back
        term.p.send_signal(signal.SIGCONT)                 # fg
        term.wait_for(b"occupations", since=left)
        os.write(term.master, b"q")
        term.p.communicate(timeout=60)
    finally:
        term.close()
    assert term.p.returncode == 0
    assert trace.exists() and not (tmp_path / "t.jsonl.partial").exists()


def test_a_quit_signal_while_the_view_starts_or_ends_does_not_kill_it():
    """SIGTERM or SIGHUP in the moment between ``rprs monitor`` opening its outputs and the
    view taking the signals (or between the view going and the outputs being closed) killed
    the process, its trace and capture left ``.partial`` (a terminal closed, or ``timeout``,
    just as it started). ``rprs monitor`` now holds them from the start: one that came before
    the view was up quits it as soon as it is, as ``q`` does."""
    import signal
    from hil.view.monitor import quit_signals
    app = sim(robots=(0, 1))
    quits = []
    exit_ = app.exit
    app.exit = lambda *a, **k: (quits.append(app.view_ready), exit_(*a, **k))[1]
    with quit_signals:
        os.kill(os.getpid(), signal.SIGTERM)          # held: this process goes on
        assert quit_signals.seen

        async def go():
            async with app.run_test(size=SIZE) as pilot:
                await pilot.pause()
                assert quits and all(quits)           # quit by itself, once the view was up
        run(go())
        assert app.return_code == 0 and not app.view_ready
        os.kill(os.getpid(), signal.SIGHUP)           # after the view: held still
    assert signal.getsignal(signal.SIGTERM) is not quit_signals.note


def test_a_radio_port_lost_under_the_monitor_ends_it_with_status_1(tmp_path):
    """``rprs monitor --radio PORT`` whose port went away (the hub stopped, a USB radio
    pulled) said PORT LOST, but quitting then ended with status 0, as if all had gone well,
    while ``rprs bench`` listeners and robots end with 1 there. It now ends with one line
    saying so, after the terminal is back, and status 1."""
    pytest.importorskip("serial")
    from hil.bench.radio_hub import RadioHub
    hub = RadioHub(2).start()
    term = None
    try:
        term = _Terminal(tmp_path, "--radio", hub.paths[0])
        at = term.wait_for(b"occupations")
        hub.close()
        term.wait_for(b"PORT LOST", since=at)
        os.write(term.master, b"q")
        term.p.communicate(timeout=60)
        term.reader.join(timeout=10)          # all it drew: the pty ends with the process
        restored = term.wait_for(b"\x1b[?1049l", since=at)
        line = term.wait_for(f"rprs: error: the radio port {hub.paths[0]} went away (".encode(),
                             since=restored, timeout=10)
    finally:
        hub.close()
        if term is not None:
            term.close()
    assert term.p.returncode == 1 and line > restored
    assert b"Traceback" not in term.screen


@pytest.mark.parametrize("port,why", [("/tmp", "Is a directory"),
                                      ("/dev/null", "not a serial port (it takes no serial "
                                                    "settings)")])
def test_a_radio_port_that_is_no_serial_port_is_one_plain_line(port, why):
    """``rprs monitor --radio /tmp`` said ``cannot open serial port /tmp: [Errno 21] could not
    open port /tmp: [Errno 21] Is a directory: '/tmp'``, and ``--radio /dev/null`` ``Could not
    configure port: (25, 'Inappropriate ioctl for device')``: pyserial's words twice over.
    The line now says why, once."""
    pytest.importorskip("serial")
    from hil.bench.serial_radio import PortError, open_port
    with pytest.raises(PortError) as e:
        open_port(port)
    assert str(e.value) == f"cannot open serial port {port}: {why}"


def test_ctrl_c_quits_the_monitor():
    """Ctrl-C in the live monitor only showed "Press ctrl+q to quit" (textual's own binding),
    although every other rprs process stops on it. It now quits."""
    app = sim()

    async def go():
        async with app.run_test(size=SIZE) as pilot:
            await pilot.press("ctrl+c")
            assert await stopped_within(app, pilot)
    run(go())
