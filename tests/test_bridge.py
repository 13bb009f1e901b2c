"""The same child firmware and submodules on a real python-can bus, in real time.

Runs on python-can's ``virtual`` interface everywhere and on SocketCAN ``vcan0`` where the
kernel has it (``scripts/vcan-vm.sh`` runs the ``vcan`` ones for real on CI).
"""
from __future__ import annotations

import subprocess
import sys

import pytest

from can_bus import dbc
from can_bus.bridge import CanOpenError, PythonCanBus, open_bus, parse_spec
from can_bus.submodules import make_submodules
from can_bus.transceiver import Transceiver82C250
from firmware_model.child import ChildFirmware
from firmware_model.kinematics import HOME
from firmware_model.mcu.can_controller import CanController
from firmware_model.radio.content import cmd
from firmware_model.radio.mac import Deliver
from firmware_model.station import build_station
from hil.sim.realtime import RealTimeScheduler


def test_dispatcher_drives_the_submodules_over_python_can(can_channel, tmp_path):
    """A Content command reaches the right joint with the right DBC signals, the joint moves
    and reports done, over a python-can bus shared by two bus objects (as two processes)."""
    sched = RealTimeScheduler()
    log = tmp_path / "child.log"
    child_bus = PythonCanBus(sched, open_bus(can_channel), log=str(log))
    node_bus = PythonCanBus(sched, open_bus(can_channel))
    try:
        station, _radio = build_station(1, sched)
        ctrl = CanController(sched)
        child = ChildFirmware(station, ctrl, Transceiver82C250(child_bus, ctrl))
        subs = make_submodules(sched, node_bus, initial_angles=HOME)
        sched.post(child._on_message,
                   Deliver(0, 1, 0, 2, (cmd("joint", 1, 12), cmd("paw", 0))), 0)
        sched.run_for(1.6)                   # 12 deg at 60 deg/s = 0.2 s; paw stroke 0.8 s
        assert subs["JOINT1"].angle_deg == pytest.approx(12, abs=0.01)
        assert subs["PAW"].opening_units == 0
        assert not child.dispatcher.jobs                 # both done events came back
        assert station.mac.outbox == ()                  # no failure reply
        assert child_bus.sent >= 2 and child_bus.received > 10   # commands out, status in
    finally:
        child_bus.close()
        node_bus.close()
    # python-can's candump writer: cantools decodes our traffic with the DBC
    text = log.read_text()
    assert " 101#" in text or "101#" in text
    r = subprocess.run([sys.executable, "-m", "cantools", "decode", str(dbc.dbc_path())],
                       input=text, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and "JOINT1_CMD" in r.stdout and "angle: 12" in r.stdout


@pytest.mark.parametrize("spec,needle", [
    ("vcan0", "not INTERFACE:CHANNEL"),
    ("nosuch:x", "unknown python-can interface"),
    ("socketcan:vcan9", "cannot open CAN bus socketcan:vcan9"),
])
def test_bad_can_specs_give_one_line_errors(spec, needle):
    with pytest.raises(CanOpenError) as e:
        open_bus(spec)
    assert needle in str(e.value) and "\n" not in str(e.value)


def test_spec_parsing():
    assert parse_spec("socketcan:vcan0") == ("socketcan", "vcan0")
    assert parse_spec("udp_multicast:224.0.0.1") == ("udp_multicast", "224.0.0.1")
