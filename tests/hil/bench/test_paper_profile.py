"""The paper profile (docs/protocol.md §9, issue 11 item 2): our robots beside a robot that
implements only the paper.

``PaperRobot`` (tests/paper_robot.py) is written from the paper's rules alone (Zhang et al.,
ROBIO 2006, §IV.C-D), in plain pyserial, nothing imported from this project.

With ``--profile rprs`` our children never leave LISTEN while such a robot talks (it never
invites them). With ``--profile paper`` they share its ring: the turns rotate, its messages are
delivered and ours reach it, no frame carries anything the paper does not define, and when it
falls silent both children disable it after three misses and go on.
"""
from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
import threading
import time

import pytest

from paths import ROOT, TESTS

pytest.importorskip("serial")

from paper_robot import (  # noqa: E402  (after the skip: the robot needs pyserial)
    PAPER_TYPES, PaperRobot)

# ==============================================================================================
# The harness: rprs radio-hub and two rprs child processes
# ==============================================================================================



def _ptys_available() -> str | None:
    try:
        master, slave = os.openpty()
    except (OSError, AttributeError) as exc:
        return f"pseudo-terminals are unavailable here: {exc}"
    os.close(master)
    os.close(slave)
    return None


class Child:
    """An ``rprs child --events`` process and the JSON lines it prints."""

    def __init__(self, *args: str) -> None:
        self.proc = subprocess.Popen([sys.executable, "-m", "hil.cli", "child", *args,
                                      "--events"], cwd=ROOT, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True)
        self.lines: list[dict] = []
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        with self.proc.stdout:                   # the reader closes it, at the end
            for line in self.proc.stdout:
                try:
                    self.lines.append(json.loads(line))
                except ValueError:
                    pass

    def find(self, **kw) -> list[dict]:
        return [e for e in list(self.lines) if all(e.get(k) == v for k, v in kw.items())]

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
        try:
            self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self.proc.stderr.close()                 # else: ResourceWarning when collected


@pytest.fixture
def hub(tmp_path):
    why = _ptys_available()
    if why:
        pytest.skip(why)
    air = tmp_path / "air"
    proc = subprocess.Popen([sys.executable, "-m", "hil.cli", "radio-hub", "--nodes", "3",
                             "--link-dir", str(air), "--seed", "1"], cwd=ROOT,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    end = time.monotonic() + 15
    while time.monotonic() < end and not all((air / f"node{i}").exists() for i in range(3)):
        time.sleep(0.05)
    assert all((air / f"node{i}").exists() for i in range(3)), \
        proc.stderr.read() if proc.poll() is not None else "the hub made no ptys"
    yield air
    proc.terminate()
    proc.wait(timeout=5)
    proc.stderr.close()


def test_the_paper_robot_imports_nothing_from_the_project():
    tree = ast.parse((TESTS / "paper_robot.py").read_text(encoding="utf-8"))
    names = [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    names += [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    assert not [m for m in names if m.split(".")[0] in ("firmware_model", "can_bus", "hil")]


@pytest.mark.timing
def test_a_paper_robot_silences_robots_of_the_full_protocol(hub):
    """The reason for the profile: a paper robot never invites anyone, and our robots in the
    rprs profile wait in LISTEN for as long as the channel is busy (clause 28)."""
    kids = [Child("--id", str(r), "--radio", str(hub / f"node{r - 1}"), "--team", "1,2,3")
            for r in (1, 2)]
    robot = PaperRobot(str(hub / "node2"), 3, {1, 2, 3})
    try:
        robot.run_for(4.0)
        assert len(robot.sent) > 4                     # it took every turn, the others missed
        assert not [k.find(ev="tx") for k in kids if k.find(ev="tx")]
        assert {s for _, s, *_ in robot.heard} <= {3}
    finally:
        robot.close()
        for k in kids:
            k.stop()


@pytest.mark.timing
def test_the_paper_profile_shares_a_ring_with_a_paper_robot(hub):
    """Children 1 and 2 with ``--profile paper`` and the paper robot 3: one ring of three, in
    ascending order; the paper robot's message is delivered to child 1 and child 1's reply
    reaches it; nothing on the air is outside the paper's frame (Types '0'-'4', no MAC
    command, empty heartbeats); when it falls silent both children disable it after three
    misses at E + Tmax and go on as a ring of two."""
    kids = {r: Child("--id", str(r), "--radio", str(hub / f"node{r - 1}"), "--team", "1,2,3",
                     "--profile", "paper",
                     *(("--can", f"virtual:paper{os.getpid()}") if r == 1 else ()))
            for r in (1, 2)}
    robot = None
    try:
        # The paper has no start-up rule: the three must start within the first cycles (before
        # the children's three misses of robot 3), so the robot starts once both children send.
        assert _wait(lambda: all(k.find(ev="tx") for k in kids.values()), 20), \
            [k.proc.stderr.read() for k in kids.values() if k.proc.poll() is not None]
        robot = PaperRobot(str(hub / "node2"), 3, {1, 2, 3})

        def rotating() -> bool:          # (its own frames it does not hear: half duplex)
            seq = [s for _, s, *_ in robot.heard[-6:]]
            return seq == [1, 2] * 3 and len(robot.sent) >= 3 and \
                len(robot.sent) - robot.sent_at_heard[-6] == 3
        assert robot.run_for(15.0, rotating), (robot.heard[-8:], robot.ring)
        for _ in range(3):           # nothing is acknowledged or retransmitted in the paper:
            robot.outbox.append((1, "status()"))     # a frame lost to a late PC is lost, so
            if robot.run_for(4.0, lambda: robot.inbox):  # the application asks again
                break
        assert robot.inbox, robot.heard[-8:]
        (src, reply), = robot.inbox[:1]
        # child 1's CAN bus has nobody on it: its truthful reply is that no submodule answers
        assert src == 1 and reply == "fail(30)status()", reply
        assert [e for e in kids[1].find(ev="deliver", src=3) if e["content"] == "status()"]
        assert kids[1].find(ev="sent", src=1, dst=3)        # sent once, never acknowledged
        for dst, src, _num, typ, content, _ in robot.heard:
            assert typ in PAPER_TYPES, (src, typ)
            assert not any(c in content for c in ("ack(", "poll(", "ring(", "crc(")), content
            if typ == 3 and dst == 7 and src in (1, 2):
                assert content == ""                        # a heartbeat is empty
        assert not kids[1].find(ev="mode", mode="listen") and \
            not kids[2].find(ev="mode", mode="listen")
        assert not kids[1].find(ev="disable") and not kids[2].find(ev="disable")
        # the paper robot falls silent: disabled by both after three misses, ring of two goes on
        robot.close()
        assert all(_wait(lambda k=k: k.find(ev="disable", robot=3), 6.0) for k in kids.values())
        misses = {r: [e for e in k.find(ev="miss", robot=3)] for r, k in kids.items()}
        assert all(len(m) >= 3 for m in misses.values()), misses
        n = {r: len(k.find(ev="tx")) for r, k in kids.items()}
        assert _wait(lambda: all(len(k.find(ev="tx")) >= n[r] + 5 for r, k in kids.items()), 5)
    finally:
        if robot is not None:
            robot.close()
        for k in kids.values():
            k.stop()


def _wait(pred, timeout: float) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.05)
    return pred()

