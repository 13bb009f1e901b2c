"""The bench processes' ``--pcap`` (hil/bench/capture.py, docs/wireshark.md): packets stamped
on the wall clock of the scheduler's tick 0, and what the serial port heard cut at frame
boundaries however the bytes arrived (an outside tester found both wrong: stamps early by
the time a process took to build its world, and a third of the frames heard split in two on a
loaded machine)."""
from __future__ import annotations

import io
import random
import time

import pcapng
import pytest

from firmware_model.mcu.scheduler import Scheduler
from firmware_model.radio.frame import Frame
from hil.bench.capture import QUIET_BYTES, BenchCapture
from hil.sim.realtime import RealTimeScheduler

BT = 16_640          # ticks a byte at 9600 baud


class _Stream(io.BytesIO):
    def close(self) -> None:         # keep the bytes readable after the capture closes
        pass


def _packets(stream: io.BytesIO) -> list[tuple[str, int, bytes]]:
    """(interface name, timestamp in ns, bytes) of every packet."""
    ifaces, out = [], []
    for b in pcapng.FileScanner(io.BytesIO(stream.getvalue())):
        name = type(b).__name__
        if name == "InterfaceDescription":
            ifaces.append(b.options["if_name"])
        elif name == "EnhancedPacket":
            out.append((ifaces[b.interface_id], (b.timestamp_high << 32) + b.timestamp_low,
                        bytes(b.packet_data)))
    return out


