"""``rprs monitor``: the live terminal view of a simulated ring or a radio (hil.view.monitor)."""
from __future__ import annotations

import argparse
import sys

from ..sim.world import ConfigError
from .common import UserError, distinct_outputs, port_name, positive, stdout_console
from .sim import (add_sim_options, close_outputs, close_writers, open_capture, open_writers,
                  print_summary_and_report, sim_config, write_failed)


def _need_a_terminal(instead: str) -> None:
    """The view reads its keys from stdin and draws on stderr (textual's driver). Without a
    terminal on both it drew escape codes into a pipe or a file and, with no ``q`` to read,
    never ended."""
    if not all(f is not None and f.isatty() for f in (sys.__stdin__, sys.__stderr__)):
        raise UserError(f"rprs monitor is a live view: it needs a terminal on stdin and stderr "
                        f"(stdout may go anywhere); without one, {instead}")


def speed(text: str) -> float:
    """``--speed``: simulated seconds per wall second, within what ``+``/``-`` reach."""
    from ..view.monitor import SPEED_MAX, SPEED_MIN
    v = positive(text)
    if not SPEED_MIN <= v <= SPEED_MAX:
        raise argparse.ArgumentTypeError(f"{text!r} is outside 1/64 to 4096 (the speeds + and - "
                                         f"reach)")
    return v


def cmd_monitor(a: argparse.Namespace) -> int:
    from ..view.monitor import quit_signals
    with quit_signals:      # SIGTERM/SIGHUP before the view is up or after it: as q (docs)
        return _monitor(a)


def _monitor(a: argparse.Namespace) -> int:
    from ..view.monitor import run_monitor_radio, run_monitor_sim
    from ..bench.serial_radio import PortError
    if a.radio is not None:
        given = [o for o, v in (("--trace", a.trace), ("--vcd", a.vcd), ("--pcap", a.pcap),
                                ("--json", a.json)) if v]
        if given:
            raise UserError(f"{', '.join(given)}: only for the simulated ring, not with --radio "
                            f"(capture a radio with rprs capture --radio PORT --pcap FILE)")
        _need_a_terminal("listen with rprs bench link --radio PORT")
        try:
            return run_monitor_radio(a.radio)
        except PortError as exc:
            raise UserError(str(exc)) from None
    cfg = sim_config(a)
    try:
        cfg.validate()
    except ConfigError as exc:
        raise UserError(str(exc)) from None
    if cfg.mac_kind != "rotational":     # the panes read the rotational MAC's ring and queue
        raise UserError(f"--mac {cfg.mac_kind}: the monitor shows the rotational MAC's ring "
                        f"(views, turns, queues); compare the peer MACs with rprs sim --mac "
                        f"{cfg.mac_kind}")
    distinct_outputs(trace=a.trace, vcd=a.vcd, pcap=a.pcap)
    _need_a_terminal("run rprs sim with the same options")
    trace, vcd = open_writers(a.trace, a.vcd)
    try:
        capture = open_capture(a.pcap)
    except UserError:
        close_writers(trace, vcd, ok=False)
        raise
    ok = False
    import time
    t0 = time.perf_counter()
    try:
        code, world = run_monitor_sim(cfg, a.speed, trace=trace,
                                      listeners=[vcd.write] if vcd is not None else (),
                                      capture=None if capture is None else capture.f)
        ok = True
    except OSError as exc:               # an output filled the disk: one line, none left
        raise write_failed(exc, trace=a.trace, VCD=a.vcd, capture=a.pcap) from None
    finally:                             # as rprs sim: a complete output is kept
        close_outputs(trace, vcd, capture, a.pcap, ok)
    wall = time.perf_counter() - t0      # (the view's time: the run paced at --speed)
    if a.json:                           # the world up to where the view was closed
        print_summary_and_report(world, wall, a, cfg)
    elif a.cpu_report:
        from ..view.cpu_report import print_cpu_report
        print_cpu_report(world, cfg.cpu, console=stdout_console)
    return code


def add(sub) -> None:
    mo = sub.add_parser("monitor", help="live terminal view of the ring (paper Fig. 9): the "
                        "simulator, or --radio PORT")
    add_sim_options(mo, progress=False)   # --trace/--vcd: the world up to where you quit
    mo.add_argument("--speed", type=speed, default=1.0,
                    help="simulated seconds per wall second, 1/64 to 4096 (default 1)")
    mo.add_argument("--radio", type=port_name, metavar="PORT",
                    help="listen to a radio hub pty or a USB radio")
    mo.set_defaults(func=cmd_monitor, duration=3600.0)
