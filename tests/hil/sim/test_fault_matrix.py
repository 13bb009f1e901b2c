"""Every fault kind, alone and in pairs, against the guarantees (docs/guarantees.md).

A ring of the father (with a standby PC) and three children with their CAN side carries
traffic; the faults act between 6 s and 16 s; traffic stops at 20 s and the run drains until
50 s. With the checksum extension on, each run must end with: every message delivered or failed
with a reason, nothing delivered twice, to the wrong robot, or corrupted, and the ring whole
again within the documented bound after the last fault.
"""
from __future__ import annotations

import itertools

import pytest

from firmware_model.radio.mac import MacConfig
from firmware_model.timing import TICK_HZ, s_to_ticks
from hil.sim.faults import Fault
from hil.sim.soak import REFORM_BOUND_S
from hil.sim.world import SimConfig, World

FAULTS = {
    "death": (Fault("fail", 2, 6.0), Fault("recover", 2, 12.0)),
    "death mid-frame": (Fault("fail", 3, 7.0137), Fault("recover", 3, 9.5)),
    "father PC": (Fault("fail", 0, 7.0), Fault("recover", 0, 13.0)),
    "forced collision": (Fault("steal", 1, 8.0),),
    "byte errors": (Fault("ber", None, 6.0, 12.0, 0.005),),
    "burst noise": (Fault("burst", None, 9.0, None, 0.3),),
    "idle noise": (Fault("noise", None, 6.0, 12.0),),
    "dropped bytes": (Fault("drop", None, 6.0, 12.0, 0.003),),
    "clock skew": (Fault("skew", 1, 0.0, None, 0.02),),
    "CAN bus-off": (Fault("busoff", 2, 8.0),),
    "stuck TXD": (Fault("stuck", 3, 8.0, 10.0),),
    "silent submodule": (Fault("silent", 1, 6.0, 12.0, None, "JOINT2"),),
    "stalled joint": (Fault("stall", 2, 7.0, 14.0, None, "JOINT1"),),
}

CASES = [(a,) for a in FAULTS] + list(itertools.combinations(FAULTS, 2))
"""Every fault alone (the fast tier) and every pair (the slow tier: 78 runs, minutes of CPU;
``pytest -m slow``)."""


def run(names):
    faults = tuple(f for n in names for f in FAULTS[n])
    evs: list[dict] = []
    w = World(SimConfig(robots=(0, 1, 2, 3), duration=50.0, seed=7, load=1.0, load_until=20.0,
                        can=True, father_standby=True, faults=faults,
                        mac=MacConfig(checksum=True, max_age=s_to_ticks(20))),
              on_event=evs.append)
    last_end = max(f.end for f in faults)
    w.run(s_to_ticks(last_end))
    reformed = None
    while w.now < w.end_tick:
        w.run(w.now + s_to_ticks(0.25))
        if reformed is None and w.ring_complete():
            reformed = w.now / TICK_HZ - last_end
    return w, evs, reformed


@pytest.mark.parametrize("names", [pytest.param(c, marks=pytest.mark.slow) if len(c) > 1 else c
                                   for c in CASES], ids=[" + ".join(c) for c in CASES])
def test_fault_matrix(names):
    w, evs, reformed = run(names)
    s = w.summary()
    assert s["submitted"] > 40
    assert s["pending"] == 0 and s["submitted"] == s["delivered"] + s["failed"]
    assert all(e["reason"] for e in evs if e["ev"] == "fail")
    assert s["duplicate_deliveries"] == 0
    assert s["wrong_robot_deliveries"] == 0
    assert s["corrupt_deliveries"] == 0                  # nobody acted on a corrupted command
    assert reformed is not None and reformed <= REFORM_BOUND_S, reformed
    assert w.ring_complete()
