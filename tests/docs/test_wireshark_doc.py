"""docs/wireshark.md's commands, run as written (in a scratch directory and home), with the real
tshark: each shell line of its code blocks, and each tshark command the text gives inline.
A line that needs what this machine has not (the Wireshark GUI, a USB radio) is named and left
out; the hub's lines, which run until stopped, run for a few seconds."""
from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from paths import ROOT

DOC = ROOT / "docs" / "wireshark.md"
TSHARK = shutil.which("tshark")
def not_here(line: str) -> str | None:
    """What this machine lacks for ``line``, or None."""
    if line.startswith("wireshark ") or "| wireshark" in line:
        return "the Wireshark GUI"
    if "/dev/ttyUSB" in line:
        return "a USB radio"
    return None


def shell_lines() -> list[str]:
    """Every command line of the page's ``sh`` code blocks (comments cut)."""
    out, inside = [], False
    for line in DOC.read_text(encoding="utf-8").splitlines():
        if line.startswith("```"):
            inside = line.strip() == "```sh" and not inside
            continue
        if inside and line.strip():
            out.append(line.split("  #")[0].strip())
    return out


def inline_tshark() -> list[str]:
    """The tshark commands the text gives in backticks that read a capture (``-r``; a bare
    option named in the text, ``tshark -2``, is no command)."""
    return [c for c in re.findall(r"`(tshark [^`]+)`", DOC.read_text(encoding="utf-8"))
            if " -r " in c]


@pytest.mark.slow  # a 20 s simulation with its capture, then tshark a few times: about 25 s
@pytest.mark.skipif(TSHARK is None, reason="tshark not installed (Debian package tshark; "
                    ".ci/run installs it)")
def test_every_command_of_the_page_runs_as_written(tmp_path):
    bindir = str(Path(sys.executable).parent)
    env = dict(os.environ, HOME=str(tmp_path), XDG_CONFIG_HOME=str(tmp_path / ".config"),
               PATH=bindir + os.pathsep + os.environ.get("PATH", ""))
    ran, left_out = [], []
    blocks = shell_lines()
    for line in blocks + inline_tshark():
        why = not_here(line)
        if why is not None:
            left_out.append((line, why))
            continue
        runs_until_stopped = "radio-hub" in line
        p = subprocess.Popen(["bash", "-c", line], cwd=tmp_path, env=env, text=True,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             start_new_session=True)
        try:
            out, err = p.communicate(timeout=4 if runs_until_stopped else 300)
        except subprocess.TimeoutExpired:          # the hub: stopped as Ctrl-C stops it
            os.killpg(p.pid, signal.SIGINT)
            try:
                out, err = p.communicate(timeout=15)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                out, err = p.communicate()
        assert "Lua" not in err and "Traceback" not in err, (line, err)
        if not runs_until_stopped:
            assert p.returncode == 0, (line, err)
        if line.startswith("tshark") and line in blocks:
            assert out.strip(), (line, err)        # it decoded, and the filter found frames
        ran.append(line)
    assert (tmp_path / "run.pcapng").stat().st_size > 10_000
    assert (tmp_path / "air.pcapng").exists()               # the hub's capture, to a file
    assert any(x.startswith("tshark") and "rprs.analysis" in x for x in ran)
    assert {why for _, why in left_out} <= {"the Wireshark GUI", "a USB radio"}
    assert len(ran) >= 5, ran
