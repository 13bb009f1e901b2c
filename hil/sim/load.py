"""The load a simulated ring carries (``SimConfig.load``): heartbeats only (``idle``), a full-size
message always queued at every robot (``saturate``), or messages arriving at each robot at a
rate (Poisson, messages/s), of one to three plausible commands to another robot or to all.
Each robot draws from its own stream, seeded by the run's seed, so the same configuration puts
the same messages on the ring to the tick; ``load_until`` ends the arrivals (a run that drains
its queues)."""
from __future__ import annotations

import random
from functools import lru_cache
from typing import TYPE_CHECKING, Callable, Iterable

from firmware_model.radio.content import Command, cmd
from firmware_model.radio.frame import BROADCAST
from firmware_model.radio.mac import SubmitError
from firmware_model.timing import TICK_HZ, s_to_ticks

if TYPE_CHECKING:
    from firmware_model.station import RadioStation

    from .config import SimConfig


def random_commands(rng: random.Random) -> list[Command]:
    """One to three plausible application commands (seeded): small tip moves, targets in the
    arm's workspace, joint angles and wheel speeds within their limits."""
    out = []
    for _ in range(rng.randint(1, 3)):
        k = rng.randrange(7)
        if k == 0:
            out.append(cmd("movex", rng.randint(-10, 10)))
        elif k == 1:
            out.append(cmd("movey", rng.randint(-10, 10)))
        elif k == 2:
            out.append(cmd("movez", rng.randint(-10, 10)))
        elif k == 3:
            out.append(cmd("moveto", rng.randint(180, 240), rng.randint(-60, 60),
                           rng.randint(60, 140)))
        elif k == 4:
            out.append(cmd("joint", 1, rng.randint(-90, 90)))
        elif k == 5:
            out.append(cmd("wheel", rng.randint(-100, 100)))
        else:
            out.append(cmd("paw", rng.randint(0, 1)))
    return out


@lru_cache(maxsize=64)
def filled_commands(size: int) -> tuple[Command, ...]:
    """Commands whose Content is ``size`` bytes or up to 7 fewer (a full-size message)."""
    out = []
    left = size
    while left >= 16:
        out.append(cmd("movex", 123456789))   # 'movex(123456789)' = 16 bytes
        left -= 16
    if left >= 8:
        out.append(cmd("movex", int("1" * (left - 7))))
    return tuple(out)


class Load:
    """The messages of the load ``cfg`` asks for, submitted with ``submit`` (``World.submit``:
    a message the MAC refuses is counted there and dropped here) at the robots of
    ``stations``. The world calls :meth:`start` when a robot powers on and :meth:`refill` when
    one of its messages ends. It holds no world of its own: the quiet ring's snapshots
    (hil/sim/quiet_ring.py) walk it as a part of the world."""

    def __init__(self, cfg: SimConfig, sched, stations: dict[int, RadioStation],
                 submit: Callable[[int, int, Iterable[Command]], object]) -> None:
        self.sched = sched
        self.stations = stations
        self.submit = submit
        self.load = cfg.load
        self.payload = cfg.payload
        self.until = None if cfg.load_until is None else s_to_ticks(cfg.load_until)
        self.rngs = {r: random.Random(f"{cfg.seed}:load:{r}") for r in cfg.robots}
        robots = sorted(cfg.robots)
        self.others = {r: [x for x in robots if x != r] for r in robots}
        self.due: dict[int, int] = {}
        """Each robot's next message arrival (tick): what the quiet ring's probe asks before
        it pays for a snapshot (hil/sim/quiet_ring.py)."""

    def next_arrival(self) -> int | None:
        """The tick of the next message arrival of any robot, None if none is due (ticks)."""
        return min(self.due.values()) if self.due else None

    def start(self, r: int) -> None:
        """Robot ``r`` has powered on: its first messages, or its first arrival."""
        if self.load == "saturate":
            for _ in range(2):
                self.refill(r)
        elif not isinstance(self.load, str):
            self._schedule_arrival(r)

    def end(self, tick: int) -> None:
        """No new message from ``tick`` on (ticks): the run drains its queues from there, as
        ``load_until`` has it when known before the run."""
        self.until = tick

    def on(self) -> bool:
        """New messages still come (``load_until`` not reached)."""
        return self.until is None or self.sched.now < self.until

    def refill(self, r: int) -> None:
        """Under ``saturate``: one more full-size message at ``r`` (the MAC's largest Content
        less its reserve, unless ``payload`` says) to one of the others."""
        if not self.on():
            return
        others = self.others[r]
        if not others:
            return
        st = self.stations[r]
        dst = self.rngs[r].choice(others)
        # (a peer MAC may take less: a slotted frame fits its slot)
        size = self.payload if self.payload is not None else min(
            st.mac.max_content - st.mac.cfg.mac_reserve,
            getattr(st.mac, "content_limit", st.mac.max_content))
        try:
            self.submit(r, dst, filled_commands(size))
        except SubmitError:
            pass

    def _schedule_arrival(self, r: int) -> None:
        dt = max(1, round(self.rngs[r].expovariate(float(self.load)) * TICK_HZ))
        self.due[r] = self.sched.now + dt
        self.sched.after(dt, self._arrival, r)

    def _arrival(self, r: int) -> None:
        del self.due[r]
        if not self.on():
            return
        rng = self.rngs[r]
        others = self.others[r]
        if others:
            dst = rng.choice(others + [BROADCAST]) if len(others) > 1 else others[0]
            try:
                self.submit(r, dst, random_commands(rng))
            except SubmitError:
                pass
        self._schedule_arrival(r)
