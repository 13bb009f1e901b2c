"""Acceptance tests for a child robot, through its external interfaces only (radio + CAN).

They run against every ``--target`` (default: model and process); against a flashed board
with ``pytest tests/acceptance --target board --radio /dev/ttyUSB0 --txen rts --can
pcan:PCAN_USBBUS1``. See docs/acceptance.md.
"""
from __future__ import annotations

import pytest

from firmware_model.radio.content import cmd

pytestmark = pytest.mark.acceptance


def _done(dut, msg):
    return lambda: msg.state in ("delivered", "failed")


def test_the_child_is_in_the_fathers_ring(dut):
    assert dut.in_ring()
    # (the bus is alive: the submodules' status frames; that the child itself is on it, the
    # tests below show: its commands, and its status reply from what it heard there)
    assert dut.run_until(lambda: len(dut.frames()) > 0, 5.0), \
        "no CAN traffic on the bus: no submodule (nor the bench's emulated ones) is on it"


def test_a_joint_command_reaches_its_joint_and_completes(dut):
    n0 = len(dut.frames("EVENT1"))
    k0 = len(dut.replies(3))
    msg = dut.send([cmd("joint", 1, 25)])
    assert dut.run_until(lambda: any(s["angle"] == 25 for _, _, s in dut.frames("JOINT1_CMD")),
                         10.0), f"no JOINT1_CMD angle 25 on the CAN bus in 10 s; {dut.explain(msg)}"
    assert dut.run_until(lambda: len(dut.frames("EVENT1")) > n0, 10.0), \
        f"joint 1 sent no EVENT1 in 10 s; {dut.explain(msg)}"
    assert dut.frames("EVENT1")[-1][2]["kind"] == 1            # done
    assert dut.run_until(_done(dut, msg), 10.0) and msg.state == "delivered", \
        f"joint(1,25) not acknowledged in 10 s; {dut.explain(msg)}"
    # the child's own report that it finished (docs/protocol.md, done(): protocol 3.0); a
    # child that never sent it passed
    reported = lambda: ["".join(c.text() for c in d.commands)  # noqa: E731
                        for d in dut.replies(3)[k0:]]
    assert dut.run_until(lambda: "done()joint(1,25)" in reported(), 10.0), \
        f"no done()joint(1,25) from the child in 10 s (it sent {reported()})"
    # ... and only once the joint said it had: a child that reported done() as soon as it
    # took the order (the joint still on its way) passed
    moved = dut.frames("EVENT1")[-1][0]
    said = next(t for t, d in dut.replies_at(3)[k0:]
                if "".join(c.text() for c in d.commands) == "done()joint(1,25)")
    assert said >= moved, (f"the child reported done()joint(1,25) {dut.seconds(moved - said):.3f}"
                           f" s before joint 1's EVENT1 (done) was on the bus")
    if dut.submodules:
        assert dut.submodules["JOINT1"].angle_deg == pytest.approx(25, abs=0.01)


def test_an_unreachable_target_comes_back_as_failure_information(dut):
    n0 = len(dut.replies(4))
    msg = dut.send([cmd("moveto", 900, 0, 0)])
    assert dut.run_until(lambda: len(dut.replies(4)) > n0, 10.0), \
        f"no failure information (Type '4') in 10 s; {dut.explain(msg)}"
    reply = dut.replies(4)[-1]
    assert [c.text() for c in reply.commands] == ["fail(1)", "moveto(900,0,0)"]


def test_an_action_is_announced_and_reported_done(dut):
    k0 = len(dut.replies())
    msg = dut.send([cmd("act", 2, 0)])
    notices = lambda: [c.text() for d in dut.replies()[k0:] for c in d.commands]  # noqa: E731
    assert dut.run_until(lambda: "act(2,1)" in notices(), 15.0), \
        f"no act(2,1) notice in 15 s; {dut.explain(msg)}"
    assert "act(2,0)" in notices(), f"act(2,1) came, but no act(2,0) before it: {notices()}"
    assert notices().index("act(2,0)") < notices().index("act(2,1)"), notices()
    assert any(s["angle"] == -90 for _, _, s in dut.frames("JOINT1_CMD"))


def test_status_reply_reports_four_joints(dut):
    k0 = len(dut.replies(3))
    msg = dut.send([cmd("status")])
    assert dut.run_until(lambda: any(c.name == "joint" for d in dut.replies(3)[k0:]
                                     for c in d.commands), 10.0), \
        f"no status reply (Type '3', joint(...)) in 10 s; {dut.explain(msg)}"
    got = [c for d in dut.replies(3)[k0:] for c in d.commands if c.name == "joint"]
    assert [c.args[0] for c in got] == [1, 2, 3, 4]
    if dut.submodules:       # the bench's own joints: their angles (at rest between tests)
        # are what the child reports (docs/protocol.md, status(): joint angles in degrees)
        angles = {c.args[0]: float(c.args[1]) for c in got}
        real = {i: dut._call(lambda i=i: dut.submodules[f"JOINT{i}"].angle_deg)
                for i in range(1, 5)}
        assert all(abs(angles[i] - real[i]) <= 0.01 for i in real), (angles, real)


def test_a_stalled_joint_is_reported(dut):
    if not dut.submodules:
        pytest.skip("the board's own submodules answer (--real-submodules): cannot stall one")
    joint = dut.submodules["JOINT2"]
    dut._call(joint.stall)
    try:
        k0 = len(dut.replies(4))
        msg = dut.send([cmd("joint", 2, 80)])
        assert dut.run_until(lambda: len(dut.replies(4)) > k0, 10.0), \
            f"no failure information (Type '4') in 10 s; {dut.explain(msg)}"
        assert dut.replies(4)[-1].commands[0].text() == "fail(12)"
    finally:
        dut._call(joint.clear_fault)
