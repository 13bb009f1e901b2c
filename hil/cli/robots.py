"""``rprs child``, ``rprs submodules`` and ``rprs father``: the firmware in real time on serial
ports and CAN buses (hil.bench.runner)."""
from __future__ import annotations

import argparse
import sys

from firmware_model.timing import TICK_HZ

from ..bench.orders import REPORT_WITHIN_S
from .common import (UserError, can_notes, digit, distinct_outputs, file_name, mac_config,
                     mac_options, port_name, positive, realtime_options, run_until_stopped,
                     stopped_by_itself, txen_option)

def cmd_child(a: argparse.Namespace) -> int:
    from ..bench.runner import Runner, RunError, build_child
    if not a.radio and not a.can:
        raise UserError("give --radio PORT, --can INTERFACE:CHANNEL, or both")
    distinct_outputs(can_log=a.can_log, pcap=a.pcap)
    runner = Runner()
    try:
        station, child = build_child(runner, a.id, a.radio, a.can, txen=a.txen,
                                     config=mac_config(a, a.id), can_log=a.can_log,
                                     events=sys.stdout if a.events else None, pcap=a.pcap)
    except RunError as exc:
        runner.run(0)
        raise UserError(str(exc)) from None
    parts = [f"child {a.id}"] + ([f"radio {a.radio} (TXEN: {a.txen})"] if a.radio else []) + \
        ([f"CAN {a.can}"] if a.can else ["no CAN side (no --can): orders are answered "
                                          "fail(42)"])
    return run_until_stopped(runner, a, "running " + ", ".join(parts) + "; Ctrl-C stops",
                lambda: child_summary(station, child, radio=bool(a.radio)),
                notes=can_notes("child", a.can))


def child_summary(station, child, radio: bool = True) -> str:
    """The closing line of ``rprs child``: with a radio, the radio's (and the replies it
    dropped, its queue full, if any); then its CAN side's, if
    it has one: the frames it sent and received, and the CAN frames the firmware ignored as
    malformed (no node's frame: a wrong length, a remote frame, an unknown id). A CAN-only
    child (``radio`` False) has no radio fields to give."""
    from ..bench.runner import summary_line
    bad = getattr(getattr(child, "dispatcher", None), "bad_frames", 0)
    malformed = (f"{bad} malformed frame{'s' if bad > 1 else ''} ignored (wrong length, "
                 f"remote or unknown id)")
    bus = getattr(getattr(getattr(child, "can", None), "xcvr", None), "bus", None)
    counts = [f"{bus.sent} frame{'s' if bus.sent != 1 else ''} sent",
              f"{bus.received} received"] if bus is not None else []
    can_side = ", ".join(counts + ([malformed] if bad else []) + bus_notes(bus))
    line = summary_line(station) if radio else f"robot {station.id}: CAN only (no radio)"
    dropped = getattr(child, "replies_dropped", None)            # a radio-only child's
    if dropped is None:
        dropped = getattr(getattr(child, "dispatcher", None), "replies_dropped", 0)
    if dropped:
        line += (f", {dropped} repl{'y' if dropped == 1 else 'ies'} dropped (the radio's "
                 f"queue full: orders came faster than its turns carry the answers)")
    return line + (f"; CAN: {can_side}" if can_side else "")


def bus_notes(bus) -> list[str]:
    """What a bench process's CAN bus (``can_bus.bridge.PythonCanBus``) heard and handed to
    no node, for its closing line: frames the kernel dropped before they were read (a flood),
    frames that are not CAN 2.0A (an extended id, CAN FD: no node of ours takes them), and
    frames no CAN 2.0A node can send (a software bus carries them)."""
    counted = (
        (getattr(bus, "lost", 0), "lost (the receive queue overflowed)"),
        (getattr(bus, "not_ours", 0), "not CAN 2.0A ignored (extended id, CAN FD or error "
                                      "frame)"),
        # rprs_unix: a peer that was not reading (a stalled process) had its queue full
        (getattr(getattr(bus, "bus", None), "tx_dropped", 0),
         "sent dropped for a peer that was not reading (its queue full)"),
        (getattr(bus, "malformed", 0), "no CAN 2.0A node can send ignored (an 11-bit id "
                                       "above 0x7FF, or a DLC that disagrees with the data)"),
    )
    notes = [f"{n} frame{'s' if n > 1 else ''} {what}" for n, what in counted if n]
    return notes


