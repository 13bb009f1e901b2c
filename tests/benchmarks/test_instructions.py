"""benchmarks/instructions.py: instruction counts of the simulator's run, by callgrind."""
from __future__ import annotations

import importlib.util
import shutil

import pytest

from paths import ROOT

_spec = importlib.util.spec_from_file_location("instructions",
                                               ROOT / "benchmarks" / "instructions.py")
bench = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench)

TINY = """
from hil.sim.world import SimConfig, World
w = World(SimConfig(robots=(0, 1, 2), duration={seconds}))
run = w.run
done = lambda: ({seconds}, w.air.occupations)
"""


def test_the_count_is_read_from_callgrinds_summary():
    assert bench.collected("==77== Events    : Ir\n==77== Collected : 1,234,567\n") == 1234567
    assert bench.collected("==77== Collected : 42") == 42
    with pytest.raises(bench.NoValgrind, match="no count"):
        bench.collected("valgrind: command not found")


def test_the_table_gives_per_second_per_frame_and_the_ratio_to_the_base():
    out = bench.table([("idle", 2_000_000, 10.0, 100, 3_000_000),
                       ("soak", 1_000, 1.0, 0, None)], "abc1234")
    lines = out.splitlines()
    assert lines[0].endswith("| abc1234 | abc1234 / this |")
    assert lines[2] == "| idle | 2,000,000 | 200,000 | 20,000 | 3,000,000 | 1.500 |"
    assert lines[3] == "| soak | 1,000 | 1,000 | 1,000 |"     # no frames: no division by zero
    assert "abc1234" not in bench.table([("idle", 5, 1.0, 1, None)], None)


@pytest.mark.parametrize("argv, message", [
    (["--only", "idle,nothing"], "unknown workload(s) nothing"),
    (["--only", ","], "unknown workload(s) (none given)"),
    (["--base", "no-such-commit-0000", "--only", "idle"], "is not a commit"),
])
def test_bad_arguments_are_clear_errors(argv, message, capsys):
    with pytest.raises(SystemExit) as e:
        bench.main(argv)
    assert e.value.code == 2
    assert message in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("valgrind") is None,
                    reason="valgrind is not installed (Debian package valgrind)")
def test_only_the_run_is_counted(monkeypatch):
    monkeypatch.setitem(bench.WORKLOADS, "tiny", TINY.format(seconds=8.0))
    n, seconds, frames = bench.count(str(ROOT), "tiny")
    assert seconds == 8.0 and frames > 0          # the ring formed and turned (from 4.2 s)
    # the interpreter's start and the imports alone execute over a billion instructions
    # (measured: 1.4e9); the run alone, some hundreds of thousands a radio frame
    assert 20_000 < n / frames < 2_000_000 and n < 300_000_000, (n, frames)
