"""The ``rprs`` command line: outputs, files, and one-line errors with status 2."""
from __future__ import annotations

import io
import json
import os
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from hil.cli import main
from paths import ROOT


def rprs(capsys, *args):
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


def test_tables_written_to_a_file_or_a_pipe_end_no_line_in_spaces(capsys):
    """A rich table pads every cell of its last column to the widest one: ``rprs conformance
    > report.txt`` had lines of some 350 columns, most of them spaces. Off a terminal every
    line of rprs's tables ends with its last character."""
    from hil.cli.common import stdout_console
    code, out, _ = rprs(capsys, "sim", "--duration", "3")
    assert code == 0 and " robot " in out
    from rich.table import Table
    t = Table("what", "why")
    t.add_row("a", "a long reason " * 5)
    t.add_row("b", "short")
    stdout_console().print(t)
    wide = capsys.readouterr().out
    assert "short" in wide
    for text in (out, wide):
        lines = text.splitlines()
        assert lines and not [line for line in lines if line.endswith(" ")], text


def test_sim_json_summary(capsys):
    code, out, err = rprs(capsys, "sim", "--robots", "0,1,2", "--duration", "6", "--load", "2",
                          "--json")
    assert code == 0
    s = json.loads(out)
    assert set(s["robots"]) == {"0", "1", "2"}
    assert s["submitted"] == s["delivered"] + s["failed"] + s["pending"]
    assert all(v["frames_sent"] > 10 for v in s["robots"].values())
    assert s["occupations"] == sum(v["frames_sent"] for v in s["robots"].values())


def test_sim_table_names_the_papers_columns(capsys):
    code, out, _ = rprs(capsys, "sim", "--duration", "5", "--fail", "2@4")
    assert code == 0
    for word in ("frames", "received", "pending", "missed", "membership changes",
                 "channel occupations", "delivered"):
        assert word in out


def test_sim_trace_file_is_complete_and_deterministic(tmp_path, capsys):
    a, b = tmp_path / "a.jsonl", tmp_path / "b.jsonl"
    for p in (a, b):
        assert rprs(capsys, "sim", "--duration", "8", "--seed", "4", "--load", "3",
                    "--ber", "0.002", "--fail", "3@3", "--recover", "3@6",
                    "--trace", str(p))[0] == 0
    assert a.read_bytes() == b.read_bytes()
    lines = a.read_text().splitlines()
    meta = json.loads(lines[0])
    assert meta["ev"] == "meta" and meta["tick_hz"] == 16_000_000
    assert meta["byte_ticks"] == {"1": 16640, "2": 16640, "3": 16640, "4": 16640}
    assert (meta["ttrans"], meta["tmax"], meta["seed"]) == (80_000, 9_600_000, 4)
    evs = [json.loads(x) for x in lines[1:]]
    assert all(x["t"] <= y["t"] for x, y in zip(evs, evs[1:]))
    kinds = {e["ev"] for e in evs}
    assert {"frame", "miss", "disable", "rejoin", "submit", "deliver"} <= kinds
    f = next(e for e in evs if e["ev"] == "frame")
    assert {"src", "dst", "num", "type", "len", "start", "end"} <= set(f)
    assert not list(tmp_path.glob("*.partial"))


def test_the_same_seed_gives_the_same_files_in_processes_with_other_string_hashes(tmp_path):
    """Determinism across processes: a set or dict of strings iterates in an order that
    Python's hash seed decides, a different one in each process. Two processes with other
    hash seeds (PYTHONHASHSEED) run one seeded world with most of the model on (the standby
    father taking over, CAN sides with a bus-off, noise, the authenticated profile, the CPU
    model) and write the same trace, capture and waveform, byte for byte."""
    key = tmp_path / "ring.key"
    key.write_text("key = 000102030405060708090a0b0c0d0e0f\n")
    outs = []
    for seed in ("0", "4242"):
        d = tmp_path / seed
        d.mkdir()
        args = ["sim", "--robots", "0,1,2,3", "--duration", "12", "--seed", "5", "--load", "1",
                "--can", "--father-standby", "--fault", "fail:0@4", "--recover", "0@6",
                "--fault", "busoff:2@3", "--noise", "--auth-key", str(key),
                "--trace", str(d / "t.jsonl"), "--pcap", str(d / "p.pcapng"),
                "--vcd", str(d / "w.vcd")]
        env = dict(os.environ, PYTHONHASHSEED=seed)
        r = subprocess.run([sys.executable, "-m", "hil.cli", *args], env=env, cwd=ROOT,
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
        outs.append([(d / n).read_bytes() for n in ("t.jsonl", "p.pcapng", "w.vcd")])
    assert all(outs[0]) and outs[0] == outs[1]


def test_a_trace_named_gz_is_written_compressed_and_the_same_for_the_same_seed(tmp_path,
                                                                               capsys):
    """``--trace run.jsonl.gz`` wrote plain text under a gzip name (``rprs plot`` and
    ``read_trace`` read gzip by its magic bytes, ``zcat`` refused it). It is gzip now: the
    plain trace's bytes inside, and byte for byte the same file for the same seed (no name or
    time in the gzip header)."""
    import gzip
    from hil.sim.trace import read_trace
    plain, a, b = tmp_path / "t.jsonl", tmp_path / "a.jsonl.gz", tmp_path / "b.jsonl.gz"
    for p in (plain, a, b):
        assert rprs(capsys, "sim", "--duration", "6", "--seed", "2", "--load", "1",
                    "--trace", str(p))[0] == 0
    assert a.read_bytes()[:2] == b"\x1f\x8b" and a.read_bytes() == b.read_bytes()
    assert gzip.decompress(a.read_bytes()) == plain.read_bytes()
    assert list(read_trace(str(a))) == list(read_trace(str(plain)))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.jsonl.gz", "b.jsonl.gz",
                                                         "t.jsonl"]


@pytest.mark.parametrize("args,needle", [
    (["sim", "--robots", "9"], "robot ID 9 is out of range"),
    (["sim", "--robots", "1,1"], "repeat"),
    (["sim", "--robots", "a,b"], "comma-separated"),
    (["sim", "--fail", "x@y"], "ID@SECONDS"),
    (["sim", "--fail", "5@1"], "not in the ring"),
    (["sim", "--duration", "-1"], "positive"),
    (["sim", "--duration", "nan"], "positive"),
    (["sim", "--ber", "2"], "probability"),
    (["sim", "--load", "lots"], "idle, saturate"),
    (["sim", "--trace", "/nonexistent-dir/t.jsonl"], "cannot write trace"),
    (["encode", "--src", "9", "--dst", "1", "movex(1)"], "source must be 0-6"),
    (["encode", "--src", "1", "--dst", "2", "movex(1"], "content byte"),
    (["encode", "--src", "1", "--dst", "2", "fly(1)"], "unknown command"),
    (["decode", "zz"], "not hexadecimal"),
    (["decode"], "give the frame"),
    (["plot", "/nonexistent/trace.jsonl", "-o", "/tmp/x.png"], "cannot read trace"),
    (["sim", "--fault", "ber@5-2:0.1"], "empty"),
    (["sim", "--fault", "stall:1.PAW@3"], "cannot stall"),
    (["sim", "--fault", "noise@1-1" + "0" * 400], "too large to be finite"),
    (["sim", "--fault", "fail:1@1" + "0" * 400], "too large to be finite"),
    (["soak", "--hours", "-1"], "positive"),
    (["child", "--id", "7", "--radio", "x"], "child ID must be 1-6"),
    (["bogus"], "invalid choice"),
    # outputs refused before the run, not after it (an outside tester's findings)
    (["sim", "--trace", "."], "cannot write trace .: Is a directory"),
    (["sim", "--vcd", "."], "cannot write VCD .: Is a directory"),
    (["sim", "--trace", "/nonexistent-dir/x", "--vcd", "/nonexistent-dir/x"],
     "--trace and --vcd name the same file"),
    (["sim", "--trace", "/nonexistent-dir/x", "--pcap", "/nonexistent-dir/./x"],
     "--trace and --pcap name the same file"),
    (["conformance", "--radio", "x", "--id", "1", "--junit", "."], "it is a directory"),
    (["conformance", "--radio", "x", "--id", "1", "--tolerance-ms", "-5"], "positive"),
    (["conformance", "--radio", "x", "--id", "1", "--team", "0,2"], "must hold the robot's ID 1"),
    (["conformance", "--radio", "x", "--id", "1", "--team", "1,2"], "and this PC's 0"),
    (["campaign", "run", "none.toml", "--scheduler", "bogus"], "missing port number"),
    (["campaign", "run", "none.toml", "--scheduler", "foo://x"], "unknown address scheme"),
    (["soak", "--hours", "0.01"], "too short"),
    (["sim", "--load", "1e9"], "'saturate'"),
    (["encode", "--src", "1", "--dst", "2", "movex(1)" * 80], "more than a frame carries (562"),
    (["sim", "--bogus"], "unrecognized arguments: --bogus (see 'rprs sim --help')"),
    (["wireshark", "--dir", "x"], "--dir is for --install or --install-extcap"),
    (["sim", "--frame-bytes", "100"], "sizes the peer MACs' frames"),
    (["bench", "latency", "--radio", "x", "--dst", "0"], "the bench's own ID"),
    (["bench", "latency", "--radio", "x", "--dst", "3", "--team", "0,1"], "must hold"),
    # an empty port meant "no radio" to rprs child and a port to others
    (["child", "--id", "1", "--radio", "", "--can", "virtual:x"], "an empty port name"),
    (["father", "--radio", " "], "an empty port name"),
    (["monitor", "--radio", ""], "an empty port name"),
    (["conformance", "--radio", "", "--id", "1"], "an empty port name"),
])
def test_user_mistakes_are_one_line_and_status_2(capsys, args, needle):
    code, out, err = rprs(capsys, *args)
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("rprs: error: ")
    assert needle in err
    assert "Traceback" not in err


def test_encode_the_papers_example(capsys):
    code, out, _ = rprs(capsys, "encode", "--src", "1", "--dst", "2", "--num", "5", "--type",
                        "2", "movex(10)")
    assert code == 0
    assert bytes.fromhex(out.strip()) == b"\x0f\x0a\x05" + b"21052" + b"0009" + \
        b"movex(10)" + b"\x17\x19"


def test_decode_reports_frames_and_garbage(capsys):
    frame = "0f0a053231303532303030396d6f766578283130291719"
    code, out, err = rprs(capsys, "decode", "ffee", frame, "0f0a")
    assert code == 0
    rows = [json.loads(x) for x in out.splitlines()]
    assert rows[0] == {"offset": 0, "garbage": 2}
    assert rows[1]["offset"] == 2 and rows[1]["frame"]["commands"] == [["movex", [10]]]
    assert rows[-1] == {"offset": 25, "garbage": 2}
    assert "1 frame(s)" in err


def test_signed_and_checksummed_frames_are_made_and_checked_by_the_tools(capsys, tmp_path):
    """``auth`` and ``crc`` end a Content (clauses 20, 52): ``rprs decode`` called ``auth`` an
    unknown command and checked neither, and ``rprs encode`` could make neither, so the tools
    could not make or check a signed frame. The spec's signed example decodes with its tag
    checked under the spec's key; one digit off, the tag fails; encode makes the same bytes."""
    key = tmp_path / "ring.key"
    key.write_text("key = 000102030405060708090a0b0c0d0e0f\n")
    spec = ("0f0a05313430313230303331737461747573282961757468283030303030303261"
            "2c333438623164646529" "1719")      # docs/protocol.md §4.11, robot 4's status()
    code, out, _ = rprs(capsys, "encode", "--src", "4", "--dst", "1", "--num", "1",
                        "--auth-key", str(key), "--fresh", "0x2a", "status()")
    assert code == 0 and out.strip() == spec
    code, out, _ = rprs(capsys, "decode", spec, "--auth-key", str(key))
    f = json.loads(out)["frame"]
    assert f["auth"] == {"fresh": "0000002a", "tag": "348b1dde", "tag_ok": True}
    assert f["commands"] == [["status", []]] and "content_error" not in f
    forged = spec.replace("3164646529", "3164646629")                  # tag ...1dde -> ...1ddf
    code, out, _ = rprs(capsys, "decode", forged, "--auth-key", str(key))
    assert json.loads(out)["frame"]["auth"]["tag_ok"] is False
    code, out, _ = rprs(capsys, "decode", spec)                           # no key: not checked
    assert json.loads(out)["frame"]["auth"]["tag_ok"] is None
    code, out, _ = rprs(capsys, "encode", "--src", "0", "--dst", "1", "--checksum",
                        "status()")
    code, out, _ = rprs(capsys, "decode", out.strip())
    f = json.loads(out)["frame"]
    assert f["crc_ok"] is True and f["content"].endswith("crc(%05d)" % f["crc"])
    # crc(65536) is past the parameter's 0-65535: no checksum, an unreadable Content, as every
    # other parameter out of its bounds (clause 16)
    code, out, _ = rprs(capsys, "decode", "0f0a05373130313230303130637263283635353336291719")
    f = json.loads(out)["frame"]
    assert "crc" not in f and "65536" in f["content_error"] and "commands" not in f
    code, _, err = rprs(capsys, "encode", "--src", "0", "--dst", "1", "--fresh", "3", "x()")
    assert code == 2 and "--fresh goes with --auth-key" in err


