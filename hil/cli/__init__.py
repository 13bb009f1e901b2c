"""The ``rprs`` command line: ``sim``, ``demo``, ``encode``, ``decode``.

A user mistake (bad option value, unreadable file, malformed input) prints one line starting
``rprs: error:`` and exits with status 2; it never shows a traceback.
"""
from __future__ import annotations

import argparse
import binascii
import json
import statistics
import sys
import time
from typing import Sequence

from firmware_model.radio.content import parse_content
from firmware_model.radio.deframer import Deframer, FrameFailed, FrameReceived, Garbage
from firmware_model.radio.errors import WireError
from firmware_model.radio.frame import Frame
from firmware_model.timing import TICK_HZ, ticks_to_s

from .world import ConfigError, Fault, SimConfig, World
from .trace import TraceWriter


class UserError(Exception):
    """A mistake the user can fix: printed as one line, exit status 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, status 2, no usage dump
        raise UserError(f"{message} (see '{self.prog} --help')")


# -- option parsing helpers ---------------------------------------------------------------

def _robot_list(text: str) -> tuple[int, ...]:
    try:
        ids = tuple(int(x) for x in text.split(",") if x.strip() != "")
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a comma-separated list of robot IDs such as 1,2,3,4") from None
    bad = [i for i in ids if not 0 <= i <= 6]
    if bad:
        raise argparse.ArgumentTypeError(
            f"robot ID {bad[0]} is out of range: IDs are 0 (father) and 1-6 (children)")
    if not ids:
        raise argparse.ArgumentTypeError("the robot list is empty")
    if len(set(ids)) != len(ids):
        raise argparse.ArgumentTypeError(f"robot IDs repeat in {text!r}")
    return ids


def _id_at(text: str) -> tuple[int, float]:
    rid, sep, when = text.partition("@")
    try:
        r, t = int(rid), float(when)
    except ValueError:
        r = t = None
    if not sep or r is None:
        raise argparse.ArgumentTypeError(f"{text!r} is not ID@SECONDS, e.g. 1@5.5")
    if not 0 <= r <= 6:
        raise argparse.ArgumentTypeError(f"robot ID {r} in {text!r} is not 0-6")
    if not t >= 0 or t != t or t == float("inf"):
        raise argparse.ArgumentTypeError(f"time in {text!r} must be a finite number >= 0")
    return r, t


def _positive(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not v > 0 or v == float("inf"):
        raise argparse.ArgumentTypeError(f"{text!r} must be a positive finite number")
    return v


def _probability(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not 0.0 <= v < 1.0:
        raise argparse.ArgumentTypeError(f"{text!r} must be a probability in [0, 1)")
    return v


def _load(text: str) -> str | float:
    if text in ("idle", "saturate"):
        return text
    try:
        v = float(text)
    except ValueError:
        v = -1.0
    if not v > 0 or v == float("inf"):
        raise argparse.ArgumentTypeError(
            f"{text!r} is not idle, saturate or a positive rate in messages/s per robot")
    return v


def _digit(lo: int, hi: int, what: str):
    def conv(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{what} {text!r} is not a whole number") from None
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f"{what} must be {lo}-{hi}, got {v}")
        return v
    return conv


# -- sim ------------------------------------------------------------------------------------

def _add_sim_options(p: argparse.ArgumentParser, demo: bool = False) -> None:
    p.add_argument("--robots", type=_robot_list, default=(0, 1, 2, 3, 4) if demo else
                   (1, 2, 3, 4), help="robot IDs in the ring; 0 adds the father "
                   "(default: %(default)s)")
    p.add_argument("--duration", type=_positive, default=30.0 if demo else 10.0,
                   metavar="SECONDS", help="simulated seconds (default: %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="seed of every random stream")
    p.add_argument("--fail", type=_id_at, action="append", default=[], metavar="ID@SECONDS",
                   help="the robot's radio goes silent at that time (repeatable)")
    p.add_argument("--recover", type=_id_at, action="append", default=[],
                   metavar="ID@SECONDS", help="the robot's radio comes back (repeatable)")
    p.add_argument("--power", type=_id_at, action="append", default=[], metavar="ID@SECONDS",
                   help="power the robot on at that time (default: all at 0)")
    p.add_argument("--ber", type=_probability, default=0.0, metavar="P",
                   help="probability that a received byte is corrupted")
    p.add_argument("--noise", action="store_true", help="radios hear random bytes when idle")
    p.add_argument("--load", type=_load, default=1.0 if demo else "idle",
                   metavar="idle|saturate|RATE", help="traffic: heartbeats only, always a "
                   "full-size message queued, or messages/s per robot (default: %(default)s)")
    p.add_argument("--fault", type=_fault, action="append", default=[], metavar="SPEC",
                   help="inject a fault (repeatable): fail:1@5, steal:2@7, ber@10-20:0.01, "
                   "noise@3-6, burst@12:0.05, drop@5-9:0.002, skew:3:0.02, busoff:1@8, "
                   "stuck:2@3-6, silent:1.JOINT2@4-8, stall:1.JOINT1@5 (docs/guarantees.md)")
    p.add_argument("--checksum", action="store_true",
                   help="the opt-in crc() integrity extension on every robot")
    p.add_argument("--father-standby", action="store_true",
                   help="a second father PC as hot standby for ID 0")
    if not demo:
        p.add_argument("--can", action="store_true", help="simulate every child's CAN side "
                       "too: controller, 82C250, dispatcher, joint/wheel/paw submodules")
        p.add_argument("--mac", choices=("rotational", "aloha", "slotted", "csma"),
                       default="rotational", help="the MAC every robot runs (peers for "
                       "comparison; default: the paper's rotational MAC)")
        p.add_argument("--frame-bytes", type=_digit(14, 576, "frame size"), metavar="N",
                       help="peer MACs: frame size of the load (default 80)")
        p.add_argument("--vcd", metavar="FILE", help="write a waveform (GTKWave) here")
    p.add_argument("--trace", metavar="FILE", help="write the JSON Lines trace here")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def _fault(text: str):
    from .faults import FaultError, parse_fault
    try:
        return parse_fault(text)
    except FaultError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _sim_config(a: argparse.Namespace) -> SimConfig:
    from firmware_model.radio.mac import MacConfig
    faults = tuple(Fault("fail", r, t) for r, t in a.fail) + \
        tuple(Fault("recover", r, t) for r, t in a.recover) + tuple(a.fault)
    peer = None
    if getattr(a, "frame_bytes", None):
        from firmware_model.radio.peer_macs import PeerConfig
        peer = PeerConfig(frame_bytes=a.frame_bytes)
    return SimConfig(robots=a.robots, duration=a.duration, seed=a.seed,
                     faults=tuple(sorted(faults, key=lambda f: (f.at, f.kind,
                                                                 -1 if f.robot is None
                                                                 else f.robot))),
                     ber=a.ber, noise=a.noise, load=a.load, power_on=dict(a.power),
                     can=getattr(a, "can", True), mac=MacConfig(checksum=a.checksum),
                     father_standby=a.father_standby,
                     mac_kind=getattr(a, "mac", "rotational"), peer=peer)


def _run_world(cfg: SimConfig, trace_path: str | None, progress: bool,
               vcd_path: str | None = None) -> tuple[World, float]:
    trace = vcd = None
    if trace_path:
        try:
            trace = TraceWriter(trace_path)
        except OSError as exc:
            raise UserError(f"cannot write trace {trace_path}: {exc.strerror}") from None
    if vcd_path:
        from .vcd import VcdError, VcdTraceWriter
        try:
            vcd = VcdTraceWriter(vcd_path)
        except (OSError, VcdError) as exc:
            if trace is not None:
                trace.discard()
            raise UserError(f"cannot write waveform {vcd_path}: {exc}") from None
    try:
        world = World(cfg, trace, on_event=vcd.write if vcd is not None else None)
        t0 = time.perf_counter()
        end = world.end_tick
        if progress:
            from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn
            cols = (TextColumn("simulating"), BarColumn(),
                    TextColumn("{task.completed:.0f}/{task.total:.0f} s"),
                    TimeRemainingColumn())
            with Progress(*cols, transient=True, console=_stderr_console()) as bar:
                task = bar.add_task("sim", total=ticks_to_s(end))
                step = TICK_HZ
                while world.now < end:
                    world.run(world.now + step)
                    bar.update(task, completed=ticks_to_s(world.now))
        else:
            world.run()
        wall = time.perf_counter() - t0
    except BaseException:
        if trace is not None:
            trace.discard()
        if vcd is not None:
            vcd.discard()
        raise
    if trace is not None:
        trace.close()
    if vcd is not None:
        vcd.close()
    return world, wall


def _stderr_console():
    from rich.console import Console
    return Console(stderr=True)


def _print_summary(world: World, wall: float, as_json: bool) -> None:
    s = world.summary()
    sim_s = ticks_to_s(s["duration_ticks"])
    s["wall_seconds"] = round(wall, 3)
    s["speed"] = round(sim_s / wall, 1) if wall > 0 else None
    if as_json:
        print(json.dumps(s, indent=1))
        return
    from rich import box
    from rich.console import Console
    from rich.table import Table
    con = Console()
    con.print(f"[bold]RPRS ring, {sim_s:g} s simulated, seed {world.cfg.seed}[/bold]")
    t = Table(box=box.SIMPLE_HEAD, show_edge=False, padding=(0, 1), collapse_padding=True)
    for col in ("robot", "mode", "sent", "recv", "pending", "missed", "submitted", "delivered",
                "failed"):
        t.add_column(col, justify="right", no_wrap=True)
    for r, v in s["robots"].items():
        name = "father 0" if r == 0 else f"R{r}"
        t.add_row(name, v["mode"], str(v["frames_sent"]), str(v["received"]),
                  str(v["pending"]), str(v["missed"]), str(v["submitted"]),
                  str(v["delivered"]), str(v["failed"]))
    con.print(t)
    con.print("sent: frames sent, recv: messages received, pending: messages not yet ended, "
              "missed: turns missed")
    changes = s["membership_changes"]
    shown = ", ".join(f"{ticks_to_s(c['t']):.3f}s {c['ev']} {c['robot']}" for c in changes[:12])
    more = f" (+{len(changes) - 12} more)" if len(changes) > 12 else ""
    con.print(f"ring membership changes: {len(changes)}" + (f": {shown}{more}" if changes
                                                             else ""))
    con.print(f"channel occupations: {s['occupations']}   collisions: {s['collisions']}"
              + (f"   CAN frames: {world.can_frames}" if world.cfg.can else ""))
    con.print(f"messages: submitted {s['submitted']}, delivered {s['delivered']}, "
              f"failed {s['failed']}, pending {s['pending']}, "
              f"duplicate deliveries {s['duplicate_deliveries']}")
    if s["speed"]:
        con.print(f"[dim]{sim_s:g} simulated s in {wall:.2f} wall s: {s['speed']:.0f}x "
                  f"real time[/dim]")


def cmd_sim(a: argparse.Namespace, demo: bool = False) -> int:
    cfg = _sim_config(a)
    try:
        cfg.validate()
    except ConfigError as exc:
        raise UserError(str(exc)) from None
    progress = not a.no_progress and sys.stderr.isatty() and cfg.duration >= 60
    world, wall = _run_world(cfg, a.trace, progress, getattr(a, "vcd", None))
    _print_summary(world, wall, a.json)
    return 0


def cmd_demo_ring(a: argparse.Namespace) -> int:
    if not a.fail and not a.recover and not a.json:
        a.fail = [(1, 8.0)]
        a.recover = [(1, 16.0)]
        print("Demo: the father (ID 0) and children R1-R4 power on together, form the ring "
              "and exchange seeded commands;\nR1's radio goes silent at 8 s (dropped after "
              "three missed turns) and comes back at 16 s (invited back).\n")
    return cmd_sim(a, demo=True)


def cmd_demo_actions(a: argparse.Namespace) -> int:
    """The paper's experiment (§V.B, Fig. 11): robots in a row take turns moving their arms."""
    from firmware_model.sequence import ACTION_NAMES
    n, cycles = a.robots, a.cycles
    order = tuple(range(1, n + 1))
    steps = 2 * n * cycles
    robots = ((0,) if a.father else ()) + order
    limit = a.timeout
    cfg = SimConfig(robots=robots, duration=limit, seed=a.seed, ber=a.ber, noise=a.noise,
                    can=True, sequence=(order, cycles), realtime=a.realtime)
    try:
        cfg.validate()
    except ConfigError as exc:
        raise UserError(str(exc)) from None
    print(f"Action sequence (paper Fig. 11): R1..R{n} in a row, {cycles} cycle(s); each robot "
          f"turns its end link left, then all return, in order.")
    print(f"{'real time' if a.realtime else 'simulated'}; ring: "
          f"{', '.join('father 0' if r == 0 else f'R{r}' for r in robots)}; "
          f"Tmax 600 ms, Ttrans 5 ms, 9600 baud\n")
    trace = None
    if a.trace:
        try:
            trace = TraceWriter(a.trace)
        except OSError as exc:
            raise UserError(f"cannot write trace {a.trace}: {exc.strerror}") from None
    letters = "abcdefghijklmnopqrstuvwxyz"
    done = [0]

    def show(ev: dict) -> None:
        if ev.get("ev") != "action":
            return
        t = ticks_to_s(ev["t"])
        if ev["phase"] == "done":
            tag = f"({letters[done[0] % 26]})"
            done[0] += 1
        else:
            tag = "   "
        print(f"  {t:8.3f} s  {tag} R{ev['robot']} {ev['phase']:5s} {ev['name']}", flush=True)

    try:
        world = World(cfg, trace, on_event=show)
        step = TICK_HZ // 10
        while world.now < world.end_tick and done[0] < steps:
            world.run(world.now + step)
    except BaseException:
        if trace is not None:
            trace.discard()
        raise
    if trace is not None:
        trace.close()
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
    turns = world.frames_between(t0, t1)
    print(f"\n{cycles} cycle(s) done in {ticks_to_s(t1 - t0):.2f} s; each action took up to "
          f"{longest:.2f} s (Tmax 0.6 s), and the ring took {turns} turns meanwhile: the "
          f"action cycle and the communication cycle ran asynchronously.")
    print(f"channel occupations {frames}, collisions {world.collisions}, CAN frames "
          f"{world.can_frames}")
    return 0


