"""``rprs radio-hub``: ptys that play the shared radio channel (hil.bench.radio_hub): its
options, its run until a stop signal, and its closing line."""
from __future__ import annotations

import argparse
import signal
import sys
import threading
from typing import Any, Sequence

from ..bench.hub_parts import (MAX_BAUD, MAX_SECONDS, MIN_BAUD, HubError, check_args, check_fault,
                               parse_baud, parse_drop)
from ..bench.radio_hub import RadioHub
from ..bench.runner import take_stop_signals
from .common import UserError, distinct_outputs, file_name


def cmd_radio_hub(a: argparse.Namespace) -> int:
    try:
        return main_radio_hub(a)
    except (ValueError, HubError) as exc:
        raise UserError(str(exc)) from None


def add(sub) -> None:
    hub = sub.add_parser("radio-hub", help="ptys that play the shared radio channel, for "
                         "robot processes and serial programs")
    add_arguments(hub)
    hub.set_defaults(func=cmd_radio_hub)


def summary_line(st: dict[str, Any]) -> str:
    """The closing line of ``rprs radio-hub``. ``dropped (slow reader)``: bytes a program that
    had its node open had no room for; ``not delivered (node not open)``: bytes for nodes no
    program had open, not written at all; the times the hub set a node raw again, if any."""
    c = st["collisions"]
    line = (f"radio-hub: {st['seconds']:.1f} s, {st['bytes_in']} bytes in, "
            f"{st['bytes_out']} bytes out, {st['transmissions']} transmissions, "
            f"{c} collision{'s' if c != 1 else ''}, {st['noise']} noise bytes, "
            f"{st['dropped']} dropped (slow reader), "
            f"{st.get('not_open', 0)} not delivered (node not open), "
            f"{st['lost']} lost (link down)")
    n = st.get("raw_restored", 0)
    if n:
        line += (f"; raw mode restored {n} time{'s' if n != 1 else ''} (a program turned echo "
                 f"or line editing on)")
    return line