def test_decode_stream_from_stdin_bytes(monkeypatch, capsys):
    frame = bytes.fromhex("0f0a053231303532303030396d6f766578283130291719")
    data = b"\x00\x0f\x0a\x05" + frame + frame[:10]      # partial header, frame, truncated
    stdin = io.TextIOWrapper(io.BufferedReader(io.BytesIO(data)))
    monkeypatch.setattr(sys, "stdin", stdin)
    code, out, err = rprs(capsys, "decode", "--stream")
    rows = [json.loads(x) for x in out.splitlines()]
    assert code == 0
    assert [r["frame"]["src"] for r in rows if "frame" in r] == [1]
    assert any("truncated" in r.get("error", "") for r in rows)


@pytest.mark.parametrize("args,stdin,n", [
    (["00112233"], None, 4),                                      # garbage only
    (["0f0a05323130353230303039"], None, 12),                     # a header, cut short
    (["--stream"], b"", 0),                                       # nothing at all
    (["--stream"], b"\x00" * 5000, 5000),                         # bytes, none a frame
    (["--stream", "--hex"], b"ffee\n0f0a\n", 4),
])
def test_decode_that_finds_no_frame_says_so_and_exits_1(monkeypatch, capsys, args, stdin, n):
    """``rprs decode 00112233`` printed its garbage line, "0 frame(s) decoded" and exited 0,
    as if it had found something. Finding nothing is status 1 (as ``rprs bench link`` and
    ``bench cycle`` that hear no frame), in one line; the rows still go to stdout."""
    if stdin is not None:
        stdin = io.TextIOWrapper(io.BufferedReader(io.BytesIO(stdin)))
        monkeypatch.setattr(sys, "stdin", stdin)
    code, out, err = rprs(capsys, "decode", *args)
    assert code == 1, err
    assert err == f"rprs decode: no frame in {n} bytes of input\n"
    assert all("frame" not in json.loads(x) for x in out.splitlines())
    if n:
        assert out                                     # what was there: garbage, errors


def test_console_script_runs_without_traceback():
    r = subprocess.run([sys.executable, "-m", "hil.cli", "sim", "--robots", "7"],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "Traceback" not in r.stderr and r.stderr.count("\n") == 1


def test_plot_refuses_an_unreadable_trace_and_leaves_no_file(tmp_path, capsys):
    bad = tmp_path / "bad.jsonl"
    bad.write_text('{"ev":"meta","tick_hz":16000000}\nnot json\n')
    out = tmp_path / "x.png"
    code, _, err = rprs(capsys, "plot", str(bad), "-o", str(out))
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err
    assert not out.exists() and not list(tmp_path.glob("*.png*"))


def test_plot_on_an_image_or_a_gzip_is_one_line(tmp_path, capsys):
    """A PNG given as the trace is refused in one line; a gzipped trace is read."""
    import gzip
    tr = tmp_path / "t.jsonl"
    assert rprs(capsys, "sim", "--duration", "3", "--trace", str(tr))[0] == 0
    png = tmp_path / "fig.png"
    assert rprs(capsys, "plot", str(tr), "-o", str(png))[0] == 0
    code, _, err = rprs(capsys, "plot", str(png), "-o", str(tmp_path / "again.png"))
    assert code == 2 and err.count("\n") == 1 and "not a JSON line" in err, err
    (tmp_path / "t.jsonl.gz").write_bytes(gzip.compress(tr.read_bytes()))
    code, _, err = rprs(capsys, "plot", str(tmp_path / "t.jsonl.gz"), "-o",
                        str(tmp_path / "gz.png"))
    assert code == 0 and (tmp_path / "gz.png").stat().st_size > 10_000, err


def test_version_names_the_package_and_the_protocol(capsys):
    """``rprs --version`` gives the installed version and the protocol version, which is the
    one docs/protocol.md declares."""
    import re
    from importlib.metadata import version
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    out = capsys.readouterr().out
    assert e.value.code == 0
    doc = (ROOT / "docs" / "protocol.md").read_text()
    declared = re.search(r"\*\*Protocol version (\d+\.\d+)\.\*\*", doc).group(1)
    assert out.strip() == f"rprs {version('rprs')}, radio protocol {declared}"


def _every_parser(parser, path=("rprs",)):
    import argparse
    yield path, parser
    for act in parser._actions:
        if isinstance(act, argparse._SubParsersAction):
            for name, sub in act.choices.items():
                yield from _every_parser(sub, path + (name,))


def test_every_option_of_every_command_has_help_text():
    from hil.cli import build_parser
    missing = []
    for path, parser in _every_parser(build_parser()):
        for act in parser._actions:
            if act.option_strings and not act.help:
                missing.append(f"{' '.join(path)} {'/'.join(act.option_strings)}")
    assert not missing, missing


def test_each_command_is_built_alone_from_its_own_module_as_in_the_whole_parser():
    """``rprs NAME ...`` builds only NAME's module (start-up); MODULE_OF must name every
    command, and the command built alone must be the command of the whole parser."""
    from hil.cli import MODULE_OF, build_parser
    whole = dict(_every_parser(build_parser()))
    commands = {path[1] for path in whole if len(path) == 2}
    assert commands == set(MODULE_OF)
    for name, module in MODULE_OF.items():
        alone = dict(_every_parser(build_parser((module,))))
        mine = {p: q for p, q in alone.items() if len(p) >= 2 and p[1] == name}
        assert set(mine) == {p for p in whole if len(p) >= 2 and p[1] == name}
        for path, parser in mine.items():
            assert parser.format_help() == whole[path].format_help(), path


def test_a_light_command_does_not_import_the_simulator():
    """``rprs encode`` and ``rprs --version`` once took 0.5 s, importing every command and
    with them python-can and cantools; each imports its own module now."""
    code = ("import sys; from hil.cli import main\n"
            "for argv in (['encode', '--src', '1', '--dst', '0', 'status()'], ['--version']):\n"
            "    try:\n        main(argv)\n    except SystemExit:\n        pass\n"
            "heavy = sorted(m for m in ('hil.sim.world', 'can', 'cantools', 'hil.cli.sim')"
            " if m in sys.modules)\n"
            "print('HEAVY', heavy)\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert "0f0a0530313030323030303873746174757328291719" in r.stdout
    assert "HEAVY []" in r.stdout, r.stdout


def test_demo_takes_the_action_sequence_options_without_naming_it(capsys):
    """``rprs demo --cycles 1`` is ``rprs demo action-sequence --cycles 1`` (it once said
    "invalid choice: '1'")."""
    code, out, err = rprs(capsys, "demo", "--cycles", "1", "--robots", "2")
    assert code == 0, err
    code2, out2, _ = rprs(capsys, "demo", "action-sequence", "--cycles", "1", "--robots", "2")
    assert code2 == 0 and out == out2 and "cycle" in out


@pytest.mark.parametrize("args,needle", [
    (["--target", "board"], "--target board needs --radio PORT (the bench radio's serial "
                            "port) and --can INTERFACE:CHANNEL"),
    (["--target", "board", "--radio", "/dev/ttyUSB0"], "--target board needs --can "
                                                       "INTERFACE:CHANNEL (the flashed"),
    # python-can's virtual bus cannot reach another process: 4 of 6 tests failed as if the
    # child were broken, and one passed on the bench's own submodules' traffic
    (["--target", "process", "--can", "virtual:x"], "--can virtual:x is python-can's "
                                                    "in-process bus"),
    (["--target", "model,board", "--radio", "/dev/ttyUSB0", "--can", "virtual:x"],
     "the child under test (--target process or board) cannot reach it"),
    (["--target", "bored"], "--target 'bored': choose from model, process, board"),
    (["--target", "model", "--dut-id", "9"], "--dut-id 9: a child's ID is 1-6"),
    (["--target", "model", "--dut-id", "0"], "--dut-id 0: a child's ID is 1-6"),
    # an unset variable in a CI job: "6 skipped", exit 0; a target twice: misleading failures
    (["--target", ""], "--target '' names no target"),
    (["--target", ","], "--target ',' names no target"),
    (["--target", "model,model"], "--target names 'model' twice"),
])
def test_acceptance_board_without_its_ports_is_a_usage_error(args, needle):
    """A board target with its ports forgotten once reported "6 skipped", exit 0."""
    r = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-n", "0",
                        "tests/acceptance", *args], capture_output=True, text=True, timeout=120,
                       cwd=ROOT)
    assert r.returncode == 4, r.stdout + r.stderr
    assert needle in r.stderr and "passed" not in r.stdout and "skipped" not in r.stdout


def test_acceptance_board_on_a_port_that_does_not_exist_says_so_in_one_line():
    """A board bench that cannot open its port once failed every test with a traceback
    through the runner; now each setup error is one line naming the port."""
    r = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-n", "0",
                        "tests/acceptance", "--target", "board", "--radio", "/nonexistent-rprs",
                        "--can", "rprs_unix:/nonexistent-rprs-can"], capture_output=True,
                       text=True, timeout=120, cwd=ROOT)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "board: the bench cannot start: serial port /nonexistent-rprs does not exist" \
        in r.stdout
    assert "Traceback" not in r.stdout and "runner.py" not in r.stdout, r.stdout


def test_txen_on_a_pty_is_refused_in_one_line():
    """A pty (a radio hub node) has no RTS or DTR line: ``--txen rts`` on it was accepted
    and every TXEN edge silently failed. Now it is a one-line error, status 2."""
    import os
    master, slave = os.openpty()
    try:
        r = subprocess.run([sys.executable, "-m", "hil.cli", "child", "--id", "1", "--radio",
                            os.ttyname(slave), "--txen", "rts"],
                           capture_output=True, text=True, timeout=60)
    finally:
        os.close(master)
        os.close(slave)
    assert r.returncode == 2, r.stderr
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert "--txen rts" in r.stderr and "no RTS line" in r.stderr


def test_demo_ring_tells_the_story_of_its_run(capsys):
    """The rejoin the demo exists to show was hidden behind "(+3 more)", and R1 was called a
    "member" while its radio was off. The story has every happening, in order, in words."""
    code, out, _ = rprs(capsys, "demo", "ring", "--no-progress")
    assert code == 0
    story = out.split("What happened:\n", 1)[1].split("\n\n", 1)[0].splitlines()
    text = [line.split(" s  ", 1)[1] for line in story]
    times = [float(line.split(" s  ", 1)[0]) for line in story]
    assert times == sorted(times)
    order = ["father 0 hears nobody and starts the ring", "R1 is in the ring",
             "R1: its radio goes silent", "R1 misses its turn", "R1 misses its turn",
             "R1 misses its turn", "R1 is dropped after three missed turns",
             "R1, alone with its radio cut off, hears nobody and claims the channel for itself",
             "R1: its radio comes back", "R1 is in the ring again"]
    at = 0
    for want in order:
        at = text.index(want, at) + 1
    cut = text.index("R1: its radio goes silent")
    back = text.index("R1: its radio comes back")
    # while its radio is cut off, R1's own view (everyone else missing) is not the story
    assert not [t for t in text[cut:back] if "misses its turn" in t and not t.startswith("R1")]
    assert "(+" not in out and "member 1" not in out
    # each happening told once, though every robot hearing the air saw it, on the CPU model
    # a tick or a handler apart: three misses, one drop, each robot in the ring once
    assert text.count("R1 misses its turn") == 3
    assert text.count("R1 is dropped after three missed turns") == 1
    for r in (1, 2, 3, 4):
        assert text.count(f"R{r} is in the ring") == 1
    assert text.count("R1 is in the ring again") == 1


