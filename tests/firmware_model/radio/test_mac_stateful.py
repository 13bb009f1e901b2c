"""Hypothesis stateful tests: hunt counterexamples to the MAC's invariants over fault timings
(issue 9, "What to build" item 3, last paragraph).

A formed ring of the father and three children (checksum extension on, as in the fault
matrix) is driven by rules: let time pass, submit a message, and inject faults at exact ticks
(a robot's radio dies or comes back, a foreign transmitter's burst of N bytes, a robot that
wrongly takes the turn, a window of byte errors, a forged frame from outside the team).
At the end, once the faults stop and the queues drain, the invariants of docs/guarantees.md
are checked with the soak's own checking function (``hil.sim.soak.SoakResult.invariants``:
every message delivered or failed, nothing delivered twice or to the wrong robot, no corrupted
command acted on, the ring whole again within ``REFORM_BOUND_S`` of the last fault, sampled
every ``SAMPLE_S`` as the soak does). After every step, and again at the end:

* no silent loss, as it happens: no message is still pending ``max_age`` + ``LOSS_SLACK_S``
  after its submission;
* nothing delivered twice or to a robot it is not for, so far;
* no action on a forged frame: a forged frame's command is never delivered (a delivery that
  matches no submitted message counts as corrupted) and a Source outside the team is never
  admitted to a ring;
* no mutual drop without a sustained fault: two robots whose radios work never drop each
  other unless an air fault longer than ``SUSTAINED_S`` (a burst, a window of byte errors),
  or a death of one of the two, came in the ``MUTUAL_WINDOW_S`` before.

Runs are derandomized (the same examples every time) and use no example database. The hunt
found three runs that broke these invariants (deeper hunts than the suite's: see
``HUNT_EXAMPLES``): members whose views of the ring differed ended sending in the same slot for
ever. Rule R-view (docs/protocol.md clause 51) fixed them; each is replayed below tick-exact on
a fresh world.
"""
from __future__ import annotations

import os
import pickle
import random

import pytest

from hypothesis import HealthCheck, settings, strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, precondition, rule

from firmware_model.radio.content import cmd
from firmware_model.radio.integrity import seal
from firmware_model.radio.mac import MacConfig, SubmitError
from firmware_model.timing import PC_BYTE_TICKS, TICK_HZ, TMAX_TICKS, s_to_ticks
from hil.sim.soak import REFORM_BOUND_S, SAMPLE_S, SoakResult
from hil.sim.world import SimConfig, World

ROBOTS = (0, 1, 2, 3)
OUTSIDERS = (4, 5, 6)            # robot IDs that are not in this team
MAX_AGE_S = 8.0
LOAD = 2.0
"""Messages a second each robot submits (seeded, to random destinations), besides the
``submit`` rule's; the load stops when the faults stop, before the drain."""
LOSS_SLACK_S = 5.0
"""How long past ``max_age`` a message may still be pending: a sender whose radio is dead
expires its queue at its own turns, and it takes turns again once it has claimed the channel
as a ring of one (Tclaim = |team| x Tmax + id x Tslot <= 3.4 s here)."""
SUSTAINED_S = TMAX_TICKS / TICK_HZ
"""An air fault longer than one Tmax (or a death of one of the two) may excuse a mutual drop."""
MUTUAL_WINDOW_S = 6.0
"""A drop needs 3 consecutive misses: at most 3 x (Tmax + a cycle) after the fault."""
DRAIN_S = MAX_AGE_S + LOSS_SLACK_S + REFORM_BOUND_S
FORGED_COMMAND = cmd("movex", -777)
"""No message of these tests carries it: delivering it is acting on a forged frame."""
B = PC_BYTE_TICKS                # a foreign transmitter's byte time

_BASE: bytes | None = None


