"""Error signalling on the simulated CAN bus (can_bus.bus): a frame destroyed by a bit, stuff or
ACK error, and a node's local errors, with the ISO 11898-1 error counters they move.
Plain functions bound as methods of :class:`~can_bus.bus.CanBus`."""
from __future__ import annotations

from typing import TYPE_CHECKING

from can_bus.bits import ERROR_DELIMITER_BITS, ERROR_FLAG_BITS, IFS_BITS, SUSPEND_TRANSMISSION_BITS
from can_bus.bus_state import (_ELEVEN, _TAIL, ACTIVE, BUS_OFF, ERROR_FRAME_TOTAL_BITS, PASSIVE,
                               CanErrorEvent, _arbitration_end, _frame_info, _Node)

if TYPE_CHECKING:
    from can_bus.bus import CanBus


def _frame_error(self: CanBus, kind: str) -> None:
    now = self.sched.now
    tpb = self.tpb
    frame = self._cur_frame
    idle_at = now + ERROR_FRAME_TOTAL_BITS * tpb
    self._phase = _TAIL
    self._busy_until = idle_at
    self.error_frames += 1
    rx = self._cur_rx
    passive_ack = kind == "ack" and bool(rx) and all(ns.state is PASSIVE
                                                     for ns in self._cur_tx)
    if passive_ack:
        # Every transmitter is error-passive: its ACK error flag is recessive, so the
        # receivers (which do not check the ACK slot) saw no error, whether the ACK came back
        # late or nobody could drive it: they take the frame at its end, not REC + 1 (ISO
        # 11898-1 exception 1).
        self.sched.at(self._cur_start + len(_frame_info(frame)[0]) * tpb,
                      self._late_ack_received, frame, self._cur_start, self._cur_tx[0],
                      list(rx))
        rx = []
    all_passive = True
    for ns in self._cur_tx:
        if not (kind == "ack" and ns.state is PASSIVE):
            ns.tec += 8
            self._update(ns, now)
        if ns.state is ACTIVE:
            all_passive = False
        if ns.state is PASSIVE:
            ns.suspend_until = idle_at + SUSPEND_TRANSMISSION_BITS * tpb
            self._watch = True
        ns.entry = None
    for ns in rx:
        if ns.state is BUS_OFF:
            continue
        ns.rec += 1
        self._update(ns, now)
        if ns.state is ACTIVE:
            all_passive = False
    trailing = _ELEVEN
    if all_passive:
        if kind == "ack":
            trailing = _frame_info(frame)[2] + 2 + ERROR_FRAME_TOTAL_BITS
        else:
            trailing = ERROR_FRAME_TOTAL_BITS
    self._seg_ev = self.sched.at(idle_at, self._segment_end, trailing)
    if self.error_trace is not None:
        self.error_trace(kind, frame, self._cur_start, now, idle_at, self._cur_tx[0].node)
    for ns in self._cur_tx:
        if ns.on_error is not None and ns.attached:
            ns.on_error(CanErrorEvent(kind, now, frame, True, ns.tec, ns.rec, ns.state))
    for ns in rx:
        if ns.on_error is not None and ns.attached and ns.state is not BUS_OFF:
            ns.on_error(CanErrorEvent(kind, now, frame, False, ns.tec, ns.rec, ns.state))


def _local_errors(self: CanBus, rx: list[_Node], wire, nstuffed: int,
                  err: tuple[int, str] | None):
    """The earliest error one receiver alone sees in this frame, as (its bit b, that
    node, where each node detects it {node: (bit, kind)}, E: the last bit of the
    superposed error flags), or None. An error-passive node's flag is recessive: it
    loses the frame and nobody else notices (``_cur_deaf``)."""
    lo = _arbitration_end(wire) + 1
    best = None
    for ns in rx:
        key = id(ns)
        if ns.state is BUS_OFF or (key not in self._local and key not in self._noisy):
            continue
        queued = self._local.get(key)
        bit = queued[0] if queued else self._noisy.get(key)
        b = min(max(nstuffed - 1 if bit is None else bit, lo), nstuffed - 1)
        if queued:
            queued.pop(0)
            if not queued:
                del self._local[key]
        if err is not None and err[0] <= b:
            continue                       # an error everyone sees comes first
        if ns.state is PASSIVE:
            # _local_errors runs just after _cur_deaf = set(): a set of its own here
            self._cur_deaf.add(key)  # type: ignore[union-attr]
            continue
        if best is None or b < best[0]:
            best = (b, ns)
    if best is None:
        return None
    b, first = best
    z = 0                                  # dominant bits in a row up to bit b
    while z <= b and wire[b - z] == 0:
        z += 1
    # the others: a transmitter sees its first recessive bit read dominant (a bit error);
    # a receiver, the sixth dominant bit in a row (stuff error) or a dominant CRC
    # delimiter (form error), whichever comes first
    d_tx = next(i for i in range(b + 1, b + 7) if i >= nstuffed or wire[i] == 1)
    d_rx, k_rx = (b + 6 - z, "stuff") if b + 6 - z < nstuffed else (nstuffed, "form")
    seen = {ns: (d_tx, "bit") for ns in self._cur_tx}
    seen.update({ns: (d_rx, k_rx) for ns in rx if ns is not first})
    seen[first] = (b, "local")
    # only an error-active node's flag is dominant; the first detector's always is
    end = max(d + ERROR_FLAG_BITS for ns, (d, _) in seen.items() if ns.state is ACTIVE)
    return b, first, seen, end


def _local_error(self: CanBus, local) -> None:
    """A local error's error frame: the flags of the first node and of everyone who then
    detects it overlap into 6-12 dominant bits (ISO 11898-1 error signalling). TEC + 8 for
    the transmitter; REC + 1 for every receiver, and + 8 more for a receiver that reads a
    dominant bit right after its own flag (the first detector, whenever the others'
    flags outlast its own)."""
    b, first, seen, end = local
    now = self.sched.now
    tpb = self.tpb
    frame = self._cur_frame
    start = self._cur_start
    idle_at = start + (end + 1 + ERROR_DELIMITER_BITS + IFS_BITS) * tpb
    self._phase = _TAIL
    self._busy_until = idle_at
    self.error_frames += 1
    for ns in self._cur_tx:
        ns.tec += 8
        self._update(ns, now)
        if ns.state is PASSIVE:
            ns.suspend_until = idle_at + SUSPEND_TRANSMISSION_BITS * tpb
            self._watch = True
        ns.entry = None
    for ns in self._cur_rx:
        if ns.state is BUS_OFF:
            continue
        d, _ = seen[ns]
        after = 8 if ns.state is ACTIVE and d + ERROR_FLAG_BITS < end else 0
        ns.rec += 1 + after
        self._update(ns, now)
    self._seg_ev = self.sched.at(idle_at, self._segment_end, _ELEVEN)
    if self.error_trace is not None:
        self.error_trace("local", frame, start, now, idle_at, self._cur_tx[0].node)
    for group, is_tx in ((self._cur_tx, True), (self._cur_rx, False)):
        for ns in group:
            if ns.on_error is not None and ns.attached and ns.state is not BUS_OFF:
                d, kind = seen[ns]
                ns.on_error(CanErrorEvent(kind, start + d * tpb, frame, is_tx, ns.tec,
                                          ns.rec, ns.state))
