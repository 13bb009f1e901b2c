"""The six executive submodules of a child (docs/can.md) as nodes on :class:`~can_bus.bus.CanBus`.

Each node implements the bus's node interface directly (``pending()`` / ``on_tx_done()`` with
its own priority queue, ``on_frame()`` for the frames addressed to it), encodes and decodes
every frame through :mod:`can_bus.dbc`, and runs an exact, deterministic physical model on the
integer-tick clock (:class:`~can_bus.clock.Clock`) at 16 MHz, the tick rate every
constant below is written for (no wall clock, no randomness).

Common behaviour
----------------
* A command takes effect at the tick the bus delivers it (``on_frame``: end of the frame's
  EOF), with no processing latency. A new command pre-empts the running one (no EVENT for
  the pre-empted command); the status ``seq`` is the seq of the last command *taken*.
* Refusals (``EVENT<n>`` kind 3): code 1 out of range (target outside the limits, speed above
  the maximum, an undefined mode/action, wheel distance whose sign disagrees with the speed),
  code 3 faulted (state 3 stalled or 4 fault, until :meth:`clear_fault`). Code 2 (busy) is
  never sent: commands pre-empt.
* ``STATUS`` every :data:`STATUS_PERIOD_TICKS` (100 ms); node ``n``'s first status goes
  ``n * STATUS_STAGGER_TICKS`` (10 ms) after the node is created, so the six status frames
  never contend for the same tick. A status still queued when the next one is due (bus
  busy / bus-off) is replaced by the newer one; events queue up in order.
* ``ESTOP`` (0x010): every node stops at once and drops its command without an EVENT (joints
  and paw hold where they are; the wheel's speed drops to 0). A faulted node stays faulted.
  A data frame with the ESTOP identifier stops the node whatever its length (fail-safe: an
  emergency stop is never refused for its form); a length other than the DBC's 1 byte is
  also counted in :attr:`bad_frames`. A remote frame with that identifier is no stop, only a
  bad frame.
* Fault injection: :meth:`stall` (motion stops; after :data:`STALL_DETECT_TICKS` (200 ms)
  without progress while a motion is commanded, ``EVENT`` kind 2 code 1 and state 3),
  :meth:`fault` (any fault code at once, state 4, or 3 for code 1), :meth:`silent` (the node
  sends nothing, its queue is dropped, commands and ESTOP are ignored; the physics keeps
  running and the status grid keeps its phase), :meth:`clear_fault`.

Physical models
---------------
* :class:`JointNode`: constant angular speed (no acceleration phase) toward the target,
  computed analytically in 0.01 deg units: travelled = floor(speed * elapsed), the EVENT
  done is sent at ``start + ceil(|delta| / speed)`` ticks exactly. After a move the joint
  holds (state 2); ``hold`` stops at once (state 2), ``relax`` stops at once (state 0);
  both complete with EVENT done at once.
* :class:`WheelNode`: 1 ms physics step with exact integers (speed in um/s, odometer in nm):
  each step the speed changes by at most ``accel`` (0.5 mm/s a step at 500 mm/s^2) and the
  odometer adds the new speed times 1 ms (semi-implicit Euler). A distance command plans its
  braking so that it stops exactly on the distance (the last step covers the remainder, at
  most one step's speed change, and the speed is then 0); EVENT done at that step. A
  distance-0 command ("keep running") completes with EVENT done when the speed reaches the
  target. Status ``speed`` (mm/s) and ``odometer`` (mm) are truncated toward zero.
  A step runs before every other event of its tick (``Scheduler.at_top``), so whatever reads
  the wheel at tick T sees the step of T done. That rule lets a *cruising* wheel (at the
  commanded speed, no distance to go) stop scheduling its steps: the odometer at any tick is
  the odometer at the last step taken plus the speed times the whole milliseconds since
  (:attr:`WheelNode.x_nm`); a command, ESTOP, stall or fault first takes those steps and puts
  the next one back on the same 1 ms grid.
* :class:`PawNode`: constant travel speed, a full stroke (0..100 %) in 800 ms, positions in
  0.01 % units, analytic like the joint. Closing with an object present stops where the
  fingers meet it (``object_size_pct``, default 40 %), grip=1, state 2 holding; EVENT done
  at contact. Opening releases the grip (grip=0) at once.

Default parameters (:func:`make_submodules`)
---------------------------------------------
=========  ====================  ==============  =========  =============
node       name                  limits (deg)    max deg/s  default deg/s
=========  ====================  ==============  =========  =============
JOINT1     base yaw              -170 .. 170     60         30
JOINT2     shoulder              -10 .. 120      60         30
JOINT3     elbow                 -135 .. 135     90         45
JOINT4     wrist (end link)      -120 .. 120     90         45
=========  ====================  ==============  =========  =============

Joints start at 0 deg (or ``initial_angles``), idle. WHEEL: max 300 mm/s, acceleration 500 mm/s^2,
odometer 0.
PAW: full stroke 800 ms, starts fully open (100 %), object size 40 %, no object.

Over 500 lines on purpose: the six submodules share one node base (queue, status, DBC coding);
the joint, wheel and paw physics are short.
"""
from __future__ import annotations

