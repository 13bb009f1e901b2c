"""Joints and the paw (can_bus.submodules): one analytic axis at constant speed, in 0.01 deg
or 0.01 % units."""
from __future__ import annotations


from can_bus import dbc
from can_bus.node import NodeBus
from can_bus.dbc import (
    ACTION_CLOSE,
    ACTION_OPEN,
    EVENT_DONE,
    EVENT_FAULT,
    FAULT_STALLED,
    MODE_HOLD,
    MODE_MOVE,
    MODE_RELAX,
    REFUSED_FAULTED,
    REFUSED_RANGE,
    STATE_HOLDING,
    STATE_IDLE,
    STATE_MOVING,
    STATE_STALLED,
)
from can_bus.clock import DEFAULT_TICK_HZ as TICK_HZ
from can_bus.clock import Cancellable as Event, Clock as Scheduler

from .params import MS, PAW_FULL, PAW_STROKE_MS
from .node import _Submodule


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
        stop, blocked = self._stop_from(p, target, d)
        if stop == p:
            self._no_progress()
            return
        self._cancel_stall()
        num, den = self._cmd_rate
        now = self.sched.now
        self._dir, self._num, self._den, self._t0, self._stop = d, num, den, now, stop
        self._arrive_tick = now + -(-abs(stop - p) * den // num)
        self._arrive_ev = self.sched.at(self._arrive_tick, self._on_reach, blocked)

    def _stop_from(self, p: int, target: int, d: int) -> tuple[int, bool]:
        """Where a motion from ``p`` toward ``target`` (direction ``d``) stops, and whether
        the obstacle stops it there (positions in the axis's units)."""
        ob = self._obstacle
        if ob is not None and (p <= ob < target if d > 0 else target < ob <= p):
            return ob, True
        return target, False

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
        stop, blocked = self._stop_from(p, target, d)
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