def _father_app(a: argparse.Namespace, app, runner, station, book, console) -> int:
    """The father's live console (hil/view/father_app.py): the firmware in a thread, the
    view in this one; quitting the view stops the firmware, and SIGTERM stops both cleanly."""
    import signal
    import threading
    worker = threading.Thread(target=runner.run, args=(a.duration,), name="firmware",
                              daemon=True)
    # the firmware's thread cannot take signals: SIGTERM (and a SIGINT sent from outside)
    # stop it from here, and the view quits when it has stopped (FatherApp's ``ended``)
    from ..bench.runner import take_stop_signals      # SIGHUP too: its terminal closed
    old = take_stop_signals(runner.stop)
    worker.start()
    try:
        app.run()
    finally:
        runner.stop()
        worker.join(timeout=5)
        for sig, handler in old.items():
            signal.signal(sig, handler)
    from ..bench.runner import summary_line
    from .common import say_closing
    say_closing(summary_line(station))         # not if the terminal has gone (SIGHUP)
    say_closing(book.closing_line())
    return stopped_by_itself(runner)


def cmd_submodules(a: argparse.Namespace) -> int:
    from ..bench.runner import Runner, RunError, build_submodules
    distinct_outputs(can_log=a.can_log, pcap=a.pcap)
    runner = Runner()
    try:
        nodes = build_submodules(runner, a.can, a.can_log, pcap=a.pcap)
    except RunError as exc:
        runner.run(0)
        raise UserError(str(exc)) from None
    return run_until_stopped(runner, a,
                             f"running joints 1-4, wheel and paw on CAN {a.can}; Ctrl-C stops",
                             lambda: submodules_summary(nodes),
                             notes=can_notes("submodules", a.can))


def submodules_summary(nodes: dict) -> str:
    """The closing line of ``rprs submodules``: the frames each node sent, the commands it
    refused (each answered by its EVENT kind 3) and those it ignored as malformed (a wrong
    length or a remote frame: no EVENT answers those)."""
    line = "submodules: " + ", ".join(f"{k} {n.sent} sent" for k, n in nodes.items())
    refused = [f"{k} {n.refused}" for k, n in nodes.items() if n.refused]
    if refused:
        line += "; commands refused (EVENT kind 3): " + ", ".join(refused)
    bad = [f"{k} {n.bad_frames}" for k, n in nodes.items() if n.bad_frames]
    if bad:
        line += "; malformed commands ignored (wrong length or remote): " + ", ".join(bad)
    notes = bus_notes(next(iter(nodes.values())).bus) if nodes else []
    if notes:
        line += "; CAN: " + ", ".join(notes)
    return line