def _add_action_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--robots", type=_digit(1, 6, "number of robots"), default=3,
                   help="robots in the row: R1..RN (default: %(default)s)")
    p.add_argument("--cycles", type=_digit(1, 99, "cycles"), default=2,
                   help="action cycles (default: %(default)s)")
    p.add_argument("--realtime", action="store_true", help="run on the wall clock")
    p.add_argument("--father", action="store_true", help="the father (ID 0) joins the ring")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--ber", type=_probability, default=0.0, metavar="P")
    p.add_argument("--noise", action="store_true")
    p.add_argument("--timeout", type=_positive, default=300.0, metavar="SECONDS",
                   help="give up after this much (simulated) time")
    p.add_argument("--trace", metavar="FILE", help="write the JSON Lines trace here")


def _demo_default(a: argparse.Namespace) -> int:
    p = _Parser(prog="rprs demo action-sequence")
    _add_action_options(p)
    return cmd_demo_actions(p.parse_args([]))


# -- encode / decode --------------------------------------------------------------------

def cmd_encode(a: argparse.Namespace) -> int:
    content = a.content.encode("ascii", "strict") if a.content.isascii() else None
    if content is None:
        raise UserError("Content must be ASCII text such as 'movex(10)'")
    try:
        parse_content(content)
        frame = Frame(dst=a.dst, src=a.src, num=a.num, type=a.type, content=content)
        data = frame.encode()
    except WireError as exc:
        raise UserError(str(exc)) from None
    print(data.hex(" ") if a.spaced else data.hex())
    return 0


