"""benchmarks/speed_targets.py: the table flags figures that come from runs too short to trust."""
from __future__ import annotations

import importlib.util
import itertools
from paths import ROOT

_spec = importlib.util.spec_from_file_location("speed_targets",
                                               ROOT / "benchmarks" / "speed_targets.py")
bench = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench)


def _table(monkeypatch, capsys, walls):
    runs = itertools.cycle([(w, 100) for w in walls])
    monkeypatch.setattr(bench, "ours", lambda seconds, can=False, **kw: next(runs))
    monkeypatch.setattr(bench, "simpy_peer", lambda seconds: (1.0, 100))
    monkeypatch.setattr(bench, "LOADS", {"saturated": {"load": "saturate"}})
    bench.side_by_side(1, 60.0)
    return capsys.readouterr().out


def test_a_figure_from_runs_shorter_than_a_quarter_second_is_flagged(monkeypatch, capsys):
    out = _table(monkeypatch, capsys, [0.08, 0.3, 0.3])
    assert "| saturated | 750 | 200 | 0.27 |" in out
    assert "Shortest timed run, wall: saturated 0.08 s" in out and "--seconds 600" in out


def test_runs_long_enough_carry_no_warning(monkeypatch, capsys):
    out = _table(monkeypatch, capsys, [2.0, 3.0, 3.0])
    assert "| saturated |" in out and "Shortest timed run" not in out


def test_a_timed_run_imports_this_checkout_wherever_it_is_started_from(tmp_path, monkeypatch):
    """``python -c`` puts its working directory first on sys.path: a run started from a
    directory holding another ``hil`` must still time this checkout's model."""
    fake = tmp_path / "hil"
    fake.mkdir()
    (fake / "__init__.py").write_text("raise ImportError('the wrong tree')\n")
    monkeypatch.chdir(tmp_path)
    import sys
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        from fresh_process import timed
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    wall, frames = timed((0, 1), 8.0)
    assert wall > 0 and frames > 0


def test_the_simpy_peer_runs_the_ring_rprs_sim_runs(tmp_path):
    """The per-frame speed ratio against the SimPy peer (docs/performance.md) is fair only if
    the peer runs the same ring: benchmarks/simpy_ring.py says "with no fault in the ring, the
    real MAC's frames are these". Checked: once the ring of rprs sim has formed, its idle cycle
    (a heartbeat of 14 bytes and Ttrans per robot, the father's bytes 16 667 ticks, a child's
    16 640) is the peer's, to the tick: the peer ends its 50th cycle at 50 of them."""
    import json
    import sys

    import pytest
    pytest.importorskip("simpy", reason="simpy not installed (pip install -e '.[bench]')")
    from hil.sim.trace import TraceWriter
    from hil.sim.world import SimConfig, World
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        import simpy_ring
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    robots = tuple(range(7))
    tw = TraceWriter(str(tmp_path / "t.jsonl"))
    World(SimConfig(robots=robots, duration=40, seed=1), trace=tw).run()
    tw.close()
    frames = [e for e in map(json.loads, (tmp_path / "t.jsonl").read_text().splitlines())
              if e["ev"] == "frame"]
    last0 = max(i for i, f in enumerate(frames) if f["src"] == 0)
    tail = frames[last0 - 70:last0]                       # the ring formed long before
    assert [f["src"] for f in tail] == list(robots) * 10
    assert {(f["kind"], f["bytes"], f["collided"]) for f in tail} == {("heartbeat", 14, False)}
    ends = [f["end"] for f in tail if f["src"] == 0]
    cycles = {b - a for a, b in zip(ends, ends[1:])}
    assert len(cycles) == 1
    cycle = cycles.pop()
    assert cycle == 6 * (14 * 16_640 + 80_000) + 14 * 16_667 + 80_000
    # the peer counts a cycle when R0 hears the last robot's End: at 50 cycles exactly
    just_after, just_before = ((50 * cycle + d) / 16_000_000 for d in (1.5, -0.5))
    assert simpy_ring.run(robots, seconds=just_after)["frames"] == 50 * len(robots)
    assert simpy_ring.run(robots, seconds=just_before)["frames"] == 49 * len(robots)
