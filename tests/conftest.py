"""Shared pytest configuration and fixtures."""
from __future__ import annotations

import fcntl
import os
import signal
import stat
import tempfile
import threading
import time
import uuid
from pathlib import Path

import pytest

from firmware_model.radio.mac_guard import ENV as MAC_TABLE_GUARD, table_guard

os.environ[MAC_TABLE_GUARD] = "1"
"""Every ``rprs`` process a test starts checks its MAC against the transition table too."""


@pytest.fixture(autouse=True, scope="session")
def _mac_table_guard():
    """The MAC's transition table guards every event of every rotational MAC the tests run
    in this process (firmware_model/radio/mac_guard.py)."""
    with table_guard():
        yield


REALTIME_MODULES = frozenset({
    "test_bench_processes", "test_bridge", "test_conformance", "test_differential",
    "test_monitor", "test_paper_profile", "test_radio_hub", "test_stranger_robot",
    "test_unixbus", "test_socketcan_smoke", "test_child_acceptance", "test_father_app",
    "test_lost_port", "test_bench_stalls",
})
"""Modules whose tests run on the wall clock: processes on the pty hub, CAN buses between
processes, the timers of a live UI."""

REALTIME_TESTS = frozenset({
    f"tests/{path}::{name}" for path, name in (
        ("firmware_model/radio/test_auth.py",
         "test_forged_and_replayed_frames_are_refused_by_every_process_on_the_hub"),
        ("firmware_model/radio/test_auth.py",
         "test_a_replayed_order_whose_number_went_backwards_is_reported_by_processes_on_the_hub"),
        ("firmware_model/radio/test_auth.py",
         "test_without_the_profile_processes_count_out_of_turn_and_own_id_frames_apart"),
        ("firmware_model/radio/test_auth.py",
         "test_conformance_checks_an_authenticated_childs_frames_and_refusals"),
        ("hil/sim/test_action_sequence.py", "test_in_real_time"),
        ("docs/test_readme_commands.py", "test_the_readme_monitor_command_runs_in_a_terminal"),
        ("firmware_model/radio/test_identity.py",
         "test_a_twin_process_and_a_stranger_team_say_so_and_the_ring_keeps_going"),
        ("firmware_model/radio/test_identity.py",
         "test_a_stalled_original_back_beside_its_twin_leaves_one_robot_2_in_the_ring"),
    )
})
"""Wall-clock tests in modules of the simulator's: processes on the hub, a real-time ring."""

NEEDS_THE_CPU_TARGETS = frozenset({"process"})
"""Acceptance targets (``tests/acceptance``, ``--target``) whose bench father keeps a ring with
a child process: in the fast tier, such a test runs with the CPU to itself (``_exclusive``),
since the other xdist worker's simulator took a core from the child and it missed turns."""


def node_key(nodeid: str) -> str:
    """``path::name`` of a node ID, without its parameters."""
    path, _, name = nodeid.partition("::")
    return f"{path}::{name.partition('[')[0]}"


def is_realtime(nodeid: str) -> bool:
    path = nodeid.partition("::")[0]
    module = path.rpartition("/")[2].removesuffix(".py")
    return module in REALTIME_MODULES or node_key(nodeid) in REALTIME_TESTS


def _lock_base(config) -> Path:
    """Path stem of this test run's lock files (the CPU lock, ``pytest_runtest_protocol``):
    one pair per run, shared by its xdist workers through the run's uid, removed when the run
    ends."""
    worker = getattr(config, "workerinput", None)
    if worker:
        uid = worker["testrunuid"]
    else:
        uid = getattr(config.option, "testrunuid", None) or f"solo-{os.getpid()}"
    return Path(tempfile.gettempdir()) / f"rprs-tests-{uid}"


def pytest_configure(config):
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        # Started as a background job of a shell without job control (``pytest &`` in a
        # script, some CI runners), this process ignores SIGINT, and every program a test
        # starts would inherit that: Python then installs no Ctrl-C handler, and a test that
        # stops ``rprs soak`` with SIGINT saw it run to the end and exit 0. Tests play a terminal's
        # foreground job: Ctrl-C is delivered.
        signal.signal(signal.SIGINT, signal.default_int_handler)
    if not getattr(config, "workerinput", None) and \
            getattr(config.option, "testrunuid", "unset") is None:
        # xdist would draw the uid in its node manager, out of the controller's reach; drawn
        # here, the controller knows which lock files are the run's to remove at its end
        config.option.testrunuid = uuid.uuid4().hex
    config.addinivalue_line(
        "markers",
        "vcan: needs a SocketCAN vcan0 interface (run them for real with scripts/vcan-vm.sh)",
    )
    config.addinivalue_line(
        "markers", "realtime: runs on the wall clock (tests/conftest.py: is_realtime)")


