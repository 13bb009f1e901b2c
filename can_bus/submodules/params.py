"""The submodules' constants and default parameters (ticks at 16 MHz, degrees, mm; rprs.dbc's
ranges), and two integer helpers of their physics."""
from __future__ import annotations

from typing import Any

from can_bus import dbc
from can_bus.clock import DEFAULT_TICK_HZ as TICK_HZ

MS = TICK_HZ // 1000
"""16000 ticks a millisecond."""
STATUS_PERIOD_TICKS = 100 * MS
STATUS_STAGGER_TICKS = 10 * MS
STALL_DETECT_TICKS = 200 * MS
WHEEL_STEP_TICKS = 1 * MS
PAW_STROKE_MS = 800
PAW_FULL = 10_000
"""Paw position units in a full stroke (0.01 % each)."""

JOINT_DEFAULT_SPEED_DPS = {1: 30.0, 2: 30.0, 3: 45.0, 4: 45.0}
"""deg/s a joint moves at for ``speed`` 0: half its rated speed (stated in rprs.dbc too)."""


def _joint_defaults(n: int) -> dict[str, Any]:
    """Joint n's limits and rated speed, from rprs.dbc's [min|max] of JOINTn_CMD."""
    lo, hi = dbc.signal_range(dbc.joint_cmd_name(n), "angle")
    return dict(limits=(float(lo), float(hi)),
                max_speed_dps=float(dbc.signal_range(dbc.joint_cmd_name(n), "speed")[1]),
                default_speed_dps=JOINT_DEFAULT_SPEED_DPS[n])


JOINT_DEFAULTS: dict[int, dict[str, Any]] = {n: _joint_defaults(n) for n in range(1, 5)}
"""1 base yaw, 2 shoulder, 3 elbow, 4 wrist (end link)."""
WHEEL_MAX_SPEED_MM_S = int(dbc.signal_range("WHEEL_CMD", "speed")[1])
"""The wheel's rated speed, either way (rprs.dbc)."""
WHEEL_ACCEL_MM_S2 = 500


def _sign(x: int) -> int:
    return (x > 0) - (x < 0)


def _trunc_div(a: int, b: int) -> int:
    """a / b truncated toward zero (b > 0)."""
    return a // b if a >= 0 else -((-a) // b)
