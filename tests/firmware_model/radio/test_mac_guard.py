"""The transition table as a guard (firmware_model/radio/mac_guard.py): on for the whole test
suite, in-process and in the ``rprs`` processes tests start; a move along no row raises."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from firmware_model.radio import mac as M
from firmware_model.radio.mac_guard import (ENV, TransitionError, enabled, table_guard,
                                            unguarded)
from paths import ROOT


def _claiming() -> M.RotationalMac:
    mac = M.RotationalMac(1, M.MacConfig(team=frozenset({1, 2})))
    mac.power_on(0)
    mac.on_timer(mac.deadline)                 # silence for Tclaim: the claim, SWITCH
    assert mac.phase == M.SWITCH
    return mac


def test_the_guard_is_on_for_the_test_suite_and_its_processes():
    assert enabled() and os.environ.get(ENV) == "1"
    probe = subprocess.run(
        [sys.executable, "-c", "import io, contextlib\n"
         "from hil.cli import main\n"
         "with contextlib.redirect_stdout(io.StringIO()):\n"
         "    try:\n"
         "        main(['encode', '--help'])\n"
         "    except SystemExit:\n"
         "        pass\n"
         "from firmware_model.radio.mac_guard import enabled\n"
         "print(enabled())"], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert probe.stdout.strip() == "True", probe.stdout + probe.stderr


def test_a_move_along_no_row_raises_naming_it(monkeypatch):
    """SWITCH's deadline sends the frame (SWITCH -> SEND); a MAC whose handler did nothing
    would stay in SWITCH, which no row allows."""
    mac = _claiming()
    monkeypatch.setitem(M.DEADLINE_HANDLERS, M.SWITCH, lambda *a: None)
    with pytest.raises(TransitionError, match=r"robot 1: SWITCH --deadline--> SWITCH is no "
                       r"row of the transition table .*on_timer made it"):
        mac.on_timer(mac.deadline)


def test_a_timer_before_the_deadline_is_no_event():
    mac = _claiming()
    assert mac.on_timer(mac.deadline - 1) == [] and mac.phase == M.SWITCH


def test_a_mac_broken_on_purpose_goes_unguarded_until_the_test_ends(monkeypatch):
    with monkeypatch.context() as mp:
        unguarded(mp.setattr)
        assert not enabled()
        mac = _claiming()
        mp.setitem(M.DEADLINE_HANDLERS, M.SWITCH, lambda *a: None)
        mac.on_timer(mac.deadline)                       # off the table, unchecked
        assert mac.phase == M.SWITCH
    assert enabled()


def test_nested_guards_leave_it_on_until_the_outermost_ends(monkeypatch):
    unguarded(monkeypatch.setattr)
    with table_guard():
        with table_guard():
            assert enabled()
        assert enabled()
    assert not enabled()


def test_turning_it_on_again_wraps_no_entry_point_twice(monkeypatch):
    """With one entry point replaced (a test's own wrapper: the guard is not all on), turning
    the guard on wraps that one only: a second layer on the others would survive ``unguarded``
    (it once did, and a test's MAC broken on purpose was still checked)."""
    monkeypatch.setattr(M.RotationalMac, "on_frame", M.RotationalMac.on_frame.__wrapped__)
    assert not enabled()
    with table_guard():
        assert enabled()
        inner = M.RotationalMac.__dict__["on_timer"].__wrapped__
        assert not getattr(inner, "__guarded__", False)
