"""An earlier commit checked out beside this tree, for a benchmark that compares the two in one
run (soak_against.py, instructions.py).

``with checkout("a4cc274") as (name, tree): ...`` gives the commit's short name and a temporary
git worktree of it (detached, removed at the end, whatever happens), after checking that a
process started in either tree imports ``hil`` from that tree and not from an installed copy.
"""
from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import tempfile
from typing import Iterator

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
"""This checkout."""


def git(*args: str) -> str:
    return subprocess.run(["git", "-C", ROOT, *args], check=True, capture_output=True,
                          text=True).stdout.strip()


def resolve(commit: str) -> str | None:
    """Short name of ``commit`` in this repository, or None if it names no commit."""
    try:
        return git("rev-parse", "--short", commit + "^{commit}")
    except subprocess.CalledProcessError:
        return None


def head_label() -> str:
    """HEAD's short name, saying so if the tree has uncommitted changes (they are measured)."""
    dirty = " (and its uncommitted changes)" if git("status", "--porcelain", "-uno") else ""
    return git("rev-parse", "--short", "HEAD") + dirty


def imports_from(tree: str) -> str:
    """Where ``hil`` is imported from when run in ``tree`` (it must be that tree)."""
    env = dict(os.environ, PYTHONPATH=tree)
    return subprocess.run([sys.executable, "-c", "import hil, os; print(os.path.dirname("
                           "os.path.dirname(os.path.abspath(hil.__file__))))"], cwd=tree,
                          env=env, check=True, capture_output=True, text=True).stdout.strip()


@contextlib.contextmanager
def checkout(commit: str, prefix: str = "bench-base-") -> Iterator[tuple[str, str]]:
    """(short name, path) of a temporary worktree of ``commit`` (which must exist)."""
    name = resolve(commit)
    if name is None:
        raise ValueError(f"{commit!r} is not a commit of {ROOT}")
    with tempfile.TemporaryDirectory(prefix=prefix) as tmp:
        tree = os.path.join(tmp, name)
        git("worktree", "add", "--detach", tree, name)
        try:
            for t in (tree, ROOT):
                where = imports_from(t)
                if os.path.realpath(where) != os.path.realpath(t):
                    raise SystemExit(f"running in {t} imports hil from {where}")
            yield name, tree
        finally:
            git("worktree", "remove", "--force", tree)