def _frame_json(frame: Frame) -> dict:
    d = {"dst": frame.dst, "src": frame.src, "num": frame.num, "type": frame.type,
         "len": len(frame.content), "content": frame.content.decode("ascii")}
    try:
        d["commands"] = [[c.name, list(c.args)] for c in parse_content(frame.content)]
    except WireError as exc:
        d["content_error"] = str(exc)
    return d


def _decode_bytes(chunks, out) -> int:
    d = Deframer()
    offset = 0
    frames = 0
    for data in chunks:
        for ev in d.feed(data, offset, 1):
            if isinstance(ev, FrameReceived):
                frames += 1
                out({"offset": ev.first, "frame": _frame_json(ev.frame)})
            elif isinstance(ev, Garbage):
                out({"offset": ev.first, "garbage": ev.count})
            elif isinstance(ev, FrameFailed):
                out({"offset": ev.first, "error": str(ev.error)})
        offset += len(data)
    ev = d.abort(offset)
    if ev is not None:
        out({"offset": ev.first, "error": f"truncated: {ev.error}"})
    for ev in d.flush():
        if isinstance(ev, Garbage):
            out({"offset": ev.first, "garbage": ev.count})
    return frames


def _unhex(text: str) -> bytes:
    cleaned = "".join(text.split())
    try:
        return binascii.unhexlify(cleaned)
    except (binascii.Error, ValueError):
        raise UserError("input is not hexadecimal bytes (e.g. 0f0a05...)") from None


