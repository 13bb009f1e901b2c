"""The README's "Using `rprs`" section, run as written in a fresh shell that has only done
what the README says (its first two commands made the venv; the section activates it).

Every command of the section runs: the quick ones exactly as written, the long ones with
their duration cut (the table SHORTER says how and why), the benchmark and script runs of
minutes with ``--help`` (which imports what the run imports; their runs have tests of their
own). The commands run in a temporary directory beside links to the checkout's examples/,
benchmarks/ and scripts/, so that what they write (run.jsonl, fig7.png, study.sqlite) stays
out of the checkout. ``.venv/bin/activate`` there puts this Python's ``rprs`` and ``python``
first on PATH, as the project's venv does.
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest
from paths import ROOT

ACTIVATE = ". .venv/bin/activate"

SHORTER = {
    "rprs sim --robots 1,2,3,4,5,6 --duration 3600 --load saturate --json":
        ("rprs sim --robots 1,2,3,4,5,6 --duration 300 --load saturate --json",
         "an hour saturated is 15-40 s of wall time"),
    "rprs soak --hours 2 --seed 11 --checksum both":
        ("rprs soak --hours 0.05 --seed 11 --checksum both --no-can",
         "the shortest soak, radio only: 2 h is about half an hour of wall time"),
    "rprs campaign run examples/study.toml --db study.sqlite":
        ("rprs campaign run examples/study.toml --db study.sqlite --workers 1 --allow-dirty",
         "the tree under test may have uncommitted changes; one worker starts fastest"),
}
"""README command -> (what this test runs instead, why)."""

HELP_ONLY = ("python benchmarks/", "python scripts/")
"""Commands of minutes (benchmarks, the lock-step search, the sleep hunt: one of its worlds
is half a minute on a busy machine): run with ``--help`` only."""

GROUPS = {
    "sim and plot": ("rprs sim --robots 0,1,2,3,4 --duration 60", "rprs plot run.jsonl"),
    "sim saturated": ("rprs sim --robots 1,2,3,4,5,6",),
    "codec": ("rprs encode", "rprs decode", "cat examples/capture.bin"),
    "soak": ("rprs soak",),
    "campaign": ("rprs campaign",),
    "listing": ("rprs listing",),
}
"""Groups of commands run in one shell, in the README's order (a group's later commands read
what its earlier ones wrote), each a test of its own; every ``python ...`` command is a
group of its own. ``rprs monitor`` has a test of its own: it needs a terminal."""


def readme_section_commands() -> list[str]:
    """The shell commands of the README's "Using `rprs`" section in order: continuation
    lines joined, comments and blank lines left out."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text.split("\n## Using `rprs`\n", 1)[1].split("\n## ", 1)[0]
    out: list[str] = []
    for block in re.findall(r"```sh\n(.*?)```", section, re.S):
        for line in block.replace("\\\n", " ").splitlines():
            line = re.sub(r"\s+#.*$", "", line).strip()
            if line and not line.startswith("#"):
                out.append(re.sub(r"\s+", " ", line))
    return out


def _planned(cmd: str) -> str:
    """What this test runs for the README's ``cmd``."""
    if cmd in SHORTER:
        return SHORTER[cmd][0]
    if cmd.startswith(HELP_ONLY):
        return cmd.split(" ")[0] + " " + cmd.split(" ")[1] + " --help"
    return cmd


def _group(cmd: str) -> str | None:
    if cmd.startswith("python "):
        return cmd
    for name, prefixes in GROUPS.items():
        if cmd.startswith(prefixes):
            return name
    return None


