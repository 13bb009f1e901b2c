"""benchmarks/speed_targets.py: the table flags figures that come from runs too short to trust."""
from __future__ import annotations

import importlib.util
import itertools
import pathlib

ROOT = pathlib.Path(__file__).parent.parent
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
