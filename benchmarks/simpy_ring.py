"""A plain SimPy byte-level model of the idle rotational ring: the peer the simulator's speed is
measured against (issue 14; docs/performance.md).

    python benchmarks/simpy_ring.py [--robots 7] [--seconds 60]

It is what a straightforward discrete-event model of the same ring looks like: every byte on
air is one SimPy timeout for the sender and one ``Store.put``/``get`` for each listening robot,
and each robot runs a byte-at-a-time deframer. The ring is the one ``rprs sim`` runs idle:
robots take turns in ID order; the next one raises TXEN at its predecessor's End, waits Ttrans
(5 ms, 80 000 ticks) and sends an empty heartbeat (Type 3 to 7, 14 bytes); the father's byte
is 16 667 ticks, a child's 16 640 (16 MHz ticks, docs/protocol.md §1). It has none of the
MAC's timers or misses: with no fault in the ring, the real MAC's frames are these (once
rprs sim's ring has formed: tests/benchmarks/test_speed_targets.py checks the two cycles to the
tick). Needs ``simpy`` (``pip install -e '.[bench]'``).
"""
from __future__ import annotations

if __name__ == "__main__":     # a Python without SimPy says so in one line
    from _project import require_project    # benchmarks/ is sys.path[0] here
    require_project(("simpy",), extra="bench")

import argparse
import time

HEADER = b"\x0f\x0a\x05"
END = b"\x17\x19"
TTRANS = 80_000
TICK_HZ = 16_000_000


def heartbeat(src: int, num: int) -> bytes:
    return HEADER + b"7%d%02d30000" % (src, num) + END


def run(robots: tuple[int, ...] = (0, 1, 2, 3, 4, 5, 6), seconds: float = 60.0) -> dict:
    """Simulate ``seconds`` of the idle ring; returns frames heard and the wall time (s)."""
    import simpy
    env = simpy.Environment()
    inbox = {r: simpy.Store(env) for r in robots}
    nxt = {r: robots[(i + 1) % len(robots)] for i, r in enumerate(robots)}
    byte_ticks = {r: 16_667 if r == 0 else 16_640 for r in robots}
    stats = {"frames": 0, "bytes": 0}

    def send(me: int, num: int):
        yield env.timeout(TTRANS)
        bt = byte_ticks[me]
        for b in heartbeat(me, num):
            yield env.timeout(bt)
            stats["bytes"] += 1
            for r in robots:
                if r != me:
                    inbox[r].put(b)

    def listen(me: int):
        buf = bytearray()
        num = 0
        while True:
            b = yield inbox[me].get()
            buf.append(b)
            n = len(buf)
            if n <= 3:
                if buf[n - 1] != HEADER[n - 1]:
                    buf.clear()
                continue
            if n >= 12 and n == 14 + int(buf[8:12]):
                if buf[-2:] == END and nxt[buf[4] - 48] == me:
                    if me == robots[0]:
                        stats["frames"] += len(robots)
                    num = (num + 1) % 100
                    env.process(send(me, num))
                buf.clear()

    for r in robots:
        env.process(listen(r))
    env.process(send(robots[0], 0))
    t0 = time.perf_counter()
    env.run(until=int(seconds * TICK_HZ))
    return {"frames": stats["frames"], "bytes": stats["bytes"],
            "wall": time.perf_counter() - t0}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--robots", type=int, default=7)
    p.add_argument("--seconds", type=float, default=60.0)
    a = p.parse_args()
    r = run(tuple(range(a.robots)), a.seconds)
    print(f"{a.seconds:g} simulated s, {r['frames']} frames, {r['bytes']} bytes: "
          f"{a.seconds / r['wall']:,.0f}x real time")


if __name__ == "__main__":
    main()
