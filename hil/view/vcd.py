"""Value Change Dump (VCD) waveform of a trace, for GTKWave (docs/visualisation.md).

Timescale ``100 ps``: one 16 MHz tick (62.5 ns) is exactly 625 units, so every trace event
lands on its exact tick. Signals (scope ``rprs``):

``rprs.owner``      3-bit integer: Source of the frame on air, held after its End until the next
                    frame starts (the last turn owner); ``x`` during a collision and before the
                    first frame.
``rprs.collision``  1 while two or more transmissions (frames, interference) are on air.
``rprs.interference`` 1 while bytes from no robot are on air (``interference`` events:
                    injected bytes, ``burst`` faults).
``rprs.can_<r>``    11-bit ID of the CAN frame on child ``r``'s bus from SOF to end of EOF, ``z``
                    between frames (only in a ``--can`` trace).
``rprs.R<r>.txen``  the robot's TXEN pin (``pc2_txen`` too for the father's standby PC).
``rprs.R<r>.tx``    1 from the first bit of the robot's frame to the last bit of its End
                    (``pc2_tx`` for the father's standby PC's frames: ``tx`` is PC1's).
``rprs.R<r>.rx``    1 while another robot's frame is on air and this robot's TXEN is low;
                    ``x`` when what is on air is garbage (a collision, interference), ``z``
                    while the robot's radio is failed (``fault`` fail .. recover).
``rprs.R<r>.miss``  an event (arrow in GTKWave) at the tick a miss of this robot is first reported
                   (its observers' reports of one miss, a tick or a handler apart, are one).

Frames and CAN frames are logged at their end (``t`` = ``end``), so changes are reordered
through a bounded look-back buffer (twice Tmax): memory does not grow with the trace length.
The output is written to ``PATH.PID.partial`` and renamed when complete, so a failed run leaves no
partial file (a device or a FIFO is written straight: ``hil.sim.trace.OutputFile``).
"""
from __future__ import annotations

import heapq
from fractions import Fraction
from typing import Any, Iterable, Iterator

from vcd import VCDWriter

from ..sim.events import (CanFrameOnBus, FaultEdge, FrameOnAir, Interference, Meta, Miss,
                          OtherEvent, TraceError, TxenEdge, typed)
from ..sim.ledger import SameHappening
from ..sim.trace import OutputFile

__all__ = ["VcdError", "VcdTraceWriter", "write_vcd", "TIMESCALE", "checked_events",
           "TickReorder"]

TIMESCALE = "100 ps"
"""VCD time unit; 625 units a 16 MHz tick."""

_TIMESCALES = [(m, u, Fraction(m) * f) for u, f in
               (("s", Fraction(1)), ("ms", Fraction(1, 10**3)), ("us", Fraction(1, 10**6)),
                ("ns", Fraction(1, 10**9)), ("ps", Fraction(1, 10**12)),
                ("fs", Fraction(1, 10**15))) for m in (100, 10, 1)]


class VcdError(ValueError):
    """The VCD file cannot be written (bad output path). Unusable input raises
    :class:`hil.sim.trace.TraceError` (also a ``ValueError``)."""


def timescale_for(tick_hz: int) -> tuple[str, int]:
    """The coarsest standard VCD timescale in which one tick is a whole number of units:
    ``("100 ps", 625)`` for 16 MHz."""
    tick = Fraction(1, tick_hz)
    for mag, unit, size in _TIMESCALES:
        units = tick / size
        if units.denominator == 1:
            return f"{mag} {unit}", int(units)
    raise TraceError(f"tick_hz {tick_hz} has no exact VCD timescale (1 fs resolution)")


# -- input checking shared with hil.view.plot ---------------------------------------------------

def checked_events(events: Iterable[Any]) -> tuple[Meta, Iterator[tuple[int, Any]]]:
    """Read ``events`` (records or typed events, hil/sim/events.py: the meta first) and
    return the meta and an iterator of ``(number, event)`` for the rest that checks the ticks
    do not go back (event 1 is the meta). TraceError for anything unreadable."""
    it = typed(events)
    meta = next(it)
    assert isinstance(meta, Meta)              # (typed() gives the meta first)

    def rest() -> Iterator[tuple[int, Any]]:
        last = 0
        for n, ev in enumerate(it, 2):
            if ev.t < last:
                raise TraceError(f"event {n} ({_kind(ev)}): tick {ev.t} is before tick {last} "
                                 f"of the event before (events out of order)")
            last = ev.t
            yield n, ev

    return meta, rest()