def run_hub_cli(nodes: int, baud: int = 9600, ber: float = 0.0, noise: bool = False,
                seed: int = 0, link_dir: str | None = None,
                drops: Sequence[tuple[int, float, float]] = (),
                faults: Sequence[Any] = (), pcap: str | None = None) -> int:
    """The ``rprs radio-hub`` command: print the node paths, run until SIGINT, SIGTERM or
    SIGHUP (its terminal closed), print a summary; HubError (one line) after the summary if a
    thread of the hub failed and stopped it. ``pcap``: a pcapng capture to this file, or ``-`` to
    stdout
    (``| wireshark -k -i -``; the paths and the summary then go to stderr), flushed packet by
    packet. Bad
    arguments raise ValueError with a one-line message."""
    check_args(nodes, baud, ber, [tuple(d) for d in drops])
    done = threading.Event()

    def on_signal(signum: int, frame: Any) -> None:
        done.set()

    out = sys.stderr if pcap == "-" else sys.stdout
    stream = None
    if pcap is not None:
        if pcap == "-":
            stream = sys.stdout.buffer
        else:
            try:
                stream = open(pcap, "wb")
            except OSError as e:
                raise ValueError(f"cannot write capture {pcap}: {e.strerror}") from None
    hub = None
    try:
        hub = RadioHub(nodes, baud=baud, ber=ber, noise=noise, seed=seed, link_dir=link_dir,
                       drops=drops, faults=faults)
        if stream is not None:
            from ..sim.pcap import PcapWriter
            # flushed packet by packet, to a file too (a few frames a second at 9600 baud):
            # a hub that is killed or loses power keeps what it captured, and a disk that
            # cannot take it (full) is said at once, by the header's flush
            try:
                writer = PcapWriter(stream, *hub.capture_interfaces(), tsresol=9, live=True)
            except OSError as e:
                hub.close()
                if pcap == "-" and isinstance(e, BrokenPipeError):
                    raise                # stdout's reader gone already: as every command ends
                raise ValueError(f"cannot write capture {pcap}: {e.strerror or e}") from None
            hub.capture(writer)
        # SIGHUP too: a closed terminal must not leave links to ptys the next one is given
        old = take_stop_signals(on_signal)     # (what stops it cleanly: bench/runner.py)
        try:
            for i, path in enumerate(hub.paths):
                line = f"node {i}: {path}"
                if hub.links:
                    line += f" ({hub.links[i]})"
                print(line, file=out)
            out.flush()
            hub.start()
            while not done.is_set() and not hub.wait(0.2):
                pass                   # a signal, or a thread of the hub that failed
        finally:
            hub.close()
            for s, h in old.items():
                signal.signal(s, h)
    finally:
        close_error = None
        if stream is not None and pcap != "-":
            try:
                stream.close()
            except OSError as e:       # its last bytes (the disk filled): said below
                close_error = e.strerror or str(e)
    if hub.capture_error:
        print(f"radio-hub: {hub.capture_error}", file=sys.stderr)
    print(summary_line(hub.stats()), file=out)
    out.flush()
    if hub.error is not None:
        raise HubError(hub.failure()) from hub.error
    if close_error is not None and not hub.capture_error:
        print(f"rprs: error: cannot write capture {pcap}: {close_error}", file=sys.stderr)
        return 1
    return 1 if hub.capture_error else 0


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The ``radio-hub`` options, for the CLI's subparser (values checked by run_hub_cli)."""
    def drop(text: str) -> tuple[int, float, float]:
        try:
            return parse_drop(text)
        except ValueError as e:
            raise argparse.ArgumentTypeError(str(e)) from None

    p.add_argument("--nodes", type=int, default=4, help="number of ptys/robots, 1-7 (4)")
    def baud(text: str) -> float:
        try:
            return parse_baud(text)
        except ValueError as e:
            raise argparse.ArgumentTypeError(str(e)) from None

    p.add_argument("--baud", type=baud, default=9600,
                   help=f"air bit rate, 8N1, {MIN_BAUD}-{MAX_BAUD} (9600)")
    p.add_argument("--ber", type=float, default=0.0, help="byte error rate per receiver (0)")
    p.add_argument("--noise", action="store_true", help="idle nodes hear random bytes")
    p.add_argument("--seed", type=int, default=0, help="seed of every random stream (0)")
    def link_dir(text: str) -> str:
        if not text.strip():          # "" was "its parent directory /work does not exist"
            raise argparse.ArgumentTypeError("an empty directory name: give the directory "
                                             "for the links, e.g. /tmp/rprs-air")
        return text

    p.add_argument("--link-dir", type=link_dir, default=None, metavar="DIR",
                   help="also create DIR/node0 ... symlinks to the ptys")
    p.add_argument("--pcap", type=file_name, metavar="FILE", default=None,
                   help="write a pcapng capture of the air here, wall-clock timestamps; '-' "
                   "streams it to stdout for a live view: | wireshark -k -i - (the node "
                   "paths then go to stderr)")
    p.add_argument("--drop", type=drop, action="append", default=[], metavar="ID@START-END",
                   help=f"node ID's link is down from START to END s after start, END at most "
                   f"{MAX_SECONDS} (repeatable)")

    def fault(text: str):
        from ..sim.faults import parse_fault
        try:
            f = parse_fault(text)
            check_fault(f)              # an air fault, at a time the hub can play
        except ValueError as e:         # FaultError is one
            raise argparse.ArgumentTypeError(str(e)) from None
        return f
    p.add_argument("--fault", type=fault, action="append", default=[], metavar="SPEC",
                   help="an air fault, as in rprs sim --fault: ber@T1-T2:P, noise@T1-T2, "
                   "burst@T:S, foreign@T:N, foreign@T:xHEX, drop@T1-T2:P, fail:N@T, "
                   "recover:N@T (repeatable)")


def main_radio_hub(args: argparse.Namespace) -> int:
    """Entry for the parsed ``radio-hub`` subcommand (see ``add_arguments``)."""
    distinct_outputs(pcap=getattr(args, "pcap", None))     # (not a serial port: it would send)
    baud = args.baud
    if isinstance(baud, float) and baud.is_integer():
        baud = int(baud)
    return run_hub_cli(args.nodes, baud, args.ber, args.noise, args.seed, args.link_dir,
                       args.drop, getattr(args, "fault", []), getattr(args, "pcap", None))
