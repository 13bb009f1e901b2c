"""A simulated CAN 2.0A bus on any integer-tick clock (:class:`~can_bus.clock.Clock`).

Timing is bit-exact (every length is a whole number of bit times, stuff bits included) but the
bus is event driven: a frame costs two scheduler events (end of EOF, end of intermission), never
one per bit.

Nodes
-----
A node is any object; the bus looks up these optional methods once, at :meth:`CanBus.attach`
(:mod:`can_bus.node` declares them as Protocols a node's class names, and ``attach`` refuses a
node that names one and lacks a hook, or has a misspelt one):

* ``pending() -> CanFrame | None``: the node's highest-priority frame waiting to be sent. If the
  node has it, the node keeps its own queue and the bus asks at every arbitration; otherwise the
  bus keeps a per-node priority queue filled by ``bus.request(node, frame)``.
* ``pending_after_request`` (optional, read at attach): True promises that ``pending()`` has no
  side effect when it returns None and returns None until the node next calls
  ``bus.request(node)``; the bus then stops asking it once it had nothing, until its next
  request (a submodule's six status frames a period would otherwise be asked for at every
  arbitration of the bus). Without it the node is asked at every arbitration (an 82C250 in
  standby watches for SOFs that way).
* ``on_frame(frame, start_tick, end_tick)``: a frame was received (every node that is not
  bus-off receives every frame it did not send; filtering is the node's business).
* ``rx_ids`` (optional, read at attach): a frozenset of the identifiers whose frames the node
  acts on; it promises that ``on_frame`` does nothing with any other, so the bus does not call
  it for them (acceptance decided once per identifier and node: a submodule hears its command
  and ESTOP, not the other submodules' six status frames a period). The node still receives
  every frame as far as the error counters go (REC).
* ``acknowledges`` (optional; if the node has it when attached, read at each frame): False
  while the node cannot drive the ACK slot (a halted controller, a transceiver in standby);
  with no receiver that can, the frame ends in an ACK error. A node without it always can.
* Its loop delay (TXD to RXD through its transceiver), set with :meth:`CanBus.set_loop_delay`
  (default: a high-speed 82C250). A transmitter that gets no acknowledging receiver's ACK back
  within the bit timing's round-trip budget (:mod:`can_bus.physical`: ``(tseg1 - sjw)``
  quanta for both loop delays and twice the bus's ``length_m`` of cable) sees an ACK error.
  If it is error-active its flag destroys the frame for everyone; if every transmitter is
  error-passive its flag is recessive, so the receivers take the frame (and take it again
  at each retry) while the transmitter keeps its TEC (ISO 11898-1 exception 1).
* ``on_tx_done(frame, end_tick)``: the node's frame was sent and acknowledged. A node with its
  own queue removes the frame here.
* ``on_arbitration_lost(frame)``: called at the SOF tick of the frame that beat ``frame``.
* ``on_error(event: CanErrorEvent)``: the node detected an error (its counters already updated).
* ``on_state_change(old: ErrorState, new: ErrorState, tick)``.

``start_tick`` is the SOF tick, ``end_tick`` the end of the last EOF bit; the bus is free for
the next SOF 3 bit times (intermission) later. ``bus.trace(frame, start, end, winner)`` sees
every successful frame; ``bus.error_trace(kind, frame, start, flag_tick, idle_tick, node)``
every destroyed one (``idle_tick`` is None for a stuck-dominant episode, whose end is unknown
when the error is detected).

Arbitration
-----------
When the bus becomes idle (end of intermission), or at the tick of a ``request`` on an idle bus
(the arbitration runs as an event at that tick, so every request made at the same tick joins),
every node that is not bus-off, not in suspend-transmission and has a pending frame sends SOF
at that same tick. Lowest ``(id, rtr)`` wins (wired-AND, dominant 0: a data frame beats a
remote frame of the same id); losers become receivers and compete again at the next idle.
Identical frames sent by several nodes merge (all of them get ``on_tx_done``); two different
frames with the same id and RTR (forbidden in CAN) both get a bit error at the first differing
wire bit. A frame occupies ``frame_length_bits(...) * ticks_per_bit`` ticks, IFS included.

Error model (ISO 11898-1 fault confinement, the common rules)
-------------------------------------------------------------
* Error-active: TEC < 128 and REC < 128; error-passive: either >= 128; bus-off: TEC > 255.
* Transmitter: TEC += 8 on an error it detects, TEC -= 1 (not below 0) after a successful frame.
  Exception kept: an error-passive transmitter whose ACK error nobody else flags keeps its TEC
  (so a node alone on the bus stops at TEC 128, error-passive, and never goes bus-off).
* Receiver: REC += 1 on an error; after a successful reception REC -= 1 if 1..127, and a REC
  above 127 is set to 127 (the standard allows 119..127).
* An error is detected by all nodes at the same bit, so all error flags coincide: an error
  frame is 6 flag + 8 delimiter bits, then 3 intermission bits (17 bit times after the flag
  starts). The flag starts the bit after the error (an ACK error: at the ACK delimiter).
* Except a local error (``inject_local_error``, ``disturb``: a disturbance on one node's
  stub), which one receiver alone sees at wire bit b. If it is error-active its flag takes
  bits b+1..b+6; the transmitter detects a bit error at its first recessive bit after b, the
  other receivers a stuff error at the sixth dominant bit in a row (or a form error at a
  dominant CRC delimiter), and each sends its own flag from the next bit: the flags overlap
  into 6-12 dominant bits, then 8 delimiter and 3 intermission bits. TEC += 8, REC += 1, and
  REC += 8 more for a receiver that reads a dominant bit right after its own flag (the first
  detector, whenever the others' flags outlast its own). If it is error-passive its flag is
  recessive: the frame goes on for everyone else, and that node loses it (REC += 1).
  REC += 8 for a dominant bit after the own error flag and the 14th/every 8th dominant bit
  rule only occur with a stuck-dominant bus (see below), where they are applied.
* An error-passive node that has just transmitted (successfully or not) waits 8 more bit
  times (suspend transmission) after the intermission before it may start a frame; if another
  node starts a frame meanwhile, it becomes a receiver of it and the suspension ends.
* Bus-off recovery, modelled exactly on the rule "128 occurrences of 11 consecutive recessive
  bits": the node counts from the end of the error flag that sent it bus-off. Every frame,
  error frame or stuck episode ends with exactly 11 recessive bits (ACK delimiter + EOF + IFS,
  or error delimiter + IFS), then idle bits add on: a run of ``r`` recessive bits ending at a
  SOF (or at recovery) counts ``r // 11`` occurrences. On an idle bus the node therefore
  recovers ``128 * 11 = 1408`` bit times after its error flag ended, i.e. ``127 * 11 = 1397``
  bit times after the bus became idle; on a busy bus each frame contributes one occurrence
  (plus whatever idle follows it), so recovery takes 128 frames' worth or longer. On recovery
  TEC = REC = 0 and the node's pending frames are offered again. A node whose controller
  recovers on request (``recovers_on_request``, the MB90F549's, which starts counting when its
  HALT bit is cleared) counts only from ``start_recovery``. (Exceptions: when every flag
  is passive the recessive run is longer: 17 bits after the error bit, or, for a lone
  passive transmitter's ACK error, the trailing recessive bits of the CRC field + 19. A node
  sent bus-off during a stuck-dominant episode counts from the release.) Not modelled: the TEC
  exception for a stuff error on a recessive stuff bit during arbitration, overload frames,
  local errors inside the arbitration field (kept after it) or in the CRC delimiter, ACK
  and EOF, and the passive flag's own wait for six equal bits.

Fault injection
---------------
* ``inject_bit_error(node=None, count=1, bit=None)``: the next ``count`` frames (sent by
  ``node``, or by anyone) get a bit error detected by the transmitter and all receivers at wire
  bit ``bit`` (0 = SOF; default: the last bit of the stuffed CRC field; clamped to the ACK
  delimiter, and after the arbitration field, where a dominant bit read is lost arbitration).
* ``hold_dominant(node, True/False)``: the bus reads dominant while any node holds it. A frame
  in flight is destroyed at the hold tick ``H`` (flag start ``F = H``; its transmitter detects
  a bit error, the others a stuff error; not modelled: inside the arbitration field, the
  transmitter losing arbitration there); otherwise every node sees a SOF and a stuff error six
  bits later (``F = H + 6`` bits). Counting from ``F``: detection (+8 / +1), REC += 8 for
  receivers if bit 7 is still dominant, then at the 14th dominant bit and every 8 more
  TEC += 8 for the transmitter and REC += 8 for receivers (ISO rule for dominant bits after
  an error flag). So an error-active transmitter goes bus-off at ``F + 254`` bits and a fresh
  receiver error-passive at ``F + 126`` bits. No frame can start while held. After the last
  release at ``R`` the bus is idle again at ``max(R, F + 6 bits) + 11`` bits.

Arbitration, error signalling and error confinement are one state machine over the same bus
state; its parts: the state (bus_state.py), error signalling (bus_errors.py), a bus held
dominant (bus_hold.py), bound here as methods of :class:`CanBus`.
"""
from __future__ import annotations