def formed_ring() -> World:
    """The ring of ``ROBOTS`` once every member has every other in its ring (pickled once)."""
    global _BASE
    if _BASE is None:
        w = World(SimConfig(robots=ROBOTS, duration=3600.0, seed=5, load=LOAD,
                            mac=MacConfig(checksum=True, max_age=s_to_ticks(MAX_AGE_S)),
                            keep_records=True),
                  on_event=[].append)
        def formed() -> bool:        # (before power-on nobody is alive: "complete" too)
            return w.ring_complete() and all(v == ROBOTS for v in w.ring_views().values())
        while not formed() and w.now < s_to_ticks(30.0):
            w.run(w.now + s_to_ticks(0.25))
        assert formed(), w.ring_views()
        w.run(w.now + s_to_ticks(1.0))
        _BASE = pickle.dumps(w, pickle.HIGHEST_PROTOCOL)
    return pickle.loads(_BASE)


class MacUnderFaults(RuleBasedStateMachine):
    def __init__(self) -> None:
        super().__init__()
        self.w = formed_ring()
        # the copy's own record list: what its on_event (a RecordListener) appends to
        self.evs: list[dict] = self.w.listeners[0].fn.__self__
        self.evs.clear()
        self.t0 = self.w.now
        self.down: dict[int, int] = {}                 # robot -> tick its radio died
        self.deaths: list[tuple[int, int, int]] = []   # (robot, died, came back)
        self.air: list[tuple[int, int]] = []           # (start, end) of air faults
        self.last_fault_end = self.w.now
        self.awaiting = False          # a fault ended and the ring has not been whole since
        self.reform: list[float] = []  # seconds from a fault's end to the ring whole again
        self.not_reformed = 0
        self.forged = 0
        self.seen = 0                                  # events already checked

    # -- rules --------------------------------------------------------------------------

    @rule(ms=st.integers(1, 1500))
    def advance(self, ms):
        self._run_until(self.w.now + s_to_ticks(ms / 1000))

    def _run_until(self, t):
        """Run to tick ``t``, looking every SAMPLE_S whether the ring is whole again after the
        last fault (as the soak does)."""
        w = self.w
        while w.now < t:
            w.run(min(t, w.now + s_to_ticks(SAMPLE_S)))
            if self.awaiting and w.now >= self.last_fault_end:
                if w.ring_complete():
                    self.reform.append((w.now - self.last_fault_end) / TICK_HZ)
                    self.awaiting = False
                elif w.now - self.last_fault_end > s_to_ticks(4 * REFORM_BOUND_S):
                    self.not_reformed += 1
                    self.awaiting = False

    @rule(src=st.sampled_from(ROBOTS), dst=st.sampled_from(ROBOTS + (7,)),
          k=st.integers(-10, 10))
    def submit(self, src, dst, k):
        if src != dst:
            try:
                self.w.submit(src, dst, [cmd("movex", k)])
            except SubmitError:
                pass

    @precondition(lambda self: len(self.down) < len(ROBOTS) - 1)
    @rule(robot=st.sampled_from(ROBOTS), delay=st.integers(1, 400_000))
    def fail(self, robot, delay):
        if robot not in self.down:
            t = self.w.now + delay
            self.w.inject("fail", robot, t)
            self.down[robot] = t

    @precondition(lambda self: bool(self.down))
    @rule(data=st.data(), delay=st.integers(1, 400_000))
    def recover(self, data, delay):
        robot = data.draw(st.sampled_from(sorted(self.down)))
        t = max(self.w.now, self.down[robot]) + delay
        self.w.inject("recover", robot, t)
        self.deaths.append((robot, self.down.pop(robot), t))
        self._ended(t)

    @rule(n=st.integers(1, 600), delay=st.integers(1, 400_000), seed=st.integers(0, 2**16))
    def burst(self, n, delay, seed):
        t = self.w.now + delay
        self.w.inject_bytes(random.Random(seed).randbytes(n), t)
        self._air(t, t + n * B)

    @rule(robot=st.sampled_from(ROBOTS), delay=st.integers(1, 400_000))
    def steal(self, robot, delay):
        t = self.w.now + delay
        self.w.inject("steal", robot, t)
        self._ended(t)

    @rule(p=st.floats(0.001, 0.02), ms=st.integers(10, 3000), delay=st.integers(1, 400_000))
    def byte_errors(self, p, ms, delay):
        t = self.w.now + delay
        end = t + s_to_ticks(ms / 1000)
        self.w.inject("ber", None, t, end, p)
        self._air(t, end)

    @rule(src=st.sampled_from(OUTSIDERS), dst=st.sampled_from(ROBOTS + (7,)),
          num=st.integers(0, 99), delay=st.integers(1, 400_000))
    def forge(self, src, dst, num, delay):
        """A frame with a good checksum from a robot ID outside the team."""
        data = seal(dst, src, num, 2, FORGED_COMMAND.text().encode()).encode()
        t = self.w.now + delay
        self.w.inject_bytes(data, t)
        self._air(t, t + len(data) * B)
        self.forged += 1

    def _air(self, start, end):
        self.air.append((start, end))
        self._ended(end)

    def _ended(self, t):
        """A fault ends at tick ``t``: the ring must be whole within REFORM_BOUND_S of the last
        one to end (a fault that comes before it is whole restarts the clock)."""
        self.last_fault_end = max(self.last_fault_end, t)
        self.awaiting = True

    # -- invariants ---------------------------------------------------------------------

    @invariant()
    def nothing_delivered_twice_wrongly_or_forged(self):
        w = self.w
        assert all(c == 1 for c in w.deliveries.values()), \
            [k for k, c in w.deliveries.items() if c > 1]
        assert w.wrong_deliveries == 0
        assert w.corrupt_deliveries == 0           # with the checksum: forged or corrupted

    @invariant()
    def no_outsider_admitted(self):
        assert all(not set(v) & set(OUTSIDERS) for v in self.w.ring_views().values())

    @invariant()
    def no_silent_loss_so_far(self):
        limit = self.w.now - s_to_ticks(MAX_AGE_S + LOSS_SLACK_S)
        late = [m for m in self.w.messages if m.state in ("queued", "sent") and
                m.submitted < limit]
        assert not late, [(m.src, m.dst, m.num, m.submitted, m.state) for m in late]

    @invariant()
    def no_mutual_drop_without_a_sustained_fault(self):
        new = self.evs[self.seen:]
        self.seen = len(self.evs)
        drops = {(e["by"], e["robot"]): e["t"] for e in self.evs if e["ev"] == "disable"}
        for e in new:
            if e["ev"] != "disable" or (e["robot"], e["by"]) not in drops:
                continue
            a, b = e["by"], e["robot"]
            t1, t2 = sorted((drops[(b, a)], e["t"]))
            if t2 - t1 > s_to_ticks(MUTUAL_WINDOW_S):
                continue                           # two separate episodes
            lo = t1 - s_to_ticks(MUTUAL_WINDOW_S)
            assert self._sustained(lo, t2, (a, b)), (
                f"robots {a} and {b} dropped each other at ticks {t1} and {t2} with no fault "
                f"longer than {SUSTAINED_S} s since tick {lo}: {self._history()}")

    def _sustained(self, lo, hi, pair) -> bool:
        long = s_to_ticks(SUSTAINED_S)
        spans = list(self.air) + [(d, back) for r, d, back in self.deaths if r in pair] + \
            [(d, self.w.now) for r, d in self.down.items() if r in pair]
        return any(end - start > long and start <= hi and end >= lo for start, end in spans)

    def _history(self) -> str:
        return f"air {self.air}, deaths {self.deaths}, down {self.down}"

    # -- the end ------------------------------------------------------------------------

    def teardown(self):
        w = self.w
        w.load.end(w.now)                          # no new messages: let the queues drain
        for robot, died in list(self.down.items()):
            t = max(w.now, died) + 1
            w.inject("recover", robot, t)
            self.deaths.append((robot, self.down.pop(robot), t))
            self._ended(t)
        self._run_until(max(w.now, self.last_fault_end) + s_to_ticks(DRAIN_S))
        if self.awaiting:
            self.not_reformed += 1
        self.no_mutual_drop_without_a_sustained_fault()
        kinds = {"fail": len(self.deaths), "air": len(self.air), "forged": self.forged}
        res = SoakResult(hours=(w.now - self.t0) / TICK_HZ / 3600, seed=5, checksum=True,
                         faults=kinds, summary=w.summary(), reform_s=self.reform,
                         not_reformed=self.not_reformed)
        broken = {k: v for k, v in res.invariants.items() if not v}
        s = res.summary
        assert not broken, (broken, {k: s[k] for k in ("submitted", "delivered", "failed",
                                                       "pending")}, self.reform, self._history())
        assert all(e["reason"] for e in self.evs if e["ev"] == "fail")
        assert not [e for e in self.evs if e["ev"] in ("join", "rejoin") and
                    e["robot"] in OUTSIDERS]


