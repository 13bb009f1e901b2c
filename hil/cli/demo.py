"""``rprs demo``: the paper's action sequence (Fig. 11) and a ring with a failure and a recovery."""
from __future__ import annotations

import argparse

from firmware_model.timing import TICK_HZ, ticks_to_s

from ..sim import events as E
from ..sim.ledger import SameHappening
from ..sim.trace import TraceWriter
from ..sim.world import ConfigError, SimConfig, World
from .common import (Parser, UserError, auth_option, checked_mac_config, digit, file_name,
                     positive, probability, profile_option)
from .sim import (
    add_sim_options, close_writers, cmd_sim, cpu_costs, cpu_option, dispatch_latency_lines,
    write_failed,
)

STORY_EVENTS = (E.Mode, E.Join, E.Rejoin, E.Disable, E.Miss, E.FaultEdge, E.Collision)
"""The kinds of event the ring demo tells (hil/sim/events.py)."""


def _name(r: int) -> str:
    return "father 0" if r == 0 else f"R{r}"


def ring_story(events: list[E.TraceEvent]) -> list[str]:
    """The run told in lines, one a happening: faults, misses, drops, claims, invitations,
    joins, collisions (each observer's view of the same happening is one line)."""
    lines: list[str] = []
    cut: set[int] = set()                   # robots whose radio a fault has cut off
    meta = next((ev for ev in events if isinstance(ev, E.Meta)), None)
    # the observers' reports of one miss, drop or join, as the run's accounting takes them
    same = SameHappening(meta.tmax // 2 if meta is not None else 0)
    for ev in events:
        k = type(ev)
        if k not in STORY_EVENTS:
            continue
        t = ev.t / TICK_HZ
        if isinstance(ev, E.Collision):
            who = " and ".join(_name(x) for x in ev.robots if x >= 0) or "a foreign radio"
            lines.append(f"{t:8.3f} s  collision: {who} sent at once")
            continue
        r = getattr(ev, "robot", None)
        if r is None:
            continue                        # a fault on the whole channel (noise, a burst)
        by = getattr(ev, "by", None)
        if isinstance(ev, E.Miss) and by in cut:
            continue                        # a robot that hears nothing counts everyone out
        # miss, disable, join, rejoin: told once (a join and a rejoin at once are one
        # admission, as the run's accounting takes them: hil/sim/ledger.py)
        kind = "join" if ev.KIND == "rejoin" else ev.KIND
        if by is not None and not same.first(kind, r, ev.t):
            continue
        if isinstance(ev, E.FaultEdge):
            if ev.phase == "start" and ev.kind in ("fail", "recover"):
                (cut.add if ev.kind == "fail" else cut.discard)(r)
                text = "its radio goes silent" if ev.kind == "fail" else "its radio comes back"
                lines.append(f"{t:8.3f} s  {_name(r)}: {text}")
        elif isinstance(ev, E.Miss):
            lines.append(f"{t:8.3f} s  {_name(r)} misses its turn")
        elif isinstance(ev, E.Disable):
            lines.append(f"{t:8.3f} s  {_name(r)} is dropped after three missed turns")
        elif isinstance(ev, (E.Join, E.Rejoin)):
            again = " again" if isinstance(ev, E.Rejoin) else ""
            lines.append(f"{t:8.3f} s  {_name(r)} is in the ring{again}")
        elif isinstance(ev, E.Mode) and ev.mode == "member":
            reason = ev.reason
            if r in cut and reason == "claimed the silent channel":
                lines.append(f"{t:8.3f} s  {_name(r)}, alone with its radio cut off, hears "
                             f"nobody and claims the channel for itself")
            elif reason == "claimed the silent channel":
                lines.append(f"{t:8.3f} s  {_name(r)} hears nobody and starts the ring")
            elif reason.startswith("invited by robot "):
                lines.append(f"{t:8.3f} s  {_name(r)} answers "
                             f"{_name(int(reason.rsplit(' ', 1)[1]))}'s invitation")
            else:
                lines.append(f"{t:8.3f} s  {_name(r)}: {reason}")
        elif isinstance(ev, E.Mode):
            lines.append(f"{t:8.3f} s  {_name(r)} goes to {ev.mode.upper()}: {ev.reason}")
    return lines


RING_DEMO_FAIL_S = 8.0
RING_DEMO_RECOVER_S = 16.0
"""Simulated seconds: when ``rprs demo ring``'s child goes silent and comes back."""


def cmd_demo_ring(a: argparse.Namespace) -> int:
    if not a.fail and not a.recover:
        # the demo's own story (with --json too: the same run, only told as JSON)
        robots = sorted(a.robots)
        names = ", ".join("the father (ID 0)" if r == 0 else f"R{r}" for r in robots)
        children = [r for r in robots if r != 0]
        what = (f"Demo: {names} power on together, form the ring and exchange seeded "
                f"commands" if len(robots) > 1 else
                f"Demo: {names} powers on alone and claims the silent channel")
        if len(robots) >= 3 and children and a.duration >= RING_DEMO_RECOVER_S + 8.0:
            # one child's radio fails and comes back, when there is time to see it invited
            # back (a few cycles after its recovery) and a ring left while it is away
            victim = children[0]
            a.fail = [(victim, RING_DEMO_FAIL_S)]
            a.recover = [(victim, RING_DEMO_RECOVER_S)]
            what += (f";\nR{victim}'s radio goes silent at {RING_DEMO_FAIL_S:g} s (dropped "
                     f"after three missed turns) and comes back at {RING_DEMO_RECOVER_S:g} s "
                     f"(invited back)")
        if not a.json:
            print(what + ".\n")

    def story(events: list[E.TraceEvent]) -> None:
        if a.json:
            return
        print("What happened:")
        for line in ring_story(events):
            print(line)
        print()
    return cmd_sim(a, demo=True, before_summary=story)


def cmd_demo_actions(a: argparse.Namespace) -> int:
    """The paper's experiment (§V.B, Fig. 11): robots in a row take turns moving their arms."""
    n, cycles = a.robots, a.cycles
    order = tuple(range(1, n + 1))
    steps = 2 * n * cycles
    robots = ((0,) if a.father else ()) + order
    limit = a.timeout
    cfg = SimConfig(robots=robots, duration=limit, seed=a.seed, ber=a.ber, noise=a.noise,
                    can=True, sequence=(order, cycles), realtime=a.realtime, cpu=cpu_costs(a),
                    mac=checked_mac_config(profile=a.profile, auth=a.auth_key))
    try:
        cfg.validate()
    except ConfigError as exc:
        raise UserError(str(exc)) from None
    trace = None
    if a.trace:
        try:
            trace = TraceWriter(a.trace)
        except OSError as exc:
            raise UserError(f"cannot write trace {a.trace}: {exc.strerror}") from None
    print(f"Action sequence (paper Fig. 11): R1..R{n} in a row, {cycles} cycle(s); each robot "
          f"turns its end link left, then all return, in order.")
    print(f"{'real time' if a.realtime else 'simulated'}; ring: "
          f"{', '.join('father 0' if r == 0 else f'R{r}' for r in robots)}; "
          f"Tmax 600 ms, Ttrans 5 ms, 9600 baud\n")
    letters = "abcdefghijklmnopqrstuvwxyz"
    done = [0]

    def show(ev: E.TraceEvent) -> None:
        if type(ev) is not E.Action:
            return
        t = ticks_to_s(ev.t)
        if ev.phase == "done":
            tag = f"({letters[done[0] % 26]})"
            done[0] += 1
        else:
            tag = "   "
        print(f"  {t:8.3f} s  {tag} R{ev.robot} {ev.phase:5s} {ev.name}", flush=True)

    try:
        world = World(cfg, trace, listeners=[show])
        step = TICK_HZ // 10
        while world.now < world.end_tick and done[0] < steps:
            world.run(world.now + step)
    except BrokenPipeError:
        # standard output's reader has gone (``| head -4``): the run stops there, its trace
        # unfinished and so not kept, and the command ends as every command then ends
        if trace is not None:
            trace.discard()
        raise
    except OSError as exc:        # the trace could not be written during the run (disk full)
        if trace is not None:
            trace.discard()
        raise write_failed(exc, trace=a.trace) from None
    except BaseException:
        if trace is not None:
            trace.discard()
        raise
    close_writers(trace, None, ok=True)
    acts = world.actions
    frames = sum(world.air.sent.values())
    if done[0] < steps:
        print(f"\nstopped after {ticks_to_s(world.now):g} s with {done[0]} of {steps} actions "
              f"done")
        return 1
    durations = [t2 - t1 for (t1, r1, a1, p1), (t2, r2, a2, p2) in zip(acts, acts[1:])
                 if p1 == "start" and p2 == "done" and r1 == r2]
    longest = max(durations) / TICK_HZ if durations else 0
    t0, t1 = acts[0][0], acts[-1][0]
    turns = world.action_turns[-1] - world.action_turns[0]    # transmissions meanwhile
    print(f"\n{cycles} cycle(s) done in {ticks_to_s(t1 - t0):.2f} s; each action took up to "
          f"{longest:.2f} s (Tmax 0.6 s), and the ring took {turns} turns meanwhile: the "
          f"action cycle and the communication cycle ran asynchronously.")
    print(f"channel occupations {frames}, collisions {world.collisions}, CAN frames "
          f"{world.can_frames}")
    for line in dispatch_latency_lines(world.summary()):
        print(line)
    return 0


def add_action_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--robots", type=digit(1, 6, "number of robots"), default=3,
                   help="robots in the row: R1..RN (default: %(default)s)")
    p.add_argument("--cycles", type=digit(1, 99, "cycles"), default=2,
                   help="action cycles (default: %(default)s)")
    p.add_argument("--realtime", action="store_true", help="run on the wall clock")
    p.add_argument("--father", action="store_true", help="the father (ID 0) joins the ring")
    p.add_argument("--seed", type=int, default=0,
                   help="the same seed gives the same run (default %(default)s)")
    p.add_argument("--ber", type=probability, default=0.0, metavar="P",
                   help="probability that a received byte is corrupted (default 0)")
    p.add_argument("--noise", action="store_true",
                   help="radios hear random bytes when idle")
    p.add_argument("--timeout", type=positive, default=300.0, metavar="SECONDS",
                   help="give up after this much (simulated) time")
    p.add_argument("--trace", type=file_name, metavar="FILE",
                   help="write the JSON Lines trace here")
    cpu_option(p)
    profile_option(p)
    auth_option(p)


def demo_default(a: argparse.Namespace) -> int:
    """``rprs demo [OPTIONS]`` with no DEMO: the action sequence, with the options given."""
    return cmd_demo_actions(a)


def add(sub) -> None:
    d = sub.add_parser("demo", help="demos: the paper's action sequence (default), the ring",
                       description="With no DEMO, the action sequence runs with the options "
                       "below (rprs demo --cycles 3 = rprs demo action-sequence --cycles 3).")
    add_action_options(d)
    demos = d.add_subparsers(dest="demo", metavar="DEMO", parser_class=Parser)
    d.set_defaults(func=demo_default)
    act = demos.add_parser("action-sequence", help="the paper's experiment (Fig. 11)")
    add_action_options(act)
    act.set_defaults(func=cmd_demo_actions)
    ring = demos.add_parser("ring", help="father + 4 children, traffic, a failure and a "
                            "recovery")
    add_sim_options(ring, demo=True)
    ring.set_defaults(func=cmd_demo_ring)
