"""``rprs soak``: hours of simulated time with random faults and traffic, ending with the
invariants (hil.sim.soak)."""
from __future__ import annotations

import argparse
import json

from .common import UserError, load_rate, output_path, positive, progress_bars, robot_list
from .sim import close_writers, cpu_costs, cpu_option, open_writers, write_failed

def _hours(text: str) -> float:
    from ..sim.soak import DRAIN_S, MIN_HOURS
    h = positive(text)
    if h < MIN_HOURS:
        raise argparse.ArgumentTypeError(
            f"{text} h is too short: a soak lasts at least {MIN_HOURS:g} h ({MIN_HOURS * 3600:g} "
            f"s; faults stop {DRAIN_S:g} s before the end so that the ring can drain)")
    return h


def cmd_soak(a: argparse.Namespace) -> int:
    from ..sim.soak import report, run_soaks
    if len(a.robots) < 2:
        raise UserError(f"--robots {','.join(map(str, a.robots))}: a soak needs at least two "
                        f"robots (its traffic goes between them; one alone ends with nothing "
                        f"checked)")
    modes = {"on": [True], "off": [False], "both": [True, False]}[a.checksum_mode]
    if a.trace is not None and len(modes) > 1:
        raise UserError(f"--trace {a.trace}: a trace is one run's, and --checksum both makes "
                        f"two; give --checksum on or off")
    trace, _ = open_writers(a.trace, None)
    # one bar per run (with --checksum both, the two run side by side on two CPUs)
    updates, close = progress_bars(a.hours * 3600, [f"soak, checksum {'on' if ck else 'off'}"
                                                    for ck in modes])
    ok = False
    try:
        results = run_soaks(a.hours, a.seed, modes, robots=a.robots, can=not a.no_can,
                            load=a.rate, cpu=cpu_costs(a), progress=None if updates is None else
                            (lambda i, s: updates[i](s)), trace=trace)
        ok = True
    except OSError as exc:           # the trace could not be written (a full disk)
        raise write_failed(exc, trace=a.trace) from None
    finally:
        close()
        close_writers(trace, None, ok)
    if a.json:
        print(json.dumps([{"checksum": r.checksum, "invariants": r.invariants,
                           "promised": {k: r.checksum or k not in r.CHECKSUM_ONLY
                                        for k in r.invariants},
                           "kept": r.kept,
                           "summary": {k: v for k, v in r.summary.items()
                                       if k not in ("membership_changes",)},
                           "faults": r.faults, "reform_s_max": max(r.reform_s, default=None),
                           "wall_s": round(r.wall_s, 1)} for r in results]))
    else:
        print(report(results))
    return 0 if all(r.kept for r in results) else 1


def add(sub) -> None:
    so = sub.add_parser("soak", help="hours of simulated time with random faults and "
                        "traffic; ends with the invariants")
    so.add_argument("--hours", type=_hours, default=1.0,
                    help="simulated hours (default %(default)s; a soak too short to inject "
                    "anything is refused)")
    so.add_argument("--seed", type=int, default=0,
                    help="the same seed gives the same faults, traffic and trace")
    so.add_argument("--robots", type=robot_list, default=(0, 1, 2, 3, 4),
                    help="robot IDs in the ring (default 0,1,2,3,4)")
    so.add_argument("--rate", type=load_rate, default=0.5, metavar="MSG/S",
                    help="messages per second per robot (default 0.5)")
    so.add_argument("--checksum", dest="checksum_mode", choices=("on", "off", "both"),
                    default="on", help="the integrity extension (both: compare); exit "
                    "status 1 if a run broke what it promises (without the checksum: not "
                    "'nothing twice' nor 'no corrupted command')")
    so.add_argument("--no-can", action="store_true", help="radio only (faster; no CAN faults)")
    cpu_option(so)
    so.add_argument("--json", action="store_true", help="print the summary as JSON")
    so.add_argument("--trace", type=output_path, metavar="FILE",
                    help="write the run's JSON Lines trace here (docs/trace.md; one run: "
                    "--checksum on or off)")
    so.set_defaults(func=cmd_soak)