def _kind(ev: Any) -> str:
    return ev.kind if isinstance(ev, OtherEvent) else ev.KIND


class TickReorder:
    """Items logged late (a frame at its end) come out in tick order: push ``(tick, item)``
    with ``tick`` at most ``lookback`` before the newest event's tick; ``ready(now)`` pops
    everything before ``now - lookback``."""

    def __init__(self, lookback: int) -> None:
        self.lookback = lookback
        self._heap: list[tuple[int, int, int, Any]] = []
        self._seq = 0
        self.done = -1     # every item before this tick has been popped

    def push(self, tick: int, item: Any, prio: int = 0, n: int = 0) -> None:
        if tick < self.done:
            raise TraceError(f"event {n}: tick {tick} lies more than {self.lookback} ticks "
                             f"before the event's own tick (frame longer than 2 Tmax?)")
        self._seq += 1
        heapq.heappush(self._heap, (tick, prio, self._seq, item))

    def ready(self, now: int | None) -> Iterator[tuple[int, Any]]:
        """Pop items in (tick, prio, push order) before ``now - lookback`` (all if None)."""
        limit = None if now is None else now - self.lookback
        h = self._heap
        while h and (limit is None or h[0][0] < limit):
            tick, _, _, item = heapq.heappop(h)
            self.done = max(self.done, tick)
            yield tick, item
        if limit is not None:
            self.done = max(self.done, limit)

    def __len__(self) -> int:
        return len(self._heap)


# -- the writer ----------------------------------------------------------------------------

