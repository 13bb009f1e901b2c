"""The wheel (can_bus.submodules): a 1 ms physics step in exact integers (um/s, nm), that a
cruising wheel stops scheduling."""
from __future__ import annotations


from can_bus import dbc
from can_bus.node import NodeBus
from can_bus.dbc import (
    EVENT_DONE,
    EVENT_FAULT,
    FAULT_STALLED,
    REFUSED_FAULTED,
    REFUSED_RANGE,
    STATE_IDLE,
    STATE_MOVING,
    STATE_STALLED,
)
from can_bus.clock import Cancellable as Event, Clock as Scheduler

from .params import WHEEL_ACCEL_MM_S2, WHEEL_MAX_SPEED_MM_S, WHEEL_STEP_TICKS, _sign, _trunc_div
from .node import _Submodule


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

    def status_values_at(self, tick: int) -> tuple[int, ...]:
        """:meth:`status_values` at a later ``tick`` (its step done), while it cruises on
        undisturbed: the odometer in closed form (a simulator that skips the wheel's
        periods asks it for the frames it would send)."""
        c = self._cruise_from
        if c is None or tick < c:
            raise ValueError("the status ahead of time is known only while cruising")
        x = self._x_nm + self.v_ums * ((tick - c) // WHEEL_STEP_TICKS)
        return self.speed_mm_s, _trunc_div(x, 1_000_000), self.state, self.seq

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