def cmd_father(a: argparse.Namespace) -> int:
    from ..bench.orders import OrderBook, book_keeper
    from ..bench.runner import (Runner, RunError, build_father, feed_orders, summary_line,
                                take_order)
    from ..view.father import HELP_WORDS, FatherConsole, Tee, order_help
    if a.json and a.quiet:
        raise UserError("--json and --quiet: choose one")
    if sys.stdin is None:
        a.no_input = True          # (started with its standard input closed: no orders to read)
    distinct_outputs(log=a.log, pcap=a.pcap)
    log = None
    if a.log:
        try:
            log = open(a.log, "a", encoding="utf-8", buffering=1)
        except OSError as exc:
            raise UserError(f"cannot write the log {a.log}: {exc.strerror or exc}") from None
    runner = Runner()
    if log is not None:
        runner.on_close(log.close, last=True)

    def log_failed(exc: OSError) -> None:      # (the disk filled): the session's record is cut
        runner.fail(f"cannot write the log {a.log}: {exc.strerror or exc}")
    # what goes to stdout goes to --log too: the story, or with --json every JSON line
    out = sys.stdout if log is None else Tee(sys.stdout, log, on_error=log_failed)
    app = None
    if not (a.plain or a.json or a.quiet or a.no_input or a.exit_when_done) and \
            sys.stdin.isatty() and sys.stdout.isatty():
        from ..bench.runner import HISTORY_FILE
        from ..view.father_app import FatherApp, LinesTo
        app = FatherApp(lambda line: order(line), lambda: head(), HISTORY_FILE,
                        ended=runner.finished.is_set)
        console = FatherConsole(LinesTo(app.post_line) if log is None else
                                Tee(LinesTo(app.post_line), log, on_error=log_failed), "human")
    else:
        console = FatherConsole(out, "json" if a.json else "quiet" if a.quiet else "human")
    try:
        station = build_father(runner, a.radio, txen=a.txen, standby=a.standby,
                               config=mac_config(a, 0), events=out if a.json else None,
                               pc=a.pc, pcap=a.pcap)
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
    # the orders still open when it stops end then, their lines told before the console and
    # its log close (the runner's closers run in reverse order)
    runner.on_close(lambda: book.close(runner.sched.now, _stop_reason(runner)))

    def expire() -> None:                          # once a second, on the station's clock
        book.expire(runner.sched.now, a.report_within)
        runner.sched.after(TICK_HZ, expire)
    runner.sched.post(expire)

    def order(line: str) -> str | None:          # a typed order (the app's thread)
        if line.strip().lower() in HELP_WORDS:
            assert app is not None                 # (typed into the live view)
            for text in order_help():
                app.post_line(text)
            return None
        # a line that is no order too: take_order gives it its record, ended ``refused`` with
        # the reason, shown, logged and counted as a piped one is (docs/bench.md)
        runner.sched.post(take_order, runner, station, book, line, False)
        return None

    def head() -> str:                            # the app's header
        return father_head(station.mac, a.radio, book)
    station.add_observer(book_keeper(book), first=True)   # the book first, as orders end
    station.add_observer(console.ring)
    role = "standby PC" if a.standby else "PC"
    how = ("orders given here are refused until it takes over" if a.standby else
           "type orders like '2 movex(10)' or '1 act(1,0)' (DST COMMANDS)")
    if app is not None:
        return _father_app(a, app, runner, station, book, console)
    def show_help() -> None:
        # (with --json, stdout carries JSON lines only: the help goes to stderr, and is no
        # order either way)
        for text in order_help():
            print(text, file=sys.stderr if a.json else sys.stdout, flush=True)
    if not a.no_input:
        feed_orders(runner, station, book, sys.stdin, on_eof=eof, on_help=show_help)
    elif a.exit_when_done:
        runner.sched.post(maybe_exit)
    code = run_until_stopped(runner, a, f"father (ID 0, {role}) on {a.radio}; {how}; "
                             f"Ctrl-C stops",
                             lambda: summary_line(station) + "\n" + book.closing_line())
    if a.exit_when_done and not code and not book.all_succeeded():
        from .common import say_closing
        say_closing("rprs: not every order succeeded (done, replied, or sent-only for a "
                    "broadcast or the paper profile): exit status 1")
        code = 1
    return code


def _stop_reason(runner) -> str:
    """Why the father stopped, for the orders it leaves open (OrderBook.close)."""
    failure = getattr(runner, "failure", None)
    return failure if failure is not None else "the father stopped"


def father_head(mac, radio: str, book) -> str:
    """The live view's header: the father's mode, the ring it sees, whose turn it is (only as
    a member, and only a member's turn: a frame from outside the ring owns nothing), and its
    orders; a standby says so, and that orders are refused there."""
    ring = " ".join("father 0" if r == 0 else f"R{r}" for r in mac.ring)
    owner = mac.owner
    if mac.mode != "member" or owner is None or owner not in mac.ring:
        turn = "-"
    else:
        turn = "father 0" if owner == 0 else f"R{owner}"
    mode = mac.mode
    if getattr(mac, "standby", False):
        mode += " (standing by: new orders are refused until this PC takes over)"
    return (f"father (ID 0) on {radio}: {mode}; ring [{ring}]; turn: {turn}; "
            f"orders open: {len(book.open_orders())} of {len(book.orders)}\n"
            f"type DST COMMANDS (1 joint(2,60), 1 status()); up/down: history; "
            f"ctrl+q or ctrl+c quits")


