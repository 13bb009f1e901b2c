"""pcapng captures (hil/sim/pcap.py, `rprs sim --pcap`) and the Wireshark dissector
(hil/wireshark/rprs.lua), read back by tshark where Debian's package is installed (CI installs
it) and by python-pcapng everywhere. Every packet is compared with the run's own trace."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import pcapng
import pytest

from firmware_model.radio.frame import parse_frame
from firmware_model.radio.errors import FrameError
from hil.sim.pcap import CAN_ERR_FLAG, UNITS_PER_TICK
from hil.wireshark import plugin_path

TSHARK = shutil.which("tshark")
needs_tshark = pytest.mark.skipif(TSHARK is None, reason="tshark not installed (Debian "
                                  "package tshark; .ci/run installs it)")
ARGS = ("--robots", "0,1,2", "--duration", "6", "--seed", "4", "--can", "--load", "1",
        "--fault", "steal:1@3", "--fault", "foreign@4:x0f0a05323130303230303033616263ffff",
        "--no-progress")


def rprs(*args):
    return subprocess.run([sys.executable, "-m", "hil.cli", *args], capture_output=True,
                          text=True, timeout=120)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    d = tmp_path_factory.mktemp("pcap")
    p = rprs("sim", *ARGS, "--pcap", str(d / "run.pcapng"), "--trace", str(d / "run.jsonl"))
    assert p.returncode == 0, p.stderr
    trace = [json.loads(x) for x in (d / "run.jsonl").read_text().splitlines()]
    return d / "run.pcapng", trace


def _packets(path):
    ifaces, out = {}, []
    with open(path, "rb") as fh:
        blocks = list(pcapng.FileScanner(fh))
    for b in blocks:
        name = type(b).__name__
        if name == "InterfaceDescription":
            ifaces[len(ifaces)] = (b.link_type, b.options["if_name"])
        elif name == "EnhancedPacket":
            ticks = ((b.timestamp_high << 32) + b.timestamp_low) // UNITS_PER_TICK
            out.append((ifaces[b.interface_id], ticks, bytes(b.packet_data),
                        b.options.get("opt_comment")))
    return ifaces, out


def test_every_transmission_and_can_frame_is_in_the_capture(run):
    path, trace = run
    ifaces, pkts = _packets(path)
    frames = [e for e in trace if e["ev"] == "frame"]
    radio = [(p[1], p[2]) for p in pkts if p[0][0] == 147 and p[0][1] != "foreign transmitters"]
    assert [t for t, _ in radio] == [e["end"] for e in frames]
    for (_, data), e in zip(radio, frames):
        if not e["collided"] and not e["aborted"]:
            f = parse_frame(data)
            assert (f.src, f.dst, f.type, f.num) == (e["src"], e["dst"], e["type"], e["num"])
    cans = [e for e in trace if e["ev"] == "can"]
    can_pkts = [p for p in pkts if p[0][0] == 227 and not
                int.from_bytes(p[2][:4], "big") & CAN_ERR_FLAG]
    assert [(p[1], int.from_bytes(p[2][:4], "big"), p[2][8:8 + p[2][4]].hex())
            for p in can_pkts] == [(e["end"], e["id"], e["data"]) for e in cans]


def test_collisions_and_foreign_bytes_are_kept_and_marked(run):
    path, trace = run
    _, pkts = _packets(path)
    assert sum(1 for e in trace if e["ev"] == "frame" and e["collided"]) == \
        sum(1 for p in pkts if p[3] and "collided" in p[3] and p[0][0] == 147
            and p[0][1] != "foreign transmitters")
    foreign = [p for p in pkts if p[0][1] == "foreign transmitters"]
    assert len(foreign) == 1 and foreign[0][2].endswith(b"\xff\xff")
    assert "no robot" in foreign[0][3]


def test_timestamps_are_ticks_and_in_order(run):
    path, _ = run
    _, pkts = _packets(path)
    ticks = [p[1] for p in pkts]
    assert ticks == sorted(ticks)


@needs_tshark
def test_tshark_with_the_plugin_reads_every_field_the_trace_has(run):
    path, trace = run
    out = subprocess.run(
        [TSHARK, "-X", f"lua_script:{plugin_path()}", "-r", str(path), "-T", "fields",
         "-E", "separator=|", "-e", "frame.interface_name", "-e", "rprs.src", "-e", "rprs.dst",
         "-e", "rprs.num", "-e", "rprs.type", "-e", "can.id"],
        capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    rows = [r.split("|") for r in out.stdout.splitlines()]
    radio = [r for r in rows if r[0].endswith(" radio")]      # not "foreign transmitters"
    frames = [e for e in trace if e["ev"] == "frame"]
    assert len(radio) == len(frames)
    checked = 0
    for r, e in zip(radio, frames):
        if e["aborted"]:
            continue                                   # cut: its fields may be missing
        assert (int(r[1]), int(r[2]), int(r[3]), int(r[4])) == \
            (e["src"], e["dst"], e["num"], e["type"]), (r, e)
        checked += 1
    assert checked > 100
    cans = [int(r[5], 0) for r in rows if r[5]]
    assert [c for c in cans if not c & CAN_ERR_FLAG] == \
        [e["id"] for e in trace if e["ev"] == "can"]


@needs_tshark
def test_tshark_filters_and_flags_a_bad_frame(run):
    path, _ = run
    plugin = f"lua_script:{plugin_path()}"
    bad = subprocess.run([TSHARK, "-X", plugin, "-r", str(path), "-Y", "rprs.end.bad",
                          "-T", "fields", "-e", "rprs.src"],
                         capture_output=True, text=True, timeout=120)
    assert bad.returncode == 0, bad.stderr
    assert bad.stdout.split() == ["1"]        # the forged frame "from R1" with End FF FF
    movex = subprocess.run([TSHARK, "-X", plugin, "-r", str(path), "-Y", 'rprs.type == 5',
                            "-T", "fields", "-e", "rprs.src"],
                           capture_output=True, text=True, timeout=120)
    assert movex.returncode == 0 and movex.stdout.split()     # every robot's BOOT frame


def test_a_capture_that_cannot_be_written_is_a_clear_error(tmp_path):
    p = rprs("sim", "--duration", "1", "--pcap", str(tmp_path / "no" / "such" / "x.pcapng"),
             "--no-progress")
    assert p.returncode == 2 and "cannot write capture" in p.stderr
    assert "Traceback" not in p.stderr


def test_the_dissector_installs_where_asked(tmp_path):
    p = rprs("wireshark", "--install", "--dir", str(tmp_path / "plugins"))
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "plugins" / "rprs.lua").read_text() == plugin_path().read_text()
    assert p.stdout.startswith(f"installed {tmp_path / 'plugins' / 'rprs.lua'}")
    # a dissector there already (one edited by hand) is replaced, and the line says so
    (tmp_path / "plugins" / "rprs.lua").write_text("-- mine\n")
    p = rprs("wireshark", "--install", "--dir", str(tmp_path / "plugins"))
    assert p.stdout.startswith(f"replaced {tmp_path / 'plugins' / 'rprs.lua'}"), p.stdout
    # a file where the folder would be: named as such (mkdir said "File exists")
    (tmp_path / "afile").write_text("x")
    for d in (tmp_path / "afile", tmp_path / "afile" / "sub"):
        p = rprs("wireshark", "--install", "--dir", str(d))
        assert p.returncode == 2 and p.stderr == (
            f"rprs: error: cannot install in {d}: {tmp_path / 'afile'} is a file, not a "
            f"directory\n"), p.stderr
    p = rprs("wireshark", "--path")
    assert p.returncode == 0 and p.stdout.strip() == str(plugin_path())


# ---------------------------------------------------------------- CAN payloads and crc()
def test_the_dbc_table_command_helps_and_says_a_bad_plugin_in_one_line(tmp_path):
    """``python -m hil.wireshark.dbc_table --help`` was a traceback (it took --help for the
    plugin's path); it helps, and a missing plugin or one without the table is one line and
    exit status 2, the file left as it was."""
    import subprocess
    import sys
    cmd = [sys.executable, "-m", "hil.wireshark.dbc_table"]
    r = subprocess.run([*cmd, "--help"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and r.stdout.startswith("usage:"), r.stdout + r.stderr
    other = tmp_path / "other.lua"
    other.write_text("-- no table here\n")
    for path, why in ((tmp_path / "none.lua", "No such file"), (other, "no DBC table")):
        r = subprocess.run([*cmd, str(path)], capture_output=True, text=True, timeout=60)
        assert r.returncode == 2 and r.stdout == "", r.stdout
        assert r.stderr.count("\n") == 1 and why in r.stderr and "Traceback" not in r.stderr
    assert other.read_text() == "-- no table here\n"


def test_the_plugin_carries_the_dbc_table_rprs_dbc_gives():
    # regenerate with: python -m hil.wireshark.dbc_table
    from hil.wireshark.dbc_table import lua_table, section
    assert section(plugin_path().read_text()) == lua_table()


def _tshark_json(path, *extra):
    out = subprocess.run([TSHARK, "-X", f"lua_script:{plugin_path()}", "-r", str(path),
                          "-T", "json", *extra], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


def _fields(tree, prefix, out=None):
    """Every field under ``tree`` whose name starts with ``prefix``: {name: [values]}."""
    out = {} if out is None else out
    for k, v in tree.items():
        if isinstance(v, dict):
            _fields(v, prefix, out)
        elif k.startswith(prefix):
            out.setdefault(k, []).append(v)
    return out


@needs_tshark
def test_every_can_payload_decodes_as_cantools_decodes_it(run):
    # the Lua table against cantools reading can_bus/rprs.dbc: every signal of every frame
    from can_bus.frames import CanFrame
    from can_bus.dbc import decode
    path, trace = run
    pkts = [p["_source"]["layers"] for p in _tshark_json(path, "-Y", "rprs_can")]
    cans = [e for e in trace if e["ev"] == "can"]
    assert len(pkts) == len(cans) > 100
    kinds = set()
    for layers, e in zip(pkts, cans):
        name, values = decode(CanFrame(e["id"], bytes.fromhex(e["data"])))
        got = _fields(layers.get("rprs_can", {}), "rprs_can.")
        assert got.pop("rprs_can.msg") == [name]
        got.pop("rprs_can.sender")
        assert {k.split(".")[-1]: float(v[0]) for k, v in got.items()} == \
            pytest.approx({k: float(v) for k, v in values.items()}), (e, got)
        kinds.add(name.rstrip("0123456789").split("_")[-1])
    assert {"STATUS", "CMD", "EVENT"} <= kinds       # commands and their events are there



@pytest.fixture(scope="module")
def checksummed(tmp_path_factory):
    d = tmp_path_factory.mktemp("crc")
    content = b"joint(1,80)crc(12345)"
    forged = b"\x0f\x0a\x05" + b"10522%04d" % len(content) + content + b"\x17\x19"
    p = rprs("sim", "--robots", "0,1,2", "--duration", "6", "--seed", "4", "--load", "1",
             "--checksum", "--fault", f"foreign@4:x{forged.hex()}", "--no-progress",
             "--pcap", str(d / "crc.pcapng"))
    assert p.returncode == 0, p.stderr
    return d / "crc.pcapng", forged


@needs_tshark
def test_crc_is_verified_and_a_wrong_one_flagged(checksummed):
    from firmware_model.radio.integrity import crc16
    path, forged = checksummed
    out = subprocess.run(
        [TSHARK, "-X", f"lua_script:{plugin_path()}", "-r", str(path), "-T", "fields",
         "-E", "separator=|", "-e", "frame.interface_name", "-e", "rprs.crc",
         "-e", "rprs.crc.computed", "-e", "rprs.crc.ok", "-e", "_ws.expert.message"],
        capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    rows = [r.split("|") for r in out.stdout.splitlines()]
    robots = [r for r in rows if r[0].endswith(" radio") and r[1]]
    assert len(robots) > 50 and all(r[3] in ("1", "True") for r in robots), robots[:3]
    assert all(r[1] == r[2] for r in robots)
    foreign = [r for r in rows if r[0] == "foreign transmitters"]
    assert len(foreign) == 1
    # the CRC the dissector computes is the project's, over Destination .. "joint(1,80)"
    want = crc16(forged[3:12 + len(b"joint(1,80)")])
    assert (foreign[0][1], foreign[0][2], foreign[0][3]) == ("12345", str(want), "0") or \
        (foreign[0][1], foreign[0][2], foreign[0][3]) == ("12345", str(want), "False")
    assert "crc() does not match" in foreign[0][4]


@pytest.fixture(scope="module")
def not_digits(tmp_path_factory):
    # two forged frames: Type 'x' only, then every digit field bad (Destination 'a', Source
    # 'b', Number '0x', Type 'y', Length '00z0')
    d = tmp_path_factory.mktemp("digits")
    one = b"\x0f\x0a\x05" + b"7100x0000" + b"\x17\x19"
    every = b"\x0f\x0a\x05" + b"ab0xy00z0" + b"\x17\x19"
    p = rprs("sim", "--robots", "1,2", "--duration", "6", "--checksum", "--no-progress",
             "--fault", f"foreign@4.5:x{one.hex()}", "--fault", f"foreign@5:x{every.hex()}",
             "--pcap", str(d / "forged.pcapng"))
    assert p.returncode == 0, p.stderr
    return d / "forged.pcapng"


@needs_tshark
def test_a_field_that_is_not_digits_has_no_value_and_names_its_byte(not_digits):
    # protocol clause 3.1: Destination, Source, Number, Type and Length are ASCII digits; a
    # field that is not gets no value (no filter on it matches) and a '?' in the Info column
    def tshark(*args):
        out = subprocess.run([TSHARK, "-X", f"lua_script:{plugin_path()}", "-r",
                              str(not_digits), *args], capture_output=True, text=True,
                             timeout=120)
        assert out.returncode == 0, out.stderr
        return out.stdout.splitlines()
    foreign = 'frame.interface_name == "foreign transmitters"'
    summary = tshark("-Y", foreign)               # the Info column ends each line
    assert len(summary) == 2
    assert summary[0].endswith(" 1 -> 7 #0 type ?") and summary[1].endswith(" ? -> ? #? type ?")
    rows = tshark("-Y", foreign, "-T", "fields", "-E", "separator=|", "-E", "occurrence=a",
                  "-E", "aggregator=;", "-e", "rprs.dst", "-e", "rprs.src", "-e", "rprs.num",
                  "-e", "rprs.type", "-e", "rprs.len", "-e", "_ws.expert.message")
    one, every = [r.split("|") for r in rows]
    assert one[:5] == ["7", "1", "0", "", "0"]
    assert "Type: byte 1 of 1, 0x78 'x', is not an ASCII decimal digit" in one[5]
    assert every[:5] == ["", "", "", "", ""]
    for bad in ("Destination: byte 1 of 1, 0x61 'a'", "Source: byte 1 of 1, 0x62 'b'",
                "Number: byte 2 of 2, 0x78 'x'", "Type: byte 1 of 1, 0x79 'y'",
                "Length: byte 3 of 4, 0x7a 'z'"):
        assert bad + ", is not an ASCII decimal digit" in every[5], every[5]
    assert tshark("-Y", f"rprs.type == 0 && {foreign}") == []
    for field in ("rprs.dst", "rprs.src", "rprs.num", "rprs.len"):
        assert len(tshark("-Y", f"{field} && {foreign}")) == 1, field     # the first only
    assert len(tshark("-Y", "rprs.digit.bad")) == 2


def test_can_error_frames_carry_the_type_the_bus_knows(tmp_path):
    # docs/wireshark.md, "Interfaces": busoff -> bit errors, stuck with no transmitter ->
    # stuff, noisy (a local error only the disturbed node sees the cause of) -> no type
    from hil.sim.pcap import CAN_ERR_PROT
    p = rprs("sim", "--robots", "1,2", "--duration", "4", "--can", "--load", "1",
             "--fault", "noisy:1.JOINT2@1-1.5", "--fault", "stuck:2@2-2.1",
             "--fault", "busoff:1@3", "--no-progress", "--pcap", str(tmp_path / "e.pcapng"))
    assert p.returncode == 0, p.stderr
    _, pkts = _packets(tmp_path / "e.pcapng")
    errors = {}
    for (link, _), _, data, comment in pkts:
        can_id = int.from_bytes(data[:4], "big")
        if link == 227 and can_id & CAN_ERR_FLAG:
            kind = comment.split("(")[1].split(")")[0] if "(" in comment else comment
            errors.setdefault(kind, set()).add((can_id & ~CAN_ERR_FLAG, data[8 + 2]))
    assert errors == {"local": {(CAN_ERR_PROT, 0)}, "bit": {(CAN_ERR_PROT, 0x01)},
                      "stuff": {(CAN_ERR_PROT, 0x04)}}, errors


def test_a_packet_seen_before_is_written_as_the_library_writes_it():
    """PcapWriter builds each distinct packet once with python-pcapng and puts the timestamp
    into those bytes for a repeat: the file must be byte for byte the one the library writes
    block by block, repeats, comments, both link types and 64-bit timestamps included."""
    import io
    import random

    from pcapng import blocks

    from hil.sim.pcap import PcapWriter, socketcan_frame

    rng = random.Random(5)
    packets = []
    for i in range(400):
        radio = rng.random() < 0.6
        key = rng.choice([0, 1, "foreign"]) if radio else rng.choice([1, 2])
        data = rng.choice([b"\xaa\x55heartbeat", bytes(rng.randrange(256) for _ in range(5)),
                           b"\x01"]) if radio else bytes(rng.choice([0, 1, 8]))
        comment = rng.choice([None, None, "collided", "a transmitter that is no robot; é"])
        tick = rng.randrange(1 << 54) if i % 50 == 0 else i * 160_000 + rng.randrange(99)
        packets.append((radio, key, tick, data, comment if radio else None))

    radios, buses = {0: "father 0 radio", 1: "R1 radio", "foreign": "foreign"}, {1: "c1",
                                                                                  2: "c2"}
    out = io.BytesIO()
    w = PcapWriter(out, radios, buses)
    for radio, key, tick, data, comment in packets:
        if radio:
            w.radio(key, tick, data, comment)
        else:
            w.can(key, tick, 0x181, data)

    ref = io.BytesIO()
    shb = blocks.SectionHeader(options={"shb_userappl": "rprs"})
    ids = {}
    for key, name in radios.items():
        ids[("radio", key)] = shb.new_member(
            blocks.InterfaceDescription, link_type=147, snaplen=65535,
            options={"if_name": name, "if_description": "RPRS radio channel, 9600 baud "
                     "(rprs.lua)", "if_tsresol": bytes((10,))}).interface_id
    for key, name in buses.items():
        ids[("can", key)] = shb.new_member(
            blocks.InterfaceDescription, link_type=227, snaplen=65535,
            options={"if_name": name, "if_description": "CAN 2.0A, 500 kbit/s",
                     "if_tsresol": bytes((10,))}).interface_id
    lib = pcapng.FileWriter(ref, shb)
    for radio, key, tick, data, comment in packets:
        ts = tick * UNITS_PER_TICK
        lib.write_block(shb.new_member(
            blocks.EnhancedPacket, interface_id=ids[("radio" if radio else "can", key)],
            timestamp_high=ts >> 32, timestamp_low=ts & 0xFFFFFFFF,
            packet_data=data if radio else socketcan_frame(0x181, data),
            options={"opt_comment": comment} if comment else {}))
    assert w.packets == len(packets)
    assert out.getvalue() == ref.getvalue()
    assert len(out.getvalue()) > 400 * 32


def test_a_radio_that_dies_in_its_first_byte_leaves_an_empty_packet(tmp_path):
    """A robot failing within the first byte of its frame sent no whole byte: the capture
    keeps the transmission as a packet of 0 bytes with its comment (python-pcapng refuses
    to write one; it used to end ``rprs sim --pcap`` with a traceback)."""
    from firmware_model.timing import TICK_HZ
    from hil.sim.world import SimConfig, World

    cfg = SimConfig(robots=(0, 1, 2), duration=5, seed=1)     # the ideal CPU, as --cpu ideal
    evs: list = []
    World(cfg, on_event=evs.append).run()
    start = [e for e in evs if e.get("ev") == "frame" and e["src"] == 1][3]["start"]
    path = tmp_path / "c.pcapng"
    r = subprocess.run([sys.executable, "-m", "hil.cli", "sim", "--robots", "0,1,2",
                        "--duration", "5", "--seed", "1", "--no-progress", "--cpu", "ideal",
                        "--fail", f"1@{(start + 100) / TICK_HZ!r}", "--pcap", str(path)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    with open(path, "rb") as f:
        pkts = [b for b in pcapng.FileScanner(f) if isinstance(b, pcapng.blocks.EnhancedPacket)]
    empty = [p for p in pkts if p.captured_len == 0]
    assert len(empty) == 1 and empty[0].packet_len == 0
    assert empty[0].options["opt_comment"] == "aborted: the sender's radio died"
    assert abs(empty[0].timestamp - (start + 100) / TICK_HZ) < 1e-6   # when it died
    if shutil.which("tshark"):
        out = subprocess.run(["tshark", "-r", str(path), "-Y", "frame.len == 0", "-T",
                              "fields", "-e", "frame.comment"], capture_output=True, text=True)
        assert out.stdout.strip() == "aborted: the sender's radio died", out.stderr


@needs_tshark
def test_a_frame_cut_short_under_14_bytes_has_the_fields_it_carries(tmp_path):
    """The dissector called any packet under 14 bytes "not a frame" with "No Header 0F 0A
    05", a Header it had; ``rprs decode`` says "truncated after 12 of 14 bytes". The fields
    the bytes hold are decoded now, with the Length expert saying the frame is cut short."""
    path = tmp_path / "cut.pcapng"
    r = subprocess.run([sys.executable, "-m", "hil.cli", "sim", "--robots", "0,1,2",
                        "--duration", "8", "--seed", "1", "--cpu", "ideal", "--no-progress",
                        "--fault", "foreign@6:x0f0a05373130303130303030", "--pcap", str(path)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    out = subprocess.run([TSHARK, "-X", f"lua_script:{plugin_path()}", "-r", str(path), "-Y",
                          "frame.len == 12", "-T", "fields", "-e", "_ws.col.Info", "-e",
                          "rprs.dst", "-e", "rprs.src", "-e", "rprs.num", "-e", "rprs.type",
                          "-e", "rprs.len", "-e", "_ws.expert.message", "-e",
                          "frame.comment"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    info, dst, src, num, typ, length, experts, comment = out.stdout.rstrip("\n").split("\t")
    # (the burst met a robot's frame here: the capture says so, and so does the dissector)
    assert info == ("[collided] " if "collided" in comment else "") + \
        "cut short after 12 of at least 14 bytes"
    assert (dst, src, num, typ, length) == ("7", "1", "0", "1", "0")
    assert "Cut short: 12 bytes, a frame has at least 14" in experts
    assert "No Header" not in experts


@needs_tshark
def test_tshark_decodes_the_authenticated_profiles_freshness_and_tag(tmp_path):
    """docs/protocol.md clause 52: with --auth-key every frame ends with auth(FFFFFFFF,TTTTTTTT);
    the dissector shows both as fields (rprs.auth.fresh, rprs.auth.tag), the values each
    packet's bytes carry, and a forged frame's made-up ones too (it cannot check a tag: it has
    no key)."""
    from firmware_model.radio.auth import AUTH_TEXT_LEN
    key = tmp_path / "ring.key"
    key.write_text("key = 000102030405060708090a0b0c0d0e0f\n")
    forged = b"\x0f\x0a\x05" + b"10522%04d" % 34 + b"joint(1,80)auth(0000beef,12345678)" + \
        b"\x17\x19"
    pcap = tmp_path / "auth.pcapng"
    p = rprs("sim", "--robots", "0,1,2", "--duration", "3", "--seed", "4", "--load", "1",
             "--auth-key", str(key), "--fault", f"foreign@2:x{forged.hex()}", "--no-progress",
             "--pcap", str(pcap))
    assert p.returncode == 0, p.stderr
    want = []
    for (_, name), _, data, _ in _packets(pcap)[1]:
        if name.endswith(" radio") or name == "foreign transmitters":
            c = parse_frame(data).content[-AUTH_TEXT_LEN:]
            want.append((name, int(c[5:13], 16), int(c[14:22], 16)))
    out = subprocess.run(
        [TSHARK, "-X", f"lua_script:{plugin_path()}", "-r", str(pcap), "-Y", "rprs",
         "-T", "fields", "-E", "separator=|", "-e", "frame.interface_name",
         "-e", "rprs.auth.fresh", "-e", "rprs.auth.tag"],
        capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    got = [(r[0], int(r[1], 16), int(r[2], 16))
           for r in (x.split("|") for x in out.stdout.splitlines())]
    assert len(got) == len(want) > 15 and got == want
    assert ("foreign transmitters", 0xBEEF, 0x12345678) in got


RETRY_ARGS = ("--robots", "0,1,2", "--duration", "20", "--seed", "4", "--load", "2",
              "--ber", "0.002", "--no-progress")
"""Byte errors under load: frames lost, messages sent again, acknowledgements late."""


@pytest.fixture(scope="module")
def retries(tmp_path_factory):
    d = tmp_path_factory.mktemp("retries")
    p = rprs("sim", *RETRY_ARGS, "--pcap", str(d / "run.pcapng"), "--trace",
             str(d / "run.jsonl"))
    assert p.returncode == 0, p.stderr
    trace = [json.loads(x) for x in (d / "run.jsonl").read_text().splitlines()]
    return d / "run.pcapng", trace


def _tshark_rows(path, *args):
    out = subprocess.run([TSHARK, "-X", f"lua_script:{plugin_path()}", "-r", str(path),
                          *args], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    return out.stdout.splitlines()


@needs_tshark
def test_tshark_names_the_robots_in_the_source_and_destination_columns(run):
    path, _ = run
    lines = _tshark_rows(path, "-Y", "rprs")
    assert all(("→" in x) for x in lines)
    assert any("father 0 → all" in x for x in lines)
    assert any(" R1 → " in x or " R2 → " in x for x in lines)


@needs_tshark
def test_every_retransmission_on_the_air_is_flagged_and_every_ack_found(retries):
    """The simulator's ground truth: a message delivered after ``attempts`` sendings was on
    the air ``attempts`` times, so ``attempts - 1`` of its frames repeat it; the dissector must
    flag exactly those, each pointing at the message's first sending."""
    path, trace = retries
    ended = {(e["src"], e["num"]): e["attempts"] for e in trace if e["ev"] == "delivered"}
    failed = {(e["src"], e["num"]) for e in trace if e["ev"] == "fail"}
    rows = [r.split("|") for r in _tshark_rows(
        path, "-2", "-T", "fields", "-E", "separator=|", "-e", "frame.number", "-e",
        "rprs.src", "-e", "rprs.num", "-e", "rprs.analysis.retransmission_of", "-e",
        "rprs.analysis.acked_in", "-e", "rprs.content", "-e", "rprs.analysis.collided")]
    by_number = {r[0]: r for r in rows}
    flagged: dict[tuple[int, int], int] = {}
    for n, src, num, of, _acked, _content, collided in rows:
        if of and not collided:
            key = (int(src), int(num))
            flagged[key] = flagged.get(key, 0) + 1
            first = by_number[of]
            assert (first[1], first[2]) == (src, num) and int(of) < int(n)
    expected = {k: a - 1 for k, a in ended.items() if a > 1 and k not in failed}
    assert expected, "the run sent nothing twice: no check"
    assert {k: v for k, v in flagged.items() if k in expected} == expected
    assert not {k for k in flagged if k not in expected and k not in failed}
    acked = [r for r in rows if r[4]]
    assert len(acked) > 20
    for r in acked:
        ack = by_number[r[4]]
        assert f"ack({r[1]},{int(r[2])})" in ack[5] and int(ack[0]) > int(r[0])


@needs_tshark
def test_collided_frames_are_flagged_as_errors(run):
    path, trace = run
    collided = [e for e in trace if e["ev"] in ("frame", "interference") and e["collided"]]
    rows = _tshark_rows(path, "-Y", "rprs.analysis.collided", "-T", "fields", "-e",
                        "frame.number")
    assert collided and len(rows) == len(collided)
    experts = _tshark_rows(path, "-Y", "rprs.analysis.collided.expert", "-T", "fields", "-e",
                           "frame.number")
    assert experts == rows


@needs_tshark
def test_a_can_enumeration_filters_by_its_value_name(run):
    path, _ = run
    def states(name):
        return _tshark_rows(path, "-Y", f'rprs_can.joint1_status.state == "{name}"', "-T",
                            "fields", "-e", "rprs_can.joint1_status.state")
    moving, idle = states("moving"), states("idle")
    assert moving and idle
    assert set(moving) == {"1"} and set(idle) == {"0"}      # can_bus/rprs.dbc's VAL_


@needs_tshark
def test_the_installed_plugin_and_the_documented_x_option_together_load_it_once(run, tmp_path):
    """docs/wireshark.md installs the dissector, then runs tshark with -X lua_script:PATH:
    the file runs twice, and once failed to register its protocols again (a Lua traceback on
    every run)."""
    import os
    path, _ = run
    env = dict(os.environ, HOME=str(tmp_path), XDG_CONFIG_HOME=str(tmp_path / ".config"))
    inst = subprocess.run([sys.executable, "-m", "hil.cli", "wireshark", "--install"], env=env,
                          capture_output=True, text=True, timeout=60)
    assert inst.returncode == 0, inst.stderr
    assert (tmp_path / ".local" / "lib" / "wireshark" / "plugins" / "rprs.lua").exists()
    for extra in ([], ["-X", f"lua_script:{plugin_path()}"]):
        out = subprocess.run([TSHARK, *extra, "-r", str(path), "-Y", "rprs.src == 1"], env=env,
                             capture_output=True, text=True, timeout=120)
        assert out.returncode == 0 and "Lua" not in out.stderr, out.stderr
        assert "R1 → " in out.stdout


def _stat_table(lines: list[str], title: str) -> list[list[str]]:
    """The rows of the ``-z rprs,...`` table whose first line starts with ``title`` (its
    header line skipped), each split on whitespace, a robot's name kept whole."""
    i = next(k for k, x in enumerate(lines) if x.startswith(title))
    rows = []
    for x in lines[i + 2:]:
        if not x.strip() or x.startswith("RPRS "):
            break
        rows.append(x.replace("father 0", "father-0").split())
    return rows


@needs_tshark
def test_statistics_per_robot_and_per_conversation_are_the_captures(retries):
    """``-z rprs,robots`` (endpoints) and ``-z rprs,conv`` (conversations) count what the
    capture's own fields give: frames and retransmissions by Source, frames by Destination and
    by Source -> Destination pair; each robot's turn (its frames' spacing) about a cycle."""
    path, trace = retries
    fields = [r.split("|") for r in _tshark_rows(
        path, "-Y", "rprs.src", "-T", "fields", "-E", "separator=|", "-e", "rprs.src", "-e",
        "rprs.dst", "-e", "rprs.analysis.retransmission")]
    lines = _tshark_rows(path, "-q", "-z", "rprs,robots", "-z", "rprs,conv")
    name = lambda r: "father-0" if r == "0" else "all" if r == "7" else f"R{r}"  # noqa: E731
    robots = {row[0]: row[1:] for row in _stat_table(lines, "RPRS robots")}
    for r in {f[0] for f in fields}:
        frames, _bytes, to_it, retrans, _collided, turn = robots[name(r)]
        assert int(frames) == sum(f[0] == r for f in fields)
        assert int(to_it) == sum(f[1] == r for f in fields)
        assert int(retrans) == sum(f[0] == r and f[2] != "" for f in fields)
        assert 50 < float(turn) < 200             # three robots, a turn each in a cycle
    assert sum(int(v[3]) for v in robots.values()) > 0, "no retransmission: no check"
    conv = _stat_table(lines, "RPRS conversations")
    pairs = {(name(f[0]), name(f[1])) for f in fields}
    assert {(c[0], c[1]) for c in conv} == pairs
    for src, dst, frames, *_ in conv:
        assert int(frames) == sum((name(f[0]), name(f[1])) == (src, dst) for f in fields)
    sent = [e for e in trace if e["ev"] == "frame"]
    assert sum(int(c[2]) for c in conv) == len(fields) <= len(sent)


@needs_tshark
def test_preferences_turn_the_checksum_check_and_the_analysis_off(checksummed, retries):
    crc_path, _ = checksummed
    on = _tshark_rows(crc_path, "-Y", "rprs.crc.computed")
    off = _tshark_rows(crc_path, "-o", "rprs.check_crc:FALSE", "-Y", "rprs.crc.computed")
    carried = _tshark_rows(crc_path, "-o", "rprs.check_crc:FALSE", "-Y", "rprs.crc")
    assert len(on) > 50 and off == [] and len(carried) == len(on)
    assert _tshark_rows(crc_path, "-o", "rprs.check_crc:FALSE", "-Y", "rprs.crc.ok == 0") == []
    path, _ = retries
    assert _tshark_rows(path, "-Y", "rprs.analysis.retransmission")
    assert _tshark_rows(path, "-o", "rprs.analyze:FALSE", "-Y",
                        "rprs.analysis.retransmission || rprs.analysis.acks") == []


MY_DBC = '''VERSION ""

NS_ :

BS_:

BU_: SENSOR MCU

BO_ 768 MY_SENSOR: 3 SENSOR
 SG_ temp : 0|16@1- (0.1,0) [-100|100] "degC" MCU
 SG_ state : 16|8@1+ (1,0) [0|2] "" MCU

VAL_ 768 state 0 "off" 1 "warming" 2 "ready" ;
'''


@needs_tshark
def test_install_with_a_users_own_dbc_decodes_its_frames(tmp_path):
    """``rprs wireshark --install --dbc FILE``: the installed dissector decodes the CAN
    payloads with the user's DBC (signals scaled, signed, value names)."""
    from hil.sim.pcap import PcapWriter
    (tmp_path / "my.dbc").write_text(MY_DBC)
    p = rprs("wireshark", "--install", "--dir", str(tmp_path / "plugins"), "--dbc",
             str(tmp_path / "my.dbc"))
    assert p.returncode == 0, p.stderr
    assert "my.dbc" in p.stdout
    plugin = tmp_path / "plugins" / "rprs.lua"
    with open(tmp_path / "c.pcapng", "wb") as fh:
        w = PcapWriter(fh, {}, {1: "R1 CAN"})
        w.can(1, 16_000, 0x300, bytes([0xD7, 0x00, 2]))       # 215 x 0.1 = 21.5, ready
        w.can(1, 32_000, 0x300, bytes([0x9C, 0xFF, 0]))       # -100 x 0.1 = -10.0, off
    out = subprocess.run([TSHARK, "-X", f"lua_script:{plugin}", "-r",
                          str(tmp_path / "c.pcapng"), "-T", "fields", "-E", "separator=|",
                          "-e", "rprs_can.msg", "-e", "rprs_can.my_sensor.temp", "-e",
                          "rprs_can.my_sensor.state"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines() == ["MY_SENSOR|21.5|2", "MY_SENSOR|-10|0"]
    ready = subprocess.run([TSHARK, "-X", f"lua_script:{plugin}", "-r",
                            str(tmp_path / "c.pcapng"), "-Y",
                            'rprs_can.my_sensor.state == "ready"'],
                           capture_output=True, text=True, timeout=120)
    assert ready.returncode == 0 and len(ready.stdout.splitlines()) == 1


def test_a_dbc_that_cannot_be_used_is_one_line(tmp_path):
    (tmp_path / "bad.dbc").write_text("BO_ what\n")
    (tmp_path / "float.dbc").write_text(MY_DBC.replace("0|16@1-", "0|12@1-"))
    for args, says in ((["--install", "--dbc", str(tmp_path / "none.dbc")], "cannot read"),
                       (["--install", "--dbc", str(tmp_path / "bad.dbc")], "not a DBC"),
                       (["--install", "--dbc", str(tmp_path / "float.dbc")], "byte-aligned"),
                       (["--dbc", str(tmp_path / "bad.dbc")], "give --install too")):
        p = rprs("wireshark", "--dir", str(tmp_path / "p"), *args) if args[0] == "--install" \
            else rprs("wireshark", *args)
        assert p.returncode == 2 and says in p.stderr, (args, p.stderr)
        assert "Traceback" not in p.stderr and len(p.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "p" / "rprs.lua").exists()


@pytest.mark.slow   # a live capture on the wall clock through Wireshark's extcap: about 6 s
@pytest.mark.skipif(TSHARK is None or shutil.which("socat") is None,
                    reason="tshark or socat not installed (Debian packages; .ci/run installs "
                           "them)")
def test_wireshark_captures_live_from_a_radio_port_through_the_extcap(tmp_path):
    """``rprs wireshark --install-extcap``: tshark lists the interface rprs-radio and, given a
    port (here one end of a socat pty pair, frames written to the other), captures and decodes
    the frames as they come."""
    import threading
    import time
    from firmware_model.radio.frame import Frame
    env = dict(os.environ, HOME=str(tmp_path), XDG_CONFIG_HOME=str(tmp_path / ".config"))
    p = subprocess.run([sys.executable, "-m", "hil.cli", "wireshark", "--install-extcap"],
                       capture_output=True, text=True, timeout=60, env=env)
    assert p.returncode == 0, p.stderr
    listed = subprocess.run([TSHARK, "-D"], capture_output=True, text=True, timeout=60,
                            env=env)
    assert "rprs-radio" in listed.stdout, listed.stdout
    a, b = tmp_path / "a", tmp_path / "b"
    socat = subprocess.Popen(["socat", f"pty,raw,echo=0,link={a}", f"pty,raw,echo=0,link={b}"])
    stop = threading.Event()

    def send() -> None:
        n = 0
        while not a.exists() and not stop.is_set():
            time.sleep(0.05)
        with open(a, "wb", buffering=0) as port:
            while not stop.wait(0.3):
                n += 1
                port.write(Frame(dst=7, src=2, num=n % 100, type=2, content=b"poll()").encode())
    writer = threading.Thread(target=send, daemon=True)
    writer.start()
    try:
        while not b.exists():
            time.sleep(0.05)
        out = subprocess.run([TSHARK, "-i", "rprs-radio", "-o", f"extcap.rprs_radio.port:{b}",
                              "-c", "5", "-X", f"lua_script:{plugin_path()}", "-T", "fields",
                              "-e", "rprs.src", "-e", "rprs.dst", "-e", "rprs.cmd"],
                             capture_output=True, text=True, timeout=60, env=env)
    finally:
        stop.set()
        socat.terminate()
        socat.wait(timeout=10)
        writer.join(timeout=10)
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines() == ["2\t7\tpoll"] * 5, out.stdout


def test_the_extcap_answers_wiresharks_questions_and_refuses_what_it_cannot_do(capsys):
    from hil.cli import extcap
    assert extcap.main(["--extcap-interfaces"]) == 0
    assert "interface {value=rprs-radio}" in capsys.readouterr().out
    assert extcap.main(["--extcap-interface", "rprs-radio", "--extcap-dlts"]) == 0
    assert "dlt {number=147}{name=USER0}" in capsys.readouterr().out
    assert extcap.main(["--extcap-interface", "rprs-radio", "--extcap-config"]) == 0
    assert "{call=--port}" in capsys.readouterr().out
    assert extcap.main(["--extcap-interface", "eth9", "--extcap-dlts"]) == 2
    assert "no interface 'eth9'" in capsys.readouterr().err
    assert extcap.main(["--extcap-interface", "rprs-radio", "--capture", "--fifo", "f"]) == 2
    assert "needs --fifo and --port" in capsys.readouterr().err


@needs_tshark
def test_the_ring_key_as_a_preference_checks_every_tag(tmp_path):
    """The authenticated profile with ``rprs.auth_key``: every robot's tag is right under the
    ring's key, a forged frame's made-up tag is flagged, and under another key every tag is."""
    key = "000102030405060708090a0b0c0d0e0f"
    (tmp_path / "ring.key").write_text(f"key = {key}\n")
    c = b"movex(5)auth(00000001,deadbeef)"
    forged = b"\x0f\x0a\x05" + b"12%02d%d%04d" % (3, 2, len(c)) + c + b"\x17\x19"
    p = rprs("sim", "--robots", "0,1,2", "--duration", "10", "--seed", "3", "--load", "1",
             "--auth-key", str(tmp_path / "ring.key"), "--fault", f"foreign@6:x{forged.hex()}",
             "--no-progress", "--pcap", str(tmp_path / "auth.pcapng"))
    assert p.returncode == 0, p.stderr
    path = tmp_path / "auth.pcapng"

    def rows(k: str, flt: str) -> list[str]:
        return _tshark_rows(path, "-o", f"rprs.auth_key:{k}", "-Y", flt, "-T", "fields",
                            "-e", "frame.interface_name")
    tagged = _tshark_rows(path, "-Y", "rprs.auth.tag", "-T", "fields", "-e", "frame.number")
    good, bad = rows(key, "rprs.auth.ok == 1"), rows(key, "rprs.auth.bad")
    assert len(tagged) > 100 and len(good) == len(tagged) - 1
    assert bad == ["foreign transmitters"]
    assert len(rows("f" * 32, "rprs.auth.bad")) == len(tagged)
    assert _tshark_rows(path, "-Y", "rprs.auth.ok") == []          # no key: not checked


@needs_tshark
def test_the_hand_over_gap_is_the_traces_and_a_frame_sent_too_soon_is_early(run, retries):
    """``rprs.analysis.gap``: from the previous frame's end to this one's start, as the trace
    has them (the dissector takes the father's byte as a PC's 10/9600 s, the simulator as
    16,667 ticks: 21 ns a byte apart);
    ``rprs.analysis.early`` where that is under Ttrans less the tolerance: none in a ring
    that takes turns (byte errors and all), the stealing robot's frame in one that does not."""
    path, trace = retries
    frames = [e for e in trace if e["ev"] == "frame"]
    rows = [r.split("|") for r in _tshark_rows(
        path, "-Y", "rprs", "-T", "fields", "-E", "separator=|", "-e", "rprs.analysis.gap",
        "-e", "rprs.analysis.early")]
    assert len(rows) == len(frames) > 200 and rows[0][0] == ""
    for (gap, early), before, e in zip(rows[1:], frames, frames[1:]):
        want = (e["start"] - before["end"]) / 16e6
        assert abs(float(gap) - want) < 1e-7 + 25e-9 * e["bytes"], (gap, want, e)
        assert early == ""
    path, trace = run
    early = _tshark_rows(path, "-Y", "rprs.analysis.early", "-T", "fields", "-e", "rprs.src",
                         "-e", "rprs.analysis.collided")
    assert early and all(x.split("\t")[1] in ("1", "True") for x in early)
    assert "1" in {x.split("\t")[0] for x in early}                  # steal:1@3
    # the preferences: with Ttrans taken as 6 ms, every hand-over under 5.5 ms is early
    path, _ = retries
    strict = _tshark_rows(path, "-o", "rprs.ttrans_us:6000", "-Y", "rprs.analysis.early")
    assert len(strict) == sum(e["start"] - b["end"] < 5.5e-3 * 16e6
                              for b, e in zip(frames, frames[1:])) > 100


@needs_tshark
def test_a_robot_acknowledging_a_message_again_is_a_duplicate_ack(retries):
    """``rprs.analysis.duplicate_ack``: the frames (of those that parse) in which a robot
    acknowledges a message it acknowledged in an earlier frame, as Python finds them in the
    same capture's bytes."""
    import re
    path, _ = retries
    _, packets = _packets(path)
    seen: set[tuple[bytes, int]] = set()
    want, parsed = [], []
    for number, ((link, _name), _t, data, _c) in enumerate(packets, 1):
        try:
            frame = parse_frame(data) if link == 147 else None
        except FrameError:
            frame = None
        if frame is None:
            continue
        parsed.append(str(number))
        acks = {(m.group(0), frame.src) for m in re.finditer(rb"ack\(\d+,\d+\)", frame.content)}
        if acks & seen:
            want.append(str(number))
        seen |= acks
    got = _tshark_rows(path, "-Y", "rprs.analysis.duplicate_ack", "-T", "fields", "-e",
                       "frame.number")
    assert want and [n for n in got if n in set(parsed)] == want


@needs_tshark
@pytest.mark.parametrize("cut", [0.5, 1.5, 5.5, 12.5])
def test_a_frame_cut_short_by_its_senders_death_is_marked_however_short(tmp_path, cut):
    """The capture says "aborted" on the packet of a transmission whose sender's radio died;
    the dissector marked it only from 14 bytes on, and a packet of no byte not at all."""
    sim = ("--robots", "0,1,2,3", "--duration", "3", "--can", "--load", "1", "--seed", "1",
           "--no-progress")
    p = rprs("sim", *sim, "--trace", str(tmp_path / "t.jsonl"))
    assert p.returncode == 0, p.stderr
    trace = [json.loads(x) for x in (tmp_path / "t.jsonl").read_text().splitlines()]
    start = next(e["start"] for e in trace if e["ev"] == "frame" and e["src"] == 1)
    at = (start + int(16640 * cut)) / 16e6                # a child's byte: 16,640 ticks
    path = tmp_path / "cut.pcapng"
    p = rprs("sim", *sim, "--fail", f"1@{at!r}", "--pcap", str(path))
    assert p.returncode == 0, p.stderr
    rows = _tshark_rows(path, "-Y", 'frame.comment contains "aborted"', "-T", "fields", "-e",
                        "frame.len", "-e", "rprs.analysis.aborted", "-e", "_ws.col.Info")
    assert len(rows) == 1, rows
    length, aborted, info = rows[0].split("\t")
    assert int(length) == int(cut) and aborted in ("1", "True") and "[cut short]" in info


@needs_tshark
def test_a_burst_that_collided_is_marked_collided_though_it_is_no_frame(tmp_path):
    """A foreign burst with no Header is "not a frame"; its packet's comment says collided,
    which the dissector did not mark (a -Y rprs.analysis.collided filter missed it)."""
    path = tmp_path / "b.pcapng"
    p = rprs("sim", "--robots", "0,1,2,3", "--duration", "6", "--load", "1", "--seed", "2",
             "--fault", "steal:1@3.5", "--fault", "burst@3:0.1", "--no-progress", "--pcap",
             str(path))
    assert p.returncode == 0, p.stderr
    rows = _tshark_rows(path, "-Y", "rprs.analysis.collided", "-T", "fields", "-e",
                        "frame.interface_name", "-e", "_ws.col.Info")
    assert any(r.startswith("foreign transmitters\t[collided] not a frame") for r in rows), rows


def test_a_frame_sent_in_pieces_is_paused_not_aborted(tmp_path):
    """A transmit handler slower than a byte time (docs/cpu.md's ``uart_tx_byte = 20000``)
    sends each child frame in pieces, its carrier kept on. The trace called each piece
    ``aborted`` ("the sender's radio died") and the capture commented it so; tshark counted
    11,916 frames cut short. The pieces are now ``paused`` and ``continued``; the dissector
    shows them as pieces, a note, not an error."""
    costs = tmp_path / "slow.toml"
    costs.write_text("[costs]\nuart_tx_byte = 20000\n")
    trace, path = tmp_path / "t.jsonl", tmp_path / "p.pcapng"
    p = rprs("sim", "--robots", "0,1,2", "--duration", "6", "--seed", "1", "--load", "1",
             "--cpu", "estimated", "--cpu-costs", str(costs), "--no-progress", "--trace",
             str(trace), "--pcap", str(path))
    assert p.returncode == 0, p.stderr
    frames = [e for e in map(json.loads, trace.read_text().splitlines()) if e["ev"] == "frame"]
    pieces = [e for e in frames if e.get("paused") or e.get("continued")]
    assert pieces and not any(e["aborted"] for e in frames)
    # each child's paused piece is followed, on that child, by a continued one
    for e in pieces:
        if e.get("paused"):
            nxt = next((f for f in frames if f["src"] == e["src"] and f["start"] > e["start"]),
                       None)
            assert nxt is None or (nxt.get("continued") and nxt["start"] >= e["end"]), (e, nxt)
    if TSHARK is None:
        return
    rows = _tshark_rows(path, "-Y", "rprs.analysis.aborted or rprs.header.bad "
                        "or rprs.len.bad", "-T", "fields", "-e", "frame.number")
    assert rows == [] or rows == [""], rows[:5]
    pieces_seen = _tshark_rows(path, "-Y", "rprs.analysis.paused or rprs.analysis.continued",
                               "-T", "fields", "-e", "frame.number")
    assert len([r for r in pieces_seen if r]) == len(pieces)