HUNT_EXAMPLES = int(os.environ.get("RPRS_HUNT_EXAMPLES", "10"))
HUNT_STEPS = int(os.environ.get("RPRS_HUNT_STEPS", "30"))
HUNT_RANDOM = bool(os.environ.get("RPRS_HUNT_RANDOM"))
"""The fast tier's hunt is modest (10 examples of 30 steps, about 5 s of CPU); the slow tier
hunts 60 (``MacUnderFaultsThoroughly``). A deeper one, still derandomized (the same examples
for the same numbers): ``RPRS_HUNT_EXAMPLES=1000 RPRS_HUNT_STEPS=80`` (minutes). Other
examples: ``RPRS_HUNT_RANDOM=1`` with ``--hypothesis-seed=N``."""


def _hunt(examples: int) -> settings:
    return settings(max_examples=examples, stateful_step_count=HUNT_STEPS,
                    derandomize=not HUNT_RANDOM, database=None, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow], print_blob=False)


class MacUnderFaultsThoroughly(MacUnderFaults):
    """The same machine, for the slow tier's longer hunt."""


MacUnderFaults.TestCase.settings = _hunt(HUNT_EXAMPLES)
MacUnderFaultsThoroughly.TestCase.settings = _hunt(max(60, HUNT_EXAMPLES))
test_mac_invariants_hold_under_fault_timings = MacUnderFaults.TestCase
test_mac_invariants_hold_under_fault_timings_thoroughly = pytest.mark.slow(
    MacUnderFaultsThoroughly.TestCase)



