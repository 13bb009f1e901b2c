"""The MAC seam (firmware_model/radio/station_mac.py): what the station uses of a MAC, and
every MAC that plugs into the station (the rotational one, the peer MACs) giving all of it."""
from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

from firmware_model import child, station
from firmware_model.radio.content import cmd
from firmware_model.radio.mac import MacConfig, RotationalMac, TxEnable
from firmware_model.radio.peer_macs import AlohaMac, CsmaMac, SlottedAlohaMac, install
from firmware_model.radio.station_mac import StationMac
from firmware_model.timing import TICK_HZ, TTRANS_TICKS
from hil.sim.world import SimConfig, World

PEERS = ("aloha", "slotted", "csma")


def _members(proto: type) -> set[str]:
    return {n for n in vars(proto) if not n.startswith("_")}


SIM_READS = {"mode", "pending", "max_content", "frames_sent"}
"""What the simulator (hil/sim) reads of any station's MAC, beside what the station uses."""


def test_the_protocol_lists_exactly_what_the_station_the_child_and_the_simulator_use():
    used = set()
    for mod in (station, child):
        used |= set(re.findall(r"\bmac\.([a-z_]+)", Path(mod.__file__).read_text()))
    assert {"on_frame", "on_timer", "resync", "deadline", "ring"} <= used
    sim = set()
    for f in Path(sys.modules[World.__module__].__file__).parent.glob("*.py"):
        sim |= set(re.findall(r"\bmac\.([a-z_]+)", f.read_text()))
    assert SIM_READS <= sim
    assert _members(StationMac) == used | SIM_READS


@pytest.mark.parametrize("cls", [RotationalMac, AlohaMac, SlottedAlohaMac, CsmaMac])
def test_every_mac_the_station_can_run_has_every_member(cls):
    mac = cls(1, MacConfig(team=frozenset({1, 2})))
    missing = sorted(n for n in _members(StationMac) if not hasattr(mac, n))
    assert not missing, f"{cls.__name__} lacks {missing}"


@pytest.mark.parametrize("cls", [AlohaMac, CsmaMac])
def test_a_peer_mac_resynced_with_txen_up_lowers_it_and_decides_again(cls):
    mac = cls(1, MacConfig(team=frozenset({1, 2})), seed=0)
    mac.power_on(0)
    mac.submit(2, [cmd("movex", 10)], 1000)
    now = mac.deadline
    out = mac.on_timer(now)
    if cls is CsmaMac:                       # it senses first, then raises TXEN
        while TxEnable(True) not in out:
            now = mac.deadline
            out = mac.on_timer(now)
    assert mac.phase == "switch"
    later = now + 10 * TICK_HZ // 1000
    assert mac.resync(later) == [TxEnable(False)]
    assert mac.phase == "rx" and mac.deadline is not None and mac.deadline >= later
    # the message is still there: the MAC raises TXEN for it again
    for _ in range(20):
        out = mac.on_timer(mac.deadline)
        if TxEnable(True) in out:
            break
    assert TxEnable(True) in out and mac.pending == 1
    assert mac.deadline >= later + TTRANS_TICKS


@pytest.mark.parametrize("kind", PEERS)
def test_a_station_running_a_peer_mac_survives_a_resync(kind):
    # RadioStation.resync (a stalled bench process) calls mac.resync: a peer MAC had none, so
    # the station died with an AttributeError. Resynced every 700 ms, robot 1 goes on.
    w = World(SimConfig(robots=(0, 1, 2), duration=12.0, seed=4, load=1.0, load_until=8.0))
    install(w, kind)
    st = w.stations[1]
    for k in range(1, 15):
        w.sched.at(k * 7 * TICK_HZ // 10, st.resync, TICK_HZ // 10)
    w.run()
    s = w.summary()
    assert s["submitted"] >= 15 and s["pending"] == 0
    assert s["submitted"] == s["delivered"] + s["failed"]
    assert s["delivered"] >= 0.8 * s["submitted"]