@pytest.fixture
def shell_dir(tmp_path: Path) -> Path:
    """A directory like the checkout's root after the README's first two commands: links to
    examples/, benchmarks/ and scripts/, and a ``.venv/bin/activate`` whose ``rprs`` and
    ``python`` run this test's Python (wrappers, not links: a venv's python finds its
    site-packages from the path it was started by)."""
    for d in ("examples", "benchmarks", "scripts"):
        (tmp_path / d).symlink_to(ROOT / d)
    bin_dir = tmp_path / ".venv" / "bin"
    bin_dir.mkdir(parents=True)
    (bin_dir / "python").write_text(f'#!/bin/sh\nexec "{sys.executable}" "$@"\n')
    (bin_dir / "rprs").write_text(f'#!/bin/sh\nexec "{sys.executable}" -m hil.cli "$@"\n')
    for f in ("python", "rprs"):
        (bin_dir / f).chmod(0o755)
    (bin_dir / "activate").write_text(f'PATH="{bin_dir}:$PATH"; export PATH\n')
    return tmp_path


def _env() -> dict:
    """This test's environment (PYTHONPATH included: the tree under test), without a venv on
    PATH: only ``. .venv/bin/activate`` gives the commands ``rprs``."""
    env = dict(os.environ)
    env["PATH"] = os.pathsep.join(p for p in env.get("PATH", "").split(os.pathsep)
                                  if not (Path(p) / "rprs").exists()) or "/usr/bin:/bin"
    env.pop("VIRTUAL_ENV", None)
    return env