def test_the_ring_demo_in_json_is_the_run_it_tells(capsys):
    """``rprs demo ring --json`` left out the demo's failure and recovery of R1 (its setup sat
    under the intro text, which --json leaves out): another run than the one told."""
    code, out, _ = rprs(capsys, "demo", "ring", "--no-progress", "--json")
    assert code == 0
    s = json.loads(out)
    code, told, _ = rprs(capsys, "demo", "ring", "--no-progress")
    assert code == 0
    assert f"channel occupations: {s['occupations']} " in told
    assert s["robots"]["1"]["missed"] == 3
    assert [c for c in s["membership_changes"] if c["robot"] == 1 and c["ev"] in
            ("disable", "rejoin")] != []


def test_the_progress_bar_run_is_the_same_run():
    """With a progress bar the world runs in one-second steps that leave sleeping CAN sides
    asleep (``World.run_in_steps``); the summary is the one-go run's."""
    from hil.cli.sim import run_world
    from hil.sim.world import SimConfig
    cfg = SimConfig(robots=(0, 1, 2), duration=12, can=True, seed=3, load=1)
    stepped, _ = run_world(cfg, None, True)
    whole, _ = run_world(cfg, None, False)
    assert sum(q.periods_skipped for q in stepped.quiet.values()) > 0
    assert json.dumps(stepped.summary(), sort_keys=True) == \
        json.dumps(whole.summary(), sort_keys=True)


def test_every_frame_gives_the_same_summary(capsys):
    """``--every-frame`` runs an idle ring frame by frame, without leaps over its cycles or
    sleeping CAN sides: the same summary, byte for byte, as the default run, which leaps."""
    args = ("sim", "--robots", "0,1,2,3", "--duration", "120", "--can", "--fail", "2@40",
            "--recover", "2@70", "--json")
    code, fast, _ = rprs(capsys, *args)
    assert code == 0
    code, slow, _ = rprs(capsys, *args, "--every-frame")
    assert code == 0
    fast, slow = json.loads(fast), json.loads(slow)
    for timing in ("speed", "wall_seconds"):
        del fast[timing], slow[timing]
    assert fast == slow
    assert fast["occupations"] > 2000


def test_the_progress_bar_leaps_too():
    """The progress bar's steps (a hundredth of the run) leave the ring room to leap."""
    from hil.cli.sim import run_world
    from hil.sim.world import SimConfig
    cfg = SimConfig(robots=(0, 1, 2), duration=600, seed=4)
    stepped, _ = run_world(cfg, None, True)
    assert stepped.quiet_ring.ticks_skipped > 0.8 * stepped.now


def test_a_directory_given_for_campaign_results_is_refused(tmp_path, capsys):
    spec = tmp_path / "c.toml"
    spec.write_text('[campaign]\nname = "x"\nseeds = 1\nduration = 5\n[grid]\nber = [0.0]\n')
    code, _, err = rprs(capsys, "campaign", "run", str(spec), "--db", str(tmp_path))
    assert code == 2 and "is a directory" in err and "Traceback" not in err
    code, _, err = rprs(capsys, "campaign", "run", str(spec), "--db",
                        str(tmp_path / "no" / "r.sqlite"))
    assert code == 2 and "no directory" in err and not (tmp_path / "no").exists()


def test_encode_notes_a_frame_no_station_sends_but_encodes_it(capsys):
    """Receivers must take reserved Destinations and Types (docs/protocol.md §3), so a test
    frame may carry them: encoded, with a note on stderr."""
    code, out, err = rprs(capsys, "encode", "--src", "1", "--dst", "8", "movex(1)")
    assert code == 0 and bytes.fromhex(out.strip())[3:5] == b"81"
    assert "reserved" in err and "Traceback" not in err
    # a PC's frame over its 561 bytes (clause 14): the same, noted (a child's 562 is fine)
    big = "movex(1)" * 69 + "movex(100)"                  # 562 bytes
    code, out, err = rprs(capsys, "encode", "--src", "0", "--dst", "1", big)
    assert code == 0 and "a PC sends at most 561 Content bytes" in err, err
    code, out, err = rprs(capsys, "encode", "--src", "2", "--dst", "1", big)
    assert code == 0 and err == ""


def test_the_ring_demo_tells_the_ring_it_runs(capsys):
    """Its default outage is of the ring's first child, and only when the run lasts long
    enough to see it come back (it once named R1 and R1-R4 whatever --robots said)."""
    code, out, _ = rprs(capsys, "demo", "ring", "--robots", "0,2,3")
    assert code == 0
    assert out.startswith("Demo: the father (ID 0), R2, R3 power on together")
    assert "R2's radio goes silent at 8 s" in out and "R1" not in out
    code, out, _ = rprs(capsys, "demo", "ring", "--duration", "5")
    assert code == 0 and "goes silent" not in out and "R4 power on" in out


def test_sim_json_with_the_cpu_report_is_one_document(capsys):
    code, out, _ = rprs(capsys, "sim", "--robots", "0,1", "--duration", "2", "--cpu-report",
                        "--json")
    assert code == 0
    doc = json.loads(out)
    assert "cpu_report" in doc and "delivered" in doc


def test_the_cpu_report_counts_a_handler_still_running_at_the_end(capsys, tmp_path):
    """A receive handler of 1e11 cycles (longer than the run) kept each child's CPU busy from
    its first byte on: the report said load 0.00 %, response 0 and a worst case of 43 us
    against the byte's 1040 us, its cycles not being in any finished call."""
    costs = tmp_path / "big.toml"
    costs.write_text("[costs]\nuart_rx_byte = 100000000000\n")
    code, out, _ = rprs(capsys, "sim", "--robots", "1,2", "--duration", "5", "--cpu-costs",
                        str(costs), "--cpu-report", "--json", "--no-progress")
    assert code == 0
    doc = json.loads(out)
    rep = doc["cpu_report"]["2"]         # (R1 claims the channel; R2 hears its first byte)
    row = next(h for h in rep["handlers"] if h["handler"] == "UART0 RX")
    assert rep["load"] > 0.5 and row["load"] > 0.5 and doc["cpu_load"]["2"] > 0.5
    assert row["running_us"] > 1e6 and row["worst_case_us"] > row["deadline_us"]
    assert row["costs"]["uart_rx_byte"]["source"] == "big.toml (was 95)"


def test_a_can_log_that_cannot_be_written_is_one_line_and_closes_the_bus():
    """python-can warns at exit about a bus never shut down: that was a second line."""
    for log in (".", "x.unknown-format"):
        r = subprocess.run([sys.executable, "-m", "hil.cli", "child", "--id", "1", "--can",
                            "virtual:cli-test", "--can-log", log], capture_output=True,
                           text=True, timeout=60)
        assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
        assert r.stderr.startswith("rprs: error: cannot write CAN log")


def test_a_can_log_format_python_can_cannot_write_here_is_one_line(tmp_path, capsys,
                                                                   monkeypatch):
    """``--can-log x.mf4`` without asammdf (python-can's optional [mf4]) ended in a
    NotImplementedError traceback and python-can's 'not properly shut down' line."""
    import can

    def no_mf4(path, **kw):
        raise NotImplementedError("The asammdf package was not found. Install python-can with "
                                  "the optional dependency [mf4] to use the MF4Writer.")
    monkeypatch.setattr(can, "Logger", no_mf4)
    log = tmp_path / "x.mf4"
    code, out, err = rprs(capsys, "child", "--id", "1", "--can", "virtual:cli-mf4",
                          "--can-log", str(log))
    assert code == 2 and err.count("\n") == 1, err
    assert err.startswith(f"rprs: error: cannot write CAN log {log}: The asammdf package")


def test_a_can_only_child_closes_with_its_can_side_not_radio_fields(capsys):
    """``rprs child --can ...`` without ``--radio``: its closing line was the radio's, "robot
    1: listen, ring [], frames sent 0, heard 0, bad frames 0, pending 0", for a station that
    never had a radio. It now gives what the child has: its CAN side."""
    code, out, err = rprs(capsys, "child", "--id", "1", "--can", "virtual:cli-can-only",
                          "--duration", "0.3")
    assert code == 0, err
    last = err.strip().splitlines()[-1]
    assert last == "robot 1: CAN only (no radio); CAN: 0 frames sent, 0 received", err
    assert "ring" not in err and "heard" not in err


def test_a_child_with_a_radio_and_a_can_side_closes_with_both(capsys):
    """``rprs child --radio ... --can ...``: its closing line was the radio's alone, with no
    CAN frame counts (a CAN-only child gives them); it now gives both sides."""
    code, out, err = rprs(capsys, "child", "--id", "1", "--team", "1", "--radio", "loop://",
                          "--can", "virtual:cli-both", "--duration", "0.3")
    assert code == 0, err
    last = err.strip().splitlines()[-1]
    assert last.startswith("robot 1: ") and "frames sent" in last, err
    radio, sep, can_side = last.partition("; CAN: ")
    assert sep and "CAN only" not in radio, err
    assert re.fullmatch(r"\d+ frames? sent, \d+ received", can_side), err


@pytest.mark.parametrize("command", [
    ["child", "--id", "1", "--team", "1", "--events"],
    ["father", "--team", "0", "--json", "--no-input"],
    ["father", "--team", "0"],
], ids=["child --events", "father --json", "father"])
def test_a_robot_whose_stdout_closes_stops_quietly_with_its_summary(command):
    """``rprs child --events | head -1``: the write after head exited raised BrokenPipeError
    out of the firmware's scheduler, and the process ended at once with status 0 and no
    closing line, as if it had never run. A closed stdout now stops a robot as rprs stops
    every command whose reader went away (hil/cli/__init__.py: status 1, no error): quietly,
    but cleanly, its ports closed and its closing line on stderr, as on Ctrl-C."""
    orders = "--no-input" not in command and "--events" not in command
    p = subprocess.Popen([sys.executable, "-m", "hil.cli", *command, "--radio", "loop://",
                          "--duration", "60"], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, stdin=subprocess.PIPE if orders else None,
                         text=True)
    try:
        first = p.stdout.readline()              # a lone robot claims its ring within 1 s
        assert first.strip(), first
        p.stdout.close()                          # what head -1 does once it has its line
        t_closed = time.monotonic()
        if orders:                                # the father's console writes of it next
            p.stdin.write("1 status()\n")
            p.stdin.flush()
        err = p.stderr.read()
        code = p.wait(timeout=30)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
        if p.stdin is not None:
            p.stdin.close()
        p.stdout.close()
        p.stderr.close()
    assert time.monotonic() - t_closed < 20, "it ran on to its --duration"
    assert code == 1, err                         # as every rprs command (test below)
    assert "Traceback" not in err and "Exception ignored" not in err and "Broken" not in err
    lines = err.strip().splitlines()
    assert lines[0].startswith(("running child 1", "father (ID 0")), err
    if command[0] == "father":                   # the station's line, then the orders'
        assert lines[-1].startswith("orders: "), err
        lines.pop()
    assert lines[-1].startswith(("robot 1: member", "robot 0: member")), err


FRAME_HEX = "0f0a053231303532303030396d6f766578283130291719"


@pytest.mark.parametrize("command", [
    ["sim", "--robots", "1,2", "--duration", "2"],
    ["sim", "--robots", "1,2", "--duration", "2", "--json"],
    ["sim", "--robots", "1,2", "--duration", "1", "--cpu-report"],
    ["decode", FRAME_HEX],
    ["encode", "--src", "1", "--dst", "2", "movex(10)"],
    ["--help"],
    ["sim", "--help"],
    ["--version"],
    ["demo"],
], ids=["sim", "sim --json", "sim --cpu-report", "decode", "encode", "--help", "sim --help",
        "--version", "demo"])