def pytest_unconfigure(config):
    lock = config.stash.get(_CPU_LOCK, None)
    if lock is not None:
        lock.close()
    if not getattr(config, "workerinput", None):
        base = _lock_base(config)
        for suffix in (".turnstile", ".cpu"):
            Path(f"{base}{suffix}").unlink(missing_ok=True)


DEFAULT_TIERS = "not slow and not timing"
"""The ``-m`` of pyproject.toml's addopts: the fast tier, the README's test command."""

VCAN_IN_VM = "RPRS_VCAN_RAN_IN_VM"
"""Set to 1 by .ci/run once scripts/vcan-vm.sh ran the SocketCAN tests (``-m vcan``) inside
its VM and they passed: the host's run, which has no vcan0, then deselects them and says
where they ran, instead of listing them as skipped."""


def _vcan_ran_in_vm() -> bool:
    return os.environ.get(VCAN_IN_VM) == "1" and os.environ.get("RPRS_VCAN") != "1"


def pytest_collection_modifyitems(config, items):
    for item in items:
        if is_realtime(item.nodeid):
            item.add_marker(pytest.mark.realtime)
    if _vcan_ran_in_vm():
        ran = [i for i in items if i.get_closest_marker("vcan")]
        if ran:
            items[:] = [i for i in items if not i.get_closest_marker("vcan")]
            config.hook.pytest_deselected(items=ran)


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    if getattr(config, "workerinput", None):
        return
    if _vcan_ran_in_vm():
        terminalreporter.write_line(
            f"SocketCAN tests (marked vcan) deselected here: {VCAN_IN_VM}=1 says they ran and "
            "passed inside the user-mode Linux VM (scripts/vcan-vm.sh) before this run")
    if config.option.markexpr == DEFAULT_TIERS:
        terminalreporter.write_line(
            "the fast tier: the slow and timing tiers were deselected; "
            "`pytest -m \"slow or timing\"` runs them (CI does, in a step of its own)")


