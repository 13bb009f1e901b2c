"""``rprs sim``: a ring of robots simulated faster than real time, with its summary."""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from typing import Iterable

from firmware_model.radio.peer_macs import MIN_FRAME_BYTES
from firmware_model.timing import TICK_HZ, ms_to_ticks, ticks_to_ms, ticks_to_s

from ..sim.events import Listener, TraceEvent
from ..sim.trace import OutputFile, TraceWriter
from ..sim.config import ConfigError, SimConfig
from ..sim.faults import Fault
from ..sim.world import World
from .common import (
    READ_FILES, UserError, auth_option, checked_mac_config, digit, distinct_outputs, file_name,
    profile_option, fault_spec, id_at, load_spec, output_path, positive, probability, robot_list,
    stderr_console, stdout_console)


def add_sim_options(p: argparse.ArgumentParser, demo: bool = False,
                    progress: bool = True) -> None:
    """The world's options, and its outputs (``--trace``, ``--vcd`` outside demos,
    ``--json``, and ``--no-progress`` where there is a progress bar)."""
    robots = (0, 1, 2, 3, 4) if demo else (1, 2, 3, 4)
    p.add_argument("--robots", type=robot_list, default=robots, help="robot IDs in the ring; "
                   f"0 adds the father (default: {','.join(map(str, robots))})")
    p.add_argument("--duration", type=positive, default=30.0 if demo else 10.0,
                   metavar="SECONDS", help="simulated seconds (default: %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="seed of every random stream")
    p.add_argument("--fail", type=id_at, action="append", default=[], metavar="ID@SECONDS",
                   help="the robot's radio goes silent at that time (repeatable)")
    p.add_argument("--recover", type=id_at, action="append", default=[],
                   metavar="ID@SECONDS", help="the robot's radio comes back (repeatable)")
    p.add_argument("--power", type=id_at, action="append", default=[], metavar="ID@SECONDS",
                   help="power the robot on at that time (default: all at 0)")
    p.add_argument("--extra", type=extra_robot, action="append", default=[],
                   metavar="ID@SECONDS[:TEAM]",
                   help="another robot on the same air, outside the ring, powered on then: a "
                        "twin (an ID of --robots), or with :TEAM a robot of another team "
                        "(4@0:4,5); repeatable (docs/protocol.md clause 38)")
    p.add_argument("--ber", type=probability, default=0.0, metavar="P",
                   help="probability that a received byte is corrupted")
    p.add_argument("--noise", action="store_true", help="radios hear random bytes when idle")
    p.add_argument("--load", type=load_spec, default=1.0 if demo else "idle",
                   metavar="idle|saturate|RATE", help="traffic: heartbeats only, always a "
                   "full-size message queued, or messages/s per robot (default: %(default)s)")
    p.add_argument("--fault", type=fault_spec, action="append", default=[], metavar="SPEC",
                   help="inject a fault (repeatable): fail:1@5, steal:2@7, ber@10-20:0.01, "
                   "noise@3-6, burst@12:0.05, foreign@2.5:40, foreign@2.5:x0f0a05, "
                   "drop@5-9:0.002, skew:3:0.02 (robot 3's clock 2 %% slow), busoff:1@8, "
                   "stuck:2@3-6, silent:1.JOINT2@4-8, stall:1.JOINT1@5 (docs/guarantees.md)")
    p.add_argument("--checksum", action="store_true",
                   help="the opt-in crc() integrity extension on every robot")
    auth_option(p)
    p.add_argument("--father-standby", action="store_true",
                   help="a second father PC as hot standby for ID 0")
    cpu_option(p)
    profile_option(p)
    if not demo:
        p.add_argument("--can", action="store_true", help="simulate every child's CAN side "
                       "too: controller, 82C250, dispatcher, joint/wheel/paw submodules")
        p.add_argument("--mac", choices=("rotational", "aloha", "slotted", "csma"),
                       default="rotational", help="the MAC every robot runs (peers for "
                       "comparison; default: the paper's rotational MAC). A peer MAC takes "
                       "--checksum; --fault steal, --profile paper and --father-standby need "
                       "the rotational MAC (docs/peer-macs.md)")
        p.add_argument("--radio-switch", type=radio_switch_spec, action="append", default=[],
                       metavar="ID:TX_MS,RX_MS",
                       help="robot ID's PTR2000 switch times: TXEN high to the first byte it "
                       "sends, TXEN low to the first it hears (default: the nRF401 data "
                       "sheet's 1 and 3 ms; not the protocol's Ttrans, 5 ms); repeatable, "
                       "e.g. 1:1,5 (docs/cpu.md)")
        p.add_argument("--frame-bytes", type=digit(MIN_FRAME_BYTES, 576, "frame size"),
                       metavar="N", help="peer MACs: frame size of the load (default 80; "
                       f"{MIN_FRAME_BYTES}-576, a frame that holds an ack at least)")
        p.add_argument("--vcd", type=output_path, metavar="FILE",
                       help="write a waveform (GTKWave) here")
        p.add_argument("--cpu-costs", type=file_name, metavar="FILE",
                       help="a TOML file of cycle costs "
                       "([costs] name = cycles) over the default table; implies --cpu "
                       "estimated")
        p.add_argument("--cpu-report", action="store_true", help="print each child's CPU "
                       "budget: per handler, per second, worst case; implies --cpu estimated")
    p.add_argument("--trace", type=output_path, metavar="FILE",
                   help="write the JSON Lines trace here")
    p.add_argument("--every-frame", action="store_true",
                   help="run every frame one by one: no leap over the cycles an idle ring "
                   "repeats, no sleeping CAN side (the same results to the tick, slower; "
                   "docs/performance.md)")
    if not demo:
        p.add_argument("--pcap", type=output_path, metavar="FILE",
                       help="write a pcapng capture here: every "
                       "radio transmission and CAN frame, for Wireshark with the rprs plugin "
                       "(docs/wireshark.md)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    if progress:
        p.add_argument("--no-progress", action="store_true", help="no progress bar")


REFUSAL_WORDS = {"out_of_turn": "out of turn", "own_id": "own ID"}
"""How the summary names a kind of refused frame (the MAC's ``refused`` kinds, docs/mac.md)."""


def extra_robot(text: str) -> tuple[int, float, tuple[int, ...] | None]:
    """``ID@SECONDS[:TEAM]`` for ``--extra``: a twin of a ring robot, or one of another team."""
    at, sep, team = text.partition(":")
    r, t = id_at(at)
    if not sep:
        return r, t, None
    try:
        ids = robot_list(team)
    except argparse.ArgumentTypeError as exc:
        raise argparse.ArgumentTypeError(f"team in {text!r}: {exc}") from None
    if r not in ids:
        raise argparse.ArgumentTypeError(f"robot {r} is not in its own team {team} in "
                                         f"{text!r}")
    return r, t, tuple(ids)


def radio_switch_spec(text: str) -> tuple[int, int, int]:
    """``ID:TX_MS,RX_MS`` for ``--radio-switch``: (robot, TX-ready ticks, RX-ready ticks)."""
    rid, sep, times = text.partition(":")
    tx, comma, rx = times.partition(",")
    try:
        r, tx_ms, rx_ms = int(rid), float(tx), float(rx)
    except ValueError:
        r = None
    if not sep or not comma or r is None:
        raise argparse.ArgumentTypeError(f"{text!r} is not ID:TX_MS,RX_MS, e.g. 1:1,3")
    if not 0 <= r <= 6:
        raise argparse.ArgumentTypeError(f"robot ID {r} in {text!r} is not 0-6")
    if not (0 <= tx_ms < float("inf") and 0 <= rx_ms < float("inf")):
        raise argparse.ArgumentTypeError(f"switch times in {text!r} must be finite "
                                         f"milliseconds >= 0")
    return r, ms_to_ticks(tx_ms), ms_to_ticks(rx_ms)


def sim_config(a: argparse.Namespace) -> SimConfig:
    """The SimConfig the options ask for; a UserError for what only the options can say is
    wrong (a time past ``--duration``, a robot's radio switch times given twice, a cycle-cost
    file that cannot be read). The settings themselves are checked by
    :meth:`SimConfig.validate` (hil/sim/config.py)."""
    late = [f"--{opt} {r}@{t:g}" for opt, times in (("fail", a.fail), ("recover", a.recover),
                                                    ("power", a.power),
                                                    ("extra", [x[:2] for x in a.extra]))
            for r, t in times if t >= a.duration]
    late += [f"--fault {f.spec()}" for f in a.fault if f.at >= a.duration]
    if late:    # it would never happen, and the run would say nothing of it
        raise UserError(f"{late[0]}: the run ends at {a.duration:g} s (--duration) and never "
                        f"gets there")
    faults = tuple(Fault("fail", r, t) for r, t in a.fail) + \
        tuple(Fault("recover", r, t) for r, t in a.recover) + tuple(a.fault)
    peer = None
    if getattr(a, "frame_bytes", None):
        from firmware_model.radio.peer_macs import PeerConfig
        peer = PeerConfig(frame_bytes=a.frame_bytes)
    switch: dict[int, tuple[int, int]] = {}
    for r, tx, rx in getattr(a, "radio_switch", []):
        if r in switch:
            raise UserError(f"--radio-switch names robot {r} twice: a robot has one radio")
        switch[r] = (tx, rx)
    return SimConfig(robots=a.robots, duration=a.duration, seed=a.seed, cpu=cpu_costs(a),
                     faults=tuple(sorted(faults, key=lambda f: (f.at, f.kind,
                                                                 -1 if f.robot is None
                                                                 else f.robot))),
                     ber=a.ber, noise=a.noise, load=a.load, power_on=dict(a.power),
                     extra=tuple(a.extra),
                     can=getattr(a, "can", True),
                     mac=checked_mac_config(checksum=a.checksum, profile=a.profile,
                                            auth=a.auth_key),
                     father_standby=a.father_standby,
                     mac_kind=getattr(a, "mac", "rotational"), peer=peer,
                     fast_paths=not a.every_frame,
                     radio_switch=switch)


DEFAULT_CPU = "estimated"
"""The children's CPU when no ``--cpu`` is given: the MB90F549 model (docs/cpu.md, "The
default, and what it costs"); ``--cpu ideal`` is the paper's zero-time idealisation."""


def dispatch_latency_lines(s: dict) -> list[str]:
    """The summary's dispatcher latency (radio End to the first CAN frame's SOF) as text, and
    with the ideal CPU a line saying what it leaves out; none if no order reached a CAN bus."""
    if "dispatch_latency_ticks" not in s:
        return []
    d = {k: (round(ticks_to_ms(v) * 1000, 1) if k != "count" else v)
         for k, v in s["dispatch_latency_ticks"].items()}
    lines = [f"dispatcher latency, radio End to the first CAN frame's SOF, over {d['count']} "
             f"orders: min {d['min']:g} us, median {d['median']:g} us, max {d['max']:g} us"]
    if "cpu_load" not in s:
        # --cpu ideal: the handlers and the main loop run in zero time (docs/cpu.md)
        lines.append("  (the ideal CPU, --cpu ideal: the firmware takes no time, so this is "
                     "only the wait for a free CAN bus; the default CPU model adds its cycles)")
    return lines


def cpu_option(p: argparse.ArgumentParser) -> None:
    """``--cpu ideal|estimated`` (``rprs sim``, ``demo``, ``soak``; a campaign's grid)."""
    p.add_argument("--cpu", choices=("ideal", "estimated"), default=None,
                   help="the children's CPU: estimated (the default: the MB90F549 model, "
                   "every handler and the main loop take their cycles, docs/cpu.md) or ideal "
                   "(every handler in zero time, the paper's idealisation; far faster with "
                   "--can over long runs: only there does an idle ring leap over its cycles "
                   "while the CAN sides sleep, docs/cpu.md)")


def cpu_costs(a: argparse.Namespace):
    """The cycle-cost table the options ask for (the CPU model unless ``--cpu ideal``), or
    None for the ideal CPU."""
    choice = getattr(a, "cpu", None) or DEFAULT_CPU
    path = getattr(a, "cpu_costs", None)
    report = getattr(a, "cpu_report", False)
    if choice == "ideal" and (path or report):
        raise UserError("--cpu ideal charges no cycles: --cpu-costs and --cpu-report need "
                        "--cpu estimated")
    if choice == "ideal":
        return None
    from firmware_model.cycle_costs import DEFAULT_COSTS, load_costs
    if not path:
        return DEFAULT_COSTS
    try:
        costs = load_costs(path)
        READ_FILES[os.path.realpath(path)] = "cpu-costs"
        return costs
    except UnicodeDecodeError:
        raise UserError(f"cannot read the cost table {path}: not a text file (a TOML table "
                        f"of cycle costs, docs/cpu.md)") from None
    except ValueError as exc:
        raise UserError(str(exc)) from None


def open_writers(trace_path: str | None, vcd_path: str | None):
    """(TraceWriter or None, VcdTraceWriter or None); a path that cannot be written is a
    UserError, and nothing is left behind."""
    trace = vcd = None
    if trace_path:
        try:
            trace = TraceWriter(trace_path)
        except OSError as exc:
            raise UserError(f"cannot write trace {trace_path}: {exc.strerror}") from None
    if vcd_path:
        from ..view.vcd import VcdError, VcdTraceWriter
        try:
            vcd = VcdTraceWriter(vcd_path)
        except (OSError, VcdError) as exc:
            if trace is not None:
                trace.discard()
            raise UserError(str(exc) if isinstance(exc, VcdError) else
                            f"cannot write waveform {vcd_path}: {exc.strerror}") from None
    return trace, vcd


def close_writers(trace, vcd, ok: bool) -> None:
    """Close the writers (their files appear whole) or, if the run failed, discard them. One
    that cannot be closed (the disk filled) is a UserError, the other closed all the same."""
    error = None
    for what, w in (("trace", trace), ("VCD", vcd)):
        if w is not None:
            try:
                w.close() if ok else w.discard()
            except OSError as exc:     # the path became a directory, the disk filled...
                error = error or UserError(f"cannot write {what} {w.path}: {exc.strerror}")
    if error is not None:
        raise error


def _outputs(**paths: str | None) -> str:
    """``trace run.jsonl, capture run.pcapng``: the outputs given, for an error message that
    cannot tell which one failed (an OSError without the output's name, ``OutputFile``)."""
    return ", ".join(f"{what} {p}" for what, p in paths.items() if p)


def write_failed(exc: OSError, **paths: str | None) -> UserError:
    """The one line for an output that could not be written during a run (a full disk):
    the output whose path ``exc`` names (``OutputFile``), else all of them."""
    failed = [f"{what} {p}" for what, p in paths.items() if p and p == exc.filename]
    which = failed[0] if failed else f"an output ({_outputs(**paths)})"
    return UserError(f"cannot write {which}: {exc.strerror or exc}")


def run_world(cfg: SimConfig, trace_path: str | None, progress: bool,
              vcd_path: str | None = None, listeners: Iterable[Listener] = (),
              pcap_path: str | None = None) -> tuple[World, float]:
    """Run the world to its end, with its trace, waveform and capture files; ``listeners``
    get every event too (hil/sim/events.py). An output that cannot be written during the run
    (a full disk) is a UserError naming that output, and no output is left; one that cannot
    be finished at the end, a UserError too, and the others are kept (:func:`close_outputs`)."""
    distinct_outputs(trace=trace_path, vcd=vcd_path, pcap=pcap_path)
    trace, vcd = open_writers(trace_path, vcd_path)
    try:
        pcap_file = open_capture(pcap_path)
    except UserError:
        close_writers(trace, vcd, ok=False)
        raise
    try:
        world = World(cfg, trace,
                      listeners=[*([vcd.write] if vcd is not None else []), *listeners])
        if pcap_file is not None:
            from ..sim.pcap import PcapWriter
            world.capture(PcapWriter(pcap_file.f, *world.capture_interfaces()))
        t0 = time.perf_counter()
        end = world.end_tick
        if progress:
            from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn
            cols = (TextColumn("simulating"), BarColumn(),
                    TextColumn("{task.completed:.0f}/{task.total:.0f} s"),
                    TimeRemainingColumn())
            with Progress(*cols, transient=True, console=stderr_console()) as bar:
                task = bar.add_task("sim", total=ticks_to_s(end))
                # a hundred updates at most: each step ends the ring's leaps (quiet_ring.py)
                for now in world.run_in_steps(max(TICK_HZ, end // 100)):
                    bar.update(task, completed=ticks_to_s(now))
        else:
            world.run()
        wall = time.perf_counter() - t0
    except BaseException as exc:
        close_outputs(trace, vcd, pcap_file, pcap_path, ok=False)
        if isinstance(exc, OSError):     # a write of an output failed: the disk is full...
            raise write_failed(exc, trace=trace_path, VCD=vcd_path, capture=pcap_path) \
                from None
        raise
    close_outputs(trace, vcd, pcap_file, pcap_path, ok=True)
    return world, wall


def close_outputs(trace, vcd, capture: OutputFile | None, capture_path: str | None,
                  ok: bool) -> None:
    """The end of a run's outputs (``rprs sim`` and ``rprs monitor`` alike): if the run went
    to its end (``ok``), each is finished and put in place, and one that cannot be finished
    (the disk filled at its last bytes) is a UserError naming it (the first, if more), while
    the others, whole, are kept: a full disk under the trace leaves the capture and the
    waveform, one under the capture leaves the trace. Not ``ok`` (the run failed or was
    interrupted, an output could not be written during it): none is left."""
    error = None
    try:
        close_writers(trace, vcd, ok)
    except UserError as exc:
        error = exc
    try:
        close_capture(capture, capture_path, ok)
    except UserError as exc:
        error = error or exc
    if error is not None:
        raise error


def open_capture(path: str | None) -> OutputFile | None:
    """The file a pcapng capture goes to (None without ``--pcap``), whole at
    :func:`close_capture` or not at all; one that cannot be opened is a UserError."""
    if not path:
        return None
    try:
        return OutputFile(path, binary=True)
    except OSError as exc:
        raise UserError(f"cannot write capture {path}: {exc.strerror}") from None


def close_capture(f: OutputFile | None, path: str | None, ok: bool) -> None:
    """Put the capture in place, or, if the run failed, leave none."""
    if f is None:
        return
    if not ok:
        f.discard()
        return
    try:
        f.commit()
    except OSError as exc:
        raise UserError(f"cannot write capture {path}: {exc.strerror or exc}") from None


def print_summary(world: World, wall: float, as_json: bool, membership: bool = True,
                  extra: dict | None = None) -> None:
    """The summary table; ``membership=False`` leaves out the list of membership changes
    (the demos tell them as a story instead). ``extra``: more keys of the JSON document (one
    document, whatever is asked for)."""
    s = world.summary()
    s.update(extra or {})
    sim_s = ticks_to_s(s["duration_ticks"])
    s["wall_seconds"] = round(wall, 3)
    s["speed"] = round(sim_s / wall, 1) if wall > 0 else None
    if as_json:
        print(json.dumps(s, indent=1))
        return
    from rich import box
    from rich.table import Table
    con = stdout_console()
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
    more = f" (+{len(changes) - 12} more: --json or --trace has them all)" \
        if len(changes) > 12 else ""
    con.print(f"ring membership changes: {len(changes)}" + (f": {shown}{more}" if changes and
                                                             membership else ""))
    con.print(f"channel occupations: {s['occupations']}   collisions: {s['collisions']}"
              + (f"   CAN frames: {world.can_frames}" if world.cfg.can else ""))
    refusals = []
    for r, v in s["robots"].items():
        if v["refused_by"] or v["numbers_behind"]:
            who = "father 0" if int(r) == 0 else f"R{r}"
            kinds = ", ".join(f"{REFUSAL_WORDS.get(k, k)} {n}" for k, n in v["refused_by"].items())
            behind = f", numbers behind {v['numbers_behind']}" if v["numbers_behind"] else ""
            refusals.append(f"{who} {sum(v['refused_by'].values())}"
                            + (f" ({kinds})" if kinds else "") + behind)
    if refusals:
        con.print("frames refused (docs/mac.md): " + "; ".join(refusals))
    unacked = (f"sent unacknowledged (paper profile) {s['unacknowledged']}, "
               if s["unacknowledged"] else "")
    if "cpu_load" in s:
        loads = ", ".join(f"R{r} {v * 100:.2f} %" for r, v in s["cpu_load"].items())
        lost = sum(s["cpu_overruns"].values())
        gaps = sum(s["cpu_tx_gaps"].values())
        con.print(f"CPU load (MB90F549 model): {loads}; UART overruns: {lost}; "
                  f"gaps in frames sent: {gaps}")
    for line in dispatch_latency_lines(s):
        con.print(line)
    for e in s.get("identity", ()):
        who = f"R{e['robot']}" if e["robot"] else "father 0"
        if e.get("extra"):
            who += f" (--extra {e['extra']})"
        if e["ev"] == "duplicate_id":
            said = (f"another robot has ID {e['robot']}"
                    + (": it yields" if e["yielding"] else ""))
        else:
            said = (f"robots {','.join(map(str, e['robots']))} outside its team hold the "
                    f"channel")
        con.print(f"{ticks_to_s(e['t']):.3f}s {who}: {said}")
    con.print(f"messages: submitted {s['submitted']}, delivered {s['delivered']}, "
              f"failed {s['failed']}, {unacked}pending {s['pending']}, "
              f"duplicate deliveries {s['duplicate_deliveries']}")
    refused = sum(v.get("refused", 0) for v in s["robots"].values())
    if refused:
        # the load's messages a MAC would not take (World.submit counts them)
        con.print(f"messages refused at submit: {refused} (longer than the MAC sends, or "
                  f"its queue full: docs/peer-macs.md, docs/mac.md)")
    if s["speed"]:
        con.print(f"[dim]{sim_s:g} simulated s in {wall:.2f} wall s: {s['speed']:.0f}x "
                  f"real time[/dim]")


def cmd_sim(a: argparse.Namespace, demo: bool = False, before_summary=None) -> int:
    """``rprs sim``; ``before_summary(events)`` (the demos) prints from the run's events."""
    cfg = sim_config(a)
    try:
        cfg.validate()
    except ConfigError as exc:
        raise UserError(str(exc)) from None
    progress = not a.no_progress and sys.stderr.isatty() and cfg.duration >= 60
    events: list[TraceEvent] = []
    world, wall = run_world(cfg, a.trace, progress, getattr(a, "vcd", None),
                            listeners=[events.append] if before_summary else (),
                            pcap_path=getattr(a, "pcap", None))
    if before_summary is not None:
        before_summary(events)
    print_summary_and_report(world, wall, a, cfg, membership=before_summary is None)
    return 0


def print_summary_and_report(world: World, wall: float, a: argparse.Namespace,
                             cfg: SimConfig, membership: bool = True) -> None:
    """The run's summary (``--json`` or text), and with ``--cpu-report`` each child's CPU
    budget: inside the JSON, or as a table after the text."""
    report = getattr(a, "cpu_report", False)
    extra = None
    if report and a.json:
        from ..view.cpu_report import cpu_budget
        assert cfg.cpu is not None              # (--cpu-report runs the CPU model)
        extra = {"cpu_report": {r: cpu_budget(
            c, cfg.cpu.sample_wait_max.cycles, world.byte_ticks[r], world.sched.now, cfg.cpu)
            for r, c in sorted(world.cpus.items())}}
    print_summary(world, wall, a.json, membership=membership, extra=extra)
    if report and not a.json:
        from ..view.cpu_report import print_cpu_report
        print_cpu_report(world, cfg.cpu, console=stdout_console)


def add(sub) -> None:
    s = sub.add_parser("sim", help="simulate a ring of robots faster than real time")
    add_sim_options(s)
    s.set_defaults(func=cmd_sim)
