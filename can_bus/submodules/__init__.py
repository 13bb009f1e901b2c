"""The six executive submodules of a child (docs/can.md) as nodes on :class:`~can_bus.bus.CanBus`.

Each node implements the bus's node interface directly (``pending()`` / ``on_tx_done()`` with
its own priority queue, ``on_frame()`` for the frames addressed to it), encodes and decodes
every frame through :mod:`can_bus.dbc`, and runs an exact, deterministic physical model on the
integer-tick clock (:class:`~can_bus.clock.Clock`) at 16 MHz, the tick rate every
constant below is written for (no wall clock, no randomness).

Common behaviour
----------------
* A command takes effect at the tick the bus delivers it (``on_frame``: end of the frame's
  EOF), with no processing latency. A new command pre-empts the running one (no EVENT for
  the pre-empted command); the status ``seq`` is the seq of the last command *taken*.
* Refusals (``EVENT<n>`` kind 3): code 1 out of range (target outside the limits, speed above
  the maximum, an undefined mode/action, wheel distance whose sign disagrees with the speed),
  code 3 faulted (state 3 stalled or 4 fault, until :meth:`clear_fault`). Code 2 (busy) is
  never sent: commands pre-empt.
* ``STATUS`` every :data:`STATUS_PERIOD_TICKS` (100 ms); node ``n``'s first status goes
  ``n * STATUS_STAGGER_TICKS`` (10 ms) after the node is created, so the six status frames
  never contend for the same tick. A status still queued when the next one is due (bus
  busy / bus-off) is replaced by the newer one; events queue up in order.
* ``ESTOP`` (0x010): every node stops at once and drops its command without an EVENT (joints
  and paw hold where they are; the wheel's speed drops to 0). A faulted node stays faulted.
  A data frame with the ESTOP identifier stops the node whatever its length (fail-safe: an
  emergency stop is never refused for its form); a length other than the DBC's 1 byte is
  also counted in :attr:`bad_frames`. A remote frame with that identifier is no stop, only a
  bad frame.
* Fault injection: :meth:`stall` (motion stops; after :data:`STALL_DETECT_TICKS` (200 ms)
  without progress while a motion is commanded, ``EVENT`` kind 2 code 1 and state 3),
  :meth:`fault` (any fault code at once, state 4, or 3 for code 1), :meth:`silent` (the node
  sends nothing, its queue is dropped, commands and ESTOP are ignored; the physics keeps
  running and the status grid keeps its phase), :meth:`clear_fault`.

Physical models
---------------
* :class:`JointNode`: constant angular speed (no acceleration phase) toward the target,
  computed analytically in 0.01 deg units: travelled = floor(speed * elapsed), the EVENT
  done is sent at ``start + ceil(|delta| / speed)`` ticks exactly. After a move the joint
  holds (state 2); ``hold`` stops at once (state 2), ``relax`` stops at once (state 0);
  both complete with EVENT done at once.
* :class:`WheelNode`: 1 ms physics step with exact integers (speed in um/s, odometer in nm):
  each step the speed changes by at most ``accel`` (0.5 mm/s a step at 500 mm/s^2) and the
  odometer adds the new speed times 1 ms (semi-implicit Euler). A distance command plans its
  braking so that it stops exactly on the distance (the last step covers the remainder, at
  most one step's speed change, and the speed is then 0); EVENT done at that step. A
  distance-0 command ("keep running") completes with EVENT done when the speed reaches the
  target. Status ``speed`` (mm/s) and ``odometer`` (mm) are truncated toward zero.
  A step runs before every other event of its tick (``Scheduler.at_top``), so whatever reads
  the wheel at tick T sees the step of T done. That rule lets a *cruising* wheel (at the
  commanded speed, no distance to go) stop scheduling its steps: the odometer at any tick is
  the odometer at the last step taken plus the speed times the whole milliseconds since
  (:attr:`WheelNode.x_nm`); a command, ESTOP, stall or fault first takes those steps and puts
  the next one back on the same 1 ms grid.
* :class:`PawNode`: constant travel speed, a full stroke (0..100 %) in 800 ms, positions in
  0.01 % units, analytic like the joint. Closing with an object present stops where the
  fingers meet it (``object_size_pct``, default 40 %), grip=1, state 2 holding; EVENT done
  at contact. Opening releases the grip (grip=0) at once.

Default parameters (:func:`make_submodules`)
---------------------------------------------
=========  ====================  ==============  =========  =============
node       name                  limits (deg)    max deg/s  default deg/s
=========  ====================  ==============  =========  =============
JOINT1     base yaw              -170 .. 170     60         30
JOINT2     shoulder              -10 .. 120      60         30
JOINT3     elbow                 -135 .. 135     90         45
JOINT4     wrist (end link)      -120 .. 120     90         45
=========  ====================  ==============  =========  =============

Joints start at 0 deg (or ``initial_angles``), idle. WHEEL: max 300 mm/s, acceleration 500 mm/s^2,
odometer 0.
PAW: full stroke 800 ms, starts fully open (100 %), object size 40 %, no object.

The rooms: ``params`` (the constants and default parameters above), ``node`` (the node base
every submodule shares: its queue, status grid, DBC coding, fault injection), ``axis`` (joints
and the paw: one analytic axis), ``wheel`` (the wheel's 1 ms integer physics).
"""
from __future__ import annotations

from typing import Sequence

from can_bus.clock import Clock as Scheduler
from can_bus.node import NodeBus

from .axis import JointNode, PawNode
from .node import _Submodule
from .params import (JOINT_DEFAULT_SPEED_DPS, JOINT_DEFAULTS, MS, PAW_FULL, PAW_STROKE_MS,
                     STALL_DETECT_TICKS, STATUS_PERIOD_TICKS, STATUS_STAGGER_TICKS,
                     WHEEL_ACCEL_MM_S2, WHEEL_MAX_SPEED_MM_S, WHEEL_STEP_TICKS)
from .wheel import WheelNode

__all__ = [
    "MS",
    "STATUS_PERIOD_TICKS",
    "STATUS_STAGGER_TICKS",
    "STALL_DETECT_TICKS",
    "WHEEL_STEP_TICKS",
    "PAW_STROKE_MS",
    "PAW_FULL",
    "JOINT_DEFAULTS",
    "JOINT_DEFAULT_SPEED_DPS",
    "WHEEL_MAX_SPEED_MM_S",
    "WHEEL_ACCEL_MM_S2",
    "JointNode",
    "WheelNode",
    "PawNode",
    "make_submodules",
]


def make_submodules(sched: Scheduler, bus: NodeBus,
                    initial_angles: Sequence[float] = (0.0, 0.0, 0.0, 0.0),
                    ) -> dict[str, _Submodule]:
    """The six executive submodules with the default parameters (module docstring table),
    attached to ``bus``, keyed by DBC node name: JOINT1..JOINT4, WHEEL, PAW.

    ``initial_angles``: joint 1..4 angles (deg) at power-up, e.g. ``kinematics.HOME`` so that
    the nodes start where the planner believes they are."""
    if len(initial_angles) != 4:
        raise ValueError("initial_angles needs the four joint angles")
    nodes: dict[str, _Submodule] = {}
    for n, params in JOINT_DEFAULTS.items():
        nodes[f"JOINT{n}"] = JointNode(sched, bus, n, initial_deg=initial_angles[n - 1], **params)
    nodes["WHEEL"] = WheelNode(sched, bus)
    nodes["PAW"] = PawNode(sched, bus)
    return nodes
