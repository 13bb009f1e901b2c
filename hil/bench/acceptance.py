"""The flash-equivalent acceptance bench: a pytest plugin (loaded by the ``pytest11`` entry
point) and the ``dut`` fixture.

An acceptance test speaks to the device under test (a child robot) only through its external
interfaces: radio bytes (the bench is the father, ID 0, on the same channel) and CAN frames
(the bench owns the child's CAN bus: the joint/wheel/paw submodules and a sniffer). So the same
test passes against:

``--target model``    the firmware model in-process, on the simulated air and CAN bus;
``--target process``  ``rprs child`` as a real-time process, radio through the pty radio hub,
                      CAN through ``rprs_unix`` (or ``--can socketcan:vcan0``);
``--target board``    a flashed MB90F549: ``--radio PORT`` (the bench's radio, ``--txen``) and
                      ``--can INTERFACE:CHANNEL`` (an adapter on the child's CAN bus).

``--target`` takes a comma-separated list (default ``model,process``); every test runs once
per target. ``--dut-id`` is the child's ID (default 1).
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from typing import Any, Callable

import pytest

from can_bus import dbc
from can_bus.frames import CanFrame
from firmware_model.radio.mac import Deliver, MacConfig, Message, Outcome
from firmware_model.timing import TICK_HZ

TARGETS = ("model", "process", "board")


def pytest_addoption(parser: Any) -> None:
    g = parser.getgroup("rprs", "RPRS acceptance tests (flash-equivalent)")
    g.addoption("--target", default="model,process",
                help="model, process and/or board (comma-separated; default: model,process)")
    g.addoption("--radio", dest="rprs_radio", metavar="PORT",
                help="board target: the bench radio's serial port or pyserial URL")
    g.addoption("--can", dest="rprs_can", metavar="INTERFACE:CHANNEL",
                help="board target: the child's CAN bus; process target: instead of rprs_unix")
    g.addoption("--txen", dest="rprs_txen", default="none", choices=("none", "rts", "dtr"),
                help="board target: the bench radio's TXEN line")
    g.addoption("--dut-id", dest="rprs_dut_id", default="1",
                help="the child's robot ID, 1-6 (default 1)")
    g.addoption("--real-submodules", dest="rprs_real_submodules", action="store_true",
                help="board target: the board's own submodules answer (do not emulate them)")


def pytest_configure(config: Any) -> None:
    config.addinivalue_line("markers", "acceptance: speaks to the DUT only through radio and "
                            "CAN (runs once per --target)")
    _targets(config)                  # a wrong --target, or a board without ports: usage error
    _sigterm_as_interrupt()


def _interrupted(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt


@pytest.hookimpl(tryfirst=True)
def pytest_sessionfinish(session: Any) -> None:
    """The devices are down: SIGTERM kills again (an interrupt in pytest's own ending would
    print its traceback)."""
    import signal
    import threading
    if threading.current_thread() is threading.main_thread() and \
            signal.getsignal(signal.SIGTERM) is _interrupted:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _sigterm_as_interrupt() -> None:
    """SIGTERM stops the run as Ctrl-C does: pytest tears the device down (a ``process``
    target's ``rprs child``, its hub, its temporary directory). By default SIGTERM killed
    pytest where it stood, leaving the child running and ``/tmp/rprs-bench-*`` behind.
    Left alone where something else handles it, or off the main thread."""
    import signal
    import threading
    if threading.current_thread() is threading.main_thread() and \
            signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
        signal.signal(signal.SIGTERM, _interrupted)


def _targets(config: Any) -> list[str]:
    given = config.getoption("--target")
    names = [t.strip() for t in given.split(",") if t.strip()]
    if not names:
        # (an unset variable in a CI job: not 'every test skipped', a usage error)
        raise pytest.UsageError(f"--target {given!r} names no target: choose from "
                                f"{', '.join(TARGETS)}")
    bad = [t for t in names if t not in TARGETS]
    if bad:
        raise pytest.UsageError(f"--target {bad[0]!r}: choose from {', '.join(TARGETS)}")
    twice = sorted({t for t in names if names.count(t) > 1})
    if twice:
        raise pytest.UsageError(f"--target names {twice[0]!r} twice: each target once (one "
                                f"device under test each)")
    robot = config.getoption("rprs_dut_id")
    if not str(robot).isdigit() or not 1 <= int(robot) <= 6:
        raise pytest.UsageError(f"--dut-id {robot}: a child's ID is 1-6")
    if "board" in names:
        missing = [what for opt, what in (
            ("rprs_radio", "--radio PORT (the bench radio's serial port)"),
            ("rprs_can", "--can INTERFACE:CHANNEL (the flashed child's CAN bus)"))
            if not config.getoption(opt)]
        if missing:
            raise pytest.UsageError(f"--target board needs {' and '.join(missing)} "
                                    f"(docs/acceptance.md)")
    can_spec = config.getoption("rprs_can") or ""
    if can_spec.partition(":")[0] == "virtual" and {"process", "board"} & set(names):
        # (the CLI's note, made an error here: the tests would fail as if the child were
        # broken, the bench's submodules talking to themselves)
        raise pytest.UsageError(f"--can {can_spec} is python-can's in-process bus: the child "
                                f"under test (--target process or board) cannot reach it; "
                                f"use rprs_unix:DIR, udp_multicast:GROUP or socketcan:vcan0")
    return names


def pytest_generate_tests(metafunc: Any) -> None:
    if "dut" in metafunc.fixturenames:
        metafunc.parametrize("dut_target", _targets(metafunc.config), scope="module")


class Dut:
    """The bench around one device under test. Thread-safe use from the test thread."""

    target = "model"

    def __init__(self, robot: int) -> None:
        self.id = robot
        self.inbox: list[tuple[int, Deliver]] = []        # what the father received
        self.outcomes: list[Outcome] = []
        self.can_log: list[tuple[int, str, dict]] = []    # decoded frames on the DUT's bus
        self.submodules: dict[str, Any] = {}
        self.father: Any = None

    # -- what a test uses --------------------------------------------------------------------

    def send(self, commands: list, type: int = 2, dst: int | None = None) -> Message:
        """The father submits ``commands`` to the DUT (or ``dst``)."""
        return self._call(self.father.submit, self.id if dst is None else dst, commands, type)

    def run_until(self, predicate: Callable[[], bool], timeout: float) -> bool:
        """Let the bench run until ``predicate()`` holds or ``timeout`` seconds (simulated
        for the model) pass; returns the predicate's final value."""
        raise NotImplementedError

    def replies(self, kind: int | None = None) -> list[Deliver]:
        return [d for _, d in self.replies_at(kind)]

    def replies_at(self, kind: int | None = None) -> list[tuple[int, Deliver]]:
        """The DUT's messages to the father with the tick each was delivered (the clock of
        ``frames``' ticks)."""
        return [(t, d) for t, d in list(self.inbox) if d.src == self.id and
                (kind is None or d.type == kind)]

    @staticmethod
    def seconds(ticks: int) -> float:
        return ticks / TICK_HZ

    def frames(self, name: str | None = None) -> list[tuple[int, str, dict]]:
        return [f for f in list(self.can_log) if name is None or f[1] == name]

    def in_ring(self) -> bool:
        return self.id in self.father.mac.ring

    def explain(self, msg: Message | None = None) -> str:
        """What the bench saw, for a failed expectation: the state of the father's message
        ``msg`` (and why it failed), and the robot's last message to the father."""
        text = "".join(c.text() for c in msg.commands) if msg is not None else ""
        parts = [f"the father's {text}: {msg.state}" + (f" ({msg.reason})" if msg.reason
                                                         else "")] if msg is not None else []
        got = self.replies()
        parts.append(f"robot {self.id} sent the father {len(got)} messages" + (
            f", the last Type '{got[-1].type}' {''.join(c.text() for c in got[-1].commands)}"
            if got else ""))
        if not self.in_ring():
            parts.append(f"robot {self.id} is no longer in the father's ring")
        return "; ".join(parts)

    def heard(self) -> str:
        """What the bench's father heard, for a report: nothing, noise, or frames."""
        f = self.father
        return (f"{f.frames_heard} good frames, {f.frames_failed} failed frames and "
                f"{f.garbage_bytes} garbage bytes")

    def now_s(self) -> float:
        raise NotImplementedError

    def close(self) -> None:
        pass

    # -- plumbing ------------------------------------------------------------------------------

    def _call(self, fn: Callable[..., Any], *args: Any) -> Any:
        return fn(*args)

    def _observe(self, st: Any, a: object, now: int) -> None:
        if type(a) is Deliver:
            self.inbox.append((now, a))
        elif type(a) is Outcome:
            self.outcomes.append(a)

    def _sniff(self, frame: CanFrame, start: int, end: int) -> None:
        try:
            name, sig = dbc.decode(frame)
        except dbc.DbcError:
            name, sig = f"0x{frame.id:03x}", {"data": frame.data.hex()}
        self.can_log.append((end, name, sig))


class ModelDut(Dut):
    """The firmware model in-process on the simulated air and CAN bus."""

    target = "model"

    def __init__(self, robot: int) -> None:
        super().__init__(robot)
        from hil.sim.world import SimConfig, World
        self.world = World(SimConfig(robots=(0, robot), duration=10_000.0, can=True))
        self.father = self.world.stations[0]
        self.father.add_observer(self._observe)
        self.submodules = self.world.submodules[robot]
        bus = self.world.can_buses[robot]
        prev_trace = bus.trace
        assert prev_trace is not None           # (the world tallies the bus's frames with it)

        def trace(frame: CanFrame, start: int, end: int, winner: Any) -> None:
            prev_trace(frame, start, end, winner)
            self._sniff(frame, start, end)
        bus.trace = trace

    def run_until(self, predicate: Callable[[], bool], timeout: float) -> bool:
        end = self.world.now + round(timeout * TICK_HZ)
        step = TICK_HZ // 100
        while not predicate() and self.world.now < end:
            self.world.run(self.world.now + step)
        return predicate()

    def now_s(self) -> float:
        return self.world.now / TICK_HZ


class _RealTimeDut(Dut):
    """A bench on the wall clock: its scheduler runs in a background thread."""

    def __init__(self, robot: int) -> None:
        super().__init__(robot)
        from hil.bench.runner import Runner
        self.runner = Runner()
        self._thread: threading.Thread | None = None

    def _start(self) -> None:
        self._thread = threading.Thread(target=self.runner.run, name="bench", daemon=True)
        self._thread.start()

    def _call(self, fn: Callable[..., Any], *args: Any) -> Any:
        done = threading.Event()
        box: list[Any] = []

        def call() -> None:
            try:
                box.append(fn(*args))
            except BaseException as exc:   # noqa: BLE001 - handed to the test thread
                box.append(exc)
            done.set()
        self.runner.sched.post(call)
        if not done.wait(10.0):
            raise TimeoutError("the bench scheduler did not answer within 10 s")
        if isinstance(box[0], BaseException):
            raise box[0]
        return box[0]

    def run_until(self, predicate: Callable[[], bool], timeout: float) -> bool:
        end = time.monotonic() + timeout
        while not predicate() and time.monotonic() < end:
            time.sleep(0.02)
        return predicate()

    def now_s(self) -> float:
        return self.runner.sched.wall() / TICK_HZ

    def _bench_side(self, radio: str, can: str, config: MacConfig, txen: str = "none",
                    emulate: bool = True) -> None:
        from can_bus.submodules import make_submodules
        from firmware_model.kinematics import HOME
        from hil.bench.runner import _can_bus, build_father
        self.father = build_father(self.runner, radio, txen=txen, config=config)
        self.father.add_observer(self._observe)
        bus = _can_bus(self.runner, can, None)
        bus.trace = lambda frame, start, end, node: self._sniff(frame, start, end)
        if emulate:
            self.submodules = make_submodules(self.runner.sched, bus, initial_angles=HOME)

    def close(self) -> None:
        self.runner.stop()
        if self._thread is not None:
            self._thread.join(timeout=5.0)


class ProcessDut(_RealTimeDut):
    """``rprs child`` as a separate real-time process on the pty radio hub and a CAN bus."""

    target = "process"

    def __init__(self, robot: int, can: str | None = None) -> None:
        super().__init__(robot)
        from hil.bench.radio_hub import RadioHub
        self._tmp = tempfile.mkdtemp(prefix="rprs-bench-")
        self.can_spec = can or f"rprs_unix:{self._tmp}/can"
        self.hub = RadioHub(nodes=2, seed=0)
        self.hub.start()
        team = f"0,{robot}"
        self.log_path = os.path.join(self._tmp, "child.log")
        self._log = open(self.log_path, "w")
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "hil.cli", "child", "--id", str(robot), "--radio",
             self.hub.paths[1], "--can", self.can_spec, "--team", team],
            stdout=self._log, stderr=subprocess.STDOUT)
        config = MacConfig(team=frozenset((0, robot)))
        try:
            self._bench_side(self.hub.paths[0], self.can_spec, config)
        except Exception:
            self.runner.run(0)            # closes what the bench side opened
            self.close()                  # the child process, the hub, the directory
            raise
        self._start()

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                self.proc.kill()
        super().close()
        self.hub.stop()
        self.hub.close()
        self._log.close()
        shutil.rmtree(self._tmp, ignore_errors=True)


