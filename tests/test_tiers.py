"""The suite's own arrangement: the fast tier the README's command runs, the slow and timing
tiers CI runs after it (pyproject.toml's markers and addopts, .ci/run), an honest summary for
the SocketCAN tests that ran in the VM, and the programs CI installs for the tests that need
them."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def _pytest(*args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    e = {k: v for k, v in os.environ.items()
         if k not in ("RPRS_VCAN", "RPRS_VCAN_RAN_IN_VM", "PYTEST_ADDOPTS")}
    e.update(env or {})
    return subprocess.run([sys.executable, "-m", "pytest", "-p", "no:randomly",
                           "-p", "no:cacheprovider", *args], cwd=ROOT, env=e,
                          capture_output=True, text=True, timeout=300)


# ---------------------------------------------------------------- tiers
SLOW_FILES = ("tests/test_fault_matrix.py", "tests/test_lockstep_search.py",
              "tests/test_soak.py", "tests/test_conformance.py")

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
    """A parametrized test whose cases are mostly slow keeps some in the fast tier, so the
    README's command still checks the property (on fewer cases)."""
    every, kept, _ = tiers
    base = lambda t: t.partition("[")[0]          # noqa: E731
    for fn in {base(t) for t, tier in every.items() if tier == "slow" and "[" in t}:
        assert any(base(t) == fn for t in kept), f"{fn}: no case left in the fast tier"


# ---------------------------------------------------------------- SocketCAN in the VM
def test_vcan_tests_that_ran_in_the_vm_are_deselected_on_the_host_and_said_so():
    """After scripts/vcan-vm.sh passed (.ci/run sets RPRS_VCAN_RAN_IN_VM=1), the host's run
    deselects the SocketCAN tests and says where they ran; without it they skip with their
    reason (on a host without vcan0)."""
    from can_bus.bridge import socketcan_missing
    r = _pytest("-n", "0", "-q", "tests/test_socketcan_smoke.py",
                env={"RPRS_VCAN_RAN_IN_VM": "1"})
    assert r.returncode == 5, r.stdout + r.stderr          # nothing left to run here
    assert "skipped" not in r.stdout and "deselected" in r.stdout, r.stdout
    assert "ran and passed inside the user-mode Linux VM" in r.stdout, r.stdout
    if socketcan_missing(os.environ.get("RPRS_VCAN_CHANNEL", "vcan0")) is None:
        return                                  # this host has vcan0: they would run here
    r = _pytest("-n", "0", "-q", "-rs", "tests/test_socketcan_smoke.py")
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
    for f in (ROOT / "tests").glob("*.py"):
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