PCAP_HELP = ("write a pcapng capture here: what this process's serial port sent and heard and "
             "its CAN bus, wall-clock timestamps (docs/wireshark.md); a FIFO gives a live view")


def add(sub) -> None:
    ch = sub.add_parser("child", help="run a child robot in real time on a serial port "
                        "and/or a CAN bus")
    ch.add_argument("--id", type=digit(1, 6, "child ID"), required=True,
                    help="this child's robot ID (1-6)")
    ch.add_argument("--radio", type=port_name, metavar="PORT",
                    help="serial port or pyserial URL")
    ch.add_argument("--can", metavar="INTERFACE:CHANNEL",
                    help="python-can bus, e.g. socketcan:vcan0, rprs_unix:/tmp/rprs-can (both "
                    "shared with other processes); virtual:NAME stays inside this process")
    ch.add_argument("--can-log", type=file_name, metavar="FILE",
                    help="log CAN traffic (.log .log.gz .asc .blf)")
    ch.add_argument("--pcap", type=file_name, metavar="FILE", help=PCAP_HELP)
    txen_option(ch)
    mac_options(ch)
    realtime_options(ch, events=True)
    ch.set_defaults(func=cmd_child)
    sm = sub.add_parser("submodules", help="run a child's joint/wheel/paw submodules on a CAN "
                        "bus in real time")
    sm.add_argument("--can", metavar="INTERFACE:CHANNEL", required=True,
                    help="the child's python-can bus, e.g. socketcan:vcan0, "
                    "rprs_unix:/tmp/rprs-can; virtual:NAME stays inside this process")
    sm.add_argument("--can-log", type=file_name, metavar="FILE",
                    help="log CAN traffic (.log .log.gz .asc .blf)")
    sm.add_argument("--pcap", type=file_name, metavar="FILE", help=PCAP_HELP)
    realtime_options(sm)
    sm.set_defaults(func=cmd_submodules)
    fa = sub.add_parser("father", help="the father station (ID 0) on a serial port")
    fa.add_argument("--radio", type=port_name, metavar="PORT", required=True,
                    help="serial port or pyserial URL of the father's radio")
    fa.add_argument("--standby", action="store_true",
                    help="start as the hot standby PC (takes ID 0's turn if the active dies)")
    fa.add_argument("--pc", type=digit(1, 2, "PC number"),
                    help="which of the father's two PCs this is (default: 2 with --standby, "
                    "else 1); PC1 decides first. Given (or --standby), the father is a pair: "
                    "an active PC back from an outage goes on probation")
    fa.add_argument("--no-input", action="store_true", help="do not read orders from stdin")
    fa.add_argument("--json", action="store_true", help="machine output: the station's events "
                    "and each order's changes as JSON lines on stdout (no other output)")
    fa.add_argument("--quiet", action="store_true", help="only each order's end (done, "
                    "replied, failed) and errors")
    fa.add_argument("--exit-when-done", action="store_true", help="exit once the input has "
                    "ended and every order has ended (for scripts); exit status 0 only if "
                    "every order succeeded: done or replied, or sent-only for a broadcast or "
                    "in the paper profile (failed, unreported and refused are not), else 1. "
                    "Piped orders wait for room in the queue; each line gets one record and "
                    "one final state")
    fa.add_argument("--report-within", type=positive, default=REPORT_WITHIN_S, metavar="S",
                    help="an acknowledged order with no report S seconds later ends "
                    "'unreported': the child reports nothing for a move to where the arm "
                    f"already is, or an order a newer one replaced (default {REPORT_WITHIN_S:g})")
    fa.add_argument("--plain", action="store_true", help="at a terminal, lines instead of the "
                    "live view (the view is used only when stdin and stdout are a terminal)")
    fa.add_argument("--pcap", type=file_name, metavar="FILE", help=PCAP_HELP)
    fa.add_argument("--log", type=file_name, metavar="FILE",
                    help="also append what the console shows (each "
                    "order's changes, replies, the ring's news; with --json the JSON lines) "
                    "to FILE: the session's record outlives the view")
    txen_option(fa)
    mac_options(fa)
    realtime_options(fa)
    fa.set_defaults(func=cmd_father)