def cmd_decode(a: argparse.Namespace) -> int:
    def out(obj):
        print(json.dumps(obj), flush=False)
    if a.stream:
        if a.hex:
            chunks = (_unhex(line) for line in sys.stdin)
        else:
            src = sys.stdin.buffer
            chunks = iter(lambda: src.read1(4096), b"")
        frames = _decode_bytes(chunks, out)
    else:
        if not a.hexdata:
            raise UserError("give the frame as hex, or --stream to read stdin")
        frames = _decode_bytes([_unhex(" ".join(a.hexdata))], out)
    sys.stdout.flush()
    print(f"{frames} frame(s) decoded", file=sys.stderr)
    return 0


# -- real time: child, submodules, father, radio hub ------------------------------------

def _realtime_common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--duration", type=_positive, metavar="SECONDS",
                   help="stop after this long (default: until Ctrl-C or SIGTERM)")
    p.add_argument("--events", action="store_true",
                   help="print MAC events as JSON lines on stdout")


def _run(runner, a: argparse.Namespace, describe: str, summary) -> int:
    print(describe, file=sys.stderr, flush=True)
    runner.run(a.duration)
    print(summary(), file=sys.stderr, flush=True)
    return 0


def cmd_child(a: argparse.Namespace) -> int:
    from .runner import Runner, RunError, build_child, summary_line
    if not a.radio and not a.can:
        raise UserError("give --radio PORT, --can INTERFACE:CHANNEL, or both")
    runner = Runner()
    try:
        station, child = build_child(runner, a.id, a.radio, a.can, txen=a.txen,
                                     config=_mac_config(a), can_log=a.can_log,
                                     events=sys.stdout if a.events else None)
    except RunError as exc:
        runner.run(0)
        raise UserError(str(exc)) from None
    parts = [f"child {a.id}"] + ([f"radio {a.radio} (TXEN: {a.txen})"] if a.radio else []) + \
        ([f"CAN {a.can}"] if a.can else [])
    return _run(runner, a, "running " + ", ".join(parts) + "; Ctrl-C stops",
                lambda: summary_line(station))


