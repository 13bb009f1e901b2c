"""Wireshark's extcap interface to a radio: capture live from a serial radio or a hub node from
Wireshark's own interface list (docs/wireshark.md, "Live from a radio").

Wireshark runs an extcap program with options that ask for its interfaces, their link types
and settings, and then for a capture into a FIFO; this one offers one interface,
``rprs-radio``, whose capture is ``rprs capture --radio PORT --pcap FIFO`` (a listen-only
station: nothing is sent). ``rprs wireshark --install-extcap`` puts a launcher for it in
Wireshark's personal extcap folder:

    python -m hil.cli.extcap --extcap-interfaces
    python -m hil.cli.extcap --extcap-interface rprs-radio --extcap-config
    python -m hil.cli.extcap --extcap-interface rprs-radio --capture --fifo F --port P
"""
from __future__ import annotations

import argparse
import sys
from importlib.metadata import PackageNotFoundError, version

INTERFACE = "rprs-radio"
LINKTYPE_USER0 = 147
"""The radio frames' link type (hil/sim/pcap.py)."""


def _version() -> str:
    try:
        return version("rprs")
    except PackageNotFoundError:       # a checkout run without installing
        return "0"


def interfaces() -> str:
    return (f"extcap {{version={_version()}}}\n"
            f"interface {{value={INTERFACE}}}{{display=RPRS radio (a serial radio or a "
            f"radio-hub node, listen only)}}\n")


def dlts() -> str:
    return f"dlt {{number={LINKTYPE_USER0}}}{{name=USER0}}{{display=RPRS radio frames}}\n"


def config() -> str:
    return ("arg {number=0}{call=--port}{display=Radio port}{type=string}{required=true}"
            "{tooltip=the serial port of a radio: /dev/ttyUSB0, a hub node /dev/pts/N, "
            "socket://host:port}\n"
            "arg {number=1}{call=--duration}{display=Stop after (s)}{type=double}"
            "{tooltip=empty: until the capture is stopped}\n")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="rprs-extcap", description=__doc__.splitlines()[0])
    p.add_argument("--extcap-interfaces", action="store_true")
    p.add_argument("--extcap-version")
    p.add_argument("--extcap-interface")
    p.add_argument("--extcap-dlts", action="store_true")
    p.add_argument("--extcap-config", action="store_true")
    p.add_argument("--extcap-capture-filter")
    p.add_argument("--extcap-control-in")
    p.add_argument("--extcap-control-out")
    p.add_argument("--capture", action="store_true")
    p.add_argument("--fifo")
    p.add_argument("--port")
    p.add_argument("--duration", type=float)
    a, _ = p.parse_known_args(argv)
    if a.extcap_interfaces:
        sys.stdout.write(interfaces())
        return 0
    if a.extcap_interface not in (None, INTERFACE):
        print(f"rprs-extcap: error: no interface {a.extcap_interface!r} (only {INTERFACE})",
              file=sys.stderr)
        return 2
    if a.extcap_dlts:
        sys.stdout.write(dlts())
        return 0
    if a.extcap_config:
        sys.stdout.write(config())
        return 0
    if a.capture:
        if not a.fifo or not a.port:
            print("rprs-extcap: error: --capture needs --fifo and --port", file=sys.stderr)
            return 2
        import contextlib
        import io
        from . import main as rprs_main
        args = ["capture", "--radio", a.port, "--pcap", a.fifo]
        if a.duration:
            args += ["--duration", str(a.duration)]
        said = io.StringIO()
        # Wireshark shows whatever an extcap writes to stderr as an error: the capture's
        # "capturing ..." and "N bytes heard" lines only when it failed
        with contextlib.redirect_stderr(said):
            code = rprs_main(args)
        if code != 0:
            sys.stderr.write(said.getvalue())
        return code
    p.print_usage(sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