def test_a_closed_stdout_ends_every_command_alike(command):
    """``rprs ... | head -1``: each command ended its own way when its reader had gone:
    ``rprs sim``'s table with status 1 (rich's own handling), ``--json`` and ``decode`` with 0
    (main's), ``--help`` with 0 (argparse swallowed the error). Every one now ends as the
    Python docs recommend for SIGPIPE: stdout pointed at /dev/null, status 1, nothing on
    stderr. The pipe's reading end is closed before the command starts, so that every
    command meets the closed pipe at its first write, whatever its output's length."""
    r, w = os.pipe()
    os.close(r)
    try:
        p = subprocess.run([sys.executable, "-m", "hil.cli", *command], stdout=w,
                           stderr=subprocess.PIPE, text=True, timeout=120)
    finally:
        os.close(w)
    assert (p.returncode, p.stderr) == (1, "")


def test_a_demo_whose_reader_goes_away_keeps_no_trace(tmp_path):
    """``rprs demo --trace T | head -4``: the demo prints as it runs, and took the broken pipe
    for a trace it could not write (status 2, "cannot write an output"). It now ends as every
    command does (status 1, nothing on stderr), its trace unfinished and so not kept."""
    r, w = os.pipe()
    os.close(r)
    trace = tmp_path / "t.jsonl"
    try:
        p = subprocess.run([sys.executable, "-m", "hil.cli", "demo", "--trace", str(trace)],
                           stdout=w, stderr=subprocess.PIPE, text=True, timeout=120)
    finally:
        os.close(w)
    assert (p.returncode, p.stderr) == (1, "") and not trace.exists()


@pytest.mark.parametrize("command", [
    ["encode", "--src", "1", "--dst", "2", "movex(10)"],
    ["sim", "--robots", "1,2", "--duration", "2", "--json"],
    ["demo"],
    ["child", "--id", "1", "--radio", "loop://", "--team", "1", "--events", "--duration", "3"],
    ["father", "--radio", "loop://", "--team", "0", "--json", "--no-input", "--duration", "3"],
], ids=["encode", "sim --json", "demo", "child --events", "father --json"])
def test_a_standard_output_that_cannot_be_written_is_one_line(command, full_device):
    """``rprs ... > /dev/full``: a standard output that fails for another reason than its
    reader going away (a full disk) ended every command in a traceback (a bench process at
    its first event, without its summary). Now: one line naming the reason, status 1; a
    bench process stops with its summary first."""
    with open(full_device, "w") as out:
        p = subprocess.run([sys.executable, "-m", "hil.cli", *command], stdout=out,
                           stderr=subprocess.PIPE, text=True, timeout=120)
    assert p.returncode == 1 and "Traceback" not in p.stderr, p.stderr
    last = p.stderr.strip().splitlines()[-1]
    assert last in ("rprs: error: cannot write standard output: No space left on device",
                    "rprs: error: cannot write the events: No space left on device"), p.stderr
    if command[0] in ("child", "father"):
        assert "member" in p.stderr and last.endswith("events: No space left on device")


def test_a_long_output_piped_to_head_ends_quietly(tmp_path):
    """Through a real ``| head -1``: ``rprs decode --stream`` of 4000 frames writes far more
    than a pipe holds, so it meets head's exit: head's one line, then status 1 and nothing
    on stderr (it was 0 and "4000 frame(s) decoded"... on a stdout nobody read)."""
    src = tmp_path / "frames.hex"
    src.write_text((FRAME_HEX + "\n") * 4000)
    p = subprocess.run(["bash", "-c", f"{sys.executable} -m hil.cli decode --stream --hex "
                        f"< {src} 2>{tmp_path / 'err'} | head -1; "
                        "echo status ${PIPESTATUS[0]}"],
                       capture_output=True, text=True, timeout=120)
    lines = p.stdout.splitlines()
    assert json.loads(lines[0])["offset"] == 0 and lines[1:] == ["status 1"], p.stdout
    assert (tmp_path / "err").read_text() == ""


@pytest.mark.parametrize("command", [["child", "--id", "1"], ["submodules"]])
def test_an_rprs_unix_bus_under_a_missing_directory_is_one_line(tmp_path, capsys, command):
    """The ``rprs_unix:`` scheme made every missing parent of its directory (a mistyped path
    gave a bus of its own, silently), the radio hub's ``--link-dir`` none: both now make only
    the last directory and refuse a missing parent in one line naming it."""
    bus = tmp_path / "no-such" / "can"
    code, out, err = rprs(capsys, *command, "--can", f"rprs_unix:{bus}", "--duration", "0.1")
    assert code == 2 and err.count("\n") == 1, err
    assert err.startswith(f"rprs: error: cannot open CAN bus rprs_unix:{bus}: ")
    assert f"its parent directory {bus.parent} does not exist" in err
    assert not bus.parent.exists()


@pytest.mark.parametrize("command,other", [(["child", "--id", "1"], "rprs submodules"),
                                           (["submodules"], "rprs child")])
def test_a_virtual_can_bus_is_said_to_be_out_of_other_processes_reach(tmp_path, capsys,
                                                                       command, other):
    """``--can virtual:NAME`` is python-can's in-process bus: no other process (rprs
    submodules, candump) ever sees its frames, and a user waited for them. The command now
    says so in one note line after its running line (not an error: it runs, status 0); a
    bus other processes share gets no note."""
    code, out, err = rprs(capsys, *command, "--can", "virtual:cli-note", "--duration", "0.2")
    assert code == 0, err
    lines = err.strip().splitlines()
    assert lines[0].startswith("running "), err
    notes = [x for x in lines if "note:" in x]
    assert len(notes) == 1 and lines[1] == notes[0], err
    assert notes[0].startswith(f"rprs {command[0]}: note: virtual:cli-note is python-can's "
                               f"in-process bus"), notes
    assert other in notes[0] and "rprs_unix:DIR" in notes[0] and "error" not in notes[0]
    code, out, err = rprs(capsys, *command, "--can", f"rprs_unix:{tmp_path / 'can'}",
                          "--duration", "0.2")
    assert code == 0 and "note:" not in err, err


def test_a_father_order_that_is_not_ascii_is_refused_in_words():
    from hil.bench.runner import parse_order
    with pytest.raises(ValueError, match="'é' is not ASCII"):
        parse_order("2 movex(1é)")
    # a byte the input's encoding could not read (surrogateescape) is named as the byte
    with pytest.raises(ValueError, match=r"^byte 0xff is not ASCII"):
        parse_order(b"2 movex(1\xff)".decode("utf-8", "surrogateescape"))


@pytest.mark.parametrize("line,words", [
    ("1 act(1,1)", r"act\(1,1\) is news a robot reports, not an order: no child carries it "
                   r"out \(start action 1 with act\(1,0\)\)"),
    ("1 fail(2)", r"fail\(2\) is news a robot reports"),
    ("2 status()done()", r"done\(\) is news a robot reports")])
def test_a_father_line_no_child_carries_out_is_refused(line, words):
    """``1 act(1,1)`` and ``1 fail(2)`` ended ``done`` once acknowledged, the father exiting
    0, though the child ignores both (docs/dispatcher.md)."""
    from hil.bench.runner import parse_order
    with pytest.raises(ValueError, match=words):
        parse_order(line)
    from firmware_model.radio.content import cmd
    assert parse_order("1 act(1,0)")[1] == [cmd("act", 1, 0)]


def test_a_father_order_to_the_father_itself_is_refused_as_it_is_parsed():
    """'0 status()' passed the order's parser ("destination ID (0-7)") and was refused later by
    the MAC as "a robot ID 0-6 other than 0", a line of another shape; now the parser says it."""
    from hil.bench.runner import parse_order
    with pytest.raises(ValueError, match=r"destination must be 1-6 \(a child\) or 7 \(every "
                       r"robot\), got 0: 0 is the father itself"):
        parse_order("0 status()")
    assert parse_order("7 status()")[0] == 7


def _read_fifo(path: Path, got: list) -> threading.Thread:
    """A reader that takes everything written to the FIFO ``path`` into ``got``."""
    def read():
        with open(path, "rb") as f:
            got.append(f.read())
    t = threading.Thread(target=read, daemon=True)
    t.start()
    return t


def test_outputs_through_a_link_or_into_a_fifo_leave_the_link_and_the_fifo(tmp_path, capsys):
    """An output was written to ``PATH.partial`` and renamed over PATH, whatever PATH was: a
    symlink became a regular file (its target never written), a FIFO was replaced by a file
    (its reader got nothing), and as root ``--trace /dev/null`` replaced /dev/null by a regular
    file. A link is written through now, and a FIFO or a device straight."""
    import os
    import stat
    real = tmp_path / "real.jsonl"
    link = tmp_path / "link.jsonl"
    link.symlink_to(real)
    fifo = tmp_path / "capture"
    os.mkfifo(fifo)
    got: list[bytes] = []
    reader = _read_fifo(fifo, got)
    code, _, err = rprs(capsys, "sim", "--duration", "3", "--trace", str(link), "--pcap",
                        str(fifo))
    reader.join(30)
    assert code == 0, err
    assert link.is_symlink() and stat.S_ISFIFO(os.stat(fifo).st_mode)
    assert real.read_text().startswith('{"ev":"meta"')
    assert got and got[0][:4] == b"\x0a\x0d\x0d\x0a" and len(got[0]) > 1000   # pcapng SHB
    assert not list(tmp_path.glob("*.partial"))


def test_a_plot_through_a_link_or_into_a_fifo(tmp_path, capsys):
    import os
    import stat
    trace = tmp_path / "t.jsonl"
    assert rprs(capsys, "sim", "--duration", "3", "--trace", str(trace))[0] == 0
    real = tmp_path / "real.svg"
    link = tmp_path / "link.svg"
    link.symlink_to(real)
    assert rprs(capsys, "plot", str(trace), "-o", str(link))[0] == 0
    assert link.is_symlink() and real.read_bytes().startswith(b"<?xml")
    fifo = tmp_path / "fig.svg"
    os.mkfifo(fifo)
    got: list[bytes] = []
    reader = _read_fifo(fifo, got)
    code, _, err = rprs(capsys, "plot", str(trace), "-o", str(fifo))
    reader.join(30)
    assert code == 0, err
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    assert got and got[0] == real.read_bytes()          # the same bytes, clip paths numbered
    assert not list(tmp_path.glob("*.partial"))


def test_a_full_disk_under_the_capture_is_one_line(capsys, full_device):
    """``--pcap /dev/full`` ended in an OSError traceback when the capture was closed."""
    code, _, err = rprs(capsys, "sim", "--duration", "2", "--pcap", str(full_device))
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith(f"rprs: error: cannot write capture {full_device}: No space left")
    assert full_device.is_char_device()


@pytest.mark.parametrize("failing,kept", [("--trace", "--pcap"), ("--pcap", "--trace")])
def test_an_output_that_cannot_be_finished_leaves_the_other_whole(tmp_path, capsys, full_device,
                                                                  failing, kept):
    """A run so short that its trace (or capture) is written only when it is finished, on a
    full disk: the one that failed is one line and status 2; the other, complete, is kept, as
    the same run without the failing output writes it. ``rprs sim`` kept a capture when its
    trace failed, but removed its trace when its capture failed (the capture was put in place
    inside the run's clean-up, the trace after it), and ``rprs monitor`` kept both
    (tests/hil/view/test_monitor.py: the same test); both now keep every complete output."""
    run = ["sim", "--robots", "1,2", "--duration", "0.2"]
    name = {"--trace": "t.jsonl", "--pcap": "p.pcapng"}
    whole = tmp_path / "whole" / name[kept]
    whole.parent.mkdir()
    assert rprs(capsys, *run, kept, str(whole))[0] == 0
    out = tmp_path / name[kept]
    code, _, err = rprs(capsys, *run, kept, str(out), failing, str(full_device))
    what = {"--trace": "trace", "--pcap": "capture"}[failing]
    assert code == 2 and err == f"rprs: error: cannot write {what} {full_device}: No space " \
        f"left on device\n", err
    assert out.read_bytes() == whole.read_bytes()
    assert not list(tmp_path.glob("*.partial")) and full_device.is_char_device()


