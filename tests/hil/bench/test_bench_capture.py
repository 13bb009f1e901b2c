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