def _run(shell_dir: Path, cmd: str, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run(["bash", "-c", f"{ACTIVATE} && {cmd}"], cwd=shell_dir, env=_env(),
                          capture_output=True, text=True, timeout=timeout)


def test_the_section_activates_the_venv_first_and_every_command_is_run_here():
    """The section starts with the venv's activation (its later bare ``rprs`` and ``python``
    are the venv's), and every command in it is one this file runs: a command added to the
    README without a way to run it here fails this test."""
    cmds = readme_section_commands()
    assert cmds[0] == ACTIVATE
    assert "rprs monitor --robots 0,1,2,3 --load 1" in cmds
    unplaced = [c for c in cmds[1:] if _group(c) is None and not c.startswith("rprs monitor")]
    assert unplaced == []
    assert set(SHORTER) <= set(cmds), set(SHORTER) - set(cmds)


@pytest.mark.parametrize("group", [*GROUPS, *(c for c in readme_section_commands()
                                              if c.startswith("python "))])
def test_the_readme_commands_run_as_written(shell_dir, group):
    cmds = [c for c in readme_section_commands()[1:] if _group(c) == group]
    assert cmds, group
    results = {}
    for cmd in cmds:
        r = _run(shell_dir, _planned(cmd))
        assert "Traceback" not in r.stderr, (cmd, r.stderr[-2000:])
        assert r.returncode == 0, (cmd, r.returncode, r.stderr[-2000:])
        results[cmd] = r
    if group == "sim and plot":
        assert (shell_dir / "run.jsonl").stat().st_size > 0
        assert (shell_dir / "fig7.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert "duplicate deliveries" in results[cmds[0]].stdout
    elif group == "sim saturated":
        summary = json.loads(results[cmds[0]].stdout)
        assert summary["delivered"] > 0 and summary["duration_ticks"] > 0
    elif group == "codec":
        encoded = results[cmds[0]].stdout.strip()
        assert cmds[1] == f"rprs decode {encoded}"        # the README decodes what it encoded
        frame = json.loads(results[cmds[1]].stdout)["frame"]
        assert frame["content"] == "movex(10)" and frame["src"] == 1 and frame["dst"] == 2
        lines = [json.loads(x) for x in results[cmds[2]].stdout.splitlines()]
        assert [next(k for k in x if k != "offset") for x in lines] == \
            ["garbage", "frame", "frame", "frame", "error", "frame"]
    elif group == "soak":
        assert "every message delivered or failed" in results[cmds[0]].stdout
    elif group == "campaign":
        assert (shell_dir / "study.sqlite").exists()
        assert "runs" in results[cmds[1]].stdout
    elif group == "listing":
        assert results[cmds[0]].stdout.splitlines()[-1].startswith("can_rx: ")
    elif _planned(group).endswith("--help"):
        assert results[group].stdout.startswith("usage:"), group


def test_the_readme_monitor_command_runs_in_a_terminal(shell_dir):
    """``rprs monitor`` as the README writes it, in a pty (a live view needs a terminal):
    it draws the ring and ends on ``q``."""
    import pty
    import threading
    cmd = next(c for c in readme_section_commands() if c.startswith("rprs monitor"))
    master, slave = pty.openpty()
    p = subprocess.Popen(["bash", "-c", f"{ACTIVATE} && {cmd}"], cwd=shell_dir, env=_env(),
                         stdin=slave, stdout=subprocess.PIPE, stderr=slave,
                         start_new_session=True)
    os.close(slave)
    screen = bytearray()

    def read():
        while True:
            try:
                chunk = os.read(master, 65536)
            except OSError:
                return
            if not chunk:
                return
            screen.extend(chunk)
    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        deadline = time.monotonic() + 120
        while b"occupations" not in screen and p.poll() is None and time.monotonic() < deadline:
            time.sleep(0.1)
        assert b"occupations" in screen, bytes(screen[-500:])
        os.write(master, b"q")
        p.communicate(timeout=120)
        assert p.returncode == 0
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
        os.close(master)
        reader.join(timeout=10)


BENCHMARKS = sorted(p.name for p in (ROOT / "benchmarks").glob("*.py")
                    if "__main__" in p.read_text(encoding="utf-8") and p.name != "_project.py")
SCRIPTS = sorted(p.name for p in (ROOT / "scripts").glob("*.py") if not p.name.startswith("_"))


def test_a_python_without_the_project_gets_one_line_from_every_benchmark():
    """``python benchmarks/run.py --quick`` with a Python that lacks the project printed six
    tracebacks and exited 1; now every benchmark run as a script says in one line what to
    run instead, exit status 2. The Python lacking the project is this one without its
    site-packages and environment (-S -s -E)."""
    assert "run.py" in BENCHMARKS and len(BENCHMARKS) >= 10
    for name in BENCHMARKS:
        args = ["--quick"] if name == "run.py" else ["--help"]
        r = subprocess.run([sys.executable, "-S", "-s", "-E", f"benchmarks/{name}", *args],
                           cwd=ROOT, capture_output=True, text=True, timeout=60)
        assert r.returncode == 2 and r.stdout == "", (name, r.returncode, r.stdout[-300:])
        assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, (name, r.stderr)
        assert f".venv/bin/python benchmarks/{name}" in r.stderr, r.stderr


def test_a_python_without_the_project_gets_one_line_from_every_script():
    """The same for scripts/*.py (they printed a ModuleNotFoundError traceback)."""
    assert len(SCRIPTS) >= 4
    for name in SCRIPTS:
        r = subprocess.run([sys.executable, "-S", "-s", "-E", f"scripts/{name}", "--help"],
                           cwd=ROOT, capture_output=True, text=True, timeout=60)
        assert r.returncode == 2 and r.stdout == "", (name, r.returncode, r.stdout[-300:])
        assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, (name, r.stderr)
        assert f".venv/bin/python scripts/{name}" in r.stderr, r.stderr


def test_every_script_and_benchmark_starts_with_the_projects_python(tmp_path):
    """``python scripts/bench_stalls.py``, as docs/guarantees.md quotes it, died at import:
    the tests' directory it put first on sys.path holds package-less ``tests/hil/``, which
    shadowed the project's ``hil`` (an editable install is found after every path entry).
    Every script and benchmark gives its usage with the project's Python, from any
    directory."""
    for path in [ROOT / "scripts" / n for n in SCRIPTS] + \
            [ROOT / "benchmarks" / n for n in BENCHMARKS if n != "run.py"]:
        r = subprocess.run([sys.executable, str(path), "--help"], cwd=tmp_path,
                           capture_output=True, text=True, timeout=60)
        assert r.returncode == 0 and "usage:" in r.stdout, (path.name, r.stderr[-400:])