# -- counterexamples the hunt found, as explicit runs ----------------------------------------

def _mode_at(evs, robot, t):
    """``robot``'s mode (member or listen) just before tick ``t`` (member once formed)."""
    mode = "member"
    for e in evs:
        if e.get("t", 0) >= t:
            break
        if e["ev"] == "mode" and e["robot"] == robot:
            mode = e["mode"]
    return mode


def test_hunt_counterexample_members_that_disagree_on_a_silent_robot():
    """Found by the hunt above: once the last fault has ended, no member whose radio works is
    dropped by another member (docs/guarantees.md: after any fault ends the ring is whole
    again; paper §IV.D: every member drops a silent robot at the same tick)."""
    evs: list[dict] = []
    w = World(SimConfig(robots=ROBOTS, duration=40.0, seed=5, load=LOAD,
                        mac=MacConfig(checksum=True, max_age=s_to_ticks(MAX_AGE_S))),
              on_event=evs.append)
    for seed, n, t in ((507, 327, 42097317), (1543, 600, 94144386), (3975, 503, 117449589)):
        w.inject_bytes(random.Random(seed).randbytes(n), t)
    for kind, robot, t in (("fail", 1, 53315360), ("recover", 1, 72163165),
                           ("steal", 1, 72290013), ("fail", 3, 94144672),
                           ("steal", 0, 94146289), ("fail", 2, 94149210),
                           ("recover", 3, 117168001), ("recover", 2, 117168001)):
        w.inject(kind, robot, t)
    w.run()
    last = 117449589 + 503 * B                  # the last fault (a burst) ends
    assert last == 125833090
    dropped = [(e["t"], e["by"], e["robot"]) for e in evs if e["ev"] == "disable" and
               e["t"] > last and _mode_at(evs, e["robot"], e["t"]) == "member" and
               _mode_at(evs, e["by"], e["t"]) == "member"]
    assert dropped == []


