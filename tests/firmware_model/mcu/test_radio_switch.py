"""The PTR2000's switch times are the part's (nRF401 data sheet, Table 5: TX-ready 1 ms after
TXEN rises, RX-ready 3 ms after it falls), not the protocol's Ttrans guard (5 ms): the
previous sender hears again 2 ms before the next Header begins (docs/protocol.md clause 2,
docs/cpu.md). Before, the model made the radio deaf for Ttrans, so the hand-over margin was
zero by construction and a sender's TXEN-low latency alone could make it miss the Header."""
from __future__ import annotations

import itertools

import pytest

from firmware_model.cycle_costs import CycleCosts
from firmware_model.timing import (
    CHILD_BYTE_TICKS,
    PTR2000_RX_READY_TICKS,
    PTR2000_TX_READY_TICKS,
    TTRANS_TICKS,
)
from hil.sim.world import ConfigError, SimConfig, World


def _handovers(cpu=None, radio_switch=None, duration=4.0):
    """(robot, its End, tick its radio hears again, the next frame's first bit) for every
    hand-over from robot 1 to robot 2 in a ring 0, 1, 2; and the run's events."""
    evs: list[dict] = []
    w = World(SimConfig(robots=(0, 1, 2), duration=duration, seed=1, load=1, cpu=cpu,
                        radio_switch=radio_switch or {}), on_event=evs.append)
    heard_again: list[int] = []
    radio = w.radios[1]

    def watch(level, now):           # after the radio's own listener: TXEN fell
        if not level:
            heard_again.append(radio.rx_from)
    w.stations[1].txen.listeners.append(watch)
    w.run()
    frames = [e for e in evs if e["ev"] == "frame"]
    out = []
    for a, b in itertools.pairwise(frames):
        if a["src"] == 1 and b["src"] == 2:
            back = min(t for t in heard_again if t > a["end"])
            out.append((a["end"], back, b["start"]))
    return out, evs


@pytest.mark.parametrize("cpu,latency", [(None, 0), (CycleCosts(), 24)])
def test_the_previous_sender_hears_again_2_ms_before_the_next_header(cpu, latency):
    """Ideal CPU: TXEN falls at the End; the MB90F549 model: 24 cycles later (the TX END
    interrupt's entry). The radio hears 3 ms after that; the next Header begins Ttrans (5 ms)
    after the End, to the tick with the ideal CPU, later by the next sender's own handler
    latency with the CPU model: a margin of at least 32,000 ticks less the TXEN latency (with
    Ttrans as the radio's switch time, as the model had it, at most that next sender's
    latency)."""
    hand, evs = _handovers(cpu)
    assert len(hand) >= 3, hand
    for end, back, start in hand:
        assert back == end + latency + PTR2000_RX_READY_TICKS
        margin = start - back
        if cpu is None:
            assert margin == TTRANS_TICKS - PTR2000_RX_READY_TICKS
        else:
            assert TTRANS_TICKS - PTR2000_RX_READY_TICKS - latency <= margin < \
                TTRANS_TICKS - PTR2000_RX_READY_TICKS + CHILD_BYTE_TICKS
    assert [e for e in evs if e["ev"] in ("miss", "disable")] == []


def test_a_radio_that_switched_back_in_ttrans_had_no_margin_and_half_a_bit_saved_it():
    """The old model's figure as a per-module setting (ideal CPU, to the tick): robot 1's
    radio hears again Ttrans after TXEN falls, the very tick the next Header's first bit
    begins: no margin. It still hears it, as a UART that comes in less than half a bit late
    samples every bit mid-cell; half a bit later it misses the Header, and robot 1 counts
    robot 2 missing."""
    half_bit = CHILD_BYTE_TICKS // 20
    hand, evs = _handovers(None, {1: (PTR2000_TX_READY_TICKS, TTRANS_TICKS)})
    assert hand and all(back == start for _, back, start in hand)
    assert [e for e in evs if e["ev"] == "miss"] == []
    for rx, missed in ((TTRANS_TICKS + half_bit - 1, False), (TTRANS_TICKS + half_bit, True)):
        _, evs = _handovers(None, {1: (PTR2000_TX_READY_TICKS, rx)})
        assert bool([e for e in evs if e["ev"] == "miss" and e["by"] == 1]) is missed, rx