import heapq
from typing import AbstractSet, Any, Callable

import can

from can_bus.bits import (
    BUS_OFF_LIMIT,
    ERROR_PASSIVE_LIMIT,
    IFS_BITS,
    SUSPEND_TRANSMISSION_BITS,
    TRAILER_BITS,
    BitTiming,
    _length,
)
from can_bus.clock import Cancellable as Event, Clock as Scheduler
from can_bus.frames import CanFrame
from can_bus.node import check_node
from can_bus.physical import DEFAULT_LENGTH_M, LINE_DELAY_S_PER_M, prop_time_s
from can_bus import bus_errors, bus_hold
from can_bus.bus_state import (_ELEVEN, _FRAME, _IDLE, _NO_DEAF, _REC_AFTER_PASSIVE_RX, _RECOVERY,
                               _TAIL, ACTIVE, BUS_OFF, ERROR_FRAME_TOTAL_BITS, PASSIVE,
                               CanErrorEvent, ErrorState, NodeStatus, _arbitration_end,
                               _frame_info, _Hold, _Node,
                               _prio)

__all__ = [
    "CanBus",
    "CanErrorEvent",
    "ErrorState",
    "NodeStatus",
    "ERROR_FRAME_TOTAL_BITS",
]


class CanBus:
    """Bit-exact, event-per-frame CAN 2.0A bus. See the module docstring for the model."""

    STEADY_COUNTERS = ("frames_ok",)
    """Frames sent without error: counts only (hil/sim/steady.py)."""

    def __init__(self, scheduler: Scheduler, timing: BitTiming | None = None,
                 length_m: float = DEFAULT_LENGTH_M) -> None:
        """``length_m``: the bus's length between its two farthest nodes (m)."""
        self.sched = scheduler
        self.timing = timing if timing is not None else BitTiming()
        self.tpb = self.timing.ticks_per_bit
        if not (isinstance(length_m, (int, float)) and 0 <= length_m < 1e6):
            raise ValueError(f"CanBus length_m must be a number of metres >= 0, got {length_m!r}")
        self.length_m = float(length_m)
        self._ack_budget = prop_time_s(self.timing) - 2 * self.length_m * LINE_DELAY_S_PER_M
        self._ack_limited = False            # some pair of nodes exceeds the budget
        self._cur_late = False               # this frame's ACK error is a late ACK
        self.trace: Callable[[CanFrame, int, int, Any], None] | None = None
        self.error_trace: Callable[[str, CanFrame | None, int, int, int | None, Any], None] | None \
            = None
        self.frames_ok = 0
        self.error_frames = 0
        self._nodes: list[_Node] = []
        self._by_id: dict[int, _Node] = {}
        self._phase = _IDLE
        self._busy_until: int | None = None
        self._idle_since = scheduler.now
        self._trailing = _ELEVEN
        self._arb_ev: Event | None = None
        self._seg_ev: Event | None = None
        self._cur_frame: CanFrame | None = None
        self._cur_start = 0
        self._cur_tx: list[_Node] = []
        self._cur_rx: list[_Node] = []
        self._inject: dict[int | None, list[int | None]] = {}
        self._local: dict[int, list[int | None]] = {}      # node id -> bits, one per frame
        self._noisy: dict[int, int | None] = {}            # node id -> bit, every frame
        # passive nodes that flagged a local error
        self._cur_deaf: set[int] | frozenset[int] = _NO_DEAF
        self._watch = False
        """Some node may be bus-off or in suspend transmission: the idle time's start and end
        must look at every node (False: none is, and none needs to)."""
        self._holders: set[int] = set()
        self._hold: _Hold | None = None

    # ------------------------------------------------------------------ public API
    def attach(self, node: Any) -> None:
        if id(node) in self._by_id:
            raise ValueError(f"{node!r} is already attached")
        check_node(node)
        ns = _Node(node)
        self._nodes.append(ns)
        self._by_id[id(node)] = ns
        self._check_ack_budget()

    def set_loop_delay(self, node: Any, seconds: float) -> None:
        """``node``'s TXD-to-RXD loop delay (s), e.g. an 82C250's in slope-control mode."""
        if not (isinstance(seconds, (int, float)) and 0 <= seconds < 1):
            raise ValueError(f"loop delay must be a number of seconds >= 0, got {seconds!r}")
        self._ns(node).loop = float(seconds)
        self._check_ack_budget()

    @property
    def ack_budget_s(self) -> float:
        """The round-trip time left for two nodes' loop delays (s): ``(tseg1 - sjw)`` quanta
        less twice the bus length of cable (:mod:`can_bus.physical`)."""
        return self._ack_budget

    def ack_in_time(self, a: Any, b: Any) -> bool:
        """Does ``b``'s ACK reach ``a`` (or ``a``'s reach ``b``) within the bit timing's
        round-trip budget?"""
        return self._ns(a).loop + self._ns(b).loop <= self._ack_budget

    def _check_ack_budget(self) -> None:
        loops = sorted((ns.loop for ns in self._nodes), reverse=True)
        self._ack_limited = len(loops) >= 2 and loops[0] + loops[1] > self._ack_budget

    def start_recovery(self, node: Any) -> None:
        """A bus-off ``node`` whose controller recovers on request (``recovers_on_request``)
        asks to: from now it counts 128 occurrences of 11 consecutive recessive bits, as
        every other node counts from its error flag. Nothing happens for a node that is not
        bus-off or already counting."""
        ns = self._ns(node)
        if ns.state is not BUS_OFF or ns.counting:
            return
        ns.counting = True
        ns.occ = 0
        now = self.sched.now
        if self._phase == _IDLE and not self._holders:
            ns.count_from = now
            ns.recover_ev = self.sched.at(now + _RECOVERY * _ELEVEN * self.tpb,
                                          self._recover_event, ns)

    def detach(self, node: Any) -> None:
        """Remove a node; it gets no further callbacks and its bus-kept queue is dropped."""
        ns = self._ns(node)
        ns.attached = False
        if ns.recover_ev is not None:
            ns.recover_ev.cancel()
        self._nodes.remove(ns)
        del self._by_id[id(node)]
        self._check_ack_budget()
        self._holders.discard(id(node))
        self._inject.pop(id(ns), None)
        self._local.pop(id(ns), None)
        self._noisy.pop(id(ns), None)
        if not self._holders and self._hold is not None and self._hold.released is None:
            self._hold_release()

    def request(self, node: Any, frame: CanFrame | can.Message | None = None) -> None:
        """Ask to transmit. Nodes with ``pending()`` just wake the bus (``frame`` is ignored,
        the bus sends what ``pending()`` returns); others have ``frame`` queued by priority."""
        try:
            ns = self._by_id[id(node)]
        except KeyError:
            ns = self._ns(node)         # raises the error
        ns.asked = True
        if ns.pending_fn is None:
            if frame is None:
                raise ValueError("a node without pending() must pass the frame to request()")
            if not isinstance(frame, CanFrame):
                frame = CanFrame.from_message(frame)
            ns.seq += 1
            heapq.heappush(ns.queue, (frame.id, frame.rtr, ns.seq, frame))
        self._kick()

    def inject_bit_error(self, node: Any = None, count: int = 1, bit: int | None = None) -> None:
        if count < 0 or (bit is not None and bit < 0):
            raise ValueError("count and bit must be >= 0")
        key = None if node is None else id(self._ns(node))
        if count:
            self._inject.setdefault(key, []).extend([bit] * count)

    def inject_local_error(self, node: Any, count: int = 1, bit: int | None = None) -> None:
        """The next ``count`` frames ``node`` receives get an error only ``node`` sees (a
        disturbance on its stub), at wire bit ``bit`` (default: the last CRC bit; kept
        between the end of the arbitration field and the CRC delimiter)."""
        if count < 0 or (bit is not None and bit < 0):
            raise ValueError("count and bit must be >= 0")
        if count:
            self._local.setdefault(id(self._ns(node)), []).extend([bit] * count)

    def disturb(self, node: Any, on: bool = True, bit: int | None = None) -> None:
        """While on, every frame ``node`` receives gets a local error (a noisy stub)."""
        key = id(self._ns(node))
        if on:
            self._noisy[key] = bit
        else:
            self._noisy.pop(key, None)

    def hold_dominant(self, node: Any, on: bool = True) -> None:
        ns = self._ns(node)
        if on:
            if id(node) in self._holders:
                return
            self._holders.add(id(node))
            if len(self._holders) == 1:
                self._hold_start()
        elif id(node) in self._holders:
            self._holders.discard(id(ns.node))
            if not self._holders:
                # Released from an event at this same tick, never from inside the hold's own
                # bookkeeping: a node's error/state callback may release the bus (a firmware
                # isolating itself) while the bus is still settling that hold.
                self.sched.at(self.sched.now, self._release_if_free)

    def _release_if_free(self) -> None:
        if not self._holders and self._hold is not None:
            self._hold_release()

    def status(self, node: Any) -> NodeStatus:
        ns = self._ns(node)
        if self._hold is not None:
            self._settle(self.sched.now)
        return NodeStatus(ns.tec, ns.rec, ns.state)

    def tec(self, node: Any) -> int:
        return self.status(node).tec

    def rec(self, node: Any) -> int:
        return self.status(node).rec

    def error_state(self, node: Any) -> ErrorState:
        """The node's error state, without building a NodeStatus (the firmware's supervision
        asks at every frame it receives)."""
        ns = self._ns(node)
        if self._hold is not None:
            self._settle(self.sched.now)
        return ns.state

    def queued(self, node: Any) -> list[CanFrame]:
        """Frames in the bus-kept queue of a node without pending(), highest priority first."""
        return [e[3] for e in sorted(self._ns(node).queue)]

    @property
    def idle(self) -> bool:
        return self._phase == _IDLE and not self._holders

    @property
    def busy_until(self) -> int | None:
        """Tick the bus becomes idle (None when idle or held with no release yet)."""
        return self._busy_until

    @property
    def held(self) -> bool:
        return bool(self._holders)

    @property
    def frame_on_air(self) -> tuple[CanFrame, int] | None:
        """(the frame on the bus, the tick of its SOF) while one is, else None."""
        if self._phase == _FRAME and self._cur_frame is not None:
            return self._cur_frame, self._cur_start
        return None

    # ------------------------------------------------------------------ internals
    def _ns(self, node: Any) -> _Node:
        try:
            return self._by_id[id(node)]
        except KeyError:
            raise ValueError(f"{node!r} is not attached to this bus") from None

    def _kick(self) -> None:
        if self._phase != _IDLE or self._holders:
            return
        now = self.sched.now
        ev = self._arb_ev
        if ev is not None:
            if ev.when <= now:
                return
            ev.cancel()
        self._arb_ev = self.sched.at(now, self._arbitrate)

    def _update(self, ns: _Node, tick: int) -> None:
        old = ns.state
        if old is BUS_OFF:
            return
        if ns.tec >= BUS_OFF_LIMIT:
            new = BUS_OFF
            ns.occ = 0
            ns.suspend_until = 0
            self._watch = True
            # a controller that recovers on request (the MB90F549's: when HALT is cleared)
            # does not count until start_recovery(); others count at once (CAN 2.0)
            ns.counting = not getattr(ns.node, "recovers_on_request", False)
            ns.count_from = None
        elif ns.tec >= ERROR_PASSIVE_LIMIT or ns.rec >= ERROR_PASSIVE_LIMIT:
            new = PASSIVE
        else:
            new = ACTIVE
        if new is not old:
            ns.state = new
            if ns.on_state is not None and ns.attached:
                ns.on_state(old, new, tick)

    def _recover(self, ns: _Node, tick: int) -> None:
        if ns.recover_ev is not None:
            ns.recover_ev.cancel()
            ns.recover_ev = None
        ns.tec = ns.rec = ns.occ = 0
        ns.state = ACTIVE
        if ns.on_state is not None and ns.attached:
            ns.on_state(BUS_OFF, ACTIVE, tick)

    def _recover_event(self, ns: _Node) -> None:
        ns.recover_ev = None
        self._recover(ns, self.sched.now)
        self._kick()

    def _start_segment(self, now: int) -> None:
        """A dominant bit (SOF or a stuck bus) starts at ``now`` after an idle period."""
        if not self._watch:
            return                  # nobody counts recessive bits or waits
        run = self._trailing + (now - self._idle_since) // self.tpb
        off = False                 # after this, no node's suspend_until is past now
        for ns in self._nodes:
            if ns.state is BUS_OFF:
                off = True
                if not ns.counting:
                    continue
                if ns.recover_ev is not None:
                    ns.recover_ev.cancel()
                    ns.recover_ev = None
                mine = run
                if ns.count_from is not None:     # counting began in this idle time
                    mine = (now - ns.count_from) // self.tpb
                    ns.count_from = None
                ns.occ += mine // _ELEVEN
                if ns.occ >= _RECOVERY:
                    self._recover(ns, now)
            elif ns.suspend_until > now:
                ns.suspend_until = 0
        self._watch = off

    def _arbitrate(self) -> None:
        self._arb_ev = None
        if self._phase != _IDLE or self._holders:
            return
        now = self.sched.now
        cands: list[tuple[CanFrame, _Node]] = []
        wake: int | None = None
        for ns in self._nodes:
            if ns.state is BUS_OFF:
                continue
            if ns.pending_fn is not None:
                if not ns.asked:
                    continue
                f = ns.pending_fn()
                if f is None:
                    ns.asked = not ns.after_request
                    continue
                if not isinstance(f, CanFrame):
                    f = CanFrame.from_message(f)
            elif ns.queue:
                f = ns.queue[0][3]
            else:
                continue
            if ns.suspend_until > now:
                if wake is None or ns.suspend_until < wake:
                    wake = ns.suspend_until
                continue
            cands.append((f, ns))
        if not cands:
            if wake is not None:
                self._arb_ev = self.sched.at(wake, self._arbitrate)
            return

        if len(cands) == 1:
            winners = cands
            frame = cands[0][0]
            tx = [cands[0][1]]
        else:
            best = min(cands, key=_prio)[0]
            bid, brtr = best.id, best.rtr
            winners = [c for c in cands if c[0].id == bid and c[0].rtr == brtr]
            frame = winners[0][0]
            tx = [ns for _, ns in winners]
        for ns in tx:
            ns.entry = ns.queue[0] if ns.pending_fn is None else None

        self._start_segment(now)
        if len(tx) == 1:
            t0 = tx[0]
            if self._watch:
                rx = [ns for ns in self._nodes if ns is not t0 and ns.state is not BUS_OFF]
            else:                       # no node is bus-off
                rx = self._nodes.copy()
                rx.remove(t0)
        else:
            rx = [ns for ns in self._nodes if ns.state is not BUS_OFF and ns not in tx]
        self._phase = _FRAME
        self._cur_frame = frame
        self._cur_start = now
        self._cur_tx = tx
        self._cur_rx = rx
        nwire = _length(frame.id, frame.data, frame.rtr, frame.dlc)  # SOF..EOF bits
        nstuffed = nwire - TRAILER_BITS
        tpb = self.tpb

        # Earliest error in this frame, if any: (bit index, kind).
        err: tuple[int, str] | None = None
        for f, _ in winners[1:]:
            if f != frame:
                wire = _frame_info(frame)[0]
                w2 = _frame_info(f)[0]
                k = next((i for i, (a, b) in enumerate(zip(wire, w2)) if a != b),
                         min(len(wire), len(w2)) - 1)
                if err is None or k < err[0]:
                    err = (k, "bit")
        if self._inject:
            inj = self._inject
            for ns in tx:
                key = id(ns) if id(ns) in inj else (None if None in inj else 0)
                if key != 0:
                    lst = inj[key]
                    bit = lst.pop(0)
                    if not lst:
                        del inj[key]
                    k = nstuffed - 1 if bit is None else min(
                        max(bit, _arbitration_end(_frame_info(frame)[0]) + 1), nstuffed + 2)
                    if err is None or k < err[0]:
                        err = (k, "bit")
                    break
        self._cur_late = False
        if err is None or err[0] > nstuffed + 1:
            if not self._ack_limited:
                for ns in rx:
                    if ns.always_acks:
                        break
                else:
                    if not any(ns.node.acknowledges for ns in rx):
                        err = (nstuffed + 1, "ack")  # no receiver able to drive the ACK slot
            else:
                acking = [ns for ns in rx if ns.always_acks or ns.node.acknowledges]
                budget = self._ack_budget - max(ns.loop for ns in tx)
                if not acking:
                    err = (nstuffed + 1, "ack")
                elif not any(ns.loop <= budget for ns in acking):
                    err = (nstuffed + 1, "ack")  # every ACK comes back after the sample point
                    self._cur_late = True

        if self._local or self._noisy:
            self._cur_deaf = set()
            local = self._local_errors(rx, _frame_info(frame)[0], nstuffed, err)
            if local is not None:
                b = local[0]
                self._busy_until = now + (local[3] + 12) * tpb
                self._seg_ev = self.sched.at(now + (b + 1) * tpb, self._local_error, local)
                for f, ns in cands:
                    if ns.on_lost is not None and ns not in tx:
                        ns.on_lost(f)
                return
        else:
            self._cur_deaf = _NO_DEAF

        if err is None:
            self._busy_until = now + (nwire + IFS_BITS) * tpb
            self._seg_ev = self.sched.at(now + nwire * tpb, self._frame_done)
        else:
            self._busy_until = now + (err[0] + 1 + ERROR_FRAME_TOTAL_BITS) * tpb
            self._seg_ev = self.sched.at(now + (err[0] + 1) * tpb, self._frame_error, err[1])

        if len(cands) > 1:              # a lone candidate won
            for f, ns in cands:
                if ns.on_lost is not None and ns not in tx:
                    ns.on_lost(f)

    def _frame_done(self) -> None:
        now = self.sched.now
        tpb = self.tpb
        frame = self._cur_frame
        assert frame is not None                  # the frame this segment carried
        idle_at = now + IFS_BITS * tpb
        self._phase = _TAIL
        self._busy_until = idle_at
        self.frames_ok += 1
        for ns in self._cur_tx:
            if ns.tec > 0:
                ns.tec -= 1
                self._update(ns, now)
            if ns.state is PASSIVE:
                ns.suspend_until = idle_at + SUSPEND_TRANSMISSION_BITS * tpb
                self._watch = True
            if ns.entry is not None:
                try:
                    ns.queue.remove(ns.entry)
                    heapq.heapify(ns.queue)
                except ValueError:
                    pass
                ns.entry = None
        deaf = self._cur_deaf
        self._rx_count(self._cur_rx, deaf, now)
        self._seg_ev = self.sched.at(idle_at, self._segment_end, _ELEVEN)
        if self.trace is not None:
            self.trace(frame, self._cur_start, now, self._cur_tx[0].node)
        for ns in self._cur_tx:
            if ns.on_tx_done is not None and ns.attached:
                ns.on_tx_done(frame, now)
        self._rx_deliver(frame, self._cur_start, now, self._cur_rx, deaf)

    def _rx_count(self, rx: list[_Node], deaf: AbstractSet[int], now: int) -> None:
        """Receivers' REC after a frame they took (ISO 11898-1 rule 8)."""
        for ns in rx:
            if deaf and id(ns) in deaf and ns.state is not BUS_OFF:
                ns.rec += 1                   # its passive error flag: no frame, REC + 1
                self._update(ns, now)
                continue
            r = ns.rec
            if r and ns.state is not BUS_OFF:     # nothing to do with a REC of 0
                if r > 127:
                    ns.rec = _REC_AFTER_PASSIVE_RX
                    self._update(ns, now)
                else:
                    ns.rec = r - 1

    @staticmethod
    def _rx_deliver(frame: CanFrame, start: int, now: int, rx: list[_Node],
                    deaf: AbstractSet[int]) -> None:
        fid = frame.id
        for ns in rx:
            ids = ns.rx_ids                   # first: most nodes ignore most frames
            if (ids is None or fid in ids) and ns.on_frame is not None and ns.attached and \
                    ns.state is not BUS_OFF and not (deaf and id(ns) in deaf):
                ns.on_frame(frame, start, now)

    def _late_ack_received(self, frame: CanFrame, start: int, tx: _Node,
                           rx: list[_Node]) -> None:
        """Every transmitter was error-passive when its ACK came back late, or when no
        receiver could drive it: its error flag is recessive, so the receivers see a whole
        frame and take it at its end (``start`` + the frame's wire bits)."""
        now = self.sched.now
        rx = [ns for ns in rx if ns.attached]
        self._rx_count(rx, set(), now)
        if self.trace is not None:
            self.trace(frame, start, now, tx.node)
        self._rx_deliver(frame, start, now, rx, set())

    def _segment_end(self, trailing: int) -> None:
        now = self.sched.now
        self._seg_ev = None
        self._phase = _IDLE
        self._busy_until = None
        self._idle_since = now
        self._trailing = trailing
        self._cur_tx = self._cur_rx = []
        self._cur_frame = None
        if self._watch:
            self._count_idle(now, trailing)
        self._arbitrate()

    def _count_idle(self, now: int, trailing: int) -> None:
        """The bus fell idle at ``now`` after ``trailing`` recessive bits: each bus-off node
        that counts recovers when its 128 x 11 recessive bits are complete."""
        tpb = self.tpb
        for ns in self._nodes:
            if ns.state is BUS_OFF and ns.counting:
                ns.count_from = None
                need = _RECOVERY - ns.occ
                t = now + max(0, _ELEVEN * need - trailing) * tpb
                if t == now:
                    self._recover(ns, now)
                else:
                    if ns.recover_ev is not None:
                        ns.recover_ev.cancel()
                    ns.recover_ev = self.sched.at(t, self._recover_event, ns)

    # -- error signalling (bus_errors.py) and a bus held dominant (bus_hold.py) ----------
    _frame_error = bus_errors._frame_error
    _local_errors = bus_errors._local_errors
    _local_error = bus_errors._local_error
    _hold_start = bus_hold._hold_start
    _hold_release = bus_hold._hold_release
    _hold_tick_time = bus_hold._hold_tick_time
    _can_change = bus_hold._can_change
    _settle = bus_hold._settle
    _count = bus_hold._count
    _hold_schedule = bus_hold._hold_schedule
    _hold_tick = bus_hold._hold_tick
    _hold_finish = bus_hold._hold_finish
