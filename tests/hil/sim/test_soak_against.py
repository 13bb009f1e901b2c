"""benchmarks/soak_against.py: the soak beside an older commit, in a temporary worktree,
its accounting compared run by run."""
from __future__ import annotations

import importlib.util
import subprocess

import pytest
from paths import ROOT

_spec = importlib.util.spec_from_file_location("soak_against",
                                               ROOT / "benchmarks" / "soak_against.py")
bench = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench)


def _worktrees() -> set[str]:
    """The worktrees' paths: not their commits, which others working in the same repository
    move on (a commit on main during the run once failed the comparison)."""
    out = subprocess.run(["git", "-C", str(ROOT), "worktree", "list", "--porcelain"],
                         check=True, capture_output=True, text=True).stdout
    return {line.split(" ", 1)[1] for line in out.splitlines() if line.startswith("worktree ")}


def test_the_accounting_leaves_out_wall_times_only():
    a = '[{"wall_s": 1.5, "summary": {"delivered": 3}, "reform_s": [1.0]}]'
    b = '[{"wall_s": 9.0, "summary": {"delivered": 3}, "reform_s": [1.0]}]'
    c = '[{"wall_s": 1.5, "summary": {"delivered": 4}, "reform_s": [1.0]}]'
    assert bench.accounting(a) == bench.accounting(b) != bench.accounting(c)


def test_a_commit_that_does_not_exist_is_a_clear_error(capsys):
    with pytest.raises(SystemExit) as e:
        bench.main(["--base", "no-such-commit-0000"])
    assert e.value.code == 2
    assert "is not a commit" in capsys.readouterr().err


@pytest.mark.slow
def test_head_against_itself_gives_the_same_accounting_and_leaves_no_worktree(capsys):
    # one test for both runs: two tests that each add a worktree, on two xdist workers at
    # once, saw each other's in the list (a worktree being added is listed "locked")
    before = _worktrees()
    assert bench.main(["--base", "HEAD", "--hours", "0.05", "--runs", "1"]) == 0
    out = capsys.readouterr().out
    assert "accounting the same in every run" in out and "| rprs soak --hours 0.05" in out
    # a row for the base and one for this tree, each with its own run (once, both were
    # filed under the one commit name and each row showed both runs)
    rows = [line for line in out.splitlines() if line.startswith("| ") and " s, " not in line
            and not line.startswith("|---")]
    assert len(rows) == 2 and all(len(r.split("|")[2].split("/")) == 1 for r in rows), rows
    assert _worktrees() == before
    # the README's soak, both checksums, as each tree runs it
    assert bench.main(["--base", "HEAD", "--hours", "0.05", "--runs", "1",
                       "--checksum", "both"]) == 0
    out = capsys.readouterr().out
    assert "| rprs soak --hours 0.05 --seed 11 --checksum both" in out
    assert "accounting the same in every run" in out
    assert _worktrees() == before