class VcdTraceWriter:
    """Stream trace events into a VCD file: ``write(ev)`` each event (meta first), then
    ``close()`` (returns the summary) or ``discard()``. Usable as ``World(on_event=w.write)``.
    """

    def __init__(self, path: str) -> None:
        self.path = path
        try:
            self._out = OutputFile(path)
        except OSError as exc:
            raise VcdError(f"cannot write VCD {path}: {exc.strerror}") from None
        self._f = self._out.f
        self._w: VCDWriter | None = None
        self._n = 0
        self._closed = False

    # state, set up by the meta event
    def _start(self, meta: Meta) -> None:
        self.meta = meta
        self.tick_hz = meta.tick_hz
        timescale, self.units = timescale_for(self.tick_hz)
        self.timescale = timescale
        self.robots: list[int] = sorted(meta.robots)
        self.buses = [r for r in self.robots if r != 0] if meta.can_bitrate is not None else []
        self.lookback = 2 * meta.tmax + 2 * meta.ttrans
        self._q = TickReorder(self.lookback)
        ring = ",".join(str(r) for r in self.robots)
        w = VCDWriter(self._f, timescale=timescale, date="(simulated)",
                      version="rprs hil.view.vcd",
                      comment=f"RPRS ring {ring} seed {meta.seed} "
                              f"tick {10**9 / self.tick_hz:g} ns = {self.units} units")
        self._w = w
        self.v_owner = w.register_var("rprs", "owner", "integer", size=3, init="x")
        self.v_coll = w.register_var("rprs", "collision", "wire", size=1, init=0)
        self.v_noise = w.register_var("rprs", "interference", "wire", size=1, init=0)
        self.v_can = {b: w.register_var("rprs", f"can_{b}", "wire", size=11, init="z")
                      for b in self.buses}
        self.v_txen, self.v_tx, self.v_rx, self.v_miss = {}, {}, {}, {}
        for r in self.robots:
            sc = f"rprs.R{r}"
            self.v_txen[(r, 1)] = w.register_var(sc, "txen", "wire", size=1, init="x")
            if r == 0:
                self.v_txen[(0, 2)] = w.register_var(sc, "pc2_txen", "wire", size=1, init="z")
                self.v_pc2_tx = w.register_var(sc, "pc2_tx", "wire", size=1, init=0)
            self.v_tx[r] = w.register_var(sc, "tx", "wire", size=1, init=0)
            self.v_rx[r] = w.register_var(sc, "rx", "wire", size=1, init=0)
            self.v_miss[r] = w.register_var(sc, "miss", "event")
        # live state
        self.on_air: dict[int, int] = {}        # frame id -> src
        self.txen = {r: False for r in self.robots}
        self.dead: set[int] = set()
        self.can_on: dict[int, list[int]] = {b: [] for b in self.buses}
        self.owner: int | str = "x"
        self._fid = 0
        self._misses = SameHappening(meta.tmax // 2)
        self._deaf: set[int] = set()       # robots whose radio has failed, as events are fed
        self.frames = self.collided = self.can_frames = self.misses = self.interference = 0
        self.last_tick = 0

    def write(self, ev: Any) -> None:
        """Add one event (hil/sim/events.py; the meta event first): a world's listener."""
        if self._closed:
            raise VcdError("VCD writer already closed")
        self._n += 1
        n = self._n
        if n == 1:
            if not isinstance(ev, Meta):
                raise TraceError("the first event must be the meta event")
            self._start(ev)
            return
        t = ev.t
        if t < self.last_tick:
            raise TraceError(f"event {n} ({_kind(ev)}): tick {t} is before tick "
                             f"{self.last_tick} of the event before (events out of order)")
        self.last_tick = t
        kind = type(ev)
        q = self._q
        if kind is FrameOnAir:
            src = self._robot(ev.src, "frame", n)
            start, end = ev.start, ev.end
            if not start <= end:
                raise TraceError(f"event {n} (frame): start {start} is after end {end}")
            self._fid += 1
            self.frames += 1
            self.collided += ev.collided
            fid = -self._fid if src == 0 and ev.pc == 2 else self._fid   # (< 0: PC2's)
            q.push(start, ("fs", fid, src), 1, n)
            q.push(end, ("fe", fid, src), 0, n)
        elif kind is TxenEdge:
            r = self._robot(ev.robot, "txen", n)
            q.push(t, ("txen", (r, 2 if ev.pc == 2 and r == 0 else 1), ev.on), 2, n)
        elif kind is FaultEdge:
            hit = None if ev.robot is None else self._robot(ev.robot, "fault", n)
            if hit is not None and ev.kind in ("fail", "recover"):
                down = (ev.kind == "fail") == (ev.phase != "end")
                q.push(t, ("dead", hit, down), 2, n)
                if down:
                    self._deaf.add(ev.robot)
                else:
                    self._deaf.discard(ev.robot)
        elif kind is Interference:
            start, end = ev.start, ev.end
            if not start <= end:
                raise TraceError(f"event {n} (interference): start {start} is after end {end}")
            self._fid += 1
            self.interference += 1
            q.push(start, ("fs", self._fid, -1), 1, n)
            q.push(end, ("fe", self._fid, -1), 0, n)
        elif kind is Miss:
            r = self._robot(ev.robot, "miss", n)
            # a miss as the run's summary counts them: reported by a robot that could hear
            # the air (not one whose radio had failed), once for all its observers (whose
            # reports come a tick or a handler apart on the CPU model)
            if ev.by not in self._deaf and self._misses.first("miss", r, t):
                self.misses += 1
                q.push(t, ("miss", r), 2, n)
        elif kind is CanFrameOnBus:
            b = ev.bus
            if b not in self.v_can:
                raise TraceError(f"event {n} (can): bus {b} is not a child of the ring "
                                 f"{self.robots} (or the meta line lacks can_bitrate)")
            cid, start, end = ev.id, ev.start, ev.end
            if not 0 <= cid < 2048:
                raise TraceError(f"event {n} (can): id {cid} is not an 11-bit identifier")
            if not start <= end:
                raise TraceError(f"event {n} (can): start {start} is after end {end}")
            self.can_frames += 1
            q.push(start, ("cs", b, cid), 1, n)
            q.push(end, ("ce", b, cid), 0, n)
        self._flush(t)

    def _robot(self, r: int, kind: str, n: int) -> int:
        if r not in self.v_tx:
            raise TraceError(f"event {n} ({kind}): robot {r} is not in the ring "
                             f"{self.robots} of the meta line")
        return r

    def _flush(self, now: int | None) -> None:
        """Apply every edge that can no longer be preceded by a late one, a tick at a time."""
        batch: list[tuple[int, Any]] = []
        for tick, item in self._q.ready(now):
            if batch and tick != batch[0][0]:
                self._apply(batch)
                batch = []
            batch.append((tick, item))
        if batch:
            self._apply(batch)

    def _apply(self, batch: list[tuple[int, Any]]) -> None:
        """All the edges at one tick, then the derived signals once (no zero-width glitch)."""
        w = self._w
        assert w is not None                    # (the meta line came first)
        ts = batch[0][0] * self.units
        for _, item in batch:
            k = item[0]
            if k == "fs":
                self.on_air[item[1]] = item[2]
            elif k == "fe":
                self.on_air.pop(item[1], None)
            elif k == "txen":
                (r, pc), on = item[1], item[2]
                w.change(self.v_txen[(r, pc)], ts, int(on))
                if pc == 1:
                    self.txen[r] = on
            elif k == "dead":
                (self.dead.add if item[2] else self.dead.discard)(item[1])
            elif k == "miss":
                w.change(self.v_miss[item[1]], ts, True)
            elif k == "cs":
                self.can_on[item[1]].append(item[2])
            elif k == "ce":
                if item[2] in self.can_on[item[1]]:
                    self.can_on[item[1]].remove(item[2])
        srcs = list(self.on_air.values())          # -1: interference, no robot
        busy = len(srcs)
        noise = -1 in srcs
        w.change(self.v_coll, ts, int(busy >= 2))
        w.change(self.v_noise, ts, int(noise))
        if busy == 1 and not noise:
            self.owner = srcs[0]
        elif busy >= 2:
            self.owner = "x"
        w.change(self.v_owner, ts, self.owner)
        pc2 = any(fid < 0 for fid in self.on_air)
        for r in self.robots:
            mine = r in srcs
            if r == 0 and 0 in self.v_tx:
                w.change(self.v_pc2_tx, ts, int(pc2))
                w.change(self.v_tx[0], ts, int(any(fid > 0 and src == 0
                                                   for fid, src in self.on_air.items())))
            else:
                w.change(self.v_tx[r], ts, int(mine))
            others = busy - srcs.count(r)
            if r in self.dead:
                rx: int | str = "z"
            elif self.txen[r] or mine or others == 0:
                rx = 0
            elif busy >= 2 or noise:
                rx = "x"
            else:
                rx = 1
            w.change(self.v_rx[r], ts, rx)
        for b, on in self.can_on.items():
            w.change(self.v_can[b], ts, on[0] if len(on) == 1 else ("z" if not on else "x"))

    def close(self) -> dict:
        """Finish the file (atomically renamed into place); return a summary."""
        if self._closed:
            raise VcdError("VCD writer already closed")
        try:
            if self._n == 0:
                raise TraceError("empty trace: no meta line")
            self._flush(None)
            end = max(self.last_tick, int(self.meta.duration_ticks or 0))
            assert self._w is not None          # (the meta line came first)
            self._w.close(end * self.units)
            self._out.commit()
        except BaseException:
            self.discard()
            raise
        self._closed = True
        return {"path": self.path, "timescale": self.timescale, "units_per_tick": self.units,
                "robots": self.robots, "frames": self.frames, "collided_frames": self.collided,
                "misses": self.misses, "can_frames": self.can_frames,
                "interference": self.interference, "end_tick": end,
                "signals": 3 + len(self.buses) + 4 * len(self.robots) + 2 * (0 in self.robots)}

    def discard(self) -> None:
        """Drop the partial file."""
        self._closed = True
        self._out.discard()


def write_vcd(events: Iterable[Any], path: str) -> dict:
    """Write the VCD waveform of a trace's events (records or typed events, the meta first)
    to ``path``, atomically.

    Returns a summary: ``path``, ``timescale``, ``units_per_tick``, ``robots``, ``frames``,
    ``collided_frames``, ``misses`` (deduplicated), ``can_frames``, ``interference``,
    ``end_tick``, ``signals``.
    Raises :class:`hil.sim.trace.TraceError` for unusable events (nothing is left at ``path``) and
    :class:`VcdError` when the file cannot be created. Both are ``ValueError``s.
    """
    w = VcdTraceWriter(path)
    try:
        for ev in typed(events):
            w.write(ev)
    except BaseException:
        w.discard()
        raise
    return w.close()
