"""``rprs inject``: a foreign transmitter like any other program: write bytes into a port (a
radio-hub pty, a USB radio), the bytes of the fault ``foreign@AT:N`` or ``foreign@AT:xHEX``
under ``--seed`` (hil.sim.faults)."""
from __future__ import annotations

import argparse
import time

from .common import UserError, port_name


def cmd_inject(a: argparse.Namespace) -> int:
    import serial

    from ..bench.hub_parts import MAX_SECONDS
    from ..bench.serial_radio import PortError, open_port
    from ..sim.faults import FaultError, foreign_bytes, foreign_fault
    try:
        fault = foreign_fault(a.at, a.random, None if a.hex is None else "".join(a.hex.split()))
    except FaultError as exc:
        raise UserError(str(exc)) from None
    if not a.at <= MAX_SECONDS:         # as the hub's foreign@T: time.sleep(1e300) overflowed
        raise UserError(f"--at must be at most {MAX_SECONDS} seconds, got {a.at!r}")
    data = foreign_bytes(fault, a.seed)
    try:
        port = open_port(a.radio)
    except PortError as exc:
        raise UserError(str(exc)) from None
    try:
        # No write timeout: the port takes the bytes as fast as the far side carries them
        # (a radio hub at its --baud, behind what other writers queued), so no deadline
        # fits every documented size; the 2 s of open_port failed any write above about
        # 14 KB into a hub at 9600 baud, after part of it had gone on air. A far side that
        # goes away is an error (EIO); Ctrl-C stops a wait that is too long.
        port.write_timeout = None
        deadline = time.monotonic() + a.at
        while (left := deadline - time.monotonic()) > 0:
            time.sleep(left)
        port.write(data)
        port.flush()
    except (serial.SerialException, OSError) as exc:
        raise UserError(f"cannot write to {a.radio}: {exc}") from None
    finally:
        port.close()
    shown = data[:32].hex() + ("..." if len(data) > 32 else "")
    print(f"wrote {len(data)} bytes to {a.radio} at {a.at:g} s: {shown}")
    return 0


def add(sub) -> None:
    inj = sub.add_parser("inject", help="a foreign transmitter: write bytes into a radio-hub "
                         "pty or serial port, like any other program")
    inj.add_argument("--radio", type=port_name, metavar="PORT", required=True,
                     help="serial port, radio-hub pty or pyserial URL")
    what = inj.add_mutually_exclusive_group(required=True)
    what.add_argument("--hex", metavar="HEX", help="exactly these bytes, e.g. 0f0a05...")
    what.add_argument("--random", type=int, metavar="N", help="N random bytes, 1-65536 (from "
                      "--seed: those of the fault foreign@AT:N under that seed)")
    inj.add_argument("--seed", type=int, default=0, help="seed of --random (default 0)")
    inj.add_argument("--at", type=float, default=0.0, metavar="SECONDS",
                     help="write this long after opening the port, 0-10000000 (default 0)")
    inj.set_defaults(func=cmd_inject)