def cmd_submodules(a: argparse.Namespace) -> int:
    from .runner import Runner, RunError, build_submodules
    runner = Runner()
    try:
        nodes = build_submodules(runner, a.can, a.can_log)
    except RunError as exc:
        runner.run(0)
        raise UserError(str(exc)) from None
    return _run(runner, a, f"running joints 1-4, wheel and paw on CAN {a.can}; Ctrl-C stops",
                lambda: "submodules: " + ", ".join(
                    f"{k} {n.sent} sent" for k, n in nodes.items()))


def cmd_father(a: argparse.Namespace) -> int:
    from .runner import Runner, RunError, build_father, feed_orders, summary_line
    runner = Runner()
    try:
        station = build_father(runner, a.radio, txen=a.txen, standby=a.standby,
                               config=_mac_config(a), events=sys.stdout, pc=a.pc)
    except RunError as exc:
        runner.run(0)
        raise UserError(str(exc)) from None
    if not a.no_input:
        feed_orders(runner, station, sys.stdin)
    role = "standby PC" if a.standby else "PC"
    return _run(runner, a, f"father (ID 0, {role}) on {a.radio}; type orders like "
                f"'2 movex(10)' or '7 act(1,0)' (DST COMMANDS), Ctrl-C stops",
                lambda: summary_line(station))


def _mac_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--team", type=_robot_list, metavar="IDS",
                   help="the robot IDs that may ever join (default: 0-6); a small team forms "
                   "its ring sooner (claim after |team| x Tmax)")
    p.add_argument("--checksum", action="store_true",
                   help="the opt-in crc() integrity extension (every robot must agree)")
    p.add_argument("--idle-noise", action="store_true",
                   help="the radio outputs noise without a carrier (a bare PTR2000, or "
                   "'rprs radio-hub --noise'): the channel never falls quiet, so do not wait "
                   "for quiet after an uncertain turn (docs/mac.md, R-stagger)")


def _mac_config(a: argparse.Namespace):
    from firmware_model.radio.mac import MacConfig
    kw = {"checksum": a.checksum, "quiet_channel": not a.idle_noise}
    if a.team:
        kw["team"] = frozenset(a.team)
    return MacConfig(**kw)


def cmd_radio_hub(a: argparse.Namespace) -> int:
    from .radio_hub import main_radio_hub
    try:
        return main_radio_hub(a)
    except ValueError as exc:
        raise UserError(str(exc)) from None


def _bench_progress(total: float, label: str):
    """A progress bar on a terminal, nothing otherwise; returns (update, close)."""
    if not sys.stderr.isatty():
        return (lambda x: None), (lambda: None)
    from rich.progress import BarColumn, Progress, TextColumn
    bar = Progress(TextColumn(label), BarColumn(), TextColumn("{task.completed:.0f}/"
                   "{task.total:.0f}"), transient=True, console=_stderr_console())
    task = bar.add_task(label, total=total)
    bar.start()
    return (lambda x: bar.update(task, completed=x)), bar.stop


