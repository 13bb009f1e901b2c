"""The ``skew:R:E`` fault: what E means, and why it is never negative.

E is how much slower robot R's clock runs than nominal: every byte time and every interval
it times (Ttrans, Tmax, the poll window, the stagger, the quiet gap) is (1 + E) times its
nominal length in true ticks (hil/sim/faults.py ``skewed_mac``). A negative E (a clock that runs
fast) was half-allowed: the parser's range check took |E| < 0.2, while its pattern refused
any minus sign with "is not a fault spec like ...". And the docs said the clock runs E *fast*
while the model made it slow. A fast clock is refused now, in words, as not modelled. (It was
once refused because the radio model lost a frame sent less than Ttrans after TXEN; the
PTR2000 has the data sheet's 1 ms TX-ready delay now, and its switch times do not follow the
MCU's clock.)
"""
from __future__ import annotations

import re

import pytest

from firmware_model.timing import (
    CHILD_BYTE_TICKS,
    PC_BYTE_TICKS,
    PTR2000_RX_READY_TICKS,
    PTR2000_TX_READY_TICKS,
    TTRANS_TICKS,
)
from hil.cli import main
from hil.sim.faults import Fault, FaultError, parse_fault
from hil.sim.world import ConfigError, SimConfig, World
from paths import ROOT

DOCS = ROOT / "docs"


@pytest.mark.parametrize("spec", ["skew:2:-0.02", "skew:1:-0.001", "skew:0:-0.19"])
def test_a_negative_skew_is_refused_in_words(spec):
    with pytest.raises(FaultError, match=r"runs fast \(E < 0\) is not modelled.*0 <= E < 0.2"):
        parse_fault(spec)


def test_a_negative_skew_on_the_command_line_is_one_line(capsys):
    code = main(["sim", "--duration", "2", "--fault", "skew:2:-0.02"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith("rprs: error: argument --fault: skew -0.02: a clock that runs fast")
    assert "is not a fault spec like" not in err


def test_a_negative_skew_built_by_hand_is_refused_by_the_world():
    """Not only the parser: a SimConfig with a fast clock is a ConfigError too."""
    cfg = SimConfig(robots=(1, 2), duration=1, faults=(Fault("skew", 2, 0.0, None, -0.02),))
    with pytest.raises(ConfigError, match="skew:2:-0.02"):
        cfg.validate()


@pytest.mark.parametrize("spec,value", [("skew:2:0", 0.0), ("skew:2:0.02", 0.02),
                                        ("skew:2:0.199", 0.199)])
def test_a_skew_of_zero_up_to_a_fifth_parses_and_round_trips(spec, value):
    f = parse_fault(spec)
    assert (f.kind, f.robot, f.value) == ("skew", 2, value)
    assert parse_fault(f.spec()) == f


@pytest.mark.parametrize("spec", ["skew:2:0.2", "skew:2:1.5"])
def test_a_skew_of_a_fifth_or_more_is_refused(spec):
    with pytest.raises(FaultError, match=r"not a small fraction.*0 <= E < 0.2"):
        parse_fault(spec)


def test_a_positive_skew_makes_the_robots_clock_slow_by_that_fraction():
    """The documented effect: robot 2's byte time and MAC intervals are 2 % longer in true
    ticks (each interval rounded up to the reload timer's even ticks); the others' are not.
    The radio's own switch times are the PTR2000's whatever the MCU clock."""
    w = World(SimConfig(robots=(0, 1, 2), duration=1, faults=(parse_fault("skew:2:0.02"),
                                                                parse_fault("skew:0:0.01"))))
    assert w.byte_ticks == {0: round(PC_BYTE_TICKS * 1.01), 1: CHILD_BYTE_TICKS,
                            2: round(CHILD_BYTE_TICKS * 1.02)}
    nominal, slow = w.stations[1].mac.cfg, w.stations[2].mac.cfg
    for name in ("ttrans", "tmax", "twin", "tslot"):
        assert getattr(slow, name) == round(getattr(nominal, name) * 1.02), name
    assert slow.ttrans > TTRANS_TICKS
    assert (w.radios[2].tx_ready_delay, w.radios[2].rx_ready_delay) == \
        (PTR2000_TX_READY_TICKS, PTR2000_RX_READY_TICKS)


def test_the_docs_say_what_the_model_does():
    """docs/guarantees.md and the parser's own table: slow, E from 0 up to 0.2."""
    import hil.sim.faults as faults
    row = next(line for line in (DOCS / "guarantees.md").read_text().splitlines()
               if line.startswith("| `skew:R:E`"))
    table = next(line for line in faults.__doc__.splitlines() if line.startswith("``skew:R:E``"))
    for text in (row, table):
        assert re.search(r"\bslow\b", text) and "0 <= E < 0.2" in text, text
        assert "fast" not in text.replace("fast (E < 0)", ""), text


def test_two_skews_for_one_robot_are_refused_one_each_is_fine(capsys):
    """``--fault skew:2:0.02 --fault skew:2:0.05`` ran without a word, the last one winning."""
    from hil.cli import main
    assert main(["sim", "--robots", "0,1,2", "--duration", "1", "--fault", "skew:2:0.02",
                 "--fault", "skew:2:0.05", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "skew:2:0.02 and skew:2:0.05" in err, err
    assert main(["sim", "--robots", "0,1,2", "--duration", "1", "--fault", "skew:2:0.02",
                 "--fault", "skew:1:0.05", "--no-progress"]) == 0


@pytest.mark.parametrize("load", [None, True, [1], 0, -1.0, "busy"])
def test_a_config_with_a_load_that_is_no_rate_is_refused_in_words(load):
    """Through the Python API too (a campaign's grid, a script): a ConfigError naming the
    value, never a TypeError from comparing it."""
    with pytest.raises(ConfigError, match="load"):
        World(SimConfig(robots=(0, 1), duration=1.0, load=load))


@pytest.mark.parametrize("spec,robot", [("fail:9@5", "9"), ("fail:-1@5", "-1"),
                                        ("stuck:01@3-6", "01"), ("busoff:7@2", "7")])
def test_a_fault_on_no_robot_id_says_which_robot(spec, robot):
    """``--fault fail:9@5`` was "not a fault spec like fail:1@5, ...", as if its form were
    wrong; it names the robot ID that is none now (0-6, written as such)."""
    with pytest.raises(FaultError, match=rf"robot {robot} is no robot ID \(0 the father, "
                                         rf"1-6 the children\)"):
        parse_fault(spec)
    assert parse_fault(spec.replace(robot, "1")).robot == 1
