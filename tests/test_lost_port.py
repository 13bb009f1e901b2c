"""A radio port that goes away under a running robot (the radio hub stopped, a USB-serial
adapter pulled): the process stops with one line saying so and status 1, not silently with
the status of a Ctrl-C (docs/bench.md)."""
from __future__ import annotations

import os
import subprocess
import sys
import tty

from hil.bench.runner import Runner, build_father


def _pty() -> tuple[int, str]:
    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    os.close(slave)
    return master, path


def test_a_lost_port_stops_the_runner_and_says_why():
    master, path = _pty()
    runner = Runner()
    build_father(runner, path)
    runner.sched.post(os.close, master)
    runner.run(60.0)                 # returns long before: the port is gone
    assert runner.failure is not None
    assert runner.failure.startswith(f"the radio port {path} went away (")


def test_rprs_child_whose_port_goes_away_exits_1_with_one_line():
    master, path = _pty()
    proc = subprocess.Popen([sys.executable, "-m", "hil.cli", "child", "--id", "1", "--radio",
                             path, "--team", "0,1"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        first = proc.stderr.readline()
        assert first.startswith("running child 1"), first
        os.close(master)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    lines = err.splitlines()
    assert proc.returncode == 1, err
    assert lines[-1].startswith(f"rprs: error: the radio port {path} went away"), err
    assert lines[-2].startswith("robot 1: ") and "Traceback" not in err
