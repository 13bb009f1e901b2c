"""The CAN node seam (can_bus/node.py): what a node must and may provide, checked at attach.

The bus looks each hook up once, by name; a hook it does not find it never calls. These tests
hold the bus to refusing, at attach, the nodes whose hooks would otherwise go unheard."""
from __future__ import annotations

import can
import pytest

from can_bus.bridge import PythonCanBus
from can_bus.bus import CanBus
from can_bus.frames import CanFrame
from can_bus.node import METHOD_HOOKS, CanNode, FrameSink, FrameSource
from can_bus.submodules import make_submodules
from can_bus.transceiver import Transceiver82C250
from firmware_model.mcu.can_controller import CanController
from firmware_model.mcu.scheduler import Scheduler


class Listener:
    def __init__(self) -> None:
        self.heard: list[int] = []

    def on_frame(self, frame, start, end):
        self.heard.append(frame.id)


class Sender:
    def on_tx_done(self, frame, end):
        pass


@pytest.mark.parametrize("typo, hook", [
    ("on_frames", "on_frame"), ("on_tx_don", "on_tx_done"), ("pendng", "pending"),
    ("on_statechange", "on_state_change"), ("on_errors", "on_error"),
    ("recover_on_request", "recovers_on_request"),
])
def test_a_node_with_a_misspelt_hook_is_refused_at_attach_saying_which(typo, hook):
    node_cls = type("Typo", (Listener,), {typo: lambda self, *a: None})
    bus = CanBus(Scheduler())
    with pytest.raises(TypeError, match=f"'{typo}'.*'{hook}'"):
        bus.attach(node_cls())
    assert bus.idle and not bus._nodes          # nothing half attached


def test_a_misspelt_value_hook_set_in_init_is_refused_too():
    class Picky(Listener):
        def __init__(self):
            super().__init__()
            self.rx_id = frozenset({0x100})     # rx_ids: the bus would pass it every frame

    with pytest.raises(TypeError, match="'rx_id'.*'rx_ids'"):
        CanBus(Scheduler()).attach(Picky())


def test_a_node_that_names_a_role_must_define_its_hooks():
    class Half(FrameSource):                    # pending() but its on_tx_done misspelt
        def pending(self):
            return None

        def on_tx_don(self, frame, end):
            pass

    class Deaf(FrameSink):                      # names the role, defines nothing
        pass

    bus = CanBus(Scheduler())
    with pytest.raises(TypeError, match="FrameSource but does not define on_tx_done"):
        bus.attach(Half())
    with pytest.raises(TypeError, match="FrameSink but does not define on_frame"):
        bus.attach(Deaf())


def test_a_hook_that_is_not_callable_is_refused():
    node = Listener()
    node.on_frame = "log"                       # type: ignore[assignment,method-assign]
    with pytest.raises(TypeError, match="on_frame is a str, not a method"):
        CanBus(Scheduler()).attach(node)


def test_a_controller_with_a_misspelt_hook_is_refused_by_its_transceiver():
    class Ctrl(Sender):
        def on_arbitration_lst(self, frame):
            pass

    with pytest.raises(TypeError, match="'on_arbitration_lst'.*'on_arbitration_lost'"):
        Transceiver82C250(CanBus(Scheduler()), Ctrl())


def test_the_python_can_bridge_refuses_a_misspelt_hook_as_the_bus_does():
    bus = PythonCanBus(Scheduler(), can.Bus(interface="virtual", channel="node-typo"))
    try:
        with pytest.raises(TypeError, match="'on_frames'"):
            bus.attach(type("Typo", (), {"on_frames": lambda self, f, s, e: None})())
        assert bus.nodes == []
    finally:
        bus.close()


def test_the_project_s_nodes_attach_and_name_their_roles():
    # Names near a hook that are not one (on_wake, error_state, on_timer) pass; every node
    # the project puts on a bus names the roles whose hooks it has, so mypy checks them.
    sched = Scheduler()
    bus = CanBus(sched)
    ctrl = CanController(sched)
    xcvr = Transceiver82C250(bus, ctrl)
    nodes = make_submodules(sched, bus)
    assert CanNode in type(xcvr).__mro__ and CanNode in type(ctrl).__mro__
    for node in nodes.values():
        assert {FrameSource, FrameSink} <= set(type(node).__mro__)
    for obj in (xcvr, ctrl, *nodes.values()):
        has = {h for h in METHOD_HOOKS if callable(getattr(obj, h, None))}
        declared = {h for role in type(obj).__mro__ if role.__module__ == "can_bus.node"
                    for h in METHOD_HOOKS if h in vars(role)}
        assert has == declared, type(obj).__name__
    # and they work: a submodule's status frame reaches a plain listener
    ear = Listener()
    bus.attach(ear)
    sched.run_until(16_000_000 // 5)
    assert ear.heard


def test_a_frame_from_a_node_without_pending_still_goes_through_the_bus_queue():
    sched = Scheduler()
    bus = CanBus(sched)
    a, b = Sender(), Listener()
    bus.attach(a)
    bus.attach(b)
    bus.request(a, CanFrame(0x123, b"\x01"))
    sched.run_until(10_000)
    assert b.heard == [0x123]
