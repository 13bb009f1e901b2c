"""The calculate submodule (paper Fig. 4): the child's arm kinematics.

Geometry we assume for the SIA child robot (paper Fig. 2: a wheel module carrying a four-joint
arm that ends in the paw). Frame of the child: origin on the body at joint 1's axis, x forward,
y left, z up; millimetres and degrees.

* joint 1: base yaw about z, angle q1 (0 = forward, + = to the left);
* joint 2: shoulder pitch at height H0 = 80 mm, angle q2 (0 = horizontal, + = up);
* link 1: L1 = 150 mm shoulder to elbow; joint 3: elbow pitch q3, relative to link 1;
* link 2: L2 = 120 mm elbow to wrist;   joint 4: wrist pitch q4, relative to link 2;
* end link: L3 = 60 mm wrist to the paw's tip.

The tip is at r = L1 cos q2 + L2 cos(q2+q3) + L3 cos(q2+q3+q4) from the axis, height
z = H0 + L1 sin q2 + L2 sin(q2+q3) + L3 sin(q2+q3+q4), and x = r cos q1, y = r sin q1. The end
link's pitch phi = q2 + q3 + q4 is kept as it is when the tip moves (``movex`` translates the
paw without turning it). Inverse kinematics: q1 from atan2(y, x); the wrist point from phi; the
two-link planar solution, elbow up (q3 <= 0) first, elbow down if that breaks a joint limit.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

H0 = 80.0
L1 = 150.0
L2 = 120.0
L3 = 60.0

JOINT_LIMITS: dict[int, tuple[float, float]] = {
    1: (-170.0, 170.0),   # base yaw
    2: (-10.0, 120.0),    # shoulder
    3: (-135.0, 135.0),   # elbow
    4: (-120.0, 120.0),   # wrist (end link)
}
"""Joint limits in degrees (the submodule nodes refuse targets outside them too)."""

WHEEL_MAX_SPEED = 300
"""mm/s, either direction."""

HOME = (0.0, 45.0, -90.0, 45.0)
"""Joint angles (deg) of the rest pose: end link horizontal, pointing forward."""

REACH = L1 + L2 + L3


class Unreachable(ValueError):
    """A tip position no joint configuration reaches; ``code`` for the failure reply."""

    def __init__(self, message: str, code: int) -> None:
        super().__init__(message)
        self.code = code


CODE_UNREACHABLE = 1
CODE_JOINT_LIMIT = 2


@dataclass(frozen=True)
class Pose:
    """A tip position (mm) and end-link pitch (deg)."""

    x: float
    y: float
    z: float
    phi: float


def forward(q: tuple[float, float, float, float]) -> Pose:
    """Tip pose of joint angles ``q`` (deg)."""
    q1, q2, q3, q4 = (math.radians(a) for a in q)
    a2, a3, a4 = q2, q2 + q3, q2 + q3 + q4
    r = L1 * math.cos(a2) + L2 * math.cos(a3) + L3 * math.cos(a4)
    z = H0 + L1 * math.sin(a2) + L2 * math.sin(a3) + L3 * math.sin(a4)
    return Pose(r * math.cos(q1), r * math.sin(q1), z, math.degrees(a4))


def within_limits(q: tuple[float, ...]) -> int | None:
    """The first joint (1-4) outside its limits, or None."""
    for i, a in enumerate(q, 1):
        lo, hi = JOINT_LIMITS[i]
        if not lo - 1e-9 <= a <= hi + 1e-9:
            return i
    return None


def inverse(x: float, y: float, z: float, phi: float) -> tuple[float, float, float, float]:
    """Joint angles (deg, rounded to 0.01 as the CAN frames carry them) putting the tip at
    (x, y, z) mm with end-link pitch ``phi``; raises Unreachable."""
    r = math.hypot(x, y)
    q1 = math.degrees(math.atan2(y, x)) if r > 1e-9 else 0.0
    p = math.radians(phi)
    rw = r - L3 * math.cos(p)
    zw = z - H0 - L3 * math.sin(p)
    d = (rw * rw + zw * zw - L1 * L1 - L2 * L2) / (2 * L1 * L2)
    if not -1.0 <= d <= 1.0:
        raise Unreachable(f"({x:g}, {y:g}, {z:g}) mm is out of the arm's reach "
                          f"(wrist {math.hypot(rw, zw):.1f} mm from the shoulder; the arm "
                          f"reaches {abs(L1 - L2):g}-{L1 + L2:g} mm)", CODE_UNREACHABLE)
    bad = None
    for sign in (-1.0, 1.0):                 # elbow up, then elbow down
        q3 = sign * math.acos(d)
        q2 = math.atan2(zw, rw) - math.atan2(L2 * math.sin(q3), L1 + L2 * math.cos(q3))
        q4 = p - q2 - q3
        q = (round(q1, 2), round(math.degrees(q2), 2), round(math.degrees(q3), 2),
             round(_wrap(math.degrees(q4)), 2))
        bad = within_limits(q)
        if bad is None:
            return q
    assert bad is not None                   # both elbows were tried and failed
    lo, hi = JOINT_LIMITS[bad]
    raise Unreachable(f"({x:g}, {y:g}, {z:g}) mm needs joint {bad} outside its limits "
                      f"{lo:g}..{hi:g} deg", CODE_JOINT_LIMIT)


def _wrap(a: float) -> float:
    while a > 180.0:
        a -= 360.0
    while a <= -180.0:
        a += 360.0
    return a
