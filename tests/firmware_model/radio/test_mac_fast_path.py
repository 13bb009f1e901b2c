"""The MAC's fast path for the turn owner's heartbeat (RotationalMac.on_frame) does what the
general path does. It once did not: it skipped the checksum check with the extension on, and
kept a robot it had heard BOOT among the booting ones after its first heartbeat. Here every
heartbeat of the turn owner heard in the seeded runs of tests/trace_digests.py is also given
to a copy of the MAC with the fast path switched off: the actions and the whole state after
must be equal."""
from __future__ import annotations

import copy
import dataclasses
import random

import pytest

from firmware_model.radio.mac import RotationalMac
from trace_digests import RUNS, digest, read_recorded


def _value(v):
    """A comparable copy of ``v`` (a message is compared by identity in the MAC: here by
    its fields)."""
    if dataclasses.is_dataclass(v) and not isinstance(v, type):
        return type(v).__name__, [_value(getattr(v, f.name)) for f in dataclasses.fields(v)]
    if isinstance(v, dict):
        return sorted((repr(k), _value(x)) for k, x in v.items())
    if isinstance(v, (set, frozenset)):
        return sorted(map(repr, v))
    if isinstance(v, (list, tuple)) or type(v).__name__ == "deque":
        return type(v).__name__, [_value(x) for x in v]
    if isinstance(v, random.Random):               # the MAC's seeded draws (clause 38.2)
        return "Random", v.getstate()
    return v


MISSES = "--robots 1,2,3,4 --duration 20 --seed 8 --fault drop@4-12:0.03"
"""Bytes dropped at 3 %: turns missed, then heartbeats from robots with misses counted."""


@pytest.mark.parametrize("name", [n for n in RUNS if "--mac" not in RUNS[n]] + ["misses"])
def test_the_fast_path_leaves_what_the_general_path_leaves(name, monkeypatch):
    real = RotationalMac.on_frame
    compared = []

    def both_ways(self, frame, first, end, now):
        if frame.type != 3 or frame.src != self.owner:
            return real(self, frame, first, end, now)
        general = copy.deepcopy(self)
        general.general_path_only()
        expected = real(general, frame, first, end, now)
        got = real(self, frame, first, end, now)
        assert _value(list(got)) == _value(list(expected))
        mine, theirs = ({k: _value(v) for k, v in vars(m).items() if k != "_hb_len"}
                        for m in (self, general))
        assert mine == theirs, [k for k in mine if mine[k] != theirs[k]]
        compared.append(frame)
        return got

    monkeypatch.setattr(RotationalMac, "on_frame", both_ways)
    if name == "misses":
        digest(MISSES)
    else:
        assert digest(RUNS[name]) == read_recorded()[name]
    assert len(compared) > 100