def cmd_bench(a: argparse.Namespace) -> int:
    from . import bench
    from .serial_radio import PortError
    if a.which in ("link", "cycle"):
        update, close = _bench_progress(a.duration, f"listening on {a.radio}")
        try:
            res = bench.listen(a.radio, a.duration, update)
        except PortError as exc:
            raise UserError(str(exc)) from None
        finally:
            close()
        if a.which == "link":
            robots = sorted({f.src for f in res.frames})
            ok = bool(res.frames)
            report = {"bytes": res.bytes, "frames": len(res.frames), "garbage_bytes": res.garbage,
                      "failed_frames": res.failed, "robots_heard": robots, "link_ok": ok}
            if a.json:
                print(json.dumps(report))
            else:
                print(f"link {'OK' if ok else 'SILENT'}: {res.bytes} bytes in {a.duration:g} s, "
                      f"{len(res.frames)} good frames from robots {robots or 'none'}, "
                      f"{res.garbage} garbage bytes, {res.failed} broken frames")
            return 0 if ok else 1
        rep = bench.cycle_report(res)
        if a.json:
            print(json.dumps(rep))
            return 0
        if not rep["frames"]:
            print(f"no frames heard in {a.duration:g} s on {a.radio}")
            return 1
        print(f"ring {rep['robots']}: {rep['frames']} frames in {a.duration:g} s, "
              f"{rep['misses']} missed turns, {rep['garbage_bytes']} garbage bytes")
        if rep["turn_gap_ms_median"] is not None:
            print(f"turn hand-over (End -> next Header): median {rep['turn_gap_ms_median']:.2f} "
                  f"ms against Ttrans {rep['spec_gap_ms']:g} ms; error median "
                  f"{rep['turn_gap_error_ms_median']:.2f} ms, p99 "
                  f"{rep['turn_gap_error_ms_p99']:.2f} ms")
        for r, c in rep["cycle_ms_median"].items():
            print(f"  robot {r}: {rep['frames_per_robot'][r]} frames, cycle median {c:.1f} ms")
        return 0
    # latency: join the ring as a member and ask a robot for its status
    from firmware_model.radio.mac import MacConfig
    from .runner import Runner, RunError, build_child, build_father
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
        while a.dst not in station.mac.ring and time.monotonic() < end:
            time.sleep(0.05)
        if a.dst not in station.mac.ring:
            print(f"robot {a.dst} is not in the ring after {a.join_timeout:g} s "
                  f"(ring {list(station.mac.ring)})")
            return 1
        update, close = _bench_progress(a.count, f"asking robot {a.dst}")
        try:
            r = bench.latency(runner, station, a.dst, a.count, a.timeout, update)
        finally:
            close()
    finally:
        runner.stop()
        t.join(timeout=5)
    med = lambda v: f"{statistics.median(v):.1f}" if v else "-"  # noqa: E731
    p99 = lambda v: f"{bench.percentile(v, 99):.1f}" if v else "-"  # noqa: E731
    rep = {"sent": r.sent, "replies": r.replies, "loss": 1 - r.replies / r.sent if r.sent else 1,
           "round_trip_ms_median": statistics.median(r.round_trip_ms) if r.round_trip_ms
           else None, "ack_ms_median": statistics.median(r.ack_ms) if r.ack_ms else None,
           "failed": r.failed}
    if a.json:
        print(json.dumps(rep))
    else:
        print(f"robot {a.dst}: {r.replies}/{r.sent} status replies; round trip median "
              f"{med(r.round_trip_ms)} ms, p99 {p99(r.round_trip_ms)} ms; acknowledged in "
              f"{med(r.ack_ms)} ms (median); loss {rep['loss']:.1%}")
        for why in r.failed[:5]:
            print(f"  failed: {why}")
    return 0 if r.replies else 1


def _txen_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--txen", choices=("none", "rts", "dtr"), default="none",
                   help="serial line wired to the radio's TXEN (default: none, for the pty hub "
                   "and self-switching modules)")


# -- plot, monitor, soak -------------------------------------------------------------------

def cmd_plot(a: argparse.Namespace) -> int:
    from .plot import PlotError, plot_trace
    from .trace import TraceError, read_trace
    try:
        info = plot_trace(read_trace(a.trace), a.output, a.start, a.end)
    except (TraceError, PlotError) as exc:
        raise UserError(str(exc)) from None
    print(f"wrote {a.output}: {info['turns']} turns from {info['window_s'][0]:.3f} s to "
          f"{info['window_s'][1]:.3f} s, {info['misses']} missed, {info['collided']} collided",
          file=sys.stderr)
    return 0