def test_hunt_counterexample_a_father_that_dropped_a_live_member_never_hears_it_again():
    """Found by the hunt above: after any fault ends the ring is whole again within
    REFORM_BOUND_S (docs/guarantees.md), and stays so while no new fault comes."""
    evs: list[dict] = []
    w = World(SimConfig(robots=ROBOTS, duration=30.0, seed=5,
                        mac=MacConfig(checksum=True, max_age=s_to_ticks(MAX_AGE_S))),
              on_event=evs.append)
    forged = FORGED_COMMAND.text().encode()
    for data, t in ((random.Random(515).randbytes(83), 47882747),
                    (seal(3, 6, 81, 2, forged).encode(), 52140567),
                    (seal(3, 5, 30, 2, forged).encode(), 51888157),
                    (seal(2, 5, 77, 2, forged).encode(), 75104490),
                    (random.Random(1742).randbytes(154), 79536001),
                    (random.Random(1176).randbytes(474), 82784004),
                    (random.Random(4561).randbytes(598), 82784171)):
        w.inject_bytes(data, t)
    for t0, t1, p in ((52043741, 65355741, 0.012621879095562467),
                      (75108119, 100084119, 0.01), (83184000, 110048000, 0.01705455206199317)):
        w.inject("ber", None, t0, t1, p)
    for src, dst, k, t in ((0, 3, -10, 47856000), (1, 0, 9, 75104000), (2, 0, 10, 75104000),
                           (0, 7, -4, 75104000)):
        w.sched.at(t, lambda s=src, d=dst, k=k: w.submit(s, d, [cmd("movex", k)]))
    _whole_within_the_bound_and_stays(w, evs, 110048000)


def test_hunt_counterexample_three_robots_split_for_ever_after_two_steals():
    """Found by the hunt (the smallest of this class: every ring of 3 or more members in the
    hunt ends split this way, never a ring of two): after the last fault the ring is whole
    within REFORM_BOUND_S (docs/guarantees.md) and stays so."""
    evs: list[dict] = []
    w = World(SimConfig(robots=(1, 2, 3), duration=30.0, seed=5,
                        mac=MacConfig(checksum=True, max_age=s_to_ticks(MAX_AGE_S))),
              on_event=evs.append)
    forged = FORGED_COMMAND.text().encode()
    for (dst, src, num), t in (((7, 4, 43), 52247623), ((7, 4, 15), 60726239),
                               ((3, 6, 75), 84261287)):
        w.inject_bytes(seal(dst, src, num, 2, forged).encode(), t)
    for robot, t in ((3, 60736500), (1, 72415743), (1, 84256586)):
        w.inject("steal", robot, t)
    w.sched.at(72400000, lambda: w.submit(3, 2, [cmd("movex", 3)]))
    last = 84261287 + len(seal(3, 6, 75, 2, forged).encode()) * B
    _whole_within_the_bound_and_stays(w, evs, last)


def _whole_within_the_bound_and_stays(w, evs, last):
    w.run(last)
    whole_at = None
    while w.now < last + s_to_ticks(REFORM_BOUND_S):
        w.run(w.now + s_to_ticks(SAMPLE_S))
        if w.ring_complete():
            whole_at = w.now
            break
    assert whole_at is not None, w.ring_views()
    w.run()
    assert w.ring_complete() and not [e for e in evs if e["ev"] == "collision" and
                                      e["t"] > whole_at and -1 not in e["robots"]]
