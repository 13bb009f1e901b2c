"""``rprs radio-hub``: ptys that play the shared radio channel (hil.bench.radio_hub)."""
from __future__ import annotations

import argparse

from .common import UserError

def cmd_radio_hub(a: argparse.Namespace) -> int:
    from ..bench.radio_hub import HubError, main_radio_hub
    try:
        return main_radio_hub(a)
    except (ValueError, HubError) as exc:
        raise UserError(str(exc)) from None


def add(sub) -> None:
    from ..bench.radio_hub import add_arguments
    hub = sub.add_parser("radio-hub", help="ptys that play the shared radio channel, for "
                         "robot processes and serial programs")
    add_arguments(hub)
    hub.set_defaults(func=cmd_radio_hub)