import heapq
from typing import Any, Callable, Sequence

from can_bus import dbc
from can_bus.frames import CanFrame
from can_bus.node import FrameSink, FrameSource, NodeBus
from can_bus.dbc import (
    ACTION_CLOSE,
    ACTION_OPEN,
    EVENT_DONE,
    EVENT_FAULT,
    EVENT_REFUSED,
    FAULT_STALLED,
    MODE_HOLD,
    MODE_MOVE,
    MODE_RELAX,
    REFUSED_FAULTED,
    REFUSED_RANGE,
    STATE_FAULT,
    STATE_HOLDING,
    STATE_IDLE,
    STATE_MOVING,
    STATE_STALLED,
)
from can_bus.clock import DEFAULT_TICK_HZ as TICK_HZ
from can_bus.clock import Cancellable as Event, Clock as Scheduler

__all__ = [
    "MS",
    "STATUS_PERIOD_TICKS",
    "STATUS_STAGGER_TICKS",
    "STALL_DETECT_TICKS",
    "WHEEL_STEP_TICKS",
    "PAW_STROKE_MS",
    "PAW_FULL",
    "JOINT_DEFAULTS",
    "WHEEL_MAX_SPEED_MM_S",
    "WHEEL_ACCEL_MM_S2",
    "JointNode",
    "WheelNode",
    "PawNode",
    "make_submodules",
]

MS = TICK_HZ // 1000
"""16000 ticks a millisecond."""
STATUS_PERIOD_TICKS = 100 * MS
STATUS_STAGGER_TICKS = 10 * MS
STALL_DETECT_TICKS = 200 * MS
WHEEL_STEP_TICKS = 1 * MS
PAW_STROKE_MS = 800
PAW_FULL = 10_000
"""Paw position units in a full stroke (0.01 % each)."""

JOINT_DEFAULT_SPEED_DPS = {1: 30.0, 2: 30.0, 3: 45.0, 4: 45.0}
"""deg/s a joint moves at for ``speed`` 0: half its rated speed (stated in rprs.dbc too)."""


def _joint_defaults(n: int) -> dict[str, Any]:
    """Joint n's limits and rated speed, from rprs.dbc's [min|max] of JOINTn_CMD."""
    lo, hi = dbc.signal_range(dbc.joint_cmd_name(n), "angle")
    return dict(limits=(float(lo), float(hi)),
                max_speed_dps=float(dbc.signal_range(dbc.joint_cmd_name(n), "speed")[1]),
                default_speed_dps=JOINT_DEFAULT_SPEED_DPS[n])


JOINT_DEFAULTS: dict[int, dict[str, Any]] = {n: _joint_defaults(n) for n in range(1, 5)}
"""1 base yaw, 2 shoulder, 3 elbow, 4 wrist (end link)."""
WHEEL_MAX_SPEED_MM_S = int(dbc.signal_range("WHEEL_CMD", "speed")[1])
"""The wheel's rated speed, either way (rprs.dbc)."""
WHEEL_ACCEL_MM_S2 = 500


def _sign(x: int) -> int:
    return (x > 0) - (x < 0)


def _trunc_div(a: int, b: int) -> int:
    """a / b truncated toward zero (b > 0)."""
    return a // b if a >= 0 else -((-a) // b)


class _Submodule(FrameSource, FrameSink):
    """Queue, status timer, EVENTs, silence, ESTOP and fault bookkeeping shared by all nodes."""

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
        self.events.append((self.sched.now, kind, seq, code))
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