def cmd_monitor(a: argparse.Namespace) -> int:
    from .monitor import run_monitor_radio, run_monitor_sim
    from .serial_radio import PortError
    if a.radio:
        try:
            return run_monitor_radio(a.radio)
        except PortError as exc:
            raise UserError(str(exc)) from None
    cfg = _sim_config(a)
    try:
        cfg.validate()
    except ConfigError as exc:
        raise UserError(str(exc)) from None
    return run_monitor_sim(cfg, a.speed)


def cmd_soak(a: argparse.Namespace) -> int:
    from .soak import report, run_soak
    robots = a.robots
    modes = {"on": [True], "off": [False], "both": [True, False]}[a.checksum_mode]
    results = []
    for ck in modes:
        update, close = _bench_progress(a.hours * 3600, f"soak, checksum {'on' if ck else 'off'}")
        try:
            results.append(run_soak(a.hours, a.seed, robots=robots, checksum=ck, can=not a.no_can,
                                    load=a.rate, progress=update))
        finally:
            close()
    if a.json:
        print(json.dumps([{"checksum": r.checksum, "invariants": r.invariants,
                           "summary": {k: v for k, v in r.summary.items()
                                       if k not in ("membership_changes",)},
                           "faults": r.faults, "reform_s_max": max(r.reform_s, default=None),
                           "wall_s": round(r.wall_s, 1)} for r in results]))
    else:
        print(report(results))
    return 0 if all(all(r.invariants.values()) for r in results if r.checksum) else 1


# -- main -------------------------------------------------------------------------------