@pytest.mark.parametrize("switch,words", [
    ({3: (16_000, 48_000)}, "not in the ring"),
    ({1: (16_000,)}, "two whole tick counts"),
    ({1: (16_000, -1)}, "two whole tick counts"),
    ({1: (1.5, 48_000)}, "two whole tick counts"),
])
def test_bad_radio_switch_times_are_refused_in_words(switch, words):
    with pytest.raises(ConfigError, match=words):
        SimConfig(robots=(0, 1, 2), radio_switch=switch).validate()


def test_rprs_sim_takes_a_modules_switch_times(capsys):
    """``--radio-switch ID:TX_MS,RX_MS``: robot 1's radio hearing 5.05 ms after TXEN falls
    (its TXEN falling 24 cycles after the End: just inside the next Header's first half bit)
    keeps the ring whole; 5.06 ms and robot 1 misses robot 2's Headers and counts it missing."""
    import json

    from hil.cli import main
    missed = {}
    for rx in ("5.05", "5.06"):
        assert main(["sim", "--robots", "0,1,2", "--duration", "10", "--seed", "1", "--load",
                     "1", "--cpu", "estimated", "--no-progress", "--json",
                     "--radio-switch", f"1:1,{rx}"]) == 0
        missed[rx] = json.loads(capsys.readouterr().out)["robots"]["1"]["missed"]
    assert missed["5.05"] == 0 < missed["5.06"]


@pytest.mark.parametrize("args,words", [
    (["--radio-switch", "1:1"], "is not ID:TX_MS,RX_MS"),
    (["--radio-switch", "8:1,3"], "robot ID 8"),
    (["--radio-switch", "1:-1,3"], "finite milliseconds >= 0"),
    (["--radio-switch", "1:1,3", "--radio-switch", "1:1,4"], "names robot 1 twice"),
    (["--radio-switch", "5:1,3"], "not in the ring"),
])
def test_a_bad_radio_switch_option_is_one_line(capsys, args, words):
    from hil.cli import main
    assert main(["sim", "--robots", "0,1,2", "--duration", "1", "--no-progress", *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err and "Traceback" not in err, err


@pytest.mark.parametrize("per_byte,holds", [(20_000, True), (36_000, False)])
def test_a_transmit_handler_slower_than_a_byte_leaves_gaps_but_only_the_stall_gap_breaks_the_ring(
        tmp_path, capsys, per_byte, holds):
    """docs/cpu.md, redone with the part's figures: ``uart_tx_byte = 20000`` (1.25 ms a byte,
    longer than the 1.04 ms byte time) stretches every frame a child sends with gaps. With
    the radio deaf for Ttrans after TXEN fell that broke the ring (the sender, its TXEN late
    after its stretched frame, missed the next Header: 42 of 107 messages in 30 s, 58
    membership changes); with the part's 3 ms the ring holds. At 36,000 cycles (2.25 ms a
    byte) the gaps pass the 2.08 ms stall gap and receivers abandon the frames: that breaks
    it."""
    import json

    from hil.cli import main
    costs = tmp_path / "slow.toml"
    costs.write_text(f"[costs]\nuart_tx_byte = {per_byte}\n")
    assert main(["sim", "--robots", "0,1,2", "--duration", "10", "--seed", "1", "--load", "1",
                 "--cpu", "estimated", "--cpu-costs", str(costs), "--no-progress",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    formed = [c for c in out["membership_changes"] if c["t"] > 3 * 16_000_000]  # ticks
    assert sum(out["cpu_tx_gaps"].values()) > 1000
    assert (formed == [] and out["delivered"] >= out["submitted"] - 2) is holds, out
