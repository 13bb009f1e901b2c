"""The node base every executive submodule shares (can_bus.submodules): its priority queue,
status grid, DBC coding and fault injection on the bus's node interface."""
from __future__ import annotations

import heapq
from typing import Callable

from can_bus import dbc
from can_bus.frames import CanFrame
from can_bus.node import FrameSink, FrameSource, NodeBus
from can_bus.dbc import (
    EVENT_FAULT,
    EVENT_REFUSED,
    FAULT_STALLED,
    STATE_FAULT,
    STATE_HOLDING,
    STATE_IDLE,
    STATE_MOVING,
    STATE_STALLED,
)
from can_bus.clock import DEFAULT_TICK_HZ as TICK_HZ
from can_bus.clock import Cancellable as Event, Clock as Scheduler

from .params import STALL_DETECT_TICKS, STATUS_PERIOD_TICKS, STATUS_STAGGER_TICKS

EVENTS_KEEP = 1024
"""A submodule's ``events`` keep the latest, between this many and twice as many."""


class _Submodule(FrameSource, FrameSink):
    """Queue, status timer, EVENTs, silence, ESTOP and fault bookkeeping shared by all nodes."""

    STEADY_COUNTERS = ("sent", "_order")
    """Frames sent and acknowledged (counts only); ``_order``, its queue's tie-break, compared
    only with its own values (hil/sim/steady.py)."""
    STEADY_RECORDS = ("events",)
    """Every EVENT it queued: appended to, never read by the model (tests read it)."""

    # stall detection, kept by the nodes that detect stalls (joints and the wheel), which
    # also define _stall_detected
    _stall_ev: Event | None
    _noprog_since: int | None
    _stall_detected: Callable[[], None]

    def __init__(self, sched: Scheduler, bus: NodeBus, number: int,
                 status_offset: int | None = None) -> None:
        if bus.timing.tick_hz != TICK_HZ:
            raise ValueError(f"the submodule models run on a {TICK_HZ} Hz clock, the bus's "
                             f"bit timing says {bus.timing.tick_hz} Hz")
        self.sched = sched
        self.bus = bus
        self.number = number
        self.name = dbc.NODE_NAMES[number]
        self.cmd_id = dbc.frame_id(dbc.cmd_name(number))
        self.status_name = dbc.status_name(number)
        if dbc.signal_names(self.status_name) != self.STATUS_SIGNALS:
            raise ValueError(f"{type(self).__name__}.STATUS_SIGNALS {self.STATUS_SIGNALS} are "
                             f"not the signals of {self.status_name} in rprs.dbc's order")
        self.event_name = dbc.event_name(number)
        self._estop_id = dbc.frame_id(dbc.ESTOP)
        self._estop_dlc = dbc.dlc(dbc.ESTOP)
        self.rx_ids = frozenset({self.cmd_id, self._estop_id})
        """The frames ``on_frame`` acts on (a bus promise, can_bus/bus.py, Nodes)."""
        self.state = STATE_IDLE
        self.seq = 0
        """seq of the last command taken."""
        self.events: list[tuple[int, int, int, int]] = []
        """(tick, kind, seq, code) of every EVENT queued for sending."""
        self.bad_frames = 0
        """Frames with our command id that do not decode (wrong length, remote), and remote
        frames with the ESTOP id: ignored."""
        self.refused = 0
        """Commands refused (EVENT kind 3: out of range, faulted)."""
        self.sent = 0
        """Frames sent and acknowledged."""
        self._silent = False
        self._queue: list[tuple[int, int, CanFrame]] = []
        self._order = 0
        self._status_entry: tuple[int, int, CanFrame] | None = None
        if status_offset is None:
            status_offset = number * STATUS_STAGGER_TICKS
        self._status_ev = sched.at(sched.now + status_offset, self._status_tick)
        bus.attach(self)

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name}>"

    # ------------------------------------------------------------ bus node interface
    pending_after_request = True
    """Every frame is queued by ``_push``, which asks the bus (can_bus/bus.py, Nodes)."""

    def pending(self) -> CanFrame | None:
        if self._silent or not self._queue:
            return None
        return self._queue[0][2]

    def on_tx_done(self, frame: CanFrame, end_tick: int) -> None:
        self.sent += 1
        q = self._queue
        if q and q[0][2] == frame:
            entry = heapq.heappop(q)
        else:
            for i, entry in enumerate(q):
                if entry[2] == frame:
                    q[i] = q[-1]
                    q.pop()
                    heapq.heapify(q)
                    break
            else:
                return
        if entry is self._status_entry:
            self._status_entry = None

    def on_frame(self, frame: CanFrame, start_tick: int, end_tick: int) -> None:
        if self._silent:
            return
        fid = frame.id
        if fid == self.cmd_id:
            try:
                _, values = dbc.decode_raw(frame)
            except dbc.DbcError:
                self.bad_frames += 1
                return
            self._command(values)
        elif fid == self._estop_id:
            if frame.rtr or len(frame.data) != self._estop_dlc:
                self.bad_frames += 1          # counted as malformed (docs/can.md) ...
            if not frame.rtr:
                self._estop()                 # ... but a stop is never refused for its form

    # ------------------------------------------------------------ sending
    def _push(self, frame: CanFrame) -> tuple[int, int, CanFrame]:
        self._order += 1
        entry = (frame.id, self._order, frame)
        heapq.heappush(self._queue, entry)
        self.bus.request(self)
        return entry

    def _event(self, kind: int, seq: int, code: int = 0) -> None:
        if self._silent:
            return
        events = self.events
        events.append((self.sched.now, kind, seq, code))
        if len(events) >= 2 * EVENTS_KEEP:  # a tail to read, not a record of a day's run
            del events[:EVENTS_KEEP]
        self._push(dbc.encode_raw(self.event_name, kind=kind, seq=seq, code=code))

    def _refuse(self, seq: int, code: int) -> None:
        self.refused += 1
        self._event(EVENT_REFUSED, seq, code)

    def _status_tick(self) -> None:
        self._status_ev = self.sched.at(self.sched.now + STATUS_PERIOD_TICKS, self._status_tick)
        if self._silent:
            return
        frame = dbc.encode_raw_values(self.status_name, self.status_values())
        old = self._status_entry
        if old is not None:
            try:
                self._queue.remove(old)
            except ValueError:
                pass
            else:
                heapq.heapify(self._queue)
        self._status_entry = self._push(frame)

    @property
    def status_due(self) -> int:
        """The tick its status timer next fires (a frame then, unless it is silent)."""
        return self._status_ev.when

    STATUS_SIGNALS: tuple[str, ...] = ()
    """The status frame's signals in rprs.dbc's order, the order of :meth:`status_values`."""

    def status_values(self) -> tuple[int, ...]:
        """Raw values of the node's status frame now, in :attr:`STATUS_SIGNALS` order."""
        raise NotImplementedError

    def status_signals(self) -> dict[str, int]:
        """Raw signal values of the node's status frame, now."""
        return dict(zip(self.STATUS_SIGNALS, self.status_values()))

    @property
    def cruising(self) -> bool:
        """Moving with nothing left to do but repeat itself, its motion in closed form (no
        events of its own but the status frames): a wheel at its commanded speed. A joint or
        the paw never cruises: a move ends."""
        return False

    # ------------------------------------------------------------ fault injection
    @property
    def is_silent(self) -> bool:
        return self._silent

    def silent(self, on: bool = True) -> None:
        """Silence the node (sends nothing, ignores every frame) or give it its voice back."""
        self._silent = bool(on)
        if self._silent:
            self._queue.clear()
            self._status_entry = None

    @property
    def faulted(self) -> bool:
        return self.state in (STATE_STALLED, STATE_FAULT)

    def fault(self, code: int = dbc.FAULT_OVERCURRENT) -> None:
        """Inject a fault at once: motion stops, EVENT kind 2 with ``code``, state 4 (3 for
        code 1, stalled). Commands are refused (code 3) until :meth:`clear_fault`."""
        self._halt()
        self.state = STATE_STALLED if code == FAULT_STALLED else STATE_FAULT
        self._event(EVENT_FAULT, self.seq, code)

    def clear_fault(self) -> None:
        """Remove an injected stall/fault. A detected fault leaves the node idle (state 0);
        a motion blocked but not yet detected as stalled resumes."""
        raise NotImplementedError

    # ------------------------------------------------------------ subclass hooks
    def _command(self, values: dict[str, int]) -> None:
        raise NotImplementedError

    def _halt(self) -> None:
        """Stop all motion at once and drop the command (no EVENT, no state change)."""
        raise NotImplementedError

    def _estop(self) -> None:
        self._halt()
        if self.state == STATE_MOVING:
            self.state = self._rest_state_after_estop()

    def _rest_state_after_estop(self) -> int:
        return STATE_HOLDING

    def _no_progress(self) -> None:
        """Motion is commanded but not progressing: a stall is reported after
        STALL_DETECT_TICKS of this (joints and the wheel; ``_stall_detected`` is theirs)."""
        if self._noprog_since is None:
            self._noprog_since = self.sched.now
        if self._stall_ev is None:
            self._stall_ev = self.sched.at(self._noprog_since + STALL_DETECT_TICKS,
                                           self._stall_detected)

    def _cancel_stall(self) -> None:
        """Forget stall detection (joints and the wheel, which keep ``_stall_ev``)."""
        self._noprog_since = None
        if self._stall_ev is not None:
            self._stall_ev.cancel()
            self._stall_ev = None
