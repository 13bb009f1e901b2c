"""``rprs conformance`` (hil/bench/conformance.py) against robots on the pty radio hub: an
``rprs child`` in each profile passes every clause; a robot that answers 25 ms late fails
exactly the timing clauses; a robot that knows only the paper fails the protocol's clauses
when checked as an rprs robot."""
from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest

from hil.bench.conformance import Check, ConformanceError, Tester

from test_paper_profile import PaperRobot
import test_paper_profile

ROOT = Path(__file__).resolve().parent.parent


def _ptys_available() -> str | None:
    try:
        master, slave = os.openpty()
    except (OSError, AttributeError) as exc:
        return f"pseudo-terminals are unavailable here: {exc}"
    os.close(master)
    os.close(slave)
    return None


def _spawn(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "hil.cli", *args], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _stop(*procs) -> None:
    for p in procs:
        if p.poll() is None:
            p.terminate()
    for p in procs:
        try:
            p.wait(timeout=5)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


@pytest.fixture
def air(tmp_path):
    why = _ptys_available()
    if why:
        pytest.skip(why)
    d = tmp_path / "air"
    hub = _spawn("radio-hub", "--nodes", "2", "--link-dir", str(d), "--seed", "1")
    end = time.monotonic() + 15
    while time.monotonic() < end and not all((d / f"node{i}").exists() for i in range(2)):
        time.sleep(0.05)
    assert all((d / f"node{i}").exists() for i in range(2)), \
        hub.stderr.read() if hub.poll() is not None else "the hub made no ptys"
    yield d
    _stop(hub)


def _cases(path: Path) -> dict[tuple[str, str], bool]:
    suite = ET.parse(path).getroot()
    return {(c.get("classname"), c.get("name")): c.find("failure") is None
            for c in suite.iter("testcase")}


@pytest.mark.parametrize("profile", ["rprs", "paper"])
def test_an_rprs_child_passes_every_clause(air, tmp_path, profile):
    child = _spawn("child", "--id", "1", "--radio", str(air / "node0"), "--team", "0,1",
                   "--profile", profile, "--can", f"virtual:conf{os.getpid()}{profile}")
    junit = tmp_path / "verdicts.xml"
    try:
        time.sleep(0.5)
        run = subprocess.run([sys.executable, "-m", "hil.cli", "conformance", "--radio",
                              str(air / "node1"), "--id", "1", "--profile", profile,
                              "--junit", str(junit), "--quiet"], cwd=ROOT, capture_output=True,
                             text=True, timeout=120)
    finally:
        _stop(child)
    assert run.returncode == 0, run.stdout + run.stderr
    cases = _cases(junit)
    clauses = {c.split()[1] for c, _ in cases}
    expected = {"15", "21", "23", "24", "25", "26", "47", "38", "41"} | (
        {"29", "34", "36", "45", "48"} if profile == "rprs" else set())
    assert clauses == expected and all(cases.values()), cases
    assert "pass" in run.stdout and "FAIL" not in run.stdout


def _run_against(robot: PaperRobot, port: str, profile: str) -> dict[tuple[str, str], bool]:
    t = Tester(port, 1, profile)
    stop = threading.Event()

    def drive():
        while not stop.is_set():
            robot.step()
            time.sleep(0.0005)
    th = threading.Thread(target=drive, daemon=True)
    th.start()
    try:
        try:
            rep = t.run()
        except ConformanceError as exc:     # the run stopped: keep what was checked
            rep = t.report
            rep.checks.append(Check("-", f"stopped: {exc}", False, ""))
    finally:
        stop.set()
        th.join(timeout=2)
        robot.close()
    return {(c.clause, c.name): c.passed for c in rep.checks}


def test_a_robot_that_hands_over_late_fails_the_timing_clauses(air, monkeypatch):
    """A paper robot whose switch time is 30 ms instead of Ttrans = 5 ms: the hand-over
    (clause 23), the hand-over after a late frame (26) and the takeover (24) fail; its frames,
    heartbeats, broken-frame handling and acknowledgements (none) pass."""
    monkeypatch.setattr(test_paper_profile, "TTRANS", 0.030)
    verdicts = _run_against(PaperRobot(str(air / "node0"), 1, {0, 1}), str(air / "node1"),
                            "paper")
    failed = {c for (c, _), ok in verdicts.items() if not ok}
    passed = {c for (c, _), ok in verdicts.items() if ok}
    assert {"23", "24", "26"} <= failed and failed <= {"23", "24", "26", "-"}, verdicts
    assert {"15", "21", "41", "47"} <= passed, verdicts


def test_a_paper_only_robot_fails_the_protocols_clauses(air):
    """Checked as an rprs robot, a robot that knows only the paper does not answer the
    invitation with BOOT or JOIN (clause 34); it acknowledges nothing (47, 48) and takes the
    turn without R-stagger and R-pair (24), unless the run stops before those checks (its
    rotation, alone with a tester that does not follow it, may break off)."""
    verdicts = _run_against(PaperRobot(str(air / "node0"), 1, {0, 1}), str(air / "node1"),
                            "rprs")
    failed = {c for (c, _), ok in verdicts.items() if not ok}
    checked = {c for c, _ in verdicts}
    assert "34" in failed, verdicts
    assert {"47", "48", "24"} & checked <= failed, verdicts
    assert failed - {"34"}, verdicts           # something more: a failed clause or a stop
