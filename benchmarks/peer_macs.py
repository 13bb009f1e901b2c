"""Peer MACs against the textbook curves (docs/peer-macs.md): pure ALOHA, slotted ALOHA and
non-persistent CSMA on the simulated PTR2000 channel, same load and seeds, plus the rotational
TDMA MAC saturated with the same frames. Prints a Markdown table.

    python benchmarks/peer_macs.py [--quick] [--seed 1] [--robots 0,1,2,3,4,5,6]

Load: every robot draws Poisson arrivals (``random.Random(f"{seed}:peerload:{robot}")``) of
fixed-size unicast messages (26 Content bytes: 40-byte data frames) to a uniformly chosen other
robot; ``lam`` is the total arrival rate in new data frames per frame time T (40 bytes at the
child's 16640 ticks a byte = 665 600 ticks = 41.6 ms).

Measured over [warmup, duration) (transmissions by start tick):
* G: channel attempts per frame time: air time of every transmission (data and ack frames)
  / window length. Slotted ALOHA counts transmissions per slot instead. CSMA: data frames
  offered, i.e. every sensing of a ready data frame (a busy one reschedules and counts again,
  as in Kleinrock-Tobagi), x T / window.
* S: successful (not collided) air time / window, acks included (slotted: successful
  transmissions per slot). ``util`` is the plain air-time utilisation for every MAC.
* goodput: acknowledged data frames x T / window; delay: mean submit -> acknowledged (ms).
* CSMA's a = (Ttrans + one byte time) / T: a station that senses idle is heard by the others
  only Ttrans (its RX->TX switch) plus one byte (the first byte's stop bit) after deciding.
"""
from __future__ import annotations

if __name__ == "__main__":     # a Python without the project says so in one line
    from _project import require_project    # benchmarks/ is sys.path[0] here
    require_project()

import argparse
import math
import random
import sys
import time

from firmware_model.radio.mac import MacConfig, Outcome, SubmitError
from firmware_model.radio.peer_macs import PeerConfig, install
from firmware_model.timing import CHILD_BYTE_TICKS, FRAME_OVERHEAD, TICK_HZ, TTRANS_TICKS
from hil.sim.load import filled_commands
from hil.sim.world import SimConfig, World

FRAME_BYTES = 40
T_FRAME = FRAME_BYTES * CHILD_BYTE_TICKS
A_CSMA = (TTRANS_TICKS + CHILD_BYTE_TICKS) / T_FRAME
ACK_BYTES = FRAME_OVERHEAD + len("ack(1,23)")
"""An ack-only frame: 23 bytes."""


def analytic(kind: str, g: float, a: float = A_CSMA, n: int | None = None) -> float:
    """Textbook throughput at offered load ``g`` (infinite population), or the refined model
    with ``n`` stations: pure ALOHA, each station a Poisson source that never overlaps itself,
    S = G e^(-2G(n-1)/n); slotted, each station sends in a slot with probability G/n,
    S = G (1 - G/n)^(n-1). CSMA: Kleinrock-Tobagi (see also :func:`csma_with_acks`)."""
    if kind == "aloha":
        return g * math.exp(-2 * g * (1 if n is None else (n - 1) / n))
    if kind == "slotted":
        if n is not None:
            return g * max(0.0, 1 - g / n) ** (n - 1)
        return g * math.exp(-g)
    if kind == "csma":
        e = math.exp(-a * g)
        return g * e / (g * (1 + 2 * a) + e)
    if kind == "rotational":
        return T_FRAME / (T_FRAME + TTRANS_TICKS)
    raise ValueError(kind)


def csma_with_acks(g: float, a: float = A_CSMA,
                   ack: float = ACK_BYTES * CHILD_BYTE_TICKS / T_FRAME,
                   tail: float = (TTRANS_TICKS + 2 * CHILD_BYTE_TICKS) / T_FRAME) -> float:
    """Kleinrock-Tobagi's renewal argument with this MAC's ack exchange: every successful data
    frame (probability e^-aG) is followed by its ack, sent unsensed Ttrans later under the
    others' ack guard, which adds ``tail + ack`` to that busy period and ``ack`` to the useful
    air time. ``g``: data frames offered (every sensing) per T. Returns S counting data and
    ack air time, like the measurement."""
    p = math.exp(-a * g)
    busy = 1 + 2 * a - (1 - p) / g
    return p * (1 + ack) / (busy + p * (tail + ack) + 1 / g)


def _commands(content_bytes: int):
    cmds = filled_commands(content_bytes)
    n = sum(len(c.text()) for c in cmds)
    if n != content_bytes:
        raise ValueError(f"cannot make {content_bytes} Content bytes exactly (got {n})")
    return cmds


