"""The CAN physical layer's delays: slope resistor -> slew rate -> loop delay -> the longest bus
and the highest bit rate for a bit timing.

Every figure here is in seconds, volts, ohms or metres, and says where it comes from:

* **Slew rate** (AN96116, Philips application note "PCA82C250/251 CAN transceiver", eq. 4):
  in slope-control mode the single-ended CANH/CANL slew rate is set by the current out of Rs,
  ``SR = 0.5 Vcc / (k_SE * R)`` with ``k_SE = 7.6e-3 us/kOhm`` and Vcc = 5 V: 7 V/us at 47 kOhm,
  2.35 V/us at 140 kOhm. CANH rises and CANL falls together, so the differential voltage moves
  at ``2 SR`` (the 82C250 data sheet's 14 V/us at 47 kOhm is this differential figure).
* **Receiver thresholds and dominant level** (ISO 11898-2 and the 82C250 data sheet's DC
  characteristics): the receiver reads dominant above a differential 0.9 V and recessive below
  0.5 V; a driven dominant bit is 1.5-3.0 V, nominally 2.0 V, into 60 Ohm. Worst cases taken
  here: a dominant-going edge is read at 0.9 V, a recessive-going one at 0.5 V, falling from
  2.0 V. So a slope adds ``0.9 V / 2 SR`` to the dominant-going delay and ``1.5 V / 2 SR`` to
  the recessive-going one; in high-speed mode the edges are taken as instant.
* **Loop delay in high-speed mode** (TXD to RXD through the bus pins): 120 ns dominant-going,
  150 ns recessive-going, the PCA82C250 data sheet's maxima of t_onRXD and t_offRXD at Rs = 0.
  These two figures were not checked against a copy of the data sheet kept in this project:
  pass the ones of your part (:func:`loop_delay_s` takes them).
* **Cable**: 5 ns/m, ISO 11898-2's nominal specific line delay.
* **Bit timing** (Bosch CAN Specification 2.0, part A §8 / part B §10 "Bit timing
  requirements"): PROP_SEG compensates the physical delays, twice the sum of the bus line's
  propagation time, the input comparator delay and the output driver delay, i.e. the round
  trip ``loop(A) + loop(B) + 2 * length * 5 ns/m`` between the two farthest nodes; and the
  resynchronisation jump width is at most PHASE_SEG1. The MB90F549 (like most controllers)
  merges PROP_SEG and PHASE_SEG1 into TSEG1, so the round trip may take at most
  ``(tseg1 - sjw)`` quanta (:func:`prop_time_s`).

What the bus model does with it: a frame whose transmitter does not get any acknowledging
receiver's dominant ACK back within that budget ends in an ACK error (``can_bus.bus``). A bus
outside the design rule is taken to fail on every frame; a real one may work by margin, and
the arbitration misreads it also risks between two far transmitters are not modelled.
"""
from __future__ import annotations

import math

from can_bus.bits import BitTiming

__all__ = [
    "K_SE_US_PER_KOHM",
    "VCC",
    "V_DOMINANT",
    "V_TH_DOMINANT",
    "V_TH_RECESSIVE",
    "LOOP_HS_DOMINANT_S",
    "LOOP_HS_RECESSIVE_S",
    "LINE_DELAY_S_PER_M",
    "DEFAULT_LENGTH_M",
    "HIGH_SPEED_MAX_OHMS",
    "MAX_BITRATE",
    "slew_rate",
    "loop_delay_s",
    "prop_time_s",
    "round_trip_s",
    "max_bus_length_m",
    "max_bitrate",
]

