"""The core install (pyproject.toml's dependencies, no extra): what the firmware model, the
simulator, the bench and the captures need runs without the extras' libraries, and a command
that needs one says, in one line, which extra brings it.

The extras' libraries are installed in the test venv, so each command runs in a process whose
imports of them fail as in a core venv (a meta path finder put first refuses them)."""
from __future__ import annotations

import re
import subprocess
import sys
import textwrap

import pytest

from paths import ROOT

EXTRAS = {"numpy", "matplotlib", "dask", "distributed", "textual", "pyarrow"}

RUNNER = textwrap.dedent(f"""
    import sys

    class NoExtras:
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in {sorted(EXTRAS)!r}:
                raise ModuleNotFoundError(f"No module named {{name!r}}", name=name)
            return None

    sys.meta_path.insert(0, NoExtras())
    from hil.cli import main
    code = main(sys.argv[1:])
    leaked = sorted(m for m in sys.modules if m.split(".")[0] in {sorted(EXTRAS)!r})
    if leaked:
        print("imported:", leaked, file=sys.stderr)
        code = 99
    sys.exit(code)
""")


def core(*args: str, cwd=ROOT, timeout: float = 120) -> subprocess.CompletedProcess:
    """``rprs ARGS`` in a process that cannot import the extras' libraries."""
    return subprocess.run([sys.executable, "-c", RUNNER, *args], cwd=cwd, text=True,
                          capture_output=True, timeout=timeout)


def test_the_demo_and_the_simulator_with_a_capture_run_on_the_core(tmp_path):
    p = core("demo")                            # the README's main job
    assert p.returncode == 0, p.stderr
    assert "cycle(s) done" in p.stdout
    p = core("demo", "ring")
    assert p.returncode == 0, p.stderr
    assert "What happened" in p.stdout
    p = core("sim", "--robots", "0,1,2", "--duration", "5", "--can", "--load", "1",
             "--pcap", str(tmp_path / "run.pcapng"), "--trace", str(tmp_path / "run.jsonl"),
             "--vcd", str(tmp_path / "run.vcd"), "--no-progress")
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "run.pcapng").stat().st_size > 1000
    assert (tmp_path / "run.vcd").stat().st_size > 1000


def test_a_child_and_the_plain_father_run_on_the_core_on_the_hub(tmp_path):
    from processes import hub_links
    with hub_links(tmp_path / "air", 2):
        child = subprocess.Popen([sys.executable, "-c", RUNNER, "child", "--id", "1",
                                  "--radio", str(tmp_path / "air" / "node0"), "--team", "0,1",
                                  "--duration", "6"], cwd=ROOT, text=True,
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        father = core("father", "--plain", "--no-input", "--radio",
                      str(tmp_path / "air" / "node1"), "--team", "0,1", "--duration", "5")
        out, err = child.communicate(timeout=30)
    assert father.returncode == 0, father.stderr
    assert child.returncode == 0, err
    for said, me in ((father.stderr, 0), (out + err, 1)):
        if "stalled: it did not run for" in said:
            # the process itself did not run for longer than the margins (a busy machine),
            # said so and listened for the ring again; the run may end before it is back
            # in: it ran, sent and heard frames on the hub
            sent, heard = re.search(r"frames sent (\d+), heard (\d+)", said).groups()
            assert int(sent) > 10 and int(heard) > 10, said
        else:
            assert f"robot {me}: member, ring [0, 1]" in said, said


@pytest.mark.parametrize("args, extra", [
    (["plot", "trace.jsonl", "-o", "fig.png"], "plot"),
    (["monitor", "--robots", "1,2"], "ui"),
    (["campaign", "run", "spec.toml"], "campaign"),
])
def test_a_command_whose_extra_is_missing_says_which_in_one_line(args, extra, tmp_path):
    made = core("sim", "--robots", "1,2", "--duration", "2", "--trace",
                str(tmp_path / "trace.jsonl"), "--no-progress")
    assert made.returncode == 0, made.stderr
    (tmp_path / "spec.toml").write_text('[base]\nrobots = "1,2"\nduration = 1\n')
    p = core(*args, cwd=tmp_path)
    assert p.returncode == 2, (p.stdout, p.stderr)
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in p.stderr, p.stderr
    assert f"'{extra}' extra" in lines[0] and f"rprs[{extra}]" in lines[0], lines[0]


EXTRA_DISTS = {"numpy", "matplotlib", "dask", "distributed", "textual", "pyarrow", "bokeh"}
"""The distributions the extras bring that a core install must not have."""


@pytest.mark.slow  # a venv of its own with the project installed from its files: about 40 s
def test_a_real_core_venv_has_no_extra_and_runs_the_demo_the_simulator_and_the_bench(
        tmp_path):
    """``pip install .`` (no extra) into a fresh venv: none of the extras' libraries come
    with it, and there ``rprs demo``, ``rprs sim --pcap``, ``rprs child`` and ``rprs father
    --plain`` (on a hub the same venv runs) work."""
    venv = tmp_path / "core"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=120)
    py, rprs = venv / "bin" / "python", str(venv / "bin" / "rprs")
    got = subprocess.run([str(py), "-m", "pip", "install", "-q", str(ROOT)], text=True,
                         capture_output=True, timeout=900)
    assert got.returncode == 0, got.stderr[-3000:]
    frozen = subprocess.run([str(py), "-m", "pip", "freeze"], text=True, capture_output=True,
                            check=True).stdout
    installed = {ln.split("==")[0].split(" @ ")[0].strip().lower()
                 for ln in frozen.splitlines() if ln.strip()}
    assert "rprs" in installed and not installed & EXTRA_DISTS, sorted(installed)

    def run(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
        return subprocess.run([rprs, *args], cwd=tmp_path, text=True, capture_output=True,
                              timeout=timeout)
    p = run("demo")                                   # the README's main job
    assert p.returncode == 0 and "cycle(s) done" in p.stdout, p.stderr
    p = run("sim", "--robots", "0,1,2", "--duration", "5", "--can", "--load", "1", "--pcap",
            "run.pcapng", "--no-progress")
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "run.pcapng").stat().st_size > 1000
    air = tmp_path / "air"
    hub = subprocess.Popen([rprs, "radio-hub", "--nodes", "2", "--link-dir", str(air)],
                           stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        from processes import wait_for
        assert wait_for((air / "node1").exists, 30.0), "the hub made no node links"
        child = subprocess.Popen([rprs, "child", "--id", "1", "--radio", str(air / "node0"),
                                  "--team", "0,1", "--duration", "6"], text=True,
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        father = run("father", "--plain", "--no-input", "--radio", str(air / "node1"),
                     "--team", "0,1", "--duration", "5")
        out, err = child.communicate(timeout=30)
    finally:
        hub.terminate()
        hub.communicate(timeout=10)
    assert father.returncode == 0, father.stderr
    assert child.returncode == 0, err
    assert "robot 0: member, ring [0, 1]" in father.stderr, father.stderr
