"""``rprs bench link|cycle|latency``: bench scripts against USB radios or the radio hub."""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import time

from firmware_model.timing import TICK_HZ

from .common import (Parser, UserError, digit, port_name, positive, progress_bar, robot_list,
                     stopped_by_itself, txen_option)

def cmd_bench(a: argparse.Namespace) -> int:
    from ..bench import scripts as bench
    from ..bench.serial_radio import PortError
    if a.which in ("link", "cycle"):
        update, close = progress_bar(a.duration, f"listening on {a.radio}")
        try:
            res = bench.listen(a.radio, a.duration, update)
        except PortError as exc:
            raise UserError(str(exc)) from None
        finally:
            close()
        secs = f"{res.seconds:.1f}" if res.error else f"{a.duration:g}"

        def went_away() -> int:      # the report covers what was heard until then
            print(f"rprs: error: the radio port {a.radio} went away after {res.seconds:.1f} s "
                  f"({res.error})", file=sys.stderr, flush=True)
            return 1
        if a.which == "link":
            robots = sorted({f.src for f in res.frames})
            ok = bool(res.frames)
            report = {"bytes": res.bytes, "frames": len(res.frames), "garbage_bytes": res.garbage,
                      "joined_mid_frame_bytes": res.joined_mid_frame,
                      "failed_frames": res.failed, "robots_heard": robots, "link_ok": ok,
                      "seconds": res.seconds, "error": res.error}
            if a.json:
                print(json.dumps(report))
            else:
                verdict = "OK" if ok else "NO FRAMES" if res.bytes else "SILENT"
                print(f"link {verdict}: {res.bytes} bytes in {secs} s, "
                      f"{len(res.frames)} good frames from robots {robots or 'none'}, "
                      f"{res.garbage} garbage bytes, {res.failed} broken frames"
                      + (f", {res.joined_mid_frame} bytes of a frame it began to hear mid-way"
                         if res.joined_mid_frame else ""))
            return went_away() if res.error else 0 if ok else 1
        rep = bench.cycle_report(res)
        if a.json:
            print(json.dumps(rep))
            return went_away() if res.error else 0
        if not rep["frames"]:
            print(f"no frames heard in {secs} s on {a.radio}")
            return went_away() if res.error else 1
        print(f"ring {rep['robots']}: {rep['frames']} frames in {secs} s, "
              f"{rep['misses']} missed turns, {rep['garbage_bytes']} garbage bytes")
        if rep["stalls"]:
            print(f"this listener stalled {rep['stalls']} time{'s' if rep['stalls'] > 1 else ''}"
                  f" ({rep['stalled_s']:g} s in all: it did not run, a stopped or starved "
                  f"process): what it read then is dropped, and no turn across a stall is "
                  f"judged")
        if rep["turn_gap_ms_median"] is not None:
            print(f"turn hand-over (End -> next Header): median {rep['turn_gap_ms_median']:.2f} "
                  f"ms against Ttrans {rep['spec_gap_ms']:g} ms; error median "
                  f"{rep['turn_gap_error_ms_median']:.2f} ms, p99 "
                  f"{rep['turn_gap_error_ms_p99']:.2f} ms")
        if rep["invitation_windows"]:
            print(f"invitation windows (after a poll, not hand-overs): "
                  f"{rep['invitation_windows']}, median {rep['invitation_gap_ms_median']:.1f} ms")
        for r, c in rep["cycle_ms_median"].items():
            print(f"  robot {r}: {rep['frames_per_robot'][r]} frames, cycle median {c:.1f} ms")
        return went_away() if res.error else 0
    # latency: join the ring as a member and ask a robot for its status
    if a.dst == a.id:
        raise UserError(f"--dst {a.dst} is the bench's own ID (--id {a.id}): ask another "
                        f"robot")
    if a.team and (a.dst not in a.team or a.id not in a.team):
        raise UserError(f"--team {','.join(map(str, a.team))} must hold the bench (--id "
                        f"{a.id}) and the robot asked (--dst {a.dst})")
    from firmware_model.radio.mac import MacConfig
    from ..bench.runner import Runner, RunError, build_child, build_father
    import threading
    runner = Runner()
    cfg = MacConfig(team=frozenset(a.team)) if a.team else MacConfig()
    try:
        if a.id == 0:
            station = build_father(runner, a.radio, txen=a.txen, config=cfg)
        else:
            station, _ = build_child(runner, a.id, a.radio, None, txen=a.txen, config=cfg)
    except RunError as exc:
        runner.run(0)
        raise UserError(str(exc)) from None
    t = threading.Thread(target=runner.run, daemon=True)
    t.start()
    try:
        end = time.monotonic() + a.join_timeout
        while a.dst not in station.mac.ring and time.monotonic() < end and \
                not runner.finished.is_set():
            time.sleep(0.05)
        if stopped_by_itself(runner):
            return 1
        if a.dst not in station.mac.ring:
            print(f"robot {a.dst} is not in the ring after {a.join_timeout:g} s "
                  f"(ring {list(station.mac.ring)})")
            return 1
        update, close = progress_bar(a.count, f"asking robot {a.dst}")
        try:
            r = bench.latency(runner, station, a.dst, a.count, a.timeout, update)
        finally:
            close()
    finally:
        runner.stop()
        t.join(timeout=5)
    med = lambda v: f"{statistics.median(v):.1f}" if v else "-"  # noqa: E731
    p99 = lambda v: f"{bench.percentile(v, 99):.1f}" if v else "-"  # noqa: E731
    rtt = r.round_trip_ms
    # (each stall: the process did not run for more than a Tslot; it resynchronised, and a
    # request across it may take a retry or a missed turn: its round trip is the host's)
    stalls = list(runner.sched.stalls)
    rep = {"sent": r.sent, "replies": r.replies, "loss": 1 - r.replies / r.sent if r.sent else 1,
           "round_trip_ms_median": statistics.median(rtt) if rtt else None,
           "round_trip_ms_p99": bench.percentile(rtt, 99) if rtt else None,
           "ack_ms_median": statistics.median(r.ack_ms) if r.ack_ms else None,
           "failed": r.failed, "refused": len(r.refusals),
           "refusal": r.refusals[0] if r.refusals else None, "stalls": len(stalls),
           "stalled_s": round(sum(late for _, late in stalls) / TICK_HZ, 3)}
    if a.json:
        print(json.dumps(rep))
    else:
        what = (f"{r.replies}/{r.sent} status replies" if not r.refusals else
                f"{r.replies}/{r.sent} answers, {len(r.refusals)} of them refusals "
                f"({r.refusals[0]})")
        print(f"robot {a.dst}: {what}; round trip median "
              f"{med(r.round_trip_ms)} ms, p99 {p99(r.round_trip_ms)} ms; acknowledged in "
              f"{med(r.ack_ms)} ms (median); loss {rep['loss']:.1%}")
        for why in r.failed[:5]:
            print(f"  failed: {why}")
        if stalls:
            print(f"this bench process stalled {len(stalls)} time"
                  f"{'s' if len(stalls) > 1 else ''} ({rep['stalled_s']:g} s in all: it did "
                  f"not run, a stopped or starved process): the round trips across a stall "
                  f"are the host's, not the ring's")
    if stopped_by_itself(runner):                  # the report covers what came until then
        return 1
    return 0 if r.replies else 1