K_SE_US_PER_KOHM = 7.6e-3
"""AN96116 eq. 4 constant (us per kOhm)."""
VCC = 5.0
"""82C250 supply (V)."""
V_DOMINANT = 2.0
"""Nominal differential dominant output into 60 Ohm (V); ISO 11898-2 range 1.5-3.0 V."""
V_TH_DOMINANT = 0.9
"""Differential input above which the receiver surely reads dominant (V)."""
V_TH_RECESSIVE = 0.5
"""Differential input below which the receiver surely reads recessive (V)."""
LOOP_HS_DOMINANT_S = 120e-9
"""TXD to RXD, dominant-going, high-speed mode (s): data sheet t_onRXD max (see module doc)."""
LOOP_HS_RECESSIVE_S = 150e-9
"""TXD to RXD, recessive-going, high-speed mode (s): data sheet t_offRXD max."""
LINE_DELAY_S_PER_M = 5e-9
"""ISO 11898-2 nominal specific line delay (s/m)."""
DEFAULT_LENGTH_M = 1.0
"""Assumed length of a child's internal bus (m): the six submodules and the MCU sit inside
one robot. Set ``CanBus(length_m=...)`` for your harness."""
HIGH_SPEED_MAX_OHMS = 1_800
"""Rs resistance below which the 82C250 is in high-speed mode (AN96116: V_Rs < 0.3 Vcc)."""
MAX_BITRATE = 1_000_000
"""82C250 / CAN 2.0 maximum bit rate (bit/s)."""


def slew_rate(rs_ohms: int) -> float:
    """Typical single-ended CANH/CANL slew rate (V/us) for a slope resistor (AN96116 eq. 4)."""
    return 0.5 * VCC / (K_SE_US_PER_KOHM * rs_ohms / 1000)


def loop_delay_s(rs_ohms: int, hs_dominant_s: float = LOOP_HS_DOMINANT_S,
                 hs_recessive_s: float = LOOP_HS_RECESSIVE_S) -> float:
    """TXD-to-RXD loop delay of an 82C250 with ``rs_ohms`` on Rs (s): the slower of its two
    edges, the high-speed delay plus the time the slope takes to cross the threshold."""
    if rs_ohms < HIGH_SPEED_MAX_OHMS:
        return max(hs_dominant_s, hs_recessive_s)
    diff_v_per_s = 2 * slew_rate(rs_ohms) * 1e6
    return max(hs_dominant_s + V_TH_DOMINANT / diff_v_per_s,
               hs_recessive_s + (V_DOMINANT - V_TH_RECESSIVE) / diff_v_per_s)


def prop_time_s(timing: BitTiming) -> float:
    """The longest round trip ``timing`` allows (s): ``(tseg1 - sjw)`` quanta."""
    return (timing.tseg1 - timing.sjw) * timing.prescaler / timing.tick_hz


def round_trip_s(loop_a_s: float, loop_b_s: float, length_m: float) -> float:
    """A's bit to B and B's answer back to A (s), over ``length_m`` of cable."""
    return loop_a_s + loop_b_s + 2 * length_m * LINE_DELAY_S_PER_M


def max_bus_length_m(timing: BitTiming, rs_a: int = 0, rs_b: int = 0) -> float:
    """The longest bus (m) on which two 82C250s with ``rs_a`` and ``rs_b`` on Rs meet the
    bit-timing rule with ``timing``; negative when even a zero-length bus does not."""
    spare = prop_time_s(timing) - loop_delay_s(rs_a) - loop_delay_s(rs_b)
    return spare / (2 * LINE_DELAY_S_PER_M)


def max_bitrate(rs_ohms: int, length_m: float = DEFAULT_LENGTH_M, tq_per_bit: int = 16,
                tseg1: int = 11, sjw: int = 1, rs_other: int = 0) -> int:
    """The highest bit rate (bit/s, rounded down, at most 1 Mbit/s) at which an 82C250 with
    ``rs_ohms`` and one with ``rs_other`` meet the bit-timing rule over ``length_m``, with a bit
    of ``tq_per_bit`` quanta of which ``tseg1`` before the sample point and an ``sjw``-quanta
    jump width. The prescaler's granularity is not applied: a real clock gives only some of
    the rates below this bound."""
    if not 1 <= sjw <= tseg1 < tq_per_bit - 1:
        raise ValueError(f"no bit timing with {tq_per_bit} quanta, tseg1 {tseg1} and sjw {sjw}")
    if tseg1 == sjw:
        return 0                             # no quantum left for the round trip
    need = round_trip_s(loop_delay_s(rs_ohms), loop_delay_s(rs_other), length_m)
    bit_s = need * tq_per_bit / (tseg1 - sjw)
    return min(MAX_BITRATE, math.floor(1 / bit_s))