class _AxisNode(_Submodule):
    """Exact constant-rate motion of an integer position (analytic; no physics tick).

    The rate is ``num / den`` position units a tick. From ``p0`` at ``t0`` toward ``stop``
    the position is ``p0 + dir * min(floor(num * (t - t0) / den), |stop - p0|)`` and the
    stop is reached at ``t0 + ceil(|stop - p0| * den / num)``.

    A stall is an obstacle at a position: a motion from ``p`` toward ``target`` is blocked if
    the obstacle lies in ``[p, target)`` (direction of travel), i.e. an obstacle at the
    current position blocks every motion (jammed), one exactly at the target does not (the
    motion completes, the next one is jammed).
    """

    def __init__(self, sched: Scheduler, bus: NodeBus, number: int, position: int,
                 status_offset: int | None) -> None:
        self._p0 = position
        self._t0 = sched.now
        self._num = 0  # 0: at rest
        self._den = 1
        self._dir = 0
        self._stop = position
        self._arrive_tick = sched.now
        self._target: int | None = None
        self._cmd_rate: tuple[int, int] = (0, 1)
        self._arrive_ev: Event | None = None
        self._stall_ev: Event | None = None
        self._noprog_since: int | None = None
        self._obstacle: int | None = None
        super().__init__(sched, bus, number, status_offset)

    # ------------------------------------------------------------ kinematics
    def _position(self) -> int:
        if not self._num:
            return self._p0
        span = abs(self._stop - self._p0)
        travelled = self._num * (self.sched.now - self._t0) // self._den
        return self._p0 + self._dir * (travelled if travelled < span else span)

    def _moving(self) -> bool:
        return bool(self._num) and self.sched.now < self._arrive_tick

    def _freeze(self) -> None:
        self._p0 = self._position()
        self._t0 = self.sched.now
        self._num = 0
        if self._arrive_ev is not None:
            self._arrive_ev.cancel()
            self._arrive_ev = None

    def _start_motion(self, target: int, num: int, den: int) -> None:
        self._freeze()
        self._target = target
        self._cmd_rate = (num, den)
        self._plan()

    def _plan(self) -> None:
        """Plan the motion from the (frozen) current position toward ``_target``."""
        p, target = self._p0, self._target
        assert target is not None                 # a move was commanded
        if p == target:
            self._cancel_stall()
            self._target = None
            self._arrived()
            return
        d = 1 if target > p else -1
        stop, blocked = target, False
        ob = self._obstacle
        if ob is not None and (p <= ob < target if d > 0 else target < ob <= p):
            stop, blocked = ob, True
        if stop == p:
            self._no_progress()
            return
        self._cancel_stall()
        num, den = self._cmd_rate
        now = self.sched.now
        self._dir, self._num, self._den, self._t0, self._stop = d, num, den, now, stop
        self._arrive_tick = now + -(-abs(stop - p) * den // num)
        self._arrive_ev = self.sched.at(self._arrive_tick, self._on_reach, blocked)

    def _on_reach(self, blocked: bool) -> None:
        self._arrive_ev = None
        self._p0 = self._stop
        self._t0 = self.sched.now
        self._num = 0
        if blocked:
            self._no_progress()
        else:
            self._target = None
            self._arrived()

    def _stall_detected(self) -> None:
        self._stall_ev = None
        self._noprog_since = None
        self._target = None
        self.state = STATE_STALLED
        self._event(EVENT_FAULT, self.seq, FAULT_STALLED)

    def _halt(self) -> None:
        self._freeze()
        self._target = None
        self._cancel_stall()

    def _replan(self) -> None:
        """Re-plan after the obstacle or the target changed. A motion under way keeps its
        origin (so its arrival tick stays exact); only its stopping point moves."""
        target = self._target
        if target is None:
            return
        if not self._num:
            self._freeze()
            self._plan()
            return
        p = self._position()
        d = self._dir
        if (target - p) * d <= 0:  # target reached or behind: plan afresh from here
            self._freeze()
            self._plan()
            return
        stop, blocked = target, False
        ob = self._obstacle
        if ob is not None and (p <= ob < target if d > 0 else target < ob <= p):
            stop, blocked = ob, True
        if stop == p:
            self._freeze()
            self._no_progress()
            return
        if self._arrive_ev is not None:
            self._arrive_ev.cancel()
        self._stop = stop
        self._arrive_tick = self._t0 + -(-abs(stop - self._p0) * self._den // self._num)
        self._arrive_ev = self.sched.at(self._arrive_tick, self._on_reach, blocked)

    def _arrived(self) -> None:
        raise NotImplementedError

    def _stall_at(self, pos: int | None) -> None:
        self._obstacle = self._position() if pos is None else pos
        self._replan()

    def clear_fault(self) -> None:
        self._obstacle = None
        if self.faulted:
            self._halt()
            self.state = STATE_IDLE
        else:
            self._replan()


class JointNode(_AxisNode):
    """Joint executive ``number`` (1-4): a rate-limited servo (see the module docstring).

    ``limits`` (min_deg, max_deg) bound the accepted targets; ``max_speed_dps`` bounds the
    commanded speed (above it: refused); ``default_speed_dps`` is used for ``speed`` 0
    (default: half the maximum). Angles are kept in 0.01 deg, speeds in 0.1 deg/s.
    """

    def __init__(self, sched: Scheduler, bus: NodeBus, number: int,
                 limits: tuple[float, float] = (-170.0, 170.0), max_speed_dps: float = 60.0,
                 default_speed_dps: float | None = None, initial_deg: float = 0.0,
                 status_offset: int | None = None) -> None:
        if not 1 <= number <= 4:
            raise ValueError(f"joint number must be 1..4, got {number}")
        lo, hi = (round(x * 100) for x in limits)
        if lo > hi:
            raise ValueError(f"joint limits {limits} are reversed")
        self.min_cdeg, self.max_cdeg = lo, hi
        self.max_ddps = round(max_speed_dps * 10)
        if default_speed_dps is None:
            default_speed_dps = max_speed_dps / 2
        self.default_ddps = round(default_speed_dps * 10)
        if not 0 < self.default_ddps <= self.max_ddps:
            raise ValueError("need 0 < default speed <= max speed (0.1 deg/s resolution)")
        a0 = round(initial_deg * 100)
        if not lo <= a0 <= hi:
            raise ValueError(f"initial angle {initial_deg} deg is outside the limits {limits}")
        self._ddps = 0
        super().__init__(sched, bus, number, a0, status_offset)

    # ------------------------------------------------------------ readings
    @property
    def angle_cdeg(self) -> int:
        """Current angle in 0.01 deg (exact)."""
        return self._position()

    @property
    def angle_deg(self) -> float:
        return self._position() / 100

    @property
    def speed_ddps(self) -> int:
        """Current signed speed in 0.1 deg/s."""
        return self._dir * self._ddps if self._moving() else 0

    @property
    def target_cdeg(self) -> int | None:
        return self._target

    STATUS_SIGNALS = ("angle", "speed", "state", "seq")

    def status_values(self) -> tuple[int, ...]:
        return self._position(), self.speed_ddps, self.state, self.seq

    # ------------------------------------------------------------ commands
    def _command(self, v: dict[str, int]) -> None:
        seq, mode = v["seq"], v["mode"]
        if self.faulted:
            self._refuse(seq, REFUSED_FAULTED)
        elif mode == MODE_MOVE:
            angle, ddps = v["angle"], v["speed"] or self.default_ddps
            if not self.min_cdeg <= angle <= self.max_cdeg or ddps > self.max_ddps:
                self._refuse(seq, REFUSED_RANGE)
                return
            self.seq = seq
            self.state = STATE_MOVING
            self._ddps = ddps
            self._start_motion(angle, ddps * 10, TICK_HZ)
        elif mode in (MODE_HOLD, MODE_RELAX):
            self.seq = seq
            self._halt()
            self.state = STATE_HOLDING if mode == MODE_HOLD else STATE_IDLE
            self._event(EVENT_DONE, seq)
        else:
            self._refuse(seq, REFUSED_RANGE)

    def _arrived(self) -> None:
        self.state = STATE_HOLDING
        self._event(EVENT_DONE, self.seq)

    # ------------------------------------------------------------ fault injection
    def stall(self, at_deg: float | None = None) -> None:
        """Jam the joint now (``at_deg`` None) or when its motion reaches ``at_deg``."""
        self._stall_at(None if at_deg is None else round(at_deg * 100))


class PawNode(_AxisNode):
    """Paw (gripper) executive, node 6 (see the module docstring).

    ``stroke_ms``: time of a full 0..100 % stroke (constant speed). ``object_size_pct``: the
    opening at which the fingers meet an object placed with :meth:`place_object`.
    """

    def __init__(self, sched: Scheduler, bus: NodeBus, stroke_ms: float = PAW_STROKE_MS,
                 object_size_pct: float = 40.0, initial_opening_pct: float = 100.0,
                 status_offset: int | None = None) -> None:
        self.stroke_ticks = round(stroke_ms * MS)
        if self.stroke_ticks <= 0:
            raise ValueError("stroke time must be positive")
        self.object_present = False
        self.object_pos = self._pct(object_size_pct)
        self.grip = 0
        self.force = 0
        """Force of the last command taken (%); recorded, not modelled."""
        self._closing = False
        super().__init__(sched, bus, dbc.PAW_NUMBER, self._pct(initial_opening_pct), status_offset)

    @staticmethod
    def _pct(pct: float) -> int:
        pos = round(pct * PAW_FULL / 100)
        if not 0 <= pos <= PAW_FULL:
            raise ValueError(f"paw opening must be 0..100 %, got {pct}")
        return pos

    @property
    def opening_units(self) -> int:
        """Current opening in 0.01 % (exact)."""
        return self._position()

    @property
    def opening_pct(self) -> float:
        return self._position() * 100 / PAW_FULL

    STATUS_SIGNALS = ("opening", "grip", "state", "seq")

    def status_values(self) -> tuple[int, ...]:
        return self._position() * 100 // PAW_FULL, self.grip, self.state, self.seq

    def place_object(self, present: bool = True, size_pct: float | None = None) -> None:
        """Put an object between the fingers (or take it away). Taking it away while gripped
        leaves the paw where it is, grip 0, idle. Placing it while closing stops the paw on it."""
        if size_pct is not None:
            self.object_pos = self._pct(size_pct)
        self.object_present = bool(present)
        if not present and self.grip:
            self.grip = 0
            if self.state == STATE_HOLDING:
                self.state = STATE_IDLE
        elif present and self._closing and self._target is not None:
            self._target = self._close_target(self._position())
            self._replan()

    def _close_target(self, p: int) -> int:
        if self.object_present:
            return self.object_pos if p > self.object_pos else p
        return 0

    def _command(self, v: dict[str, int]) -> None:
        seq, action = v["seq"], v["action"]
        if self.faulted:
            self._refuse(seq, REFUSED_FAULTED)
            return
        if action not in (ACTION_CLOSE, ACTION_OPEN) or v["force"] > 100:
            self._refuse(seq, REFUSED_RANGE)
            return
        self.seq = seq
        self.force = v["force"]
        self.state = STATE_MOVING
        p = self._position()
        num, den = PAW_FULL, self.stroke_ticks
        if action == ACTION_OPEN:
            self.grip = 0
            self._closing = False
            self._start_motion(PAW_FULL, num, den)
        else:
            self._closing = True
            self._start_motion(self._close_target(p), num, den)

    def _arrived(self) -> None:
        if self._closing and self.object_present:
            self.grip = 1
            self.state = STATE_HOLDING
        else:
            self.state = STATE_IDLE
        self._closing = False
        self._event(EVENT_DONE, self.seq)

    def _halt(self) -> None:
        super()._halt()
        self._closing = False

    def _rest_state_after_estop(self) -> int:
        return STATE_HOLDING if self.grip else STATE_IDLE

    def stall(self, at_pct: float | None = None) -> None:
        """Jam the paw now (``at_pct`` None) or when its motion reaches ``at_pct``."""
        self._stall_at(None if at_pct is None else self._pct(at_pct))


class WheelNode(_Submodule):
    """Wheel executive, node 5: speed ramp and odometer (see the module docstring).

    ``max_speed_mm_s``: commands above it (in magnitude) are refused; ``accel_mm_s2``: the
    speed changes by at most this much a second (``accel_mm_s2`` um/s a 1 ms step).
    """

    def __init__(self, sched: Scheduler, bus: NodeBus, max_speed_mm_s: int = WHEEL_MAX_SPEED_MM_S,
                 accel_mm_s2: int = WHEEL_ACCEL_MM_S2, status_offset: int | None = None) -> None:
        if not isinstance(accel_mm_s2, int) or accel_mm_s2 <= 0:
            raise ValueError("accel_mm_s2 must be a positive int (um/s per 1 ms step)")
        self.max_speed_mm_s = int(max_speed_mm_s)
        self.accel_mm_s2 = accel_mm_s2
        # With 1 ms steps: the speed changes by at most accel_mm_s2 um/s a step, and a step at
        # v um/s covers exactly v nm.
        self._a = accel_mm_s2
        self.v_ums = 0
        """Speed, um/s (signed)."""
        self._x_nm = 0
        """Odometer, nm (signed), at the last step taken (see :attr:`x_nm`)."""
        self._cruise_from: int | None = None
        """While cruising (constant speed, nothing left to do but roll): the tick of the last
        step taken. The steps after it are not scheduled; their sum is :attr:`x_nm`."""
        self._v_cmd = 0
        self._remaining: int | None = None  # nm still to go (distance command), else None
        self._dir = 0
        self._reported = True  # continuous command: EVENT done already sent
        self._step_ev: Event | None = None
        self._stall_ev: Event | None = None
        self._noprog_since: int | None = None
        self.jammed = False
        super().__init__(sched, bus, dbc.WHEEL_NUMBER, status_offset)

    @property
    def x_nm(self) -> int:
        """Odometer, nm (signed), now: with the step of this tick done (``Scheduler.at_top``).
        While cruising, each 1 ms step since the last one taken adds the speed (v um/s for
        1 ms is v nm): the steps are counted, not run."""
        c = self._cruise_from
        if c is None:
            return self._x_nm
        return self._x_nm + self.v_ums * ((self.sched.now - c) // WHEEL_STEP_TICKS)

    @property
    def cruising(self) -> bool:
        """Rolling at the commanded constant speed, its steps counted in closed form."""
        return self._cruise_from is not None

    def _stop_cruising(self) -> None:
        """Take the steps counted while cruising and schedule the next one on the same 1 ms
        grid, as if every step had run: called before anything reads or changes the motion
        other than through :attr:`x_nm`."""
        c = self._cruise_from
        if c is None:
            return
        k = (self.sched.now - c) // WHEEL_STEP_TICKS
        self._x_nm += self.v_ums * k
        self._cruise_from = None
        self._step_ev = self._at_step(c + (k + 1) * WHEEL_STEP_TICKS)

    @property
    def speed_mm_s(self) -> int:
        return _trunc_div(self.v_ums, 1000)

    @property
    def odometer_mm(self) -> int:
        return _trunc_div(self.x_nm, 1_000_000)

    STATUS_SIGNALS = ("speed", "odometer", "state", "seq")

    def status_values(self) -> tuple[int, ...]:
        return self.speed_mm_s, self.odometer_mm, self.state, self.seq

    # ------------------------------------------------------------ commands
    def _command(self, v: dict[str, int]) -> None:
        seq, speed, dist = v["seq"], v["speed"], v["distance"]
        self._stop_cruising()
        if self.faulted:
            self._refuse(seq, REFUSED_FAULTED)
            return
        if abs(speed) > self.max_speed_mm_s or (dist and _sign(dist) != _sign(speed)):
            self._refuse(seq, REFUSED_RANGE)
            return
        self.seq = seq
        self._v_cmd = speed * 1000
        self._dir = _sign(speed)
        self._remaining = abs(dist) * 1_000_000 if dist else None
        self._reported = False
        self.state = STATE_MOVING
        if self.jammed:
            if self._remaining is None and speed == 0:
                self._cancel_stall()
                self._finish_continuous()
            else:
                self._no_progress()
            return
        if self._remaining is None and self.v_ums == self._v_cmd:
            self._finish_continuous()
            return
        if self._step_ev is None:
            self._step_ev = self._at_step(self.sched.now + WHEEL_STEP_TICKS)

    def _at_step(self, when: int) -> Event:
        """Schedule a 1 ms step at tick ``when``, before every other event of that tick when
        the clock can (``Scheduler.at_top``): whatever reads the wheel during a tick sees the
        step of that tick done."""
        sched = self.sched
        at = getattr(sched, "at_top", None) or sched.at
        return at(when, self._step)

    def _finish_continuous(self) -> None:
        self._reported = True
        self.state = STATE_IDLE if self.v_ums == 0 else STATE_MOVING
        self._event(EVENT_DONE, self.seq)

    @staticmethod
    def _brake(u: int, a: int) -> int:
        """Distance (nm) covered braking at full rate from speed u (um/s) with 1 ms steps."""
        if u <= 0:
            return 0
        q = u // a
        return q * u - a * q * (q + 1) // 2

    def _step(self) -> None:
        self._step_ev = None
        a = self._a
        if self._remaining is None:
            v, tgt = self.v_ums, self._v_cmd
            v += max(-a, min(a, tgt - v))
            self.v_ums = v
            self._x_nm += v
            if v == tgt:
                if not self._reported:
                    self._finish_continuous()
                if v != 0:
                    # cruising: every further step adds v and changes nothing else
                    self._cruise_from = self.sched.now
                return
        else:
            d = self._dir
            u = d * self.v_ums
            rem = self._remaining
            lo = u - a
            hi = max(lo, min(abs(self._v_cmd), u + a))
            brake = self._brake
            if hi <= 0 or hi + brake(hi, a) <= rem:
                w = hi
            elif lo + brake(lo, a) > rem:
                w = lo
            else:  # largest w in [lo, hi) with w + brake(w) <= rem
                fits, over = lo, hi
                while over - fits > 1:
                    m = (fits + over) // 2
                    if m + brake(m, a) <= rem:
                        fits = m
                    else:
                        over = m
                w = fits
            if w >= rem:
                self._x_nm += d * rem
                self.v_ums = 0
                self._remaining = None
                self._v_cmd = 0
                self._reported = True
                self.state = STATE_IDLE
                self._event(EVENT_DONE, self.seq)
            else:
                self._x_nm += d * w
                self._remaining = rem - w
                self.v_ums = d * w
        if self.v_ums != 0 or self._remaining is not None or self.v_ums != self._v_cmd:
            self._step_ev = self._at_step(self.sched.now + WHEEL_STEP_TICKS)

    # ------------------------------------------------------------ stall / halt
    def _stall_detected(self) -> None:
        self._stall_ev = None
        self._noprog_since = None
        self._v_cmd = 0
        self._remaining = None
        self._reported = True
        self.state = STATE_STALLED
        self._event(EVENT_FAULT, self.seq, FAULT_STALLED)

    def _stop_stepping(self) -> None:
        self._stop_cruising()
        if self._step_ev is not None:
            self._step_ev.cancel()
            self._step_ev = None

    def _halt(self) -> None:
        self._stop_stepping()
        self._cancel_stall()
        self.v_ums = 0
        self._v_cmd = 0
        self._remaining = None
        self._reported = True

    def _rest_state_after_estop(self) -> int:
        return STATE_IDLE

    def stall(self) -> None:
        """Jam the wheel now: its speed drops to 0 and it cannot turn until :meth:`clear_fault`.
        A motion commanded (now or later) is reported stalled 200 ms after progress stopped."""
        self.jammed = True
        self._stop_stepping()
        self.v_ums = 0
        if self.state != STATE_MOVING:
            return
        if self._v_cmd != 0 or self._remaining is not None:
            self._no_progress()
        elif not self._reported:
            self._finish_continuous()
        else:
            self.state = STATE_IDLE

    def clear_fault(self) -> None:
        self._stop_cruising()
        self.jammed = False
        if self.faulted:
            self._halt()
            self.state = STATE_IDLE
        elif self._stall_ev is not None:  # blocked, not yet detected: resume
            self._cancel_stall()
            if self._step_ev is None:
                self._step_ev = self._at_step(self.sched.now + WHEEL_STEP_TICKS)


def make_submodules(sched: Scheduler, bus: NodeBus,
                    initial_angles: Sequence[float] = (0.0, 0.0, 0.0, 0.0),
                    ) -> dict[str, _Submodule]:
    """The six executive submodules with the default parameters (module docstring table),
    attached to ``bus``, keyed by DBC node name: JOINT1..JOINT4, WHEEL, PAW.

    ``initial_angles``: joint 1..4 angles (deg) at power-up, e.g. ``kinematics.HOME`` so that
    the nodes start where the planner believes they are."""
    if len(initial_angles) != 4:
        raise ValueError("initial_angles needs the four joint angles")
    nodes: dict[str, _Submodule] = {}
    for n, params in JOINT_DEFAULTS.items():
        nodes[f"JOINT{n}"] = JointNode(sched, bus, n, initial_deg=initial_angles[n - 1], **params)
    nodes["WHEEL"] = WheelNode(sched, bus)
    nodes["PAW"] = PawNode(sched, bus)
    return nodes
