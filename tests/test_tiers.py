"""The suite's own arrangement: the fast tier the README's command runs, the slow and timing
tiers CI runs after it (pyproject.toml's markers and addopts, .ci/run), an honest summary for
the SocketCAN tests that ran in the VM, the programs CI installs for the tests that need them,
and the host-latency probe of the wall-clock tests (tests/hostload.py)."""
from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from hostload import SchedulingLatency, summarise

ROOT = Path(__file__).resolve().parent.parent


def _pytest(*args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    e = {k: v for k, v in os.environ.items()
         if k not in ("RPRS_VCAN", "RPRS_VCAN_RAN_IN_VM", "PYTEST_ADDOPTS")}
    e.update(env or {})
    return subprocess.run([sys.executable, "-m", "pytest", "-p", "no:randomly",
                           "-p", "no:cacheprovider", *args], cwd=ROOT, env=e,
                          capture_output=True, text=True, timeout=300)


# ---------------------------------------------------------------- tiers
SLOW_FILES = ("tests/hil/sim/test_fault_matrix.py", "tests/hil/sim/test_lockstep_search.py",
              "tests/hil/sim/test_soak.py", "tests/hil/sim/test_soak_against.py",
              "tests/firmware_model/radio/test_fuzz.py", "tests/benchmarks/test_instructions.py",
              "tests/hil/bench/test_conformance.py")

_TIER_DUMP = """
import pytest

@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(items):
    for i in items:
        tiers = sorted({m.name for m in i.iter_markers()} & {"slow", "timing"})
        print("TIER", i.nodeid, ",".join(tiers) or "fast")
"""


@pytest.fixture(scope="module")
def tiers(tmp_path_factory) -> tuple[dict[str, str], set[str], str]:
    """One collection of ``SLOW_FILES`` with the project's addopts, as the README's command
    makes it: (every test's tier, as its markers say, before ``-m`` deselects; the tests the
    default run keeps; pytest's output)."""
    d = tmp_path_factory.mktemp("plugin")
    (d / "tierdump.py").write_text(_TIER_DUMP)
    path = os.pathsep.join(filter(None, [str(d), os.environ.get("PYTHONPATH")]))
    r = _pytest("--collect-only", "-q", "-s", "-n", "0", "-p", "tierdump", *SLOW_FILES,
                env={"PYTHONPATH": path})
    assert r.returncode == 0, r.stdout + r.stderr
    lines = r.stdout.splitlines()
    every = dict(line[5:].rsplit(" ", 1) for line in lines if line.startswith("TIER "))
    kept = {line for line in lines if "::" in line and not line.startswith("TIER ")}
    return every, kept, r.stdout


def test_the_default_run_is_the_fast_tier_and_says_how_to_run_the_rest(tiers):
    """The README's command (pyproject's addopts) keeps exactly the tests marked neither slow
    nor timing, and its summary says how to run the others."""
    every, kept, out = tiers
    assert kept == {t for t, tier in every.items() if tier == "fast"}
    assert {"slow", "timing"} <= set(every.values()), every
    assert 'pytest -m "slow or timing"' in out, out


def test_every_exhaustive_test_keeps_a_sample_in_the_fast_tier(tiers):
    """A parametrized test whose cases are mostly slow keeps some in the fast tier, and a
    property the slow tier runs with its full budget (``<name>_thoroughly``,
    tests/budgets.py) runs with a quick one there, so the README's command still checks the
    property (on fewer cases)."""
    every, kept, _ = tiers
    base = lambda t: t.partition("[")[0].removesuffix("_thoroughly")  # noqa: E731
    for fn in {base(t) for t, tier in every.items()
               if tier == "slow" and ("[" in t or base(t) != t.partition("[")[0])}:
        assert any(base(t) == fn for t in kept), f"{fn}: no case left in the fast tier"


# ---------------------------------------------------------------- SocketCAN in the VM
def test_vcan_tests_that_ran_in_the_vm_are_deselected_on_the_host_and_said_so():
    """After scripts/vcan-vm.sh passed (.ci/run sets RPRS_VCAN_RAN_IN_VM=1), the host's run
    deselects the SocketCAN tests and says where they ran; without it they skip with their
    reason (on a host without vcan0)."""
    from can_bus.bridge import socketcan_missing
    r = _pytest("-n", "0", "-q", "tests/can_bus/test_socketcan_smoke.py",
                env={"RPRS_VCAN_RAN_IN_VM": "1"})
    assert r.returncode == 5, r.stdout + r.stderr          # nothing left to run here
    assert "skipped" not in r.stdout and "deselected" in r.stdout, r.stdout
    assert "ran and passed inside the user-mode Linux VM" in r.stdout, r.stdout
    if socketcan_missing(os.environ.get("RPRS_VCAN_CHANNEL", "vcan0")) is None:
        return                                  # this host has vcan0: they would run here
    r = _pytest("-n", "0", "-q", "-rs", "tests/can_bus/test_socketcan_smoke.py")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "skipped" in r.stdout and "run scripts/vcan-vm.sh" in r.stdout, r.stdout
    assert "inside the user-mode Linux VM" not in r.stdout, r.stdout


# ---------------------------------------------------------------- CI
CAN_UTILS = {"candump", "cangen", "cansend", "canbusload"}
"""can-utils: only the vcan tests use them, and scripts/vcan-vm.sh fetches them into the VM."""


def test_ci_installs_every_program_a_test_skips_without():
    """A test that skips when a program is missing (``shutil.which``) is skipped in CI too
    unless .ci/run installs that program: socat and GTKWave's vcd2fst were not."""
    wanted = set()
    for f in (ROOT / "tests").rglob("*.py"):
        wanted |= set(re.findall(r'shutil\.which\("([^"]+)"\)', f.read_text(encoding="utf-8")))
    wanted -= CAN_UTILS
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    installed = set(re.findall(r"^ci_deb (\S+) \S+$", ci, re.M))
    assert {"tshark", "socat", "vcd2fst"} <= wanted
    assert wanted <= installed, wanted - installed


def test_ci_runs_the_slow_and_timing_tiers_as_a_step_where_no_test_is_no_failure(tmp_path):
    """.ci/run's last step, run with a stand-in pytest: it names itself, runs
    ``-m "slow or timing"``, passes on exit status 5 (no test selected) and fails on 1."""
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    step = ci[ci.index("echo \"ci: step 'slow and timing tiers'"):]
    venv = tmp_path / ".venv" / "bin"
    venv.mkdir(parents=True)
    for status, ok in ((5, True), (1, False), (0, True)):
        (venv / "pytest").write_text(f'#!/bin/sh\necho "args: $*"\nexit {status}\n')
        (venv / "pytest").chmod(0o755)
        r = subprocess.run(["bash", "-c", "set -euo pipefail\n" + step], cwd=tmp_path,
                           capture_output=True, text=True, timeout=30)
        assert (r.returncode == 0) == ok, (status, r.stdout, r.stderr)
        assert "ci: step 'slow and timing tiers'" in r.stdout
        assert "args: -m slow or timing" in r.stdout, r.stdout



def test_ci_runs_ruff_and_mypy_before_the_tests_and_fails_on_any_finding(tmp_path):
    """.ci/run's lint step, run with stand-ins for ruff and mypy: it names itself, runs both
    (mypy too when ruff reported), fails when either reports and passes when neither does; it
    comes before the fast tier, and the install brings both (the ``lint`` extra)."""
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    start = ci.index("echo \"ci: step 'lint'")
    assert start < ci.index("echo \"ci: step 'fast tier'")
    step = ci[start:ci.index("\nfi\n", start) + 4]
    assert "pip install -e '.[test,lint]'" in ci[:start]
    venv = tmp_path / ".venv" / "bin"
    venv.mkdir(parents=True)
    for ruff, mypy, ok in ((0, 0, True), (1, 0, False), (0, 1, False), (1, 1, False)):
        for name, status in (("ruff", ruff), ("mypy", mypy)):
            (venv / name).write_text(f'#!/bin/sh\necho "{name} ran: $*"\nexit {status}\n')
            (venv / name).chmod(0o755)
        r = subprocess.run(["bash", "-c", "set -euo pipefail\n" + step], cwd=tmp_path,
                           capture_output=True, text=True, timeout=30)
        assert (r.returncode == 0) == ok, (ruff, mypy, r.stdout, r.stderr)
        assert "ci: step 'lint'" in r.stdout
        assert "ruff ran: check ." in r.stdout and "mypy ran:" in r.stdout, r.stdout

# ---------------------------------------------------------------- the latency probe
def test_latency_summary_percentiles():
    lat = summarise([float(x) for x in range(1, 101)] + [-0.5])
    assert (lat.samples, lat.median_ms, lat.p90_ms, lat.p99_ms, lat.max_ms) == \
        (101, 50.0, 90.0, 99.0, 100.0)
    assert "median 50.00 ms" in str(lat) and "worst 100.0 ms" in str(lat)
    assert summarise([]).samples == 0


def test_the_probe_measures_while_the_test_runs():
    import time
    with SchedulingLatency() as probe:
        time.sleep(1.0)
    lat = probe.result
    assert lat is not None and 0 < lat.samples <= 510, lat     # 2 ms sleeps in 1 s at most
    assert 0 <= lat.median_ms <= lat.p90_ms <= lat.p99_ms <= lat.max_ms


def test_a_failing_wall_clock_test_reports_the_host_latency_beside_its_failure(tmp_path):
    """tests/conftest.py runs the probe beside every wall-clock test and puts what it measured
    in the report of one that fails; a test that passes, or one in tick time, has none."""
    for name in ("test_monitor.py", "test_frame.py"):       # wall clock / tick time
        (tmp_path / name).write_text("def test_fails():\n    assert 1 == 2\n\n"
                                     "def test_passes():\n    pass\n")
    path = os.pathsep.join(filter(None, [str(ROOT), str(ROOT / "tests"),
                                         os.environ.get("PYTHONPATH")]))
    r = subprocess.run([sys.executable, "-m", "pytest", "-p", "conftest", "-p", "no:randomly",
                        "-p", "no:cacheprovider", "-q", "-n", "0", "test_monitor.py",
                        "test_frame.py"], cwd=tmp_path, capture_output=True, text=True,
                       timeout=300, env={**os.environ, "PYTHONPATH": path})
    assert "2 failed, 2 passed" in r.stdout, r.stdout + r.stderr
    sections = re.findall(r"-+ host scheduling latency -+\n(.*)", r.stdout)
    assert len(sections) == 1, r.stdout               # test_monitor.py's failure only
    assert re.match(r"host scheduling latency over \d+ wake-ups: median", sections[0]), sections


HUB_OR_ROBOT_PROCESSES = ("RadioHub(", "_HubRing(", "_TailHub(", "_children_on_hub(")
"""Source text by which a test starts the pty radio hub (or a ring of robot processes on it):
it then runs on the wall clock. (A test that starts one ``rprs child`` for a bad option and
reads its one line is no ring: it need not be one.)"""


def test_every_test_that_starts_the_hub_runs_as_a_wall_clock_test():
    """A test that runs processes on the pty hub beside the simulator's tests on the other
    xdist worker shares the CPU with them and with other hub tests: such a test must be a
    wall-clock one (``tests/conftest.py``: ``REALTIME_MODULES``, ``REALTIME_TESTS``), which run
    one after another. (Hub tests of the authenticated profile and of twins once ran as
    simulator tests and failed under load.)"""
    import ast
    from conftest import is_realtime
    here = Path(__file__).resolve().parent
    stray = []
    for path in sorted(here.rglob("test_*.py")):
        text = path.read_text()
        for node in ast.parse(text).body:
            if not (isinstance(node, ast.FunctionDef) and node.name.startswith("test_")):
                continue
            src = ast.get_source_segment(text, node) or ""
            uses = any(k in src for k in HUB_OR_ROBOT_PROCESSES) or \
                any(a.arg == "hub" for a in node.args.args)
            nodeid = f"tests/{path.relative_to(here).as_posix()}::{node.name}"
            if uses and not is_realtime(nodeid):
                stray.append(nodeid)
    assert stray == [], "start the pty radio hub but are not wall-clock tests: " \
        f"{stray} (add them to REALTIME_TESTS in tests/conftest.py)"


def test_no_test_module_imports_another():
    """Helpers the tests share live in modules of their own (``tests/processes.py``,
    ``tests/paper_robot.py``, ``tests/can_testbed.py``, ...), not in a test module: importing
    a test module runs its module-level code and its fixtures' imports a second time, and ties
    one file's tests to another's internals."""
    tests = Path(__file__).resolve().parent
    modules = {p.stem for p in tests.rglob("test_*.py")}
    found = []
    for path in sorted(tests.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) else []
            found += [f"{path.relative_to(tests)}: {n}" for n in names
                      if n.partition(".")[0] in modules]
    assert not found, found
