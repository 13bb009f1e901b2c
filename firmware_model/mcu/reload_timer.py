"""MB90F549 16-bit reload timer (registers TMCSR0/TMR0/TMRLR0), tick-exact.

The counter is loaded from TMRLR on a software trigger and counts down once per prescaler
clock (machine clock / 2, / 8 or / 32, TMCSR.CSL). It underflows when it passes 0000 -> FFFF, so
one period is ``(TMRLR + 1) * prescaler`` ticks; the trigger restarts the prescaler, so the
first underflow is exactly one period after the trigger. In reload mode the counter reloads and
interrupts again each period.

The firmware needs delays longer than one 16-bit period (Tmax = 600 ms): it runs the timer in
reload mode and counts underflows in the ISR. ``arm_after`` picks an exact (prescaler, TMRLR,
count) for a delay and schedules only the last underflow: the earlier ISRs only decrement the
software counter, so skipping them changes nothing observable. Re-arming is lazy: if the pending
scheduler event is not later than the new expiry it is kept and moved on when it fires, so the
MAC re-arming its timer every turn costs no heap traffic.
"""
from __future__ import annotations

from typing import Callable

from .scheduler import Clock, Event

PRESCALERS = (2, 8, 32)
"""TMCSR.CSL: machine clock divided by 2^1, 2^3, 2^5."""

MAX_RELOAD = 0xFFFF


def plan_delay(ticks: int, prescaler: int = 2) -> tuple[int, int, int]:
    """Exact timer programme for a delay: (prescaler, first TMRLR, full periods after it).

    The firmware loads TMRLR for a first, shorter period, then reloads FFFF for ``full``
    periods of 65536 counts: ``((first + 1) + full * 65536) * prescaler == ticks``. Raises
    ValueError when the delay is not a whole number of prescaler clocks."""
    if prescaler not in PRESCALERS:
        raise ValueError(f"prescaler must be one of {PRESCALERS}, got {prescaler}")
    if ticks <= 0 or ticks % prescaler:
        raise ValueError(f"a delay of {ticks} ticks is not a positive whole number of timer "
                         f"clocks (machine clock / {prescaler})")
    n = ticks // prescaler
    full = (n - 1) // (MAX_RELOAD + 1)
    first = n - full * (MAX_RELOAD + 1)
    return prescaler, first - 1, full


class ReloadTimer:
    """One reload timer channel; ``on_expiry(now)`` runs at the exact expiry tick."""

    __slots__ = ("sched", "on_expiry", "expiry", "_ev", "delay", "name", "guard")

    def __init__(self, sched: Clock, on_expiry: Callable[[int], None],
                 name: str = "TMR0") -> None:
        self.sched = sched
        self.on_expiry = on_expiry
        self.name = name
        self.guard: Callable[[int], int | None] | None = None
        """Asked when the timer is due: a later tick if the firmware is known to re-arm it
        past now in effects not yet given (bytes handed over late: firmware_model/station.py),
        to look again then; None to expire now."""
        self.expiry: int | None = None
        self._ev: Event | None = None
        self.delay = 0

    @property
    def registers(self) -> tuple[int, int, int]:
        """(prescaler, first TMRLR, full periods) the firmware wrote for the current delay."""
        return plan_delay(self.delay) if self.delay >= 2 else (2, 0, 0)

    def arm_at(self, when: int, now: int | None = None) -> None:
        """Expire at tick ``when`` (programming the delay from now with ``plan_delay``).
        ``now``: the tick the firmware programs it at, if earlier than the scheduler's (a
        handler's effects given late, Uart._replay); ``when`` is later than both."""
        if now is None:
            now = self.sched.now
        ev = self._ev
        if when <= now:
            when = now
        else:
            # The timer counts machine clock / 2: an odd delay is rounded up by one tick.
            delay = when - now
            delay += delay & 1
            self.delay = delay
            if ev is not None and ev.when <= when and not ev.cancelled:
                # Common case (re-armed later every turn): keep the pending event.
                self.expiry = now + delay
                return
            when = now + delay
        self.expiry = when
        if ev is not None and not ev.cancelled:
            if ev.when <= when:
                return  # keep the earlier event; it moves itself on when it fires
            ev.cancel()
        self._ev = self.sched.at(when, self._fire)

    def programmed(self, when: int, now: int) -> None:
        """The firmware programmed an expiry at ``when`` at tick ``now`` (earlier than the
        scheduler's) and stopped the timer since, before it expired: the registers as
        ``arm_at`` then ``stop`` leave them, without an event (bytes whose handlers armed it
        given with the next byte's, which stopped it: firmware_model/station.py)."""
        delay = when - now
        self.delay = delay + (delay & 1)
        self.stop()

    def stop(self) -> None:
        """Clear TMCSR.CNTE: no more interrupts."""
        self.expiry = None
        if self._ev is not None:
            self._ev.cancel()
            self._ev = None

    def _fire(self) -> None:
        now = self.sched.now
        exp = self.expiry
        if exp is None:
            self._ev = None
            return
        if now < exp:
            self._ev = self.sched.at(exp, self._fire)
            return
        if self.guard is not None:
            later = self.guard(now)
            if later is not None and later > now:
                self._ev = self.sched.at(later, self._fire)
                return
        self._ev = None
        self.expiry = None
        self.on_expiry(now)
