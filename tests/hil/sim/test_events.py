"""The typed trace events (hil/sim/events.py) and the world's listeners."""
from __future__ import annotations

import json
import pickle

import pytest

from hil.sim import events as E
from hil.sim.events import TraceError, from_record, typed
from hil.sim.faults import parse_fault
from hil.sim.trace import TraceWriter, read_events
from hil.sim.world import SimConfig, World

CFG = SimConfig(robots=(1, 2, 3), duration=4.0, seed=2, load=2.0)


def test_a_record_with_a_missing_or_mistyped_field_is_named():
    good = {"t": 9, "ev": "miss", "robot": 2, "by": 1}
    assert from_record(good, 5) == E.Miss(t=9, robot=2, by=1)
    with pytest.raises(TraceError, match=r"event 5 \(miss\): missing 'by'"):
        from_record({"t": 9, "ev": "miss", "robot": 2}, 5)
    with pytest.raises(TraceError, match=r"event 5 \(miss\): 'robot' is '2', not an integer"):
        from_record({**good, "robot": "2"}, 5)
    with pytest.raises(TraceError, match=r"'robot' is True, not an integer"):
        from_record({**good, "robot": True}, 5)
    with pytest.raises(TraceError, match=r"event 5 \(miss\): missing 't'"):
        from_record({"ev": "miss", "robot": 2, "by": 1}, 5)
    with pytest.raises(TraceError, match=r"event 7: a second meta event"):
        from_record({"t": 0, "ev": "meta"}, 7)
    with pytest.raises(TraceError, match="the first event must be the meta event"):
        list(typed([good]))
    with pytest.raises(TraceError, match="empty trace"):
        list(typed([]))


def test_a_kind_this_version_does_not_know_is_kept_not_refused():
    other = from_record({"t": 4, "ev": "sunspot", "level": 3}, 2)
    assert other == E.OtherEvent(4, "sunspot", {"level": 3})


def test_tags_are_left_out_when_unset_and_ticks_move_together():
    f = E.FrameOnAir(t=20, src=1, dst=None, num=None, type=None, len=None, kind=None,
                     start=10, end=20, bytes=3, collided=True, aborted=False)
    assert list(f.record()) == ["t", "ev", "src", "dst", "num", "type", "len", "kind",
                                "start", "end", "bytes", "collided", "aborted"]
    moved = f.shifted(100)
    assert (moved.t, moved.start, moved.end, moved.bytes) == (120, 110, 120, 3)
    pc2 = E.Mode(t=1, robot=0, pc=2, mode="member", reason="r")
    assert list(pc2.record()) == ["t", "ev", "robot", "pc", "mode", "reason"]
    d = E.Dispatch(t=5, robot=1, end=1, sof=5, latency=4).shifted(10)
    assert (d.t, d.end, d.sof, d.latency) == (15, 11, 15, 4)


def test_the_listeners_get_the_trace_file_event_for_event(tmp_path):
    """The trace writer, a records callback and a typed listener see the same run."""
    path = tmp_path / "t.jsonl"
    typed_evs: list = []
    records: list = []
    tw = TraceWriter(str(path))
    World(CFG, tw, on_event=records.append, listeners=[typed_evs.append]).run()
    tw.close()
    lines = [json.loads(x) for x in path.read_text().splitlines()]
    assert lines == records == [e.record() for e in typed_evs]
    assert list(read_events(str(path))) == typed_evs
    assert isinstance(typed_evs[0], E.Meta) and len(typed_evs) > 100


def test_a_listener_added_later_hears_from_then_on_and_one_removed_no_more():
    whole: list = []
    w = World(CFG, listeners=[whole.append])
    later: list = []
    w.run(2 * 16_000_000)
    w.add_listener(later.append)
    w.run(3 * 16_000_000)
    w.remove_listener(later.append)
    w.run()
    cut = [e for e in whole if 2 * 16_000_000 < e.t <= 3 * 16_000_000]
    assert later and [e for e in later if e.t > 2 * 16_000_000] == cut
    assert any(type(e) is E.TxenEdge for e in later)      # the radios report TXEN to it
    with pytest.raises(ValueError):
        w.remove_listener(later.append)


def test_nobody_listening_builds_no_event(monkeypatch):
    """Without a listener the world builds no event but the meta (the hot path's cost)."""
    built: list = []
    base = E.TraceEvent
    for name in dir(E):
        cls = getattr(E, name)
        if isinstance(cls, type) and issubclass(cls, base) and cls not in (base, E.Meta):
            monkeypatch.setattr(E, name,
                                lambda *a, _c=cls, **k: built.append(_c.KIND) or _c(*a, **k))
    cfg = SimConfig(robots=(1, 2, 3), duration=7.0, seed=1, load=2.0,
                    faults=(parse_fault("fail:2@2.5"), parse_fault("recover:2@6")))
    World(cfg).run()
    assert built == []
    World(cfg, listeners=[[].append]).run()
    assert {"miss", "disable", "rejoin", "frame", "submit"} <= set(built)


def test_a_world_with_a_records_callback_pickles_with_its_list():
    records: list = []
    w = World(CFG, on_event=records.append)
    w.run(16_000_000)
    copy = pickle.loads(pickle.dumps(w))
    own = copy.listeners[0].fn.__self__
    assert own == records and own is not records
