"""Stall a bench child again and again and count what it does to the air.

    python scripts/bench_stalls.py                 # 7 stalls of 1 s of R2 in ring 1,2,3
    python scripts/bench_stalls.py --stalls 20 --seconds 0.5

Three `rprs child` processes on a pty radio hub (this process runs the hub); once the ring
has formed, R2 is stopped (SIGSTOP) and continued (SIGCONT) ``--stalls`` times, 3 s apart.
Printed from the hub's record of every transmission: collisions, R2's transmissions that held
more than one frame, how long after each SIGCONT R2's next frame began, and the stall lines R2
wrote on stderr (docs/guarantees.md, "Stalls and restarts at the bench"). Run from the
repository's root; PYTHONPATH chooses the code the children run.
"""
from __future__ import annotations

if __name__ == "__main__":     # a Python without the project says so in one line
    import _needs_project  # noqa: F401    (scripts/ is sys.path[0] here)

import argparse
import signal
import sys
import threading
import time
from pathlib import Path

import can_bus  # noqa: E402,F401    (the project's packages first: with tests/ on sys.path,
import firmware_model  # noqa: E402,F401    its package-less tests/hil/ ... would shadow them)
from hil.bench import scripts as bench           # noqa: E402
from hil.bench.radio_hub import RadioHub         # noqa: E402

sys.path.append(str(Path(__file__).resolve().parent.parent / "tests"))   # the tests' helpers
from processes import heard, ring_is, spawn, stop, wait_for   # noqa: E402

HEADER = b"\x0f\x0a\x05"


class AirRecord:
    """The hub's capture, kept in memory: (node, end tick, bytes, marks)."""

    def __init__(self) -> None:
        self.packets: list[tuple[object, int, bytes, str]] = []
        self._lock = threading.Lock()

    def follow(self, sched) -> None:
        """(A pcap writer takes the hub's clock here; ticks are enough.)"""

    def radio(self, key, tick, data, comment) -> None:
        with self._lock:
            self.packets.append((key, tick, bytes(data), comment or ""))


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--stalls", type=int, default=7)
    p.add_argument("--seconds", type=float, default=1.0, help="how long each stall lasts")
    a = p.parse_args()
    rec = AirRecord()
    hub = RadioHub(nodes=4, seed=1)
    hub.capture(rec)
    hub.start()
    kids = {i: spawn("child", "--id", str(i), "--radio", hub.paths[i - 1], "--team", "1,2,3")
            for i in (1, 2, 3)}
    sniffer = bench.Sniffer(hub.paths[3]).start()
    try:
        if not wait_for(lambda: ring_is(sniffer, [1, 2, 3]), 60.0):
            print("the ring did not form in 60 s", file=sys.stderr)
            return 1
        c0, n0 = hub.stats()["collisions"], len(rec.packets)
        back: list[float | None] = []
        for _ in range(a.stalls):
            kids[2].send_signal(signal.SIGSTOP)
            time.sleep(a.seconds)
            kids[2].send_signal(signal.SIGCONT)
            t = sniffer.tick()
            if wait_for(lambda t=t: heard(sniffer, 2, t / 16e6) >= 1, 15.0):
                first = min(f.start for f in sniffer.snapshot() if f.src == 2 and f.start >= t)
                back.append(round((first - t) / 16e6, 2))
            else:
                back.append(None)
            time.sleep(3.0)
        collisions = hub.stats()["collisions"] - c0
        packets = rec.packets[n0:]
    finally:
        sniffer.stop()
        errs = stop(kids.values())
        hub.stop()
        hub.close()
    if None in back:                    # R2 did not come back: show what it said
        print(errs[1], file=sys.stderr)
    multi = sum(1 for k, _, data, _ in packets if k == 1 and data.count(HEADER) > 1)
    print(f"{a.stalls} stalls of {a.seconds} s: {collisions} collisions, {multi} transmissions "
          f"of R2 with more than one frame, R2's next frame after SIGCONT (s) {back}, "
          f"{errs[1].count('stalled')} stall lines")
    return 0


if __name__ == "__main__":
    sys.exit(main())