def add(sub) -> None:
    be = sub.add_parser("bench", help="bench scripts against USB radios or the radio hub")
    bsub = be.add_subparsers(dest="which", metavar="SCRIPT", parser_class=Parser,
                             required=True)
    for name, text in (("link", "listen: is anybody talking, and how clean is it"),
                       ("cycle", "listen and time the ring against the spec")):
        b = bsub.add_parser(name, help=text)
        b.add_argument("--radio", type=port_name, metavar="PORT", required=True,
                       help="serial port or pyserial URL of a radio that hears the ring")
        b.add_argument("--duration", type=positive, default=10.0, metavar="SECONDS",
                       help="how long to listen (default %(default)s)")
        b.add_argument("--json", action="store_true",
                       help="print the report as one JSON object")
        b.set_defaults(func=cmd_bench)
    b = bsub.add_parser("latency", help="join the ring and time status requests to a robot")
    b.add_argument("--radio", type=port_name, metavar="PORT", required=True,
                   help="serial port or pyserial URL of the bench's radio")
    b.add_argument("--dst", type=digit(0, 6, "destination"), required=True,
                   help="the robot to ask status() of (0-6)")
    b.add_argument("--id", type=digit(0, 6, "bench robot ID"), default=0,
                   help="the ID the bench takes in the ring (default 0, the father)")
    b.add_argument("--count", type=digit(1, 100000, "count"), default=20,
                   help="status requests to time (default %(default)s)")
    b.add_argument("--timeout", type=positive, default=10.0, metavar="SECONDS",
                   help="per request")
    b.add_argument("--join-timeout", type=positive, default=20.0, metavar="SECONDS",
                   help="give up if the bench is not in the ring by then (default %(default)s)")
    b.add_argument("--team", type=robot_list, metavar="IDS",
                   help="robot IDs of the team (default: all, 0-6)")
    b.add_argument("--json", action="store_true",
                   help="print the report as one JSON object")
    txen_option(b)
    b.set_defaults(func=cmd_bench)