def pytest_xdist_make_scheduler(config, log):
    """Under pytest-xdist (``-n``, as the project's addopts ask), the wall-clock tests are one
    unit of work: they run one after another on one worker, never two at once, while the
    simulator's tests (tick time, no wall clock) share the other workers one test at a time.
    (xdist's own ``loadgroup`` reads groups from node IDs, which pytest 9.2 no longer lets it
    rewrite: pytest-xdist issue 1386.)"""
    if config.getvalue("dist") != "load":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class WallClockTestsApart(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return "realtime" if is_realtime(nodeid) else nodeid

    return WallClockTestsApart(config, log)


@pytest.fixture(params=["virtual", pytest.param("socketcan", marks=pytest.mark.vcan)])
def can_channel(request) -> str:
    """A python-can ``INTERFACE:CHANNEL``: python-can's virtual bus everywhere, and SocketCAN
    vcan0 where the kernel has it (skipped with the reason elsewhere; under RPRS_VCAN=1, as in
    scripts/vcan-vm.sh, a missing vcan0 fails instead)."""
    if request.param == "virtual":
        return f"virtual:rprs-{uuid.uuid4().hex[:8]}"
    return f"socketcan:{_vcan_or_skip()}"


def _vcan_or_skip() -> str:
    """The SocketCAN vcan interface to test on (``RPRS_VCAN_CHANNEL``, default vcan0); skips
    with the reason where the machine has none, fails under RPRS_VCAN=1 (the VM)."""
    from can_bus.bridge import socketcan_missing
    channel = os.environ.get("RPRS_VCAN_CHANNEL", "vcan0")
    why = socketcan_missing(channel)
    if why:
        if os.environ.get("RPRS_VCAN") == "1":
            pytest.fail(f"RPRS_VCAN=1 but {why}")
        pytest.skip(f"{why}; run scripts/vcan-vm.sh for real SocketCAN")
    return channel


_LATENCY = pytest.StashKey()


@pytest.fixture(autouse=True)
def _host_latency(request):
    """A wall-clock test runs beside a probe of the host's scheduling latency
    (tests/hostload.py); if it fails, its report has a section that says how late the host
    woke a sleeping process meanwhile: the product late, or the host busy."""
    if not is_realtime(request.node.nodeid):
        yield
        return
    from hostload import SchedulingLatency
    probe = SchedulingLatency().__enter__()
    request.node.stash[_LATENCY] = probe
    try:
        yield
    finally:
        probe.__exit__(None, None, None)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    probe = item.stash.get(_LATENCY, None)
    if probe is None or call.when != "call":
        return
    rep = outcome.get_result()
    if rep.failed:
        rep.sections.append(("host scheduling latency", str(probe.stop())))


@pytest.fixture
def vcan_channel() -> str:
    """A SocketCAN vcan interface name, e.g. ``vcan0`` (see ``_vcan_or_skip``)."""
    return _vcan_or_skip()


def _exclusive(item) -> bool:
    """Whether ``item`` runs with the CPU to itself: a test of the timing tier (marked
    ``timing``: it judges wall-clock timing, hand-overs to a few ms, gaps, misses), or an
    acceptance test against a child process (``NEEDS_THE_CPU_TARGETS``)."""
    if item.get_closest_marker("timing") is not None:
        return True
    callspec = getattr(item, "callspec", None)
    return callspec is not None and callspec.params.get("dut_target") in NEEDS_THE_CPU_TARGETS


class _CpuLock:
    """This process's hold on the run's CPU lock (``pytest_runtest_protocol``): none, shared
    or exclusive. The lock files are opened once, on first use."""

    def __init__(self, config) -> None:
        base = _lock_base(config)
        self.gate = open(f"{base}.turnstile", "a+")
        self.cpu = open(f"{base}.cpu", "a+")
        self.held: int | None = None

    def take(self, mode: int) -> None:
        if self.held == mode:
            return
        self.release()
        fcntl.flock(self.gate, fcntl.LOCK_EX)
        try:
            fcntl.flock(self.cpu, mode)
        finally:
            fcntl.flock(self.gate, fcntl.LOCK_UN)
        self.held = mode

    def release(self) -> None:
        if self.held is not None:
            fcntl.flock(self.cpu, fcntl.LOCK_UN)
            self.held = None

    def close(self) -> None:
        self.release()
        self.gate.close()
        self.cpu.close()


_CPU_LOCK = pytest.StashKey()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    """The CPU lock: a test that judges wall-clock timing runs alone. On a 2-core machine
    the simulator's tests on the other xdist worker took a core from the robot processes, and
    hand-overs then came 70 ms late now and then. Such a test (``_exclusive``) takes a run-wide
    lock exclusively, every other test shares it; a turnstile lock first keeps a waiting
    timing test from being starved by a stream of others (a fair readers-writer lock on
    flock). A test that shares the lock lets it go after its teardown, so that a timing test
    waits for one test at most; a timing test followed by another keeps it, so that a run of
    them (a module) waits once, not once a test, for the other worker's test in progress."""
    lock = item.config.stash.get(_CPU_LOCK, None)
    if lock is None:
        lock = item.config.stash[_CPU_LOCK] = _CpuLock(item.config)
    exclusive = _exclusive(item)
    lock.take(fcntl.LOCK_EX if exclusive else fcntl.LOCK_SH)
    try:
        yield
    finally:
        if not (exclusive and nextitem is not None and _exclusive(nextitem)):
            lock.release()


def _child_processes() -> set[tuple[int, str]] | None:
    """(pid, command name) of this process's live children (Linux /proc; None elsewhere)."""
    if not os.path.isdir("/proc/self"):
        return None
    me, out = os.getpid(), set()
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat", "rb") as f:
                stat = f.read().decode(errors="replace")
        except OSError:
            continue                       # it ended meanwhile
        name, _, rest = stat.rpartition(")")
        fields = rest.split()
        if len(fields) > 1 and fields[1] == str(me) and fields[0] not in ("Z", "X"):
            out.add((int(entry), name.partition("(")[2]))
    return out


@pytest.fixture(scope="module", autouse=True)
def _nothing_outlives_its_module(request):
    """A module leaves no process of its own running, and a wall-clock module no thread: a
    ring left running by one module (a session-wide acceptance target once did) takes CPU
    and the GIL from every later test of the process, timing tests included; a robot or
    hub process left behind holds its ports and a core. Both get 5 s to end after the
    module's fixtures are torn down."""
    realtime = is_realtime(request.node.nodeid)
    before = set(threading.enumerate())
    procs_before = _child_processes()
    yield
    deadline = time.monotonic() + 5.0
    while True:
        # (pytest-timeout's timer thread, with --timeout-method thread, is not ours)
        left = [t.name for t in threading.enumerate()
                if t not in before and t.is_alive()
                and not t.name.startswith("pytest_timeout")] if realtime else []
        now = _child_processes()
        procs = sorted(now - procs_before) if now is not None and procs_before is not None \
            else []
        if (not left and not procs) or time.monotonic() > deadline:
            break
        time.sleep(0.05)
    assert not left, f"threads still running after {request.node.nodeid}: {left}"
    assert not procs, f"processes still running after {request.node.nodeid}: {procs}"


@pytest.fixture
def full_device(tmp_path: Path) -> Path:
    """A character device on which every write fails for want of space (ENOSPC), like
    /dev/full: a node of its own in ``tmp_path`` when the tests run as root, so that code
    under test that replaces or removes what it writes to cannot destroy the system's (as
    root, an output once renamed a file over /dev/null and pyarrow deleted /dev/full); else
    /dev/full itself, which a user cannot replace."""
    if os.geteuid() == 0:
        node = tmp_path / "full"
        os.mknod(node, 0o666 | stat.S_IFCHR, os.makedev(1, 7))
        return node
    if not Path("/dev/full").is_char_device():
        pytest.skip("no /dev/full on this system, and not root to make a node like it")
    return Path("/dev/full")
