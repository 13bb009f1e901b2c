"""``rprs capture``: a listen-only station on a radio's serial port (a USB radio, a hub node)
that writes what it hears as pcapng for Wireshark (docs/wireshark.md): the same link type and
the same cut into frames as a bench process's ``--pcap`` (hil/bench/capture.py)."""
from __future__ import annotations

import argparse
import os
import sys
import time
from types import SimpleNamespace
from typing import Any

from firmware_model.timing import PC_BYTE_TICKS, TICK_HZ

from .common import UserError, distinct_outputs, file_name


class _Ears:
    """The radio model a listen-only channel feeds: always listening, sending nothing; the
    capture (the channel's tap) is what hears."""

    def __init__(self, byte_ticks: int) -> None:
        self.uart = SimpleNamespace(byte_ticks=byte_ticks)
        self.channel: Any = None

    def listening(self, now: int) -> bool:
        return True

    def deliver(self, data: bytes, t0: int, bt: int, late_ok: bool = False,
                lead: int = 0) -> None:
        pass


CAPTURE_STALL_TICKS = 50 * TICK_HZ // 1000
"""A capture that did not run for longer than this (50 ms) drops what it then reads: the
stamps of bytes read that late would be off by more than a turn's guard (Ttrans, 5 ms) is
worth, and a frame cut by the quiet timer firing first would be two false packets."""


def cmd_capture(a: argparse.Namespace) -> int:
    from ..bench.capture import BenchCapture
    from ..bench.runner import Runner
    from ..bench.serial_radio import PortError, SerialChannel, open_port
    if a.duration is not None and not a.duration > 0:
        raise UserError(f"--duration must be a number of seconds > 0, got {a.duration:g}")
    if a.pcap != "-" and os.path.exists(a.pcap) and os.path.exists(a.radio) and \
            os.path.samefile(a.pcap, a.radio):
        # (writing the capture there would transmit it: a listener sends nothing)
        raise UserError(f"--pcap {a.pcap} is the radio's own port: give another file")
    distinct_outputs(pcap=a.pcap)          # (another radio's port: the same, on that radio)
    try:
        port = open_port(a.radio)
    except PortError as exc:
        raise UserError(str(exc)) from None
    runner = Runner()
    try:
        stream = sys.stdout.buffer if a.pcap == "-" else open(a.pcap, "wb")
        cap = BenchCapture(runner.sched, stream, None, True, None,
                           listener=f"radio on {a.radio}")
    except OSError as exc:
        port.close()
        if a.pcap == "-" and isinstance(exc, BrokenPipeError):
            raise                  # stdout's reader gone already: as every command ends then
        raise UserError(f"cannot write capture {a.pcap}: {exc.strerror or exc}") from None
    # a capture that cannot go on (its reader gone, the disk full) ends the command
    # (standard output's reader gone, ``--pcap - | head -c 100``: as every command then ends)
    cap.on_error = lambda why: runner.stdout_gone() if cap.reader_gone and a.pcap == "-" \
        else runner.fail(why)
    channel = SerialChannel(runner.sched, port, "none")
    channel.attach(_Ears(PC_BYTE_TICKS))               # type: ignore[arg-type]
    channel.tap = cap
    channel.on_lost = lambda why: runner.fail(f"the radio port {a.radio} went away ({why})")
    runner.sched.on_start(channel.flush)

    def stalled(late: int, now: int) -> None:
        # bytes read after a stall would be stamped as if heard at once: dropped, the gap said
        channel.flush()
        cap.gap(late)
        print(f"rprs: capture stalled: it did not run for {late / TICK_HZ:.2f} s; what the "
              f"radio heard meanwhile is not in the capture (its times are unknown), and the "
              f"next packet's comment says so", file=sys.stderr, flush=True)
    runner.sched.watch_stalls(CAPTURE_STALL_TICKS, stalled)
    runner.on_close(channel.close)
    runner.on_close(cap.close, last=True)
    channel.start()
    where = "stdout" if a.pcap == "-" else a.pcap
    started = time.monotonic()
    runner.run(a.duration, ready=lambda: print(
        f"capturing {a.radio} to {where} (listen only: nothing is sent); Ctrl-C stops",
        file=sys.stderr, flush=True))
    gaps = f", {cap.gaps} gap{'s' if cap.gaps != 1 else ''} (stalls)" if cap.gaps else ""
    # (the wall time it ran: the runner's clock stops at its last event, the last byte heard)
    print(f"capture: {channel.bytes_in} bytes heard in {time.monotonic() - started:.1f} s"
          f"{gaps}", file=sys.stderr)
    if runner.stdout_closed:
        raise BrokenPipeError("standard output closed by its reader")    # (main: status 1)
    if cap.error is None and cap.close_error is not None:
        print(f"rprs: error: cannot write capture {a.pcap}: {cap.close_error}", file=sys.stderr)
        return 1
    if runner.failure is not None:
        print(f"rprs: error: {runner.failure}", file=sys.stderr)
        return 1
    return 1 if cap.error else 0


def add(sub) -> None:
    c = sub.add_parser("capture", help="listen on a radio's serial port and write what it hears "
                       "as pcapng for Wireshark (nothing is sent)")
    c.add_argument("--radio", required=True, metavar="PORT",
                   help="the serial port of a radio (/dev/ttyUSB0, a hub node, socket://...)")
    c.add_argument("--pcap", required=True, type=file_name, metavar="FILE",
                   help="the capture: a file, a FIFO (mkfifo f; wireshark -k -i f), or - for "
                        "stdout (rprs capture ... --pcap - | wireshark -k -i -)")
    c.add_argument("--duration", type=float, metavar="SECONDS",
                   help="stop after this long (default: until Ctrl-C or SIGTERM)")
    c.set_defaults(func=cmd_capture)