@pytest.mark.parametrize("failing", ["--trace", "--vcd", "--pcap"])
def test_a_write_error_mid_run_names_the_output_that_failed(tmp_path, capsys, monkeypatch,
                                                            failing):
    """A write that failed during the run (a full disk) was reported as "cannot write trace
    t.jsonl, VCD v.vcd, capture p.pcapng: ...": every output given, not the one that failed.
    Here one output's file descriptor is swapped for a read-only one once it is open, so each
    of its writes fails in the OS (EBADF) as a full disk's would (ENOSPC); the others work."""
    import os
    from hil.sim import trace as trace_mod
    outs = {"--trace": tmp_path / "t.jsonl", "--vcd": tmp_path / "v.vcd",
            "--pcap": tmp_path / "p.pcapng"}
    readonly = tmp_path / "readonly"
    readonly.write_bytes(b"")
    opened = trace_mod.OutputFile.__init__

    def broken_when_failing(self, path, *a, **kw):
        opened(self, path, *a, **kw)
        if path == str(outs[failing]):
            fd = os.open(readonly, os.O_RDONLY)
            os.dup2(fd, self.f.fileno())
            os.close(fd)
    monkeypatch.setattr(trace_mod.OutputFile, "__init__", broken_when_failing)
    args = [a for opt, p in outs.items() for a in (opt, str(p))]
    code, out, err = rprs(capsys, "sim", "--duration", "20", "--load", "2", "--no-progress",
                          *args)
    what = {"--trace": "trace", "--vcd": "VCD", "--pcap": "capture"}[failing]
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert err == f"rprs: error: cannot write {what} {outs[failing]}: Bad file descriptor\n"
    assert out == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == ["readonly"]     # nothing left


@pytest.mark.parametrize("sig,status,word,twice", [("SIGTERM", 143, "terminated", False),
                                                    ("SIGINT", 130, "interrupted", False),
                                                    ("SIGHUP", 129, "hung up", False),
                                                    ("SIGTERM", 143, "terminated", True)],
                         ids=["SIGTERM", "SIGINT", "SIGHUP", "SIGTERM-twice"])
