"""The ``rprs`` command line: ``sim``, ``demo``, ``encode``, ``decode``.

A user mistake (bad option value, unreadable file, malformed input) prints one line starting
``rprs: error:`` and exits with status 2; it never shows a traceback.
"""
from __future__ import annotations

import argparse
import binascii
import json
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
    if not demo:
        p.add_argument("--can", action="store_true", help="simulate every child's CAN side "
                       "too: controller, 82C250, dispatcher, joint/wheel/paw submodules")
    p.add_argument("--trace", metavar="FILE", help="write the JSON Lines trace here")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def _sim_config(a: argparse.Namespace) -> SimConfig:
    faults = tuple(Fault("fail", r, t) for r, t in a.fail) + \
        tuple(Fault("recover", r, t) for r, t in a.recover)
    return SimConfig(robots=a.robots, duration=a.duration, seed=a.seed,
                     faults=tuple(sorted(faults, key=lambda f: (f.at, f.kind, f.robot))),
                     ber=a.ber, noise=a.noise, load=a.load, power_on=dict(a.power),
                     can=getattr(a, "can", True))


def _run_world(cfg: SimConfig, trace_path: str | None, progress: bool) -> tuple[World, float]:
    trace = None
    if trace_path:
        try:
            trace = TraceWriter(trace_path)
        except OSError as exc:
            raise UserError(f"cannot write trace {trace_path}: {exc.strerror}") from None
    try:
        world = World(cfg, trace)
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
        raise
    if trace is not None:
        trace.close()
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
    world, wall = _run_world(cfg, a.trace, progress)
    _print_summary(world, wall, a.json)
    return 0


def cmd_demo(a: argparse.Namespace) -> int:
    if not a.fail and not a.recover and not a.json:
        a.fail = [(1, 8.0)]
        a.recover = [(1, 16.0)]
        print("Demo: the father (ID 0) and children R1-R4 power on together, form the ring "
              "and exchange seeded commands;\nR1's radio goes silent at 8 s (dropped after "
              "three missed turns) and comes back at 16 s (invited back).\n")
    return cmd_sim(a, demo=True)


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


# -- main -------------------------------------------------------------------------------

def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="rprs", description="RPRS child firmware model, rotational TDMA radio "
                "MAC simulator and HIL bench")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    s = sub.add_parser("sim", help="simulate a ring of robots faster than real time")
    _add_sim_options(s)
    s.set_defaults(func=cmd_sim)
    d = sub.add_parser("demo", help="the ring demo: father + 4 children, traffic, a failure "
                       "and a recovery")
    _add_sim_options(d, demo=True)
    d.set_defaults(func=cmd_demo)
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