def test_what_was_heard_is_cut_at_frame_boundaries_however_it_arrived():
    """Noise, frames back to back, a frame broken by a byte error and one cut short, handed
    over in random chunks: one packet per frame (the broken one up to its bad byte), what lies
    between frames one packet, the cut frame written after a quiet time, each stamped with the
    tick its last byte completed."""
    frames = [Frame(dst=7, src=r, num=0, type=3, content=b"").encode() for r in (1, 2, 3)]
    frames.append(Frame(dst=2, src=1, num=5, type=2, content=b"movex(10)").encode())
    noise = b"\x00\xff\x0f\x0a"        # ends like a Header begins
    broken = frames[1][:6] + b"x" + frames[1][7:]     # a byte error in Number
    stream = noise + frames[0] + frames[1] + b"\x55" + frames[2] + frames[3] + broken + \
        frames[2] + frames[0][:9]
    for seed in range(20):
        rng = random.Random(seed)
        sched = Scheduler()
        out = _Stream()
        cap = BenchCapture(sched, out, 1, True, None)
        i = 0
        while i < len(stream):
            n = rng.randint(1, 7)
            chunk = stream[i:i + n]
            i += len(chunk)
            now = i * BT                  # byte k of the stream completes at (k + 1) * BT
            sched.run_until(now + rng.randint(0, 3) * BT)   # late, as a loaded machine is
            sched.now = max(sched.now, now)
            cap.heard(chunk, now, BT)
        sched.run_until(sched.now + (QUIET_BYTES + 1) * BT)
        heard = [(t, d) for name, t, d in _packets(out) if name.endswith("heard")]
        assert [d for _, d in heard] == [noise, frames[0], frames[1], b"\x55", frames[2],
                                         frames[3], broken[:6], broken[6:], frames[2],
                                         frames[0][:9]], seed
        ends = [stream.index(d, sum(len(x) for _, x in heard[:k])) + len(d)
                for k, (_, d) in enumerate(heard)]
        assert [t for t, _ in heard] == [e * BT * 1_000_000_000 // 16_000_000 for e in ends]
        cap.close()


def test_stamps_are_the_wall_clock_when_the_scheduler_runs_not_when_it_was_built():
    sched = RealTimeScheduler()
    out = _Stream()
    cap = BenchCapture(sched, out, 1, True, None)
    time.sleep(0.3)                   # a process building its world
    frame = Frame(dst=7, src=1, num=0, type=3, content=b"").encode()
    written: list[int] = []

    def send() -> None:
        written.append(time.time_ns())
        cap.sent(frame, sched.now - len(frame) * BT, BT)
        sched.stop()
    sched.at(0, send)
    sched.run_for(5.0)
    cap.close()
    [(_, stamp, data)] = _packets(out)
    assert data == frame
    # stamped at the event's tick on the scheduler's clock: within the event's lateness of
    # the wall clock then, not 0.3 s before it (the sleep above)
    assert -50_000_000 < stamp - written[0] <= 0


def _rprs(*args, **kw):
    import subprocess
    import sys

    from paths import ROOT
    return subprocess.Popen([sys.executable, "-m", "hil.cli", *args], cwd=ROOT, **kw)


def _ring_of_two(air, seconds: int) -> list:
    """A child (ID 1) on hub node 0 and the father on node 1, for ``seconds``: processes."""
    import subprocess
    quiet = dict(stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return [_rprs("child", "--id", "1", "--radio", str(air / "node0"), "--team", "0,1",
                  "--duration", str(seconds), **quiet),
            _rprs("father", "--plain", "--no-input", "--radio", str(air / "node1"), "--team",
                  "0,1", "--duration", str(seconds), **quiet)]


def test_rprs_capture_listens_on_a_hub_node_and_writes_the_ring_it_hears(tmp_path):
    """``rprs capture``: a listen-only station on a radio's port, here a hub node beside a
    father and a child: every packet it writes is a whole frame of theirs (or flagged noise),
    stamped on the wall clock, to a file or to stdout for a pipe."""
    import subprocess
    import sys

    from firmware_model.radio.errors import FrameError
    from firmware_model.radio.frame import parse_frame
    from paths import ROOT

    from processes import hub_links
    air = tmp_path / "air"
    with hub_links(air, 3):
        procs = _ring_of_two(air, 8)
        t0 = time.time_ns()
        to_file = subprocess.run([sys.executable, "-m", "hil.cli", "capture", "--radio",
                                  str(air / "node2"), "--pcap", str(tmp_path / "air.pcapng"),
                                  "--duration", "3"], cwd=ROOT, capture_output=True,
                                 text=True, timeout=60)
        to_pipe = subprocess.run([sys.executable, "-m", "hil.cli", "capture", "--radio",
                                  str(air / "node2"), "--pcap", "-", "--duration", "2"],
                                 cwd=ROOT, capture_output=True, timeout=60)
        for p in procs:
            p.wait(timeout=30)
    assert to_file.returncode == 0, to_file.stderr
    assert "listen only" in to_file.stderr
    pkts = _packets(_Stream((tmp_path / "air.pcapng").read_bytes()))
    assert {p[0] for p in pkts} == {f"radio on {air / 'node2'}, heard"}
    frames, cut = [], 0
    for _, _, data in pkts:
        if data[:3] == b"\x0f\x0a\x05":
            try:
                frames.append(parse_frame(data))
            except FrameError:      # begun or ended inside a frame; or, on a loaded host,
                cut += 1            # bytes late past the quiet time (hil/bench/capture.py)
    assert len(frames) > 20 and {f.src for f in frames} == {0, 1}, len(frames)
    assert cut <= 2 + len(frames) // 10, (len(frames), cut)
    assert all(t0 < ns < time.time_ns() for _, ns, _ in pkts)
    assert to_pipe.returncode == 0, to_pipe.stderr
    piped = _packets(_Stream(to_pipe.stdout))
    assert len([p for p in piped if p[2][:3] == b"\x0f\x0a\x05"]) > 10


def test_rprs_capture_refuses_a_port_that_is_not_there(tmp_path):
    import subprocess
    import sys
    p = subprocess.run([sys.executable, "-m", "hil.cli", "capture", "--radio",
                        str(tmp_path / "nothing"), "--pcap", str(tmp_path / "c.pcapng")],
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 2 and "Traceback" not in p.stderr
    assert p.stderr.strip() == f"rprs: error: serial port {tmp_path / 'nothing'} does not exist"
    assert not (tmp_path / "c.pcapng").exists()


def _comments(stream: io.BytesIO) -> list[str | None]:
    return [b.options.get("opt_comment") if "opt_comment" in b.options else None
            for b in pcapng.FileScanner(io.BytesIO(stream.getvalue()))
            if type(b).__name__ == "EnhancedPacket"]


def test_a_stall_leaves_a_marked_gap_not_false_stamps():
    """SIGSTOP (Ctrl-Z) of ``rprs capture`` for 5 s: on resume the backlog was read at once,
    each byte stamped as if heard then (251 false "early" warnings), and a frame open at the
    stop was cut in two by the quiet timer. A stall now writes what was open, cut short, and
    the next packet's comment says the capture has a gap before it."""
    frame = Frame(dst=7, src=1, num=0, type=3, content=b"").encode()
    sched = Scheduler()
    out = _Stream()
    cap = BenchCapture(sched, out, 1, True, None)
    cap.heard(frame, len(frame) * BT, BT)
    cap.heard(frame[:5], 2 * len(frame) * BT, BT)        # the stop comes mid-frame
    sched.now = 5 * 16_000_000
    cap.gap(5 * 16_000_000 - 2 * len(frame) * BT)
    cap.heard(frame, sched.now + len(frame) * BT, BT)
    sched.run_until(sched.now + (len(frame) + QUIET_BYTES + 1) * BT)
    cap.close()
    heard = [d for name, _, d in _packets(out) if name.endswith("heard")]
    assert heard == [frame, frame[:5], frame]
    comments = _comments(out)
    assert comments[:2] == [None, None] and comments[2].startswith("the capture stalled 4.")
    assert cap.gaps == 1


@pytest.mark.timing
def test_rprs_capture_stopped_and_continued_marks_the_gap_and_stamps_no_frame_early(tmp_path):
    """The outside check's Ctrl-Z and ``fg``, on the hub: before, 53 to 251 frames stamped
    closer than Ttrans to the one before (false "early" warnings) and no word of the stop."""
    import signal
    import subprocess

    from firmware_model.radio.errors import FrameError
    from firmware_model.radio.frame import parse_frame
    from processes import hub_links

    air = tmp_path / "air"
    with hub_links(air, 3):
        procs = _ring_of_two(air, 9)
        time.sleep(1.0)
        cap = _rprs("capture", "--radio", str(air / "node2"), "--pcap",
                    str(tmp_path / "air.pcapng"), "--duration", "6", stderr=subprocess.PIPE,
                    text=True)
        time.sleep(2.0)
        cap.send_signal(signal.SIGSTOP)
        time.sleep(1.5)
        cap.send_signal(signal.SIGCONT)
        _, err = cap.communicate(timeout=60)
        for p in procs:
            p.wait(timeout=30)
    assert cap.returncode == 0, err
    assert "rprs: capture stalled: it did not run for 1." in err and "1 gap (stalls)" in err, err
    out = _Stream((tmp_path / "air.pcapng").read_bytes())
    comments = _comments(out)
    assert sum(1 for c in comments if c and c.startswith("the capture stalled 1.")) == 1
    frames = []
    for (_, ns, data), note in zip(_packets(out), comments):
        try:
            parse_frame(data)
        except FrameError:
            frames.append(None)
            continue
        frames.append((ns - len(data) * BT * 1000 // 16, ns, note))
    gaps = [b[0] - a[1] for a, b in zip(frames, frames[1:])
            if a is not None and b is not None and b[2] is None]
    assert len(gaps) > 20 and min(gaps) > 2_500_000, sorted(gaps)[:5]   # ns; Ttrans is 5 ms


def test_a_frame_is_stamped_by_its_least_late_read():
    """A frame read in three chunks, the last 2 ms late (a loaded machine, a USB adapter's
    latency timer): it was stamped 2 ms late, and the hand-over after it looked 2 ms short,
    "early" against Ttrans. A read is never early, so the earliest estimate is the nearest."""
    frame = Frame(dst=7, src=1, num=0, type=3, content=b"").encode()
    sched = Scheduler()
    out = _Stream()
    cap = BenchCapture(sched, out, 1, True, None)
    late = 2 * 16_000                                  # 2 ms
    for a, b, delay in ((0, 5, 0), (5, 9, 0), (9, len(frame), late)):
        now = b * BT + delay
        sched.run_until(now)
        cap.heard(frame[a:b], now, BT)
    noise = b"\x00\x01"                                # not back to back: its last read
    now = (len(frame) + 40) * BT + late
    cap.heard(noise, now, BT)
    sched.run_until(now + (QUIET_BYTES + 1) * BT)
    cap.close()
    (_, t1, d1), (_, t2, d2) = [p for p in _packets(out) if p[0].endswith("heard")]
    assert (d1, d2) == (frame, noise)
    assert t1 == len(frame) * BT * 1_000_000_000 // 16_000_000
    assert t2 == now * 1_000_000_000 // 16_000_000


def test_the_can_interface_holds_remote_frames_and_frames_no_node_takes_as_socketcan_has_them():
    """A bench capture wrote a remote frame (101#R6, 010#R) as a data frame of length 0: an
    ESTOP data frame, which stops every node, where the bus carried a remote one, which stops
    none; and left out the frames no CAN 2.0A node takes (an extended id, CAN FD, an error
    frame), which the CAN interface of a capture holds, as SocketCAN hands them over
    (docs/wireshark.md)."""
    import struct

    import can

    from can_bus.frames import CanFrame
    sched = Scheduler()
    out = _Stream()
    cap = BenchCapture(sched, out, 1, False, "vcan0")
    cap.can_frame(CanFrame(0x101, b"", True, 6), 0, 100, None)
    cap.can_frame(CanFrame(0x010, b"", True, 0), 0, 200, None)
    cap.can_frame(CanFrame(0x181, bytes(range(8))), 0, 300, None)
    cap.can_other(can.Message(arbitration_id=0x1ABCDEF, is_extended_id=True, data=b"\x01"),
                  400)
    cap.can_other(can.Message(arbitration_id=0x20, is_error_frame=True, dlc=8,
                              data=bytes(8)), 500)
    cap.can_other(can.Message(arbitration_id=0x123, is_extended_id=False, is_fd=True,
                              bitrate_switch=True, data=bytes(range(12))), 600)
    cap.close()
    got = [struct.unpack_from(">IBB2x", d) + (d[8:],) for _, _, d in _packets(out)]
    assert got == [
        (0x40000101, 6, 0, bytes(8)),                     # CAN_RTR_FLAG, asks for 6
        (0x40000010, 0, 0, bytes(8)),
        (0x181, 8, 0, bytes(range(8))),
        (0x81ABCDEF, 1, 0, b"\x01" + bytes(7)),           # CAN_EFF_FLAG
        (0x20000020, 8, 0, bytes(8)),                     # CAN_ERR_FLAG | CAN_ERR_ACK
        (0x123, 12, 0x05, bytes(range(12)) + bytes(52)),  # canfd_frame: FDF | BRS
    ]
