"""``rprs child``, ``rprs submodules`` and ``rprs father``: the firmware in real time on serial
ports and CAN buses (hil.bench.runner)."""
from __future__ import annotations

import argparse
import sys

from .common import UserError, digit, mac_config, mac_options, realtime_options, run_until_stopped, txen_option

def cmd_child(a: argparse.Namespace) -> int:
    from ..bench.runner import Runner, RunError, build_child, summary_line
    if not a.radio and not a.can:
        raise UserError("give --radio PORT, --can INTERFACE:CHANNEL, or both")
    runner = Runner()
    try:
        station, child = build_child(runner, a.id, a.radio, a.can, txen=a.txen,
                                     config=mac_config(a), can_log=a.can_log,
                                     events=sys.stdout if a.events else None)
    except RunError as exc:
        runner.run(0)
        raise UserError(str(exc)) from None
    parts = [f"child {a.id}"] + ([f"radio {a.radio} (TXEN: {a.txen})"] if a.radio else []) + \
        ([f"CAN {a.can}"] if a.can else ["no CAN side (no --can): orders are answered "
                                          "fail(42)"])
    return run_until_stopped(runner, a, "running " + ", ".join(parts) + "; Ctrl-C stops",
                lambda: summary_line(station))


def cmd_submodules(a: argparse.Namespace) -> int:
    from ..bench.runner import Runner, RunError, build_submodules
    runner = Runner()
    try:
        nodes = build_submodules(runner, a.can, a.can_log)
    except RunError as exc:
        runner.run(0)
        raise UserError(str(exc)) from None
    return run_until_stopped(runner, a, f"running joints 1-4, wheel and paw on CAN {a.can}; Ctrl-C stops",
                lambda: "submodules: " + ", ".join(
                    f"{k} {n.sent} sent" for k, n in nodes.items()))


def cmd_father(a: argparse.Namespace) -> int:
    from ..bench.orders import OrderBook, chain
    from ..bench.runner import Runner, RunError, build_father, feed_orders, summary_line
    from ..view.father import FatherConsole
    if a.json and a.quiet:
        raise UserError("--json and --quiet: choose one")
    runner = Runner()
    console = FatherConsole(sys.stdout, "json" if a.json else "quiet" if a.quiet else "human")
    try:
        station = build_father(runner, a.radio, txen=a.txen, standby=a.standby,
                               config=mac_config(a), events=sys.stdout if a.json else None,
                               pc=a.pc)
    except RunError as exc:
        runner.run(0)
        raise UserError(str(exc)) from None
    input_ended = a.no_input

    def maybe_exit(*_: object) -> None:
        if a.exit_when_done and input_ended and not book.open_orders():
            runner.stop()

    def changed(order, now: int) -> None:
        console.order(order, now)
        if order.finished:
            maybe_exit()

    def eof() -> None:
        nonlocal input_ended
        input_ended = True
        maybe_exit()

    book = OrderBook(on_change=changed, on_news=console.news)
    ring_view = station.observer

    def observe(st, act, now: int) -> None:
        if ring_view is not None:
            ring_view(st, act, now)
        console.ring(st, act, now)
    station.observer = chain(observe, book)
    if not a.no_input:
        feed_orders(runner, station, sys.stdin, on_eof=eof)
    elif a.exit_when_done:
        runner.sched.post(maybe_exit)
    role = "standby PC" if a.standby else "PC"
    return run_until_stopped(runner, a, f"father (ID 0, {role}) on {a.radio}; type orders like "
                f"'2 movex(10)' or '1 act(1,0)' (DST COMMANDS), Ctrl-C stops",
                lambda: summary_line(station))


def add(sub) -> None:
    ch = sub.add_parser("child", help="run a child robot in real time on a serial port "
                        "and/or a CAN bus")
    ch.add_argument("--id", type=digit(1, 6, "child ID"), required=True,
                    help="this child's robot ID (1-6)")
    ch.add_argument("--radio", metavar="PORT", help="serial port or pyserial URL")
    ch.add_argument("--can", metavar="INTERFACE:CHANNEL",
                    help="python-can bus, e.g. socketcan:vcan0, rprs_unix:/tmp/rprs-can")
    ch.add_argument("--can-log", metavar="FILE", help="log CAN traffic (.log .asc .blf)")
    txen_option(ch)
    mac_options(ch)
    realtime_options(ch)
    ch.set_defaults(func=cmd_child)
    sm = sub.add_parser("submodules", help="run a child's joint/wheel/paw submodules on a CAN "
                        "bus in real time")
    sm.add_argument("--can", metavar="INTERFACE:CHANNEL", required=True,
                    help="the child's python-can bus, e.g. socketcan:vcan0")
    sm.add_argument("--can-log", metavar="FILE", help="log CAN traffic (.log .asc .blf)")
    realtime_options(sm)
    sm.set_defaults(func=cmd_submodules)
    fa = sub.add_parser("father", help="the father station (ID 0) on a serial port")
    fa.add_argument("--radio", metavar="PORT", required=True,
                    help="serial port or pyserial URL of the father's radio")
    fa.add_argument("--standby", action="store_true",
                    help="start as the hot standby PC (takes ID 0's turn if the active dies)")
    fa.add_argument("--pc", type=digit(1, 2, "PC number"),
                    help="which of the father's two PCs this is (default: 2 with --standby, "
                    "else 1); PC1 decides first")
    fa.add_argument("--no-input", action="store_true", help="do not read orders from stdin")
    fa.add_argument("--json", action="store_true", help="machine output: the station's events "
                    "and each order's changes as JSON lines on stdout (no other output)")
    fa.add_argument("--quiet", action="store_true", help="only each order's end (done, "
                    "replied, failed) and errors")
    fa.add_argument("--exit-when-done", action="store_true", help="exit once the input has "
                    "ended and every order has ended (for scripts)")
    txen_option(fa)
    mac_options(fa)
    realtime_options(fa)
    fa.set_defaults(func=cmd_father)