def measure(kind: str, lam: float | None, robots=(0, 1, 2, 3, 4, 5, 6), duration: float = 20.0,
            warmup: float = 2.0, seed: int = 1, frame_bytes: int = FRAME_BYTES,
            peer: PeerConfig | None = None, mac: MacConfig | None = None,
            drain: float = 0.0) -> dict:
    """One run. ``lam``: total new data frames per frame time (Poisson); None = saturated
    (every robot always has two messages queued). ``drain``: seconds after ``duration`` with
    no new arrivals, so every message ends (the accounting invariant)."""
    cmds = _commands(frame_bytes - FRAME_OVERHEAD)
    world = World(SimConfig(robots=tuple(robots), duration=duration + drain, seed=seed,
                            mac=mac))
    if kind != "rotational":
        install(world, kind, peer or PeerConfig(frame_bytes=frame_bytes))
    sched = world.sched
    t0 = round(warmup * TICK_HZ)
    t1 = round(duration * TICK_HZ)
    stats = dict(tx=0, tx_ok=0, air=0, air_ok=0, delivered=0, failed=0, delay=0, delay_n=0,
                 submitted=0, refused=0)
    reasons: dict[str, int] = {}

    orig_tx = world.air.on_transmission

    def on_tx(tx) -> None:
        orig_tx(tx)
        if t0 <= tx.t0 < t1:
            air = tx.end - tx.t0
            stats["tx"] += 1
            stats["air"] += air
            if not tx.collided:
                stats["tx_ok"] += 1
                stats["air_ok"] += air
    world.air.on_transmission = on_tx

    rngs = {r: random.Random(f"{seed}:peerload:{r}") for r in robots}
    others = {r: [x for x in robots if x != r] for r in robots}
    per_tick = None if lam is None else lam / len(robots) / T_FRAME   # arrivals per tick

    def submit(r: int) -> None:
        if sched.now >= t1:
            return
        try:
            world.submit(r, rngs[r].choice(others[r]), cmds)
            stats["submitted"] += 1
        except SubmitError:
            stats["refused"] += 1

    def arrival(r: int) -> None:
        if sched.now >= t1:
            return
        submit(r)
        sched.after(max(1, round(rngs[r].expovariate(per_tick))), arrival, r)

    def wrap(st) -> None:
        def obs(station, a, now):
            if type(a) is Outcome:
                m = a.message
                if a.delivered:
                    stats["delivered"] += 1
                    if m.submitted >= t0:
                        stats["delay"] += now - m.submitted
                        stats["delay_n"] += 1
                else:
                    stats["failed"] += 1
                    key = a.reason.split(" from ")[0].split(":")[0]
                    reasons[key] = reasons.get(key, 0) + 1
                if lam is None:
                    submit(station.id)
        st.add_observer(obs)

    for r, st in world.stations.items():
        wrap(st)
        if lam is None:
            sched.at(0, lambda r=r: (submit(r), submit(r)))
        else:
            sched.after(max(1, round(rngs[r].expovariate(per_tick))), arrival, r)
    snaps: list[int] = []
    if kind == "csma":
        def snap() -> None:
            snaps.append(sum(st.mac.sense_attempts for st in world.stations.values()))
        sched.at(t0, snap)
        sched.at(t1, snap)
    t_cpu = time.process_time()
    world.run()
    cpu = time.process_time() - t_cpu
    win = t1 - t0
    macs = [st.mac for st in world.stations.values()]
    if kind == "slotted":
        slot = macs[0].slot
        g = stats["tx"] * slot / win
        s = stats["tx_ok"] * slot / win
    else:
        g = stats["air"] / win
        s = stats["air_ok"] / win
    summ = world.summary()
    out = dict(kind=kind, lam=lam, G=g, S=s, util=stats["air_ok"] / win,
               goodput=stats["delay_n"] * T_FRAME / win,
               collided=1 - stats["tx_ok"] / stats["tx"] if stats["tx"] else 0.0,
               tx=stats["tx"], cpu=cpu, reasons=reasons,
               submitted=stats["submitted"], refused=stats["refused"],
               delivered=stats["delivered"], failed=stats["failed"],
               pending=sum(m.pending for m in macs),
               delay_ms=(stats["delay"] / stats["delay_n"] * 1000 / TICK_HZ
                         if stats["delay_n"] else float("nan")),
               duplicate_deliveries=summ["duplicate_deliveries"],
               corrupt_deliveries=summ["corrupt_deliveries"])
    n = len(robots)
    if kind == "csma":
        out["G_kt"] = (snaps[1] - snaps[0]) * T_FRAME / win
        tot = sum(m.sense_attempts for m in macs)
        out["busy"] = sum(m.sense_busy for m in macs) / tot if tot else 0.0
        out["model"] = analytic("csma", out["G_kt"])
        out["model_n"] = csma_with_acks(out["G_kt"])
    elif kind == "rotational":
        mean_air = stats["air"] / stats["tx"] if stats["tx"] else T_FRAME
        out["model"] = out["model_n"] = mean_air / (mean_air + TTRANS_TICKS)
    else:
        out["model"] = analytic(kind, g)
        out["model_n"] = analytic(kind, g, n=n)
    return out


