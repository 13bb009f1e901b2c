"""Executive submodule nodes (can_bus.submodules) on the simulated CAN bus."""
from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from can_bus import dbc
from can_bus.bus import CanBus
from can_bus.frames import CanFrame
from can_bus.submodules import (
    MS,
    PAW_FULL,
    STALL_DETECT_TICKS,
    STATUS_PERIOD_TICKS,
    STATUS_STAGGER_TICKS,
    JointNode,
    PawNode,
    WheelNode,
    make_submodules,
)
from firmware_model.mcu.scheduler import Scheduler
from firmware_model.timing import TICK_HZ

DONE, FAULT, REFUSED = dbc.EVENT_DONE, dbc.EVENT_FAULT, dbc.EVENT_REFUSED
IFS = 3 * 32
"""An answer queued at a command's end tick starts after the 3-bit intermission (500 kbit/s)."""


def ceil_div(a: int, b: int) -> int:
    return -(-a // b)


class Driver:
    """Stands in for the MCU: sends commands (bus-kept queue) and records every frame."""

    def __init__(self) -> None:
        self.rx: list[tuple[int, int, str, dict]] = []  # (start, end, name, raw signals)
        self.tx_end: list[int] = []

    def on_frame(self, frame, start, end):
        self.rx.append((start, end) + dbc.decode_raw(frame))

    def on_tx_done(self, frame, end):
        self.tx_end.append(end)

    def frames(self, name, since=0):
        return [(s, v) for s, _, n, v in self.rx if n == name and s >= since]


class Env:
    def __init__(self):
        self.sched = Scheduler()
        self.bus = CanBus(self.sched)
        self.nodes = make_submodules(self.sched, self.bus)
        self.drv = Driver()
        self.bus.attach(self.drv)

    def run(self, until):
        self.sched.run_until(until)

    def send(self, name, raw=False, **signals) -> int:
        """Send a command now; run until it is delivered and return its end tick."""
        n = len(self.drv.tx_end)
        frame = dbc.encode_raw(name, **signals) if raw else dbc.encode(name, **signals)
        self.bus.request(self.drv, frame)
        while len(self.drv.tx_end) == n:
            assert self.sched.step()
        return self.drv.tx_end[-1]

    def events(self, n, since=0):
        return [(s, v["kind"], v["seq"], v["code"])
                for s, v in self.drv.frames(dbc.event_name(n), since)]

    def status(self, n, since=0):
        return self.drv.frames(dbc.status_name(n), since)


@pytest.fixture
def env():
    return Env()


T0 = 205 * MS  # quiet moment: status frames go at 10..60 ms (+ k * 100 ms)


def test_make_submodules_defaults(env):
    n = env.nodes
    assert list(n) == ["JOINT1", "JOINT2", "JOINT3", "JOINT4", "WHEEL", "PAW"]
    limits = {1: (-17000, 17000), 2: (-1000, 12000), 3: (-13500, 13500), 4: (-12000, 12000)}
    for j, (lo, hi) in limits.items():
        node = n[f"JOINT{j}"]
        assert isinstance(node, JointNode) and node.number == j
        assert (node.min_cdeg, node.max_cdeg) == (lo, hi)
        assert node.max_ddps == (600 if j <= 2 else 900)
        assert node.angle_cdeg == 0 and node.state == dbc.STATE_IDLE
    assert isinstance(n["WHEEL"], WheelNode) and n["WHEEL"].max_speed_mm_s == 300
    assert n["WHEEL"].accel_mm_s2 == 500
    assert isinstance(n["PAW"], PawNode) and n["PAW"].opening_units == PAW_FULL


def test_initial_angles():
    sched = Scheduler()
    nodes = make_submodules(sched, CanBus(sched), initial_angles=(0.0, 45.0, -90.0, 45.0))
    assert [nodes[f"JOINT{j}"].angle_cdeg for j in range(1, 5)] == [0, 4500, -9000, 4500]
    with pytest.raises(ValueError):
        make_submodules(sched, CanBus(sched), initial_angles=(0.0, -45.0, 0.0, 0.0))


def test_status_frames_periodic_and_staggered(env):
    env.run(1000 * MS)
    for n in range(1, 7):
        ticks = [s for s, _ in env.status(n)]
        first = n * STATUS_STAGGER_TICKS
        assert ticks == [first + k * STATUS_PERIOD_TICKS for k in range(10)]
    # nothing else on an idle bus
    assert {name for _, _, name, _ in env.drv.rx} == {dbc.status_name(n) for n in range(1, 7)}


def test_joint_moves_at_rate_limit_and_reports_done_at_exact_tick(env):
    env.run(T0)
    end = env.send("JOINT1_CMD", angle=-90, speed=60, seq=7, mode="move")
    done = end + 9000 * TICK_HZ // 6000  # 90 deg at 60 deg/s: exactly 1.5 s
    assert done == end + 24_000_000
    env.run(done - 1)
    j = env.nodes["JOINT1"]
    assert j.state == dbc.STATE_MOVING and j.angle_cdeg == -8999 and j.speed_ddps == -600
    assert env.events(1) == []
    env.run(done + 10 * MS)
    assert env.events(1) == [(done, DONE, 7, 0)]
    assert j.angle_cdeg == -9000 and j.state == dbc.STATE_HOLDING and j.speed_ddps == 0
    # status frames in between: angle = floor(rate * elapsed), speed -60 deg/s, seq 7
    moving = [(s, v) for s, v in env.status(1, since=end) if s < done]
    assert len(moving) == 15
    for s, v in moving:
        assert v["angle"] == -(6000 * (s - end) // TICK_HZ)
        assert (v["speed"], v["state"], v["seq"]) == (-600, dbc.STATE_MOVING, 7)
    last = env.status(1, since=done)[-1][1]
    assert last == {"angle": -9000, "speed": 0, "state": dbc.STATE_HOLDING, "seq": 7}


@settings(max_examples=25, deadline=None)
@given(joint=st.integers(1, 4), start=st.integers(-9000, 9000), target=st.integers(-9000, 9000),
       speed=st.integers(0, 900))
def test_joint_done_tick_property(joint, start, target, speed):
    e = Env()
    e.run(T0)
    max_ddps = 600 if joint <= 2 else 900
    lo = -1000 if joint == 2 else -9000
    start, target = max(start, lo), max(target, lo)
    e.send(dbc.joint_cmd_name(joint), raw=True, angle=start, speed=max_ddps, seq=1, mode=0)
    e.run(e.sched.now + 4 * TICK_HZ)
    assert e.nodes[f"JOINT{joint}"].angle_cdeg == start
    end = e.send(dbc.joint_cmd_name(joint), raw=True, angle=target, speed=speed, seq=2, mode=0)
    if speed > max_ddps:
        e.run(end + 5 * MS)
        assert e.events(joint, since=end) == [(end + IFS, REFUSED, 2, dbc.REFUSED_RANGE)]
        return
    ddps = speed or max_ddps // 2
    done = end + ceil_div(abs(target - start) * TICK_HZ, ddps * 10)
    e.run(done)
    assert e.nodes[f"JOINT{joint}"].events[-1] == (done, DONE, 2, 0)
    assert e.nodes[f"JOINT{joint}"].angle_cdeg == target


def test_default_speed_and_speed_limit(env):
    env.run(T0)
    end = env.send("JOINT3_CMD", angle=45, speed=0, seq=1, mode="move")  # default 45 deg/s
    env.run(end + TICK_HZ + 5 * MS)
    assert env.events(3) == [(end + TICK_HZ, DONE, 1, 0)]
    end = env.send("JOINT3_CMD", raw=True, angle=0, speed=901, seq=2, mode=0)  # 90.1 > 90 deg/s
    env.run(end + 5 * MS)
    assert env.events(3, since=end) == [(end + IFS, REFUSED, 2, dbc.REFUSED_RANGE)]
    assert env.nodes["JOINT3"].angle_cdeg == 4500 and env.nodes["JOINT3"].seq == 1


def test_out_of_limit_target_refused(env):
    env.run(T0)
    end = env.send("JOINT2_CMD", raw=True, angle=12001, speed=100, seq=9, mode=0)  # 120.01 deg
    env.run(end + 200 * MS)
    assert env.events(2) == [(end + IFS, REFUSED, 9, dbc.REFUSED_RANGE)]
    j = env.nodes["JOINT2"]
    assert j.angle_cdeg == 0 and j.state == dbc.STATE_IDLE and j.seq == 0
    assert all(v["seq"] == 0 and v["angle"] == 0 for _, v in env.status(2))
    end = env.send("JOINT2_CMD", angle=-10, speed=10, seq=10, mode="move")  # limit itself is fine
    env.run(end + TICK_HZ + 5 * MS)
    assert env.events(2, since=end) == [(end + TICK_HZ, DONE, 10, 0)]


def test_hold_relax_and_preemption(env):
    env.run(T0)
    end = env.send("JOINT4_CMD", angle=90, speed=90, seq=1, mode="move")
    env.run(end + 500 * MS)
    end2 = env.send("JOINT4_CMD", angle=0, speed=0, seq=2, mode="hold")
    j = env.nodes["JOINT4"]
    expected = 9000 * (end2 - end) // TICK_HZ
    assert j.angle_cdeg == expected and j.state == dbc.STATE_HOLDING
    end3 = env.send("JOINT4_CMD", angle=0, speed=0, seq=3, mode="relax")
    env.run(end3 + 5 * MS)
    assert env.events(4) == [(end2 + IFS, DONE, 2, 0), (end3 + IFS, DONE, 3, 0)]
    assert [e[0] for e in j.events] == [end2, end3]  # queued at the command's end tick
    assert j.state == dbc.STATE_IDLE and j.angle_cdeg == expected
    # a new move pre-empts the running one without an EVENT for the old one
    end4 = env.send("JOINT4_CMD", angle=-10, speed=90, seq=4, mode="move")
    env.run(end4 + 50 * MS)
    end5 = env.send("JOINT4_CMD", angle=10, speed=90, seq=5, mode="move")
    p = j.angle_cdeg
    env.run(end5 + TICK_HZ)
    assert env.events(4, since=end4) == \
        [(end5 + ceil_div(abs(1000 - p) * TICK_HZ, 9000), DONE, 5, 0)]


def test_stall_at_angle_detected_and_reported(env):
    env.run(T0)
    j = env.nodes["JOINT1"]
    j.stall(at_deg=30)
    end = env.send("JOINT1_CMD", angle=90, speed=60, seq=5, mode="move")
    reach = end + 3000 * TICK_HZ // 6000  # 0.5 s to 30 deg
    env.run(reach + STALL_DETECT_TICKS - 1)
    assert j.angle_cdeg == 3000 and j.state == dbc.STATE_MOVING and j.speed_ddps == 0
    assert env.events(1) == []
    env.run(reach + STALL_DETECT_TICKS + 100 * MS)
    assert env.events(1) == [(reach + STALL_DETECT_TICKS, FAULT, 5, dbc.FAULT_STALLED)]
    assert j.state == dbc.STATE_STALLED
    assert env.status(1)[-1][1] == {"angle": 3000, "speed": 0, "state": dbc.STATE_STALLED, "seq": 5}
    # faulted: commands refused until clear_fault
    end = env.send("JOINT1_CMD", angle=0, speed=60, seq=6, mode="move")
    env.run(end + 5 * MS)
    assert env.events(1, since=end) == [(end + IFS, REFUSED, 6, dbc.REFUSED_FAULTED)]
    j.clear_fault()
    assert j.state == dbc.STATE_IDLE
    end = env.send("JOINT1_CMD", angle=0, speed=60, seq=7, mode="move")
    env.run(end + TICK_HZ)
    assert env.events(1, since=end) == [(end + 3000 * TICK_HZ // 6000, DONE, 7, 0)]


def test_stall_now_while_moving_and_clear_before_detection_resumes(env):
    env.run(T0)
    j = env.nodes["JOINT3"]
    end = env.send("JOINT3_CMD", angle=-90, speed=90, seq=1, mode="move")
    env.run(end + 300 * MS)
    j.stall()
    stuck = j.angle_cdeg
    assert stuck == -2700
    env.run(end + 400 * MS)
    assert j.angle_cdeg == stuck and j.state == dbc.STATE_MOVING
    j.clear_fault()  # within the 200 ms: motion resumes
    t = env.sched.now
    env.run(t + TICK_HZ)
    assert env.events(3) == [(t + ceil_div(6300 * TICK_HZ, 9000), DONE, 1, 0)]
    # stalled for good: fault 200 ms after progress stopped
    end = env.send("JOINT3_CMD", angle=0, speed=90, seq=2, mode="move")
    env.run(end + 100 * MS)
    j.stall()
    t = env.sched.now
    env.run(t + 300 * MS)
    assert env.events(3, since=end) == [(t + STALL_DETECT_TICKS, FAULT, 2, dbc.FAULT_STALLED)]


def test_silent_node_sends_nothing_and_ignores_commands(env):
    j = env.nodes["JOINT3"]
    j.silent(True)
    env.run(T0)
    env.send("JOINT3_CMD", angle=10, speed=10, seq=3, mode="move")
    env.run(T0 + 2 * TICK_HZ)
    ids = {dbc.frame_id(n) for n in ("JOINT3_STATUS", "EVENT3")}
    assert not [r for r in env.drv.rx if dbc.frame_id(r[2]) in ids]
    assert j.angle_cdeg == 0 and j.seq == 0 and j.sent == 0
    assert len(env.status(1)) == 22  # the others keep talking
    j.silent(False)
    t = env.sched.now
    env.run(t + 200 * MS)
    # back on its own grid (30 ms + k * 100 ms)
    assert t == 2205 * MS
    assert [s for s, _ in env.status(3)] == [2230 * MS, 2330 * MS]


def test_wheel_distance_odometry(env):
    env.run(T0)
    w = env.nodes["WHEEL"]
    end = env.send("WHEEL_CMD", speed=300, distance=1000, seq=3)
    env.run(end + 5 * TICK_HZ)
    (done, kind, seq, code), = env.events(5)
    assert (kind, seq, code) == (DONE, 3, 0)
    assert w.x_nm == 1_000_000_000 and w.odometer_mm == 1000 and w.v_ums == 0
    assert w.state == dbc.STATE_IDLE
    # ideal trapezoid: D / v + v / a = 3.333 s + 0.6 s, on a 1 ms grid
    assert (done - end) % MS == 0
    assert abs((done - end) - (1000 * TICK_HZ // 300 + 300 * TICK_HZ // 500)) <= 2 * MS
    st_ = env.status(5, since=end)
    speeds = [v["speed"] for _, v in st_]
    assert max(speeds) == 300
    assert all(abs(b - a) <= 50 for a, b in zip(speeds, speeds[1:]))  # 500 mm/s^2 * 100 ms
    odo = [v["odometer"] for _, v in st_]
    assert odo == sorted(odo) and odo[-1] == 1000
    assert st_[-1][1] == {"speed": 0, "odometer": 1000, "state": dbc.STATE_IDLE, "seq": 3}
    # short distance (no cruise) backwards: exact too
    end = env.send("WHEEL_CMD", speed=-300, distance=-25, seq=4)
    env.run(end + TICK_HZ)
    assert [e[1:] for e in env.events(5, since=end)] == [(DONE, 4, 0)]
    assert w.x_nm == 975_000_000 and max(abs(v["speed"]) for _, v in env.status(5, since=end)) < 300


def test_wheel_continuous_speed_ramp_exact(env):
    env.run(T0)
    w = env.nodes["WHEEL"]
    end = env.send("WHEEL_CMD", speed=100, distance=0, seq=1)
    env.run(end + 300 * MS)
    # 100 mm/s at 500 mm/s^2: 200 steps of 1 ms; distance sum(0.5 * k mm/s * 1 ms, k=1..200)
    assert env.events(5) == [(end + 200 * MS, DONE, 1, 0)]
    assert w.v_ums == 100_000 and w.state == dbc.STATE_MOVING
    assert w.x_nm == 500 * 200 * 201 // 2 + 100_000 * 100
    end2 = env.send("WHEEL_CMD", speed=0, distance=0, seq=2)
    env.run(end2 + 300 * MS)
    assert env.events(5, since=end2)[0][1:] == (DONE, 2, 0)
    assert w.v_ums == 0 and w.state == dbc.STATE_IDLE


def test_wheel_refusals_and_stall(env):
    env.run(T0)
    w = env.nodes["WHEEL"]
    e1 = env.send("WHEEL_CMD", raw=True, speed=301, distance=0, seq=1)
    e2 = env.send("WHEEL_CMD", speed=100, distance=-5, seq=2)
    e3 = env.send("WHEEL_CMD", speed=0, distance=5, seq=3)
    env.run(e3 + 5 * MS)
    assert [e[1:] for e in env.events(5)] == [(REFUSED, 1, 1), (REFUSED, 2, 1), (REFUSED, 3, 1)]
    assert [e[0] for e in w.events] == [e1, e2, e3]
    end = env.send("WHEEL_CMD", speed=200, distance=500, seq=4)
    env.run(end + 500 * MS)
    w.stall()
    t = env.sched.now
    odo = w.x_nm
    env.run(t + 400 * MS)
    assert env.events(5, since=end) == [(t + STALL_DETECT_TICKS, FAULT, 4, dbc.FAULT_STALLED)]
    assert w.x_nm == odo and w.state == dbc.STATE_STALLED and env.status(5)[-1][1]["speed"] == 0
    w.clear_fault()
    end = env.send("WHEEL_CMD", speed=200, distance=100, seq=5)
    env.run(end + 2 * TICK_HZ)
    assert w.x_nm == odo + 100_000_000


def test_paw_close_without_object(env):
    env.run(T0)
    p = env.nodes["PAW"]
    end = env.send("PAW_CMD", action="close", force=50, seq=1)
    env.run(end + TICK_HZ)
    assert env.events(6) == [(end + 800 * MS, DONE, 1, 0)]  # full stroke 800 ms
    assert (p.opening_units, p.grip, p.state) == (0, 0, dbc.STATE_IDLE)
    assert env.status(6)[-1][1] == {"opening": 0, "grip": 0, "state": dbc.STATE_IDLE, "seq": 1}


def test_paw_grips_an_object(env):
    env.run(T0)
    p = env.nodes["PAW"]
    p.place_object(True)  # 40 % wide
    end = env.send("PAW_CMD", action="close", force=80, seq=2)
    env.run(end + TICK_HZ)
    assert env.events(6) == [(end + 480 * MS, DONE, 2, 0)]  # 60 % of the stroke
    assert (p.opening_units, p.grip, p.state) == (4000, 1, dbc.STATE_HOLDING)
    assert env.status(6)[-1][1] == {"opening": 40, "grip": 1, "state": dbc.STATE_HOLDING, "seq": 2}
    end = env.send("PAW_CMD", action="open", force=0, seq=3)
    assert p.grip == 0 and p.state == dbc.STATE_MOVING
    env.run(end + TICK_HZ)
    assert env.events(6, since=end) == [(end + 480 * MS, DONE, 3, 0)]
    assert (p.opening_units, p.grip, p.state) == (PAW_FULL, 0, dbc.STATE_IDLE)


def test_estop_stops_everything_without_events(env):
    env.run(T0)
    env.send("JOINT1_CMD", angle=90, speed=60, seq=1, mode="move")
    env.send("WHEEL_CMD", speed=300, distance=0, seq=2)
    env.run(T0 + 300 * MS)
    n_events = len(env.events(5))
    env.send("ESTOP", reason=1)
    a = env.nodes["JOINT1"].angle_cdeg
    env.run(T0 + 2 * TICK_HZ)
    assert env.nodes["JOINT1"].angle_cdeg == a and env.nodes["JOINT1"].state == dbc.STATE_HOLDING
    assert env.nodes["WHEEL"].v_ums == 0 and env.nodes["WHEEL"].state == dbc.STATE_IDLE
    assert env.events(1) == [] and len(env.events(5)) == n_events


@pytest.mark.parametrize("data", [b"", bytes(2), bytes(8)])
def test_an_estop_of_the_wrong_length_still_stops_and_is_counted(env, data):
    """Fail-safe (docs/can.md): a stop is never refused for its form, only counted."""
    env.run(T0)
    env.send("JOINT1_CMD", angle=90, speed=60, seq=1, mode="move")
    env.run(T0 + 300 * MS)
    env.bus.request(env.drv, CanFrame(dbc.frame_id("ESTOP"), data))
    env.run(T0 + 320 * MS)
    j = env.nodes["JOINT1"]
    a = j.angle_cdeg
    env.run(T0 + 2 * TICK_HZ)
    assert j.angle_cdeg == a and j.state == dbc.STATE_HOLDING and env.events(1) == []
    assert all(n.bad_frames == 1 for n in env.nodes.values())


def test_malformed_command_ignored(env):
    env.run(T0)
    env.bus.request(env.drv, CanFrame(dbc.frame_id("JOINT1_CMD"), bytes(5)))
    env.run(T0 + 50 * MS)
    assert env.nodes["JOINT1"].bad_frames == 1 and env.events(1) == []


def test_a_remote_frame_with_the_estop_id_stops_nothing(env):
    """``cansend vcan0 010#R`` (a request for the MCU's ESTOP frame, carrying no data) to
    ``rprs submodules`` stopped a moving joint where it was and dropped its command: no done
    EVENT ever came, and the closing line counted nothing. A remote frame is no command: the
    nodes ignore it and count it as malformed; an ESTOP data frame still stops them."""
    env.run(T0)
    end = env.send("JOINT1_CMD", angle=30, speed=60, seq=3, mode="move")
    env.bus.request(env.drv, CanFrame(dbc.frame_id("ESTOP"), b"", True, 1))
    done = end + 3000 * TICK_HZ // 6000            # 30 deg at 60 deg/s: 0.5 s
    env.run(done + 10 * MS)
    assert env.events(1) == [(done, DONE, 3, 0)]
    assert env.nodes["JOINT1"].angle_cdeg == 3000
    assert [n.bad_frames for n in env.nodes.values()] == [1] * 6
    back = env.send("JOINT1_CMD", angle=0, speed=60, seq=4, mode="move")
    env.run(back + 100 * MS)
    env.send("ESTOP", reason=1)
    env.run(done + 2 * TICK_HZ)
    assert env.nodes["JOINT1"].state == dbc.STATE_HOLDING and env.events(1, since=done + MS) == []
    assert 0 < env.nodes["JOINT1"].angle_cdeg < 3000


def test_deterministic():
    def scenario():
        e = Env()
        e.run(T0)
        e.send("JOINT2_CMD", angle=77.77, speed=33.3, seq=1, mode="move")
        e.send("WHEEL_CMD", speed=-250, distance=-333, seq=2)
        e.nodes["PAW"].place_object(True, size_pct=25)
        e.send("PAW_CMD", action="close", force=10, seq=3)
        e.nodes["JOINT4"].stall()
        e.send("JOINT4_CMD", angle=5, speed=0, seq=4, mode="move")
        e.run(4 * TICK_HZ)
        return e.drv.rx

    assert scenario() == scenario()


def test_paw_object_placed_while_closing_keeps_exact_timing(env):
    env.run(T0)
    p = env.nodes["PAW"]
    end = env.send("PAW_CMD", action="close", force=10, seq=1)
    env.run(end + 200 * MS)  # 25 % of the stroke done
    p.place_object(True, size_pct=50)
    env.run(end + TICK_HZ)
    assert p.events == [(end + 400 * MS, DONE, 1, 0)]
    assert (p.opening_units, p.grip) == (5000, 1)
    p.place_object(False)
    assert (p.grip, p.state) == (0, dbc.STATE_IDLE)


def test_wheel_reversal_distance_is_relative_to_the_command(env):
    env.run(T0)
    w = env.nodes["WHEEL"]
    env.send("WHEEL_CMD", speed=300, distance=0, seq=1)
    env.run(env.sched.now + TICK_HZ)
    env.send("WHEEL_CMD", speed=-100, distance=-200, seq=2)
    x0 = w.x_nm  # the command took effect at its end tick
    env.run(env.sched.now + 5 * TICK_HZ)
    assert w.x_nm - x0 == -200_000_000 and w.v_ums == 0
    assert [e[1:] for e in w.events] == [(DONE, 1, 0), (DONE, 2, 0)]


def _stepping_reference(w: WheelNode) -> None:
    """Make ``w`` run every 1 ms step as an event, as before its cruise had a closed form:
    after each step, stop cruising at once (which schedules the next step on the grid)."""
    def step():
        WheelNode._step(w)
        w._stop_cruising()
    w._step = step


_WHEEL_ACTIONS = st.one_of(
    # distance 0: a continuous command (it cruises once at speed); else a distance to go
    st.tuples(st.just("cmd"), st.integers(-300, 300),
              st.one_of(st.just(0), st.just(0), st.integers(-400, 400))),
    st.tuples(st.sampled_from(["stall", "clear", "estop", "fault", "observe"])),
)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 600), st.sampled_from([0, 1, -1, 7]), _WHEEL_ACTIONS),
                min_size=1, max_size=12))
def test_a_cruising_wheel_in_closed_form_is_the_wheel_stepping_every_ms(script):
    """The cruise counts its steps instead of running them (WheelNode.x_nm). Against a wheel
    that runs every step as an event, the same script of commands, ESTOPs, stalls and faults
    gives the same frames, EVENTs and state at every tick either reads, ties included: the
    actions land on whole milliseconds after the first command (a step's tick) or one tick
    either side, and statuses (every 100 ms) meet steps whenever the grid allows."""
    def play(reference: bool):
        e = Env()
        w = e.nodes["WHEEL"]
        if reference:
            _stepping_reference(w)
        seen: list = []
        t = T0
        seq = 0

        def act(action):
            nonlocal seq
            kind = action[0]
            if kind == "cmd":
                speed, dist = action[1], action[2]
                if dist and (speed == 0 or (dist > 0) != (speed > 0)):
                    dist = -dist if speed else 0
                seq = (seq + 1) % 256
                frame = dbc.encode_raw("WHEEL_CMD", speed=speed, distance=dist, seq=seq)
                w.on_frame(frame, e.sched.now - 100, e.sched.now)
            elif kind == "estop":
                w.on_frame(dbc.encode("ESTOP", reason=1), e.sched.now - 100, e.sched.now)
            elif kind == "stall":
                w.stall()
            elif kind == "clear":
                w.clear_fault()
            elif kind == "fault":
                w.fault()
            seen.append((e.sched.now, kind, w.x_nm, w.v_ums, w.state, w.status_signals()))

        for ms, off, action in script:
            t += ms * MS + off
            e.sched.at(t, act, action)
        e.run(t + 3 * TICK_HZ)
        return seen, e.drv.rx, w.events, w.x_nm, w.v_ums, w.state

    assert play(False) == play(True)


def test_a_cruising_wheel_schedules_no_steps(env):
    """What the closed form is for: at a constant speed the wheel has no event pending but its
    status; its odometer still moves every 1 ms (including the step of the tick read)."""
    w = env.nodes["WHEEL"]
    env.run(T0)
    end = env.send("WHEEL_CMD", speed=100, distance=0, seq=1)
    env.run(end + 200 * MS)          # the 200th step reaches 100 mm/s
    assert w.cruising and w.v_ums == 100_000
    x = w.x_nm
    before = len(env.sched)
    env.run(end + 1200 * MS)
    assert len(env.sched) <= before
    assert w.x_nm == x + 100_000 * 1000
    env.run(end + 1200 * MS + MS - 1)
    assert w.x_nm == x + 100_000 * 1000
    env.run(end + 1201 * MS)
    assert w.x_nm == x + 100_000 * 1001


def test_status_values_are_the_status_frame_in_dbc_order(env):
    """Each node's status_values() are its status frame's signals in rprs.dbc's order
    (encode_raw_values takes them so), and status_signals() names them."""
    env.send("JOINT2_CMD", angle=50, speed=30, seq=7, mode=0)
    env.send("WHEEL_CMD", speed=-120, distance=0, seq=3)
    env.send("PAW_CMD", action=0, force=50, seq=9)
    env.run(env.sched.now + 3 * TICK_HZ)      # every move done; the wheel cruising
    for node in env.nodes.values():
        assert node.STATUS_SIGNALS == dbc.signal_names(node.status_name)
        values = node.status_values()
        assert all(type(v) is int for v in values)
        assert node.status_signals() == dict(zip(node.STATUS_SIGNALS, values))
        assert dbc.encode_raw_values(node.status_name, values) == \
            dbc.encode_raw(node.status_name, **node.status_signals())
        # what went on the bus last is what the node reports now (the wheel rolls on)
        start, last = env.status(node.number)[-1]
        if node.number != dbc.WHEEL_NUMBER:
            assert tuple(last[k] for k in node.STATUS_SIGNALS) == values


def test_a_node_whose_status_order_is_not_the_dbcs_is_refused():
    class Backwards(PawNode):
        STATUS_SIGNALS = ("seq", "state", "grip", "opening")

    sched = Scheduler()
    with pytest.raises(ValueError, match="STATUS_SIGNALS.*PAW_STATUS"):
        Backwards(sched, CanBus(sched))