class BoardDut(_RealTimeDut):
    """A flashed MB90F549 child reached through a bench radio and a CAN adapter."""

    target = "board"

    def __init__(self, robot: int, radio: str, can: str, txen: str, emulate: bool) -> None:
        super().__init__(robot)
        try:
            self._bench_side(radio, can, MacConfig(), txen=txen, emulate=emulate)
        except Exception:
            self.runner.run(0)            # closes the port opened before the bus failed
            raise
        self._start()


@pytest.fixture(scope="module")
def dut(dut_target: str, request: Any):
    """The device under test for this target, with the ring formed, for one test module.

    Not session-wide: a ring left running (a child process, the pty hub's threads and the
    bench side's threads in the test process) after its module went on taking CPU and the
    GIL from every later test of that process; the father console's UI test ran 15 s
    instead of 3, and tests that judge wall-clock timing shared the machine with it."""
    from hil.bench.runner import RunError
    cfg = request.config
    robot = int(cfg.getoption("rprs_dut_id"))
    why = None
    try:
        if dut_target == "model":
            d: Dut = ModelDut(robot)
        elif dut_target == "process":
            d = ProcessDut(robot, cfg.getoption("rprs_can"))
        else:
            radio, can = cfg.getoption("rprs_radio"), cfg.getoption("rprs_can")
            d = BoardDut(robot, radio, can, cfg.getoption("rprs_txen"),
                         not cfg.getoption("rprs_real_submodules"))
    except RunError as exc:           # a port or bus that cannot be opened: one line
        why = f"{dut_target}: the bench cannot start: {exc}"
    if why is not None:
        pytest.fail(why, pytrace=False)
    try:
        if not d.run_until(d.in_ring, 30.0):
            extra = ""
            if isinstance(d, ProcessDut):
                d._log.flush()
                extra = "; child log: " + open(d.log_path).read()[-400:]
            pytest.fail(f"{dut_target}: robot {robot} did not join the father's ring in 30 s; "
                        f"the bench's radio heard {d.heard()}" + extra, pytrace=False)
        yield d
    finally:
        d.close()
