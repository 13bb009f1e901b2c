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


def test_rprs_capture_listens_on_a_hub_node_and_writes_the_ring_it_hears(tmp_path):
    """``rprs capture``: a listen-only station on a radio's port, here a hub node beside a
    father and a child: every packet it writes is a whole frame of theirs (or flagged noise),
    stamped on the wall clock, to a file or to stdout for a pipe."""
    import subprocess
    import sys

    from firmware_model.radio.errors import FrameError
    from firmware_model.radio.frame import parse_frame
    from paths import ROOT

    def rprs(*args, **kw):
        return subprocess.Popen([sys.executable, "-m", "hil.cli", *args], cwd=ROOT, **kw)
    from processes import hub_links
    air = tmp_path / "air"
    with hub_links(air, 3):
        procs = [rprs("child", "--id", "1", "--radio", str(air / "node0"), "--team", "0,1",
                      "--duration", "8", stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL),
                 rprs("father", "--plain", "--no-input", "--radio", str(air / "node1"),
                      "--team", "0,1", "--duration", "8", stdout=subprocess.DEVNULL,
                      stderr=subprocess.DEVNULL)]
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