def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="rprs", description="RPRS child firmware model, rotational TDMA radio "
                "MAC simulator and HIL bench")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    s = sub.add_parser("sim", help="simulate a ring of robots faster than real time")
    _add_sim_options(s)
    s.set_defaults(func=cmd_sim)
    d = sub.add_parser("demo", help="demos: the paper's action sequence (default), the ring")
    demos = d.add_subparsers(dest="demo", metavar="DEMO", parser_class=_Parser)
    d.set_defaults(func=_demo_default)
    act = demos.add_parser("action-sequence", help="the paper's experiment (Fig. 11)")
    _add_action_options(act)
    act.set_defaults(func=cmd_demo_actions)
    ring = demos.add_parser("ring", help="father + 4 children, traffic, a failure and a "
                            "recovery")
    _add_sim_options(ring, demo=True)
    ring.set_defaults(func=cmd_demo_ring)
    ch = sub.add_parser("child", help="run a child robot in real time on a serial port "
                        "and/or a CAN bus")
    ch.add_argument("--id", type=_digit(1, 6, "child ID"), required=True)
    ch.add_argument("--radio", metavar="PORT", help="serial port or pyserial URL")
    ch.add_argument("--can", metavar="INTERFACE:CHANNEL",
                    help="python-can bus, e.g. socketcan:vcan0, rprs_unix:/tmp/rprs-can")
    ch.add_argument("--can-log", metavar="FILE", help="log CAN traffic (.log .asc .blf)")
    _txen_option(ch)
    _mac_options(ch)
    _realtime_common(ch)
    ch.set_defaults(func=cmd_child)
    sm = sub.add_parser("submodules", help="run a child's joint/wheel/paw submodules on a CAN "
                        "bus in real time")
    sm.add_argument("--can", metavar="INTERFACE:CHANNEL", required=True)
    sm.add_argument("--can-log", metavar="FILE")
    _realtime_common(sm)
    sm.set_defaults(func=cmd_submodules)
    fa = sub.add_parser("father", help="the father station (ID 0) on a serial port")
    fa.add_argument("--radio", metavar="PORT", required=True)
    fa.add_argument("--standby", action="store_true",
                    help="start as the hot standby PC (takes ID 0's turn if the active dies)")
    fa.add_argument("--pc", type=_digit(1, 2, "PC number"),
                    help="which of the father's two PCs this is (default: 2 with --standby, "
                    "else 1); PC1 decides first")
    fa.add_argument("--no-input", action="store_true", help="do not read orders from stdin")
    _txen_option(fa)
    _mac_options(fa)
    _realtime_common(fa)
    fa.set_defaults(func=cmd_father)
    pl = sub.add_parser("plot", help="draw the paper's Fig. 7 timeline from a trace")
    pl.add_argument("trace", metavar="TRACE")
    pl.add_argument("-o", "--output", required=True, metavar="FILE.png|svg")
    pl.add_argument("--start", type=float, metavar="S", help="window start (s)")
    pl.add_argument("--end", type=float, metavar="S", help="window end (s)")
    pl.set_defaults(func=cmd_plot)
    mo = sub.add_parser("monitor", help="live terminal view of the ring (paper Fig. 9): the "
                        "simulator, or --radio PORT")
    _add_sim_options(mo)
    mo.add_argument("--speed", type=_positive, default=1.0,
                    help="simulated seconds per wall second (default 1)")
    mo.add_argument("--radio", metavar="PORT", help="listen to a radio hub pty or a USB radio")
    mo.set_defaults(func=cmd_monitor, duration=3600.0)
    so = sub.add_parser("soak", help="hours of simulated time with random faults and "
                        "traffic; ends with the invariants")
    so.add_argument("--hours", type=_positive, default=1.0)
    so.add_argument("--seed", type=int, default=0)
    so.add_argument("--robots", type=_robot_list, default=(0, 1, 2, 3, 4))
    so.add_argument("--rate", type=_positive, default=0.5, metavar="MSG/S",
                    help="messages per second per robot (default 0.5)")
    so.add_argument("--checksum", dest="checksum_mode", choices=("on", "off", "both"),
                    default="on", help="the integrity extension (both: compare)")
    so.add_argument("--no-can", action="store_true", help="radio only (faster; no CAN faults)")
    so.add_argument("--json", action="store_true")
    so.set_defaults(func=cmd_soak)
    hub = sub.add_parser("radio-hub", help="ptys that play the shared radio channel, for "
                         "robot processes and serial programs")
    from .radio_hub import add_arguments as _hub_args
    _hub_args(hub)
    hub.set_defaults(func=cmd_radio_hub)
    be = sub.add_parser("bench", help="bench scripts against USB radios or the radio hub")
    bsub = be.add_subparsers(dest="which", metavar="SCRIPT", parser_class=_Parser,
                             required=True)
    for name, text in (("link", "listen: is anybody talking, and how clean is it"),
                       ("cycle", "listen and time the ring against the spec")):
        b = bsub.add_parser(name, help=text)
        b.add_argument("--radio", metavar="PORT", required=True)
        b.add_argument("--duration", type=_positive, default=10.0, metavar="SECONDS")
        b.add_argument("--json", action="store_true")
        b.set_defaults(func=cmd_bench)
    b = bsub.add_parser("latency", help="join the ring and time status requests to a robot")
    b.add_argument("--radio", metavar="PORT", required=True)
    b.add_argument("--dst", type=_digit(0, 6, "destination"), required=True)
    b.add_argument("--id", type=_digit(0, 6, "bench robot ID"), default=0,
                   help="the ID the bench takes in the ring (default 0, the father)")
    b.add_argument("--count", type=_digit(1, 100000, "count"), default=20)
    b.add_argument("--timeout", type=_positive, default=10.0, metavar="SECONDS",
                   help="per request")
    b.add_argument("--join-timeout", type=_positive, default=20.0, metavar="SECONDS")
    b.add_argument("--team", type=_robot_list, metavar="IDS")
    b.add_argument("--json", action="store_true")
    _txen_option(b)
    b.set_defaults(func=cmd_bench)
    e = sub.add_parser("encode", help="print a frame as hex")
    e.add_argument("--src", type=_digit(0, 6, "source"), required=True)
    e.add_argument("--dst", type=_digit(0, 9, "destination"), required=True)
    e.add_argument("--num", type=_digit(0, 99, "number"), default=0)
    e.add_argument("--type", type=_digit(0, 9, "type"), default=2)
    e.add_argument("--spaced", action="store_true", help="space between bytes")
    e.add_argument("content", help="Content text, e.g. 'movex(10)moveto(1.5,-2,0)'")
    e.set_defaults(func=cmd_encode)
    c = sub.add_parser("decode", help="find frames in hex or in a byte stream")
    c.add_argument("hexdata", nargs="*", metavar="HEX")
    c.add_argument("--stream", action="store_true", help="read bytes from stdin")
    c.add_argument("--hex", action="store_true", help="with --stream: stdin is hex text")
    c.set_defaults(func=cmd_decode)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    try:
        a = parser.parse_args(argv)
        if not getattr(a, "command", None):
            parser.print_help()
            return 2
        return a.func(a)
    except UserError as exc:
        print(f"rprs: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("rprs: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