def test_a_signal_mid_run_leaves_no_output_and_a_signal_status(tmp_path, sig, status, word,
                                                               twice):
    """SIGTERM killed ``rprs sim`` where it stood: ``t.jsonl.partial`` and ``v.vcd.partial``
    were left behind and ``p.pcapng``, written in place, was cut in the middle of a packet
    (tshark: "appears to have been cut short"). SIGTERM now ends it as Ctrl-C does: one line,
    no output file of any kind, status 128 + the signal. So does SIGHUP (the terminal the
    run was started from closed), which left a ``.partial`` file and said nothing. SIGTERM
    twice at once (GNU ``timeout`` signals the process, then its group) is one stop: the
    second killed it mid-clean-up, without its line."""
    import signal
    import time
    outs = {"--trace": tmp_path / "t.jsonl", "--vcd": tmp_path / "v.vcd",
            "--pcap": tmp_path / "p.pcapng"}
    args = [a for opt, p in outs.items() for a in (opt, str(p))]
    proc = subprocess.Popen([sys.executable, "-m", "hil.cli", "sim", "--duration", "100000",
                             "--load", "1", "--no-progress", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 60
        while not any(p.stat().st_size > 10_000 for p in tmp_path.iterdir()):
            assert proc.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
        proc.send_signal(getattr(signal, sig))
        if twice:
            time.sleep(0.02)
            proc.send_signal(getattr(signal, sig))
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == status, err
    assert err == f"rprs: {word}\n" and out == ""
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("args,running,stopped", [
    (["sim", "--duration", "100000", "--load", "1", "--no-progress"], None, 143),
    (["submodules", "--can", f"virtual:rprs-nohup-{os.getpid()}"], "running joints", 0)])
def test_a_run_started_under_nohup_outlives_its_terminal(tmp_path, args, running, stopped):
    """Under ``nohup`` (SIGHUP ignored) a run must go on when the terminal it was started from
    closes; the handlers that stop a run cleanly on SIGHUP (``rprs sim``'s, a bench
    process's) had put themselves over the ignore. SIGTERM still stops it as before."""
    import signal
    out = tmp_path / "nohup.out"
    with out.open("w") as f:
        proc = subprocess.Popen([sys.executable, "-m", "hil.cli", *args], stdout=f,
                                stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                preexec_fn=lambda: signal.signal(signal.SIGHUP,
                                                                 signal.SIG_IGN))
    try:
        deadline = time.monotonic() + 60
        # a run is under way: its line said, or, for rprs sim, well past its imports
        while (running not in out.read_text()) if running else \
                time.monotonic() < deadline - 58:
            assert proc.poll() is None and time.monotonic() < deadline, out.read_text()
            time.sleep(0.05)
        proc.send_signal(signal.SIGHUP)
        time.sleep(1.0)
        assert proc.poll() is None, out.read_text()              # still running
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == stopped, out.read_text()


@pytest.mark.parametrize("option", ["--trace", "--vcd", "--pcap"])
@pytest.mark.parametrize("path", ["", "-"])
def test_an_empty_or_dash_output_name_is_refused(capsys, tmp_path, monkeypatch, option, path):
    """``--trace ''`` wrote no trace and said nothing; ``--pcap -`` (stdout, to the radio hub)
    wrote a file named '-'."""
    monkeypatch.chdir(tmp_path)
    code, _, err = rprs(capsys, "sim", "--duration", "1", option, path)
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert f"argument {option}:" in err
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("args,needle", [
    (["--fail", "1@20"], "--fail 1@20"),
    (["--recover", "2@10"], "--recover 2@10"),
    (["--power", "3@12.5"], "--power 3@12.5"),
    (["--fault", "steal:2@30"], "--fault steal:2@30"),
    (["--fault", "ber@10-20:0.01"], "--fault ber@10-20:0.01"),
])
def test_a_fault_or_power_on_after_the_end_of_the_run_is_refused(capsys, args, needle):
    """``--duration 10 --fail 1@20`` ran, exit 0, and no radio failed: the fault was silently
    never reached. A time the run never gets to is a mistake, said before it runs."""
    code, _, err = rprs(capsys, "sim", "--duration", "10", *args)
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert needle in err and "the run ends at 10 s" in err, err
    # a window that begins before the end is fine, and so is an event before it
    assert rprs(capsys, "sim", "--duration", "10", "--fault", "noise@9-20", "--fail", "1@9.9",
                "--power", "2@5")[0] == 0


@pytest.mark.parametrize("mac", ["aloha", "slotted", "csma"])
@pytest.mark.parametrize("args,needle", [
    (["--fault", "steal:2@3"], "--fault steal:2@3"),
    (["--fault", "fail:1@2", "--fault", "steal:3@4.5"], "--fault steal:3@4.5"),
    (["--profile", "paper"], "--profile paper"),
    (["--robots", "0,1,2", "--father-standby"], "--father-standby"),
])
def test_a_rotational_mac_option_with_a_peer_mac_is_refused(capsys, mac, args, needle):
    """``--mac csma --fault steal:2@3`` ran and said nothing: a peer MAC has no turn to steal
    (its ``force_turn`` does nothing). ``--profile paper`` is a profile of the rotational MAC
    that the peer MACs never read. Each is refused in one line naming the option and the MAC."""
    code, out, err = rprs(capsys, "sim", "--duration", "5", "--mac", mac, *args)
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith(f"rprs: error: {needle}") and f"--mac {mac}" in err, err
    assert out == ""
    # the same with the rotational MAC runs (the steals are real steals there)
    code, _, err = rprs(capsys, "sim", "--duration", "5", "--mac", "rotational", *args)
    assert code == 0, err


def test_the_checksum_and_the_other_sim_options_apply_to_the_peer_macs_too(capsys):
    """What the peer MACs do use is taken: ``--checksum`` seals and checks their frames
    (firmware_model/radio/peer_macs.py), and the air's faults, the CAN side and the load are
    the same for every MAC."""
    from hil.cli.sim import add_sim_options, sim_config
    from hil.cli.common import Parser
    from hil.sim.world import World
    p = Parser(prog="rprs sim")
    add_sim_options(p)
    cfg = sim_config(p.parse_args(["--mac", "aloha", "--checksum", "--duration", "4", "--load",
                                   "1", "--robots", "0,1,2"]))
    w = World(cfg)
    frames: list[bytes] = []
    heard = w.air.on_transmission
    w.air.on_transmission = lambda tx: (frames.append(bytes(tx.data)), heard(tx))
    w.run()
    assert frames and all(b"crc(" in f for f in frames)
    code, out, err = rprs(capsys, "sim", "--duration", "5", "--mac", "csma", "--checksum",
                          "--can", "--fault", "ber@1-2:0.001", "--fault", "skew:1:0.01",
                          "--fault", "busoff:1@3", "--load", "1", "--json")
    assert code == 0, err
    assert json.loads(out)["delivered"] > 0


def test_a_run_shorter_than_one_tick_is_refused(capsys):
    """``rprs sim --duration 1e-9`` ran 0 ticks and exited 0 as if it had simulated something."""
    code, out, err = rprs(capsys, "sim", "--duration", "1e-9", "--no-progress")
    assert code == 2 and err.count("\n") == 1 and "shorter than one tick" in err, err
    assert out == ""
    code, _, _ = rprs(capsys, "sim", "--robots", "1,2", "--duration", "0.0000001",
                      "--no-progress")                   # 1.6 ticks: runs
    assert code == 0


@pytest.mark.parametrize("command", [["submodules", "--can", "virtual:rprs-ev"],
                                     ["father", "--radio", "loop://"]])
def test_events_is_an_option_of_the_child_only(capsys, command):
    """``rprs submodules --events`` and ``rprs father --events`` were accepted and printed
    nothing: the submodules have no MAC, and the father prints its station's events with
    --json. Only ``rprs child`` takes it now; the others refuse it in one line."""
    from hil.cli import main
    assert main([*command, "--events", "--duration", "0.1"]) == 2
    err = capsys.readouterr().err
    assert "unrecognized arguments: --events" in err and "Traceback" not in err, err


def _latency_lines(out: str) -> list[str]:
    lines = out.splitlines()
    i = next(i for i, x in enumerate(lines) if x.startswith("dispatcher latency"))
    return lines[i:i + 2]


def test_the_ring_demos_zero_latency_says_it_is_the_ideal_cpus(capsys):
    """``rprs demo ring`` printed a median dispatcher latency of 0 us, unexplained: with the
    ideal CPU the firmware takes no time and only the wait for a free CAN bus is left. The
    line now says so; on the CPU model the figure is the firmware's and no such note is
    printed."""
    code, out, _ = rprs(capsys, "demo", "ring", "--duration", "6", "--no-progress",
                        "--cpu", "ideal")
    assert code == 0
    head, note = _latency_lines(out)
    assert " median 0 us," in head
    assert "the ideal CPU, --cpu ideal: the firmware takes no time" in note
    assert "only the wait for a free CAN bus" in note
    code, out, _ = rprs(capsys, "sim", "--robots", "0,1,2", "--duration", "6", "--load", "1",
                        "--can", "--cpu", "estimated")
    assert code == 0
    head, after = _latency_lines(out)
    median = float(head.split(" median ", 1)[1].split(" us", 1)[0])
    assert median > 0 and "ideal CPU" not in out


@pytest.mark.parametrize("cmd", [("demo",), ("demo", "ring", "--duration", "6"),
                                 ("sim", "--can", "--load", "1", "--duration", "6")])
def test_the_commands_run_the_cpu_model_by_default(capsys, cmd):
    """Issue 45: ``rprs demo``, ``rprs demo ring`` and ``rprs sim --can`` give a dispatcher
    latency above zero without being asked (the MB90F549 model's cycles, docs/cpu.md), and
    ``--cpu ideal`` gives the paper's zero-time CPU back."""
    extra = ("--no-progress",) if cmd[0] == "sim" or "ring" in cmd else ()
    code, out, _ = rprs(capsys, *cmd, *extra)
    assert code == 0
    line = next(x for x in out.splitlines() if x.startswith("dispatcher latency"))
    assert float(line.split(" min ", 1)[1].split(" us", 1)[0]) > 0
    assert "ideal CPU" not in out
    code, out, _ = rprs(capsys, *cmd, *extra, "--cpu", "ideal")
    assert code == 0
    line = next(x for x in out.splitlines() if x.startswith("dispatcher latency"))
    assert " min 0 us," in line and "the ideal CPU, --cpu ideal" in out


def test_output_to_a_pipe_is_neither_wrapped_nor_coloured():
    """Rich wrapped at 80 columns when stdout was not a terminal: ``rprs sim | grep
    "duplicate deliveries 0"`` found nothing. Into a pipe, no line is wrapped and nothing is
    coloured, even with FORCE_COLOR set; the CPU report's tables included."""
    env = dict(os.environ, FORCE_COLOR="1")
    env.pop("COLUMNS", None)
    r = subprocess.run([sys.executable, "-m", "hil.cli", "sim", "--robots", "0,1,2",
                        "--duration", "6", "--load", "2", "--can", "--cpu", "estimated",
                        "--cpu-report"], capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 0, r.stderr[-500:]
    assert "\x1b[" not in r.stdout
    lines = r.stdout.splitlines()
    assert any(x.startswith("messages: submitted") and "duplicate deliveries 0" in x
               for x in lines)
    assert any(x.startswith("dispatcher latency") and x.rstrip().endswith(" us")
               for x in lines)
    budget = [x for x in lines if x.startswith("R1 CPU budget")]
    assert len(budget) == 1 and "gaps in frames sent" in budget[0]


def test_output_to_a_terminal_is_still_rich():
    """The no-wrap, no-colour console is for pipes and files only: on a terminal the summary
    keeps rich's bold title."""
    import pty
    master, slave = pty.openpty()
    env = dict(os.environ, COLUMNS="100")
    env.pop("NO_COLOR", None)
    p = subprocess.Popen([sys.executable, "-m", "hil.cli", "sim", "--robots", "0,1",
                          "--duration", "2"], stdout=slave, stderr=subprocess.PIPE,
                         stdin=subprocess.DEVNULL, env=env)
    os.close(slave)
    out = bytearray()
    while True:
        try:
            chunk = os.read(master, 65536)
        except OSError:
            break
        if not chunk:
            break
        out.extend(chunk)
    p.wait(timeout=120)
    os.close(master)
    assert p.returncode == 0
    assert b"\x1b[1mRPRS ring" in out, bytes(out[:300])


@pytest.mark.parametrize("args, level", [
    ([], "WARNING"),
    (["-v"], "INFO"),
    (["-vv"], "DEBUG"),
    (["--log-level", "error"], "ERROR"),
    (["-vv", "--log-level", "warning"], "WARNING"),      # the level named wins
])
def test_logging_is_configured_once_from_v_or_log_level(capsys, args, level):
    import logging
    before = logging.getLogger().level
    try:
        code, _, _ = rprs(capsys, "sim", "--robots", "1,2", "--duration", "1", "--no-progress",
                          *args)
        assert code == 0
        assert logging.getLevelName(logging.getLogger().level) == level
        code, _, _ = rprs(capsys, *args, "sim", "--robots", "1,2", "--duration", "1",
                          "--no-progress")                 # before the command's name too
        assert code == 0
        assert logging.getLevelName(logging.getLogger().level) == level
    finally:
        logging.getLogger().setLevel(before)


def test_every_command_takes_the_logging_options():
    from hil.cli import build_parser
    p = build_parser()
    for argv in (["sim", "-v"], ["campaign", "run", "x.toml", "--log-level", "debug"],
                 ["bench", "cycle", "--radio", "/dev/null", "-vv"],
                 ["decode", "-v", "--hex", "00"]):
        a, _ = p.parse_known_args(argv)
        assert getattr(a, "verbose", None) or getattr(a, "log_level", None), argv


def test_a_bench_process_logs_what_it_opened_at_v(tmp_path):
    from processes import hub_links
    with hub_links(tmp_path / "air", 1):
        p = subprocess.run([sys.executable, "-m", "hil.cli", "child", "-v", "--id", "1",
                            "--radio", str(tmp_path / "air" / "node0"), "--duration", "1"],
                           cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    assert re.search(r"rprs: INFO rprs\.bench: robot 1: radio on .*node0, TXEN none, 16640 "
                     r"ticks a byte", p.stderr), p.stderr
    assert "DEBUG" not in p.stderr


def test_the_father_prints_help_and_keeps_its_log(tmp_path):
    """``help`` at the father's prompt lists the order form and every application command;
    ``--log FILE`` appends what the console shows, so the session's record outlives it."""
    log = tmp_path / "father.log"
    p = subprocess.run([sys.executable, "-m", "hil.cli", "father", "--plain", "--radio",
                        "loop://", "--duration", "3", "--log", str(log)],
                       input="help\n7 status()\n", capture_output=True, text=True, timeout=60)
    assert p.returncode in (0, 1), p.stderr                    # (the order finds nobody)
    assert "an order: DST COMMANDS" in p.stdout
    assert "  joint(index [joint no.], angle [deg]): " in p.stdout
    assert "  movex(" in p.stdout and "ack(" not in p.stdout    # application commands only
    orders = [x for x in p.stdout.splitlines() if "#1 -> all status()" in x]
    assert orders, p.stdout
    logged = log.read_text().splitlines()
    assert [x for x in logged if "#1 -> all status()" in x] == orders
    assert not any("an order: DST COMMANDS" in x for x in logged)   # the story, not the help


def test_help_under_json_goes_to_stderr_and_is_no_order(tmp_path):
    """With ``--json`` (stdout: JSON lines only) ``help`` and ``?`` were taken for orders,
    refused, and counted in the closing line (exit status 1): 30 orders for 28 lines of
    input. They are help, on stderr, and no order."""
    p = subprocess.run([sys.executable, "-m", "hil.cli", "father", "--json", "--radio",
                        "loop://", "--duration", "3"],
                       input="help\n?\n7 status()\n", capture_output=True, text=True,
                       timeout=60)
    assert p.returncode in (0, 1), p.stderr                    # (the order finds nobody)
    assert p.stderr.count("an order: DST COMMANDS") == 2, p.stderr
    records = [json.loads(x) for x in p.stdout.splitlines()]   # every line JSON
    assert "an order: DST COMMANDS" not in p.stdout
    assert "orders: 1 (" in p.stderr, p.stderr
    assert not any(r.get("text") in ("help", "?") for r in records), records


def test_a_log_that_cannot_be_written_is_one_line(tmp_path):
    p = subprocess.run([sys.executable, "-m", "hil.cli", "father", "--plain", "--radio",
                        "loop://", "--duration", "1", "--log", str(tmp_path)],
                       capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL)
    assert p.returncode == 2 and "Traceback" not in p.stderr
    assert p.stderr.strip() == f"rprs: error: cannot write the log {tmp_path}: Is a directory"


def test_a_librarys_chatty_logger_stays_quiet_at_the_default_level(capsys):
    """distributed sets its loggers to INFO: at the default level (warning) their records
    reach the root's handler and must stop there (campaign run printed the scheduler's
    'closing all comms')."""
    import logging
    before = logging.getLogger().level
    chatty = logging.getLogger("chatty.library")
    chatty.setLevel(logging.INFO)
    try:
        code, _, _ = rprs(capsys, "sim", "--robots", "1,2", "--duration", "1", "--no-progress")
        assert code == 0
        chatty.info("scheduler closing all comms")
        chatty.warning("a real warning")
        err = capsys.readouterr().err
        assert "closing all comms" not in err and "a real warning" in err
    finally:
        chatty.setLevel(logging.NOTSET)
        logging.getLogger().setLevel(before)


def test_the_log_goes_to_the_stderr_of_the_moment(capsys, monkeypatch):
    """The handler ``main`` configures outlives the command: a record logged later (main
    called in a process that goes on, as the tests call it) goes to the stderr of that
    moment, not to a stream since closed."""
    import logging
    code, _, _ = rprs(capsys, "sim", "--robots", "1,2", "--duration", "1", "--no-progress")
    assert code == 0
    later = io.StringIO()
    monkeypatch.setattr(sys, "stderr", later)
    logging.getLogger("after.the.command").warning("still heard")
    assert "still heard" in later.getvalue()


# -- outputs that cannot be written (a full disk: /dev/full), found by outside checks -------

FULL = "/dev/full"


@pytest.mark.skipif(not os.path.exists(FULL), reason="needs /dev/full (a Linux device)")
def test_a_demo_trace_that_cannot_be_written_is_one_line(capsys, tmp_path):
    """``rprs demo --trace /dev/full`` ended in a traceback (``demo ring`` said it in one
    line)."""
    code, out, err = rprs(capsys, "demo", "--trace", FULL)
    assert code == 2 and err == f"rprs: error: cannot write trace {FULL}: No space left on " \
        "device\n"


def _capture(*args, **kw):
    return subprocess.Popen([sys.executable, "-m", "hil.cli", "capture", *args], cwd=ROOT,
                            stderr=subprocess.PIPE, text=False, **kw)


@pytest.mark.skipif(not os.path.exists(FULL), reason="needs /dev/full (a Linux device)")
def test_a_capture_that_cannot_be_written_or_would_transmit_is_refused():
    """``rprs capture --pcap /dev/full``: a traceback; ``--pcap`` naming its own ``--radio``:
    the pcapng header went on air from a command that says it sends nothing."""
    master, slave = os.openpty()
    port = os.ttyname(slave)
    try:
        for pcap, said in ((FULL, f"cannot write capture {FULL}: No space left on device"),
                           (port, "is the radio's own port")):
            p = _capture("--radio", port, "--pcap", pcap, "--duration", "1")
            _, err = p.communicate(timeout=30)
            assert p.returncode == 2 and said in err.decode() and b"Traceback" not in err
    finally:
        os.close(master)
        os.close(slave)


def test_a_capture_whose_reader_goes_away_stops():
    """``rprs capture --pcap - | head -c 300``: it said ``capture stopped: Broken pipe`` only
    when killed, listening on (holding the port) meanwhile. It stops now, status 1, as every
    command whose reader has gone (its summary line on stderr, no error)."""
    from firmware_model.radio.frame import Frame
    master, slave = os.openpty()
    try:
        p = _capture("--radio", os.ttyname(slave), "--pcap", "-", stdout=subprocess.PIPE)
        p.stdout.read(50)                         # the reader takes a little, then goes
        p.stdout.close()
        frame = Frame(src=1, dst=7, num=0, type=3, content=b"").encode()
        deadline = time.monotonic() + 20
        while p.poll() is None and time.monotonic() < deadline:
            os.write(master, frame)
            time.sleep(0.1)
        assert p.poll() == 1, "still capturing with its reader gone"
        err = p.stderr.read()
        # as every command whose standard output's reader has gone: status 1, no error line
        # (it said "capture stopped: [Errno 32] Broken pipe" once the header was written)
        assert b"Traceback" not in err and b"rprs: error" not in err, err
    finally:
        if p.poll() is None:
            p.kill()
        p.wait()
        p.stderr.close()
        os.close(master)
        os.close(slave)


@pytest.mark.skipif(not os.path.exists(FULL), reason="needs /dev/full (a Linux device)")
def test_a_hub_whose_capture_cannot_be_written_says_so_at_once():
    """``rprs radio-hub --pcap /dev/full`` ran, then crashed at Ctrl-C with a traceback and no
    summary line; then it ran the whole session and said so only at its end. Its capture is
    flushed packet by packet, so a disk that cannot take it is found by the header: one line,
    status 2, before any node is offered."""
    r = subprocess.run([sys.executable, "-m", "hil.cli", "radio-hub", "--nodes", "2",
                        "--pcap", FULL], cwd=ROOT, capture_output=True, text=True, timeout=30)
    assert r.returncode == 2 and "Traceback" not in r.stderr and r.stdout == ""
    assert r.stderr.strip() == f"rprs: error: cannot write capture {FULL}: No space left on device"


def _father_on_a_pty(*args):
    master, slave = os.openpty()
    try:
        r = subprocess.run([sys.executable, "-m", "hil.cli", "father", "--radio",
                            os.ttyname(slave), "--no-input", "--duration", "3", "--team",
                            "0,1", *args],
                           cwd=ROOT, capture_output=True, text=True, timeout=60)
    finally:
        os.close(master)
        os.close(slave)
    return r


@pytest.mark.skipif(not os.path.exists(FULL), reason="needs /dev/full (a Linux device)")
def test_a_father_log_that_cannot_be_written_stops_it_in_one_line():
    """``rprs father --log /dev/full --plain``: a traceback from a scheduler callback, the
    closing lines lost; with ``--json`` no error at all, status 0."""
    for mode in ("--plain", "--json"):
        r = _father_on_a_pty(mode, "--log", FULL)
        assert r.returncode == 1 and "Traceback" not in r.stderr, (mode, r.stderr)
        assert f"rprs: error: cannot write the log {FULL}: No space left on device" in \
            r.stderr, (mode, r.stderr)


def test_a_father_json_log_holds_every_json_line(tmp_path):
    """``--log FILE`` appends what the console shows, with ``--json`` the JSON lines: it held
    the order records only, not the station's events."""
    log = tmp_path / "f.log"
    r = _father_on_a_pty("--json", "--log", str(log))
    assert r.returncode == 0, r.stderr
    printed = [line for line in r.stdout.splitlines() if line.startswith("{")]
    assert printed and log.read_text().splitlines() == printed
    assert any('"ev":"tx"' in line for line in printed)


@pytest.mark.timing
def test_sigterm_to_an_acceptance_run_tears_its_child_process_down():
    """SIGTERM to ``pytest tests/acceptance --target process`` killed pytest where it stood:
    its ``rprs child`` ran on and ``/tmp/rprs-bench-*`` was left. It stops as on Ctrl-C now,
    the device torn down."""
    import glob
    import signal
    import tempfile
    before = set(glob.glob(os.path.join(tempfile.gettempdir(), "rprs-bench-*")))
    p = subprocess.Popen([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-n", "0",
                          "-q", "tests/acceptance", "--target", "process"], cwd=ROOT,
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        deadline = time.monotonic() + 60
        mine: set[str] = set()
        while not mine and time.monotonic() < deadline and p.poll() is None:
            mine = set(glob.glob(os.path.join(tempfile.gettempdir(), "rprs-bench-*"))) - before
            time.sleep(0.05)
        assert mine, "the process target never started"
        time.sleep(0.5)
        p.send_signal(signal.SIGTERM)
        out, _ = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    assert p.returncode != -signal.SIGTERM, out          # not killed where it stood
    assert not any(os.path.exists(d) for d in mine), out  # the device was torn down


@pytest.mark.parametrize("args", [
    ["demo", "--trace", ""],
    ["sim", "--duration", "1", "--cpu-costs", ""],
    ["father", "--radio", "loop://", "--no-input", "--duration", "1", "--log", ""],
    ["father", "--radio", "loop://", "--no-input", "--duration", "1", "--pcap", ""],
    ["child", "--id", "1", "--radio", "loop://", "--duration", "1", "--pcap", ""],
    ["campaign", "report", "x.sqlite", "--plots", ""],
    ["campaign", "status", "x.toml", "--db", ""],
    ["campaign", "export", "x.sqlite", "--csv", ""],
    ["conformance", "--radio", "loop://", "--junit", ""],
    ["wireshark", "--install", "--dir", ""],
])
def test_an_empty_file_or_directory_name_is_refused_wherever_an_option_takes_one(
        capsys, tmp_path, monkeypatch, args):
    """``--log ''``, ``--db ''``, ``--dir ''`` ... ran as if the option were not given: no
    log, the default database, and ``wireshark --install --dir ''`` wrote into the user's
    own plugins folder. Each is one line, status 2, and nothing written."""
    monkeypatch.chdir(tmp_path)
    code, _, err = rprs(capsys, *args)
    assert code == 2 and err.count("\n") == 1 and "an empty name" in err, err
    assert not list(tmp_path.iterdir())


def test_a_soak_rate_past_the_simulators_limit_is_one_line(capsys):
    """``rprs soak --rate 1001`` died in a ConfigError traceback after forking its runs."""
    code, _, err = rprs(capsys, "soak", "--hours", "0.05", "--rate", "1001", "--no-can")
    assert code == 2 and err.count("\n") == 1 and "argument --rate" in err, err


def test_a_listing_that_is_no_utf8_text_is_one_line_naming_it(capsys, tmp_path):
    path = tmp_path / "lat1.asm"
    path.write_bytes(b"MOV A, #1\n\xe9\n")
    code, _, err = rprs(capsys, "listing", "--file", str(path))
    assert code == 2 and err.count("\n") == 1 and "lat1.asm: not UTF-8" in err, err


def test_a_trace_and_a_capture_whose_partial_names_meet_are_refused(capsys, tmp_path,
                                                                    monkeypatch):
    """``--trace x.PID.partial --pcap x``: the capture, written to x.PID.partial first, was
    renamed over by the trace, which took the capture's name; exit 0, no capture anywhere."""
    monkeypatch.chdir(tmp_path)
    partial = f"x.{os.getpid()}.partial"           # (main() runs in this process)
    code, _, err = rprs(capsys, "sim", "--duration", "1", "--trace", partial, "--pcap", "x")
    assert code == 2 and err.count("\n") == 1 and partial in err, err
    assert not list(tmp_path.iterdir())
    code, _, err = rprs(capsys, "sim", "--duration", "1", "--trace", "x.partial", "--pcap", "x")
    assert code == 0 and sorted(p.name for p in tmp_path.iterdir()) == ["x", "x.partial"]


def test_two_runs_writing_one_trace_leave_one_whole_run(tmp_path):
    """Two ``rprs sim`` runs given one ``--trace``: both wrote ``FILE.partial``, so the file
    left mixed the two runs' lines (refused by ``rprs plot``), or was the other seed's behind
    the run that said it wrote it, while the other run said "cannot write trace: No such
    file". Each run writes a partial file of its own now: both succeed, and the file is one
    whole run's, byte for byte."""
    out = tmp_path / "t.jsonl"
    runs = [subprocess.Popen([sys.executable, "-m", "hil.cli", "sim", "--duration", "60",
                              "--load", "1", "--seed", str(seed), "--no-progress", "--trace",
                              str(out)], cwd=ROOT, stdout=subprocess.DEVNULL,
                             stderr=subprocess.PIPE, text=True) for seed in (1, 2)]
    errs = [r.communicate(timeout=300)[1] for r in runs]
    assert [r.returncode for r in runs] == [0, 0], errs
    assert not list(tmp_path.glob("*.partial"))
    alone = {}
    for seed in (1, 2):
        one = tmp_path / f"alone{seed}.jsonl"
        subprocess.run([sys.executable, "-m", "hil.cli", "sim", "--duration", "60", "--load",
                        "1", "--seed", str(seed), "--no-progress", "--trace", str(one)],
                       cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
        alone[seed] = one.read_bytes()
    assert out.read_bytes() in (alone[1], alone[2])


def test_the_fathers_log_and_capture_naming_one_file_are_refused(capsys, tmp_path,
                                                                 monkeypatch):
    """The console's text went into the pcapng, which capinfos then called corrupt."""
    monkeypatch.chdir(tmp_path)
    code, _, err = rprs(capsys, "father", "--radio", "loop://", "--no-input", "--duration",
                        "1", "--pcap", "y.pcap", "--log", "./y.pcap")
    assert code == 2 and err.count("\n") == 1 and "name the same file" in err, err
    assert not list(tmp_path.iterdir())


def test_a_capture_stopped_by_ctrl_c_says_how_long_it_listened(tmp_path):
    """``rprs capture`` stopped by Ctrl-C after 3 s said ``0 bytes heard in 0.0 s`` (the time
    of its last event, not of the capture)."""
    master, slave = os.openpty()
    try:
        p = _capture("--radio", os.ttyname(slave), "--pcap", str(tmp_path / "c.pcap"))
        ready = p.stderr.readline()
        assert ready.startswith(b"capturing"), ready
        time.sleep(2.0)
        import signal
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=30)
        line = [x for x in err.decode().splitlines() if x.startswith("capture:")]
        assert line and line[0].startswith("capture: 0 bytes heard in "), err
        assert float(line[0].split(" in ")[1].split(" s")[0]) >= 1.9, line
    finally:
        os.close(master)
        os.close(slave)


def test_decode_with_stream_and_hex_arguments_is_refused(capsys):
    """``rprs decode --stream 0f0a`` read stdin and dropped the HEX argument silently."""
    code, _, err = rprs(capsys, "decode", "--stream", "0f0a05")
    assert code == 2 and err.count("\n") == 1 and "not both" in err, err


def test_a_child_says_how_many_bytes_came_while_its_radio_was_deaf():
    """On a port without the air's pacing (one end of a pty pair, a peer's script at the other)
    a peer that answered the moment the child's frame reached it answered while the child's
    radio model was still sending it: deaf, as a PTR2000 is, so the answer was dropped, and
    the closing line said ``heard 0, bad frames 0``: a ring that never formed, and no clue.
    The closing line says how many bytes came while the radio was deaf."""
    import select
    import signal
    master, slave = os.openpty()
    p = subprocess.Popen([sys.executable, "-m", "hil.cli", "child", "--id", "1", "--radio",
                          os.ttyname(slave), "--team", "0,1"], cwd=ROOT,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        frames = 0
        while frames < 5 and time.monotonic() < deadline:     # a lone claimer's frames
            if select.select([master], [], [], 0.1)[0] and os.read(master, 4096):
                frames += 1
                os.write(master, b"\x00" * 8)       # at once: its radio still sends
        assert frames == 5, "the child sent nothing"
        time.sleep(0.3)
        p.send_signal(signal.SIGTERM)
        out, err = p.communicate(timeout=30)
    finally:
        if p.poll() is None:
            p.kill()
            p.communicate()
        os.close(master)
        os.close(slave)
    assert p.returncode == 0, err
    assert re.search(r"robot 1: .*, \d+ bytes came while its radio sent or switched "
                     r"\(deaf: dropped\)", out + err), out + err


@pytest.mark.parametrize("command", [
    ["capture", "--radio", "PORT", "--pcap", "PTY", "--duration", "1"],
    ["sim", "--robots", "1,2", "--duration", "1", "--pcap", "PTY"],
    ["child", "--id", "1", "--radio", "loop://", "--pcap", "PTY", "--duration", "1"],
    ["father", "--radio", "loop://", "--pcap", "PTY", "--no-input", "--duration", "1"],
    ["radio-hub", "--nodes", "2", "--pcap", "PTY"],
], ids=["capture", "sim", "child", "father", "radio-hub"])
def test_a_capture_onto_a_serial_port_is_refused(command, capsys):
    """``rprs capture --radio node3 --pcap node2``: the listener that "sends nothing" wrote
    its pcapng onto another radio's pty, which the radio transmitted (and it heard itself).
    Any output that is a terminal, pty or serial port is refused, from its device number:
    the port is not opened (that raises DTR, which may key a radio)."""
    master, slave = os.openpty()
    m2, s2 = os.openpty()
    try:
        args = [os.ttyname(slave) if x == "PTY" else os.ttyname(s2) if x == "PORT" else x
                for x in command]
        code, out, err = rprs(capsys, *args)
    finally:
        for fd in (master, slave, m2, s2):
            os.close(fd)
    assert code == 2 and err.count("\n") == 1, err
    assert err.startswith("rprs: error: --pcap ") and \
        "is a terminal or a serial port: what is written there would be sent" in err


def test_is_terminal_tells_ttys_from_files_and_other_devices(tmp_path):
    from hil.cli.common import is_terminal
    master, slave = os.openpty()
    try:
        assert is_terminal(os.ttyname(slave))
    finally:
        os.close(master)
        os.close(slave)
    (tmp_path / "f").write_text("")
    assert not is_terminal(str(tmp_path / "f")) and not is_terminal(str(tmp_path / "none"))
    assert not is_terminal(os.devnull)
    r, w = os.pipe()
    try:
        assert not is_terminal(f"/proc/self/fd/{w}")
    finally:
        os.close(r)
        os.close(w)


@pytest.mark.parametrize("command", [["child", "--id", "1", "--team", "2,3"],
                                     ["father", "--team", "1,2", "--no-input"]])
def test_a_team_without_the_robots_own_id_is_refused(command, capsys):
    """``--team 2,3`` for robot 1 (or ``1,2`` for the father, ID 0): the station claimed the
    channel and formed a ring of itself outside the team it was told."""
    code, out, err = rprs(capsys, *command, "--radio", "loop://", "--duration", "1")
    own = "1" if command[0] == "child" else "0"
    assert (code, err) == (2, f"rprs: error: --team {command[command.index('--team') + 1]} "
                              f"leaves out this robot's own ID {own}: give the team it "
                              f"belongs to\n")


def test_a_closed_standard_input_is_no_traceback():
    """Started with standard input closed (``0<&-``): ``decode --stream`` says so in one
    line (it was an AttributeError traceback); the father reads no orders, as with
    ``--no-input`` (its input thread died in a traceback)."""
    p = subprocess.run([sys.executable, "-m", "hil.cli", "decode", "--stream"],
                       stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=60,
                       preexec_fn=lambda: os.close(0))
    assert (p.returncode, p.stderr) == (2, "rprs: error: standard input is closed: --stream "
                                           "reads the bytes from it\n")
    p = subprocess.run([sys.executable, "-m", "hil.cli", "father", "--radio", "loop://",
                        "--duration", "1", "--plain"], stdin=subprocess.DEVNULL,
                       capture_output=True, text=True, timeout=60,
                       preexec_fn=lambda: os.close(0))
    assert p.returncode == 0 and "Traceback" not in p.stderr and "Exception" not in p.stderr
    assert p.stderr.splitlines()[-1].startswith("orders: 0"), p.stderr


def test_a_hub_whose_capture_reader_is_gone_at_start_ends_quietly():
    """``rprs radio-hub --pcap - | true``: "cannot write capture -: Broken pipe", status 2;
    now as every command whose standard output's reader has gone: status 1, and nothing on
    stderr but what the hub says there in place of stdout (its ports, its summary)."""
    r, w = os.pipe()
    os.close(r)
    try:
        p = subprocess.run([sys.executable, "-m", "hil.cli", "radio-hub", "--nodes", "2",
                            "--pcap", "-"], stdout=w, stderr=subprocess.PIPE, text=True,
                           timeout=60)
    finally:
        os.close(w)
    assert p.returncode == 1 and "error" not in p.stderr, p.stderr


@pytest.mark.parametrize("args,line", [
    (["encode", "--src", "1", "--dst", "2", "--checksum", "movex(1)crc(12345)"],
     "rprs: error: the Content already ends with crc(...); --checksum seals it itself: give "
     "the Content without it (or leave the option out to send it as it is)\n"),
    (["sim", "--duration", "1e300"],
     "rprs: error: duration 1e+300 s is more than 1e+09 s (about 31 years), the longest run "
     "simulated\n"),
    (["soak", "--robots", "1"],
     "rprs: error: --robots 1: a soak needs at least two robots (its traffic goes between "
     "them; one alone ends with nothing checked)\n"),
    (["soak", "--rate", "0"],
     "rprs: error: argument --rate: '0' is not a positive rate in messages/s per robot (see "
     "'rprs soak --help')\n"),
    (["soak", "--rate", "1e6"],
     "rprs: error: argument --rate: 1e6 messages/s per robot is more than 1000: the channel "
     "carries a few dozen short messages a second in all, so any rate far above that only "
     "costs the simulator each message it offers (see 'rprs soak --help')\n"),
    (["sim", "--mac", "aloha", "--frame-bytes", "14", "--duration", "1"],
     "rprs: error: argument --frame-bytes: frame size must be 23-576, got 14 (see 'rprs sim "
     "--help')\n"),
], ids=["encode crc twice", "sim 1e300 s", "soak of one", "soak rate 0", "soak rate 1e6",
        "frame bytes 14"])
def test_more_user_mistakes_are_one_line(args, line, capsys):
    """``encode --checksum`` on a Content that has its crc wrote two (clause 20: once, last);
    ``sim --duration 1e300`` ran with float ticks and 300-digit counts; ``soak --robots 1``
    ran an hour of nothing and ended with its invariants empty; ``soak --rate`` takes a rate
    only, and its errors offered ``idle`` and ``saturate``, which it refuses; ``--frame-bytes``
    14-22 passed the command line and died in a traceback (a peer MAC's frame holds an ack)."""
    code, out, err = rprs(capsys, *args)
    assert (code, out, err) == (2, "", line)


def test_encode_notes_numbers_a_sender_never_writes(capsys):
    """``rprs encode 'movex(1.50)'`` encodes what it is given (receivers must take it) and
    notes how a sender writes it (docs/protocol.md clause 17)."""
    code, out, err = rprs(capsys, "encode", "--src", "1", "--dst", "2", "movex(1.50)")
    assert code == 0 and bytes.fromhex(out.strip())[12:-2] == b"movex(1.50)"
    assert err == ("rprs encode: note: a sender writes numbers as 'movex(1.5)' "
                   "(docs/protocol.md clauses 17, 20); receivers must still take these\n")
    code, out, err = rprs(capsys, "encode", "--src", "1", "--dst", "2", "movex(1.5)")
    assert code == 0 and err == ""


@pytest.mark.parametrize("content,said", [
    ("crc(1)", "writes numbers as 'crc(00001)'"),
    ("crc(000001)", "writes numbers as 'crc(00001)'"),
    ("movex(1)crc(00012)", None),
    ("crc(00001)movex(1)", "crc(...) comes once, last"),
    ("stop()crc(07426)ack(1,2)", "crc(...) comes once, last"),
])
def test_encode_notes_a_crc_as_clause_20_writes_it(content, said, capsys):
    """A crc's number is five digits, zero padded, and the crc comes last (clause 20): the
    note said a sender writes ``crc(1)`` as '' (the crc left out), and called a canonical
    Content with its crc in the middle a matter of clause 17's numbers."""
    code, out, err = rprs(capsys, "encode", "--src", "4", "--dst", "1", content)
    assert code == 0 and bytes.fromhex(out.strip())[12:-2] == content.encode()
    if said is None:
        assert err == ""
    else:
        assert said in err and "''" not in err


@pytest.mark.parametrize("seal", ["--checksum", "--auth-key"])
def test_encode_counts_the_seal_in_the_562_bytes(seal, tmp_path, capsys):
    """Length counts the crc() or auth() the seal adds (clauses 11, 20, 52): 560 bytes of
    Content sealed made a frame of Length 570 or 583, which ``rprs decode`` refuses, with
    status 0. Refused now, as a message too long is (clause 14); 552 bytes with a crc fit."""
    key = tmp_path / "ring.key"
    key.write_text("key = 000102030405060708090a0b0c0d0e0f\n")
    opts = [seal] if seal == "--checksum" else [seal, str(key)]
    code, out, err = rprs(capsys, "encode", "--src", "1", "--dst", "2", *opts,
                          "stop()" * 92 + "movex(1)")
    total = 570 if seal == "--checksum" else 583
    assert (code, out) == (2, "") and err == (
        f"rprs: error: Content is 560 bytes, {total} with the "
        f"{'crc()' if seal == '--checksum' else 'auth()'} it ends with: more than a frame "
        f"carries (562, docs/protocol.md clause 11)\n")
    fits = "stop()" * (92 if seal == "--checksum" else 89)
    code, out, err = rprs(capsys, "encode", "--src", "1", "--dst", "2", *opts, fits)
    assert code == 0 and err == ""
    code, out, _ = rprs(capsys, "decode", out.strip())
    assert code == 0 and "content_error" not in json.loads(out)["frame"]


def test_a_cost_table_that_is_not_text_is_named(tmp_path, capsys):
    bad = tmp_path / "costs.toml"
    bad.write_bytes(b"\xff\xfe\x00")
    code, out, err = rprs(capsys, "sim", "--duration", "1", "--cpu-costs", str(bad))
    assert (code, err) == (2, f"rprs: error: cannot read the cost table {bad}: not a text file "
                              f"(a TOML table of cycle costs, docs/cpu.md)\n")


@pytest.mark.parametrize("args,name", [
    (["--auth-key", "KEY", "--trace", "KEY"], "--trace {} is the file --auth-key reads"),
    (["--cpu-costs", "COSTS", "--pcap", "COSTS"], "--pcap {} is the file --cpu-costs reads"),
], ids=["trace over the ring key", "capture over the cost table"])
def test_an_output_over_a_file_the_command_reads_is_refused(args, name, tmp_path, capsys):
    """``rprs sim --auth-key k.key --trace k.key`` overwrote the ring key with the trace; the
    file is kept and the command refused in one line."""
    key, costs = tmp_path / "k.key", tmp_path / "c.toml"
    key.write_text("key = 000102030405060708090a0b0c0d0e0f\n")
    costs.write_text("[costs]\nreti = 12\n")
    paths = {"KEY": str(key), "COSTS": str(costs)}
    before = {p: open(p).read() for p in paths.values()}
    code, out, err = rprs(capsys, "sim", "--robots", "1,2", "--duration", "1",
                          *[paths.get(x, x) for x in args])
    target = paths[args[-1]]
    assert (code, err) == (2, f"rprs: error: {name.format(target)}: give the output another "
                              f"name (it would be overwritten)\n")
    assert {p: open(p).read() for p in paths.values()} == before
    # and the next command in the process is not refused for the last one's inputs
    code, out, err = rprs(capsys, "sim", "--robots", "1,2", "--duration", "1", "--trace",
                          target)
    assert code == 0, err


@pytest.mark.parametrize("command", [["child", "--id", "1", "--team", "1,2"], ["father"]])
def test_a_bench_pc_with_a_key_whose_epoch_is_to_come_refuses_to_start(command, tmp_path,
                                                                       capsys):
    """A bench process seeds its freshness values from its clock since the key's epoch
    (clause 52): with an ``epoch =`` day still to come every start gave 0, and a restarted
    child's frames were refused as replayed by the ring, which it never knew. One line,
    status 2, before it sends anything."""
    key = tmp_path / "future.key"
    key.write_text("key = 000102030405060708090a0b0c0d0e0f\nepoch = 2099-01-01\n")
    master, slave = os.openpty()
    try:
        code, out, err = rprs(capsys, *command, "--radio", os.ttyname(slave), "--auth-key",
                              str(key), "--duration", "1")
    finally:
        os.close(master)
        os.close(slave)
    assert code == 2 and out == ""
    assert err.startswith("rprs: error: this PC's clock (") and err.count("\n") == 1
    assert "before the ring key's epoch (2099-01-01 00:00 UTC)" in err


@pytest.mark.parametrize("pair", [["--pc", "1"], ["--pc", "2"], ["--standby"]])
def test_a_paper_profile_father_is_no_pair(pair, capsys):
    """``rprs father --profile paper --pc 1`` was taken, and the father pair's probation
    (clause 50, this project's) put its takeover Header 75 ms after E + Tmax, where the paper
    puts it at Ttrans: a paper robot's conformance run failed clause 24. Refused in one
    line, as ``--standby`` was."""
    master, slave = os.openpty()
    try:
        code, out, err = rprs(capsys, "father", "--radio", os.ttyname(slave), "--profile",
                              "paper", "--no-input", "--duration", "0.2", *pair)
    finally:
        os.close(master)
        os.close(slave)
    assert (code, out) == (2, "") and err == (
        "rprs: error: --profile paper: the paper profile has no checksum extension and no "
        "father pair (a standby PC, --pc: both are this project's extensions)\n")