GRID = {
    # New-load rates picked so the measured G spans about 0.1 ... 3 (7 robots, seed 1).
    "aloha": (0.05, 0.1, 0.15, 0.25, 0.5, 0.7),
    "slotted": (0.03, 0.07, 0.13, 0.2, 0.4, 0.6),
    "csma": (0.05, 0.1, 0.2, 0.3, 0.4, 1.0),
}
QUICK = {"aloha": (0.1, 0.15, 0.5), "slotted": (0.07, 0.2, 0.6), "csma": (0.1, 0.3, 1.0)}
TOL = 0.05
"""A row "fits" when |S - S refined| <= TOL."""


def _fmt(r: dict) -> str:
    g = r.get("G_kt", r["G"])
    lam = "saturated" if r["lam"] is None else f"{r['lam']:.2f}"
    gtxt = f"{g:.2f}" + (f" (tx {r['G']:.2f})" if "G_kt" in r else "")
    fit = "yes" if abs(r["S"] - r["model_n"]) <= TOL else "no"
    delay = "-" if math.isnan(r["delay_ms"]) else f"{r['delay_ms']:.0f}"
    return (f"| {r['kind']} | {lam} | {gtxt} | {r['S']:.3f} | {r['model']:.3f} | "
            f"{r['model_n']:.3f} | {fit} | {r['util']:.3f} | {r['goodput']:.3f} | "
            f"{r['collided']:.0%} | {delay} | {r['delivered']}/{r['failed']} |")


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="shorter runs, fewer points")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--robots", default="0,1,2,3,4,5,6")
    p.add_argument("--kinds", default="aloha,slotted,csma,rotational")
    a = p.parse_args(argv)
    robots = tuple(int(x) for x in a.robots.split(","))
    duration, warmup = (20.0, 2.0) if a.quick else (120.0, 3.0)
    n = len(robots)
    print(f"{n} robots {list(robots)}, seed {a.seed}, 40-byte data frames (T = {T_FRAME} ticks "
          f"= {T_FRAME * 1000 / TICK_HZ:.1f} ms), Ttrans = {TTRANS_TICKS} ticks, CSMA a = "
          f"(Ttrans + 1 byte) / T = {A_CSMA:.3f}, measured over {warmup:g}-{duration:g} s "
          f"(rotational: {warmup + 15:g}-{duration + 15:g} s, after the ring forms)\n")
    print(f"| MAC | new λ /T | G | S | S textbook | S refined | fits ±{TOL} | air util | "
          f"goodput | collided tx | delay ms | delivered/failed |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    t_all = time.process_time()
    fits = total = 0
    for kind in a.kinds.split(","):
        if kind == "rotational":
            rows = [measure("rotational", None, robots, duration + 15.0, warmup + 15.0, a.seed)]
        else:
            grid = QUICK[kind] if a.quick else GRID[kind]
            rows = [measure(kind, lam, robots, duration, warmup, a.seed) for lam in grid]
        for r in rows:
            print(_fmt(r))
            sys.stdout.flush()
            if kind != "rotational":
                total += 1
                fits += abs(r["S"] - r["model_n"]) <= TOL
    print(f"\n{fits}/{total} peer rows within ±{TOL} of the refined model; CPU "
          f"{time.process_time() - t_all:.0f} s.")
    print("G: channel attempts (data and ack frames) per frame time T; slotted: per slot; "
          "CSMA: data frames offered, every sensing counted (its transmissions in brackets). "
          "S: successful air time / time (slotted: successful slots / slots), acks included. "
          "Textbook (infinite population): pure ALOHA G e^-2G (max 0.184 at G = 0.5), slotted "
          "G e^-G (max 0.368 at G = 1), non-persistent CSMA G e^-aG / (G(1+2a) + e^-aG) (max "
          f"0.449 at G = 2.0 for a = {A_CSMA:.3f}). Refined: ALOHAs with N = {n} stations "
          "(pure G e^-2G(N-1)/N, slotted G (1-G/N)^(N-1)); CSMA with the ack exchange "
          "(csma_with_acks). Rotational: L / (L + Ttrans) for its mean frame L.")


if __name__ == "__main__":
    main()
