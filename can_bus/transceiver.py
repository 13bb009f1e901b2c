"""Philips (PCA)82C250 CAN transceiver between one CAN controller and the :class:`CanBus`.

The transceiver is the object attached to the bus: it implements the bus node interface (see
:mod:`can_bus.bus`) and forwards to its controller, so a controller sees the bus only through
its 82C250::

    ctrl = CanController(sched)                  # firmware_model.mcu.can_controller
    xcvr = Transceiver82C250(bus, ctrl)          # attaches itself to ``bus``

A controller is any object with the bus node methods it wants (``pending``, ``on_frame``,
``on_tx_done``, ``on_arbitration_lost``, ``on_error``, ``on_state_change``, looked up once at
:meth:`Transceiver82C250.connect`; the roles of :mod:`can_bus.node`); it asks for an
arbitration with :meth:`request`, reads its error counters with :meth:`status` and may look
at ``bus_idle`` and ``ticks_per_bit``. ``connect`` sets ``controller.transceiver = self``.

Rs pin (pin 8) modes
--------------------
* ``HIGH_SPEED``: Rs to ground (0 .. 1.8 kOhm); edges as fast as possible, up to 1 Mbit/s.
* ``SLOPE_CONTROL``: Rs to ground through ``rs_ohms`` (16.5 .. 140 kOhm, the range Philips
  application note AN96116 gives). The slew rate is proportional to the current out of Rs
  (AN96116 eq. 4: single-ended ``SR = 0.5 Vcc / (7.6e-3 us/kOhm * R)``, 7 V/us at 47 kOhm,
  2.35 V/us at 140 kOhm), so the bus takes longer to cross the receivers' thresholds and the
  loop delay TXD -> bus -> RXD grows: 150 ns in high-speed mode, 469 ns at 140 kOhm
  (:func:`can_bus.physical.loop_delay_s`, which gives every figure's source). The transceiver
  tells the bus its loop delay (``CanBus.set_loop_delay``); the bus checks each frame's
  acknowledgement against the bit timing's round-trip budget, ``(tseg1 - sjw)`` quanta for both
  loop delays and twice the bus length of cable (Bosch CAN 2.0, bit timing requirements). A
  transmitter whose receivers' ACKs all come back after its sample point sees an ACK error
  (see :mod:`can_bus.bus` for what the others then see). :attr:`Transceiver82C250.slope_limited`
  says whether this node and a high-speed peer break that budget on this bus;
  :attr:`Transceiver82C250.max_bitrate` gives the highest bit rate with the bus's bit-timing
  shape and length at which they do not. Worked figures (default 500 kbit/s timing, 1250 ns
  budget): 140 kOhm with a high-speed peer works up to a 63 m bus; at 1 Mbit/s with 16 quanta
  (625 ns) it fails even on 1 m, and 130 kOhm works. The slope's real purpose, lower
  emissions, and the edge shape within a bit are not modelled.
* ``STANDBY``: Rs high. Transmitter off, receiver in low-power mode. The controller gets no
  frames, no errors and is offered no arbitration (its requests stay pending until the
  transceiver is back in a normal mode). A dominant bus level is passed to RxD so the MCU can
  wake up: ``on_wake(tick)`` fires once, when the bus has been dominant for at least
  ``WAKE_DOMINANT_S`` (3 us, AN96116 §3.3) after entering standby: within a frame, 3 us into its
  first run of dominant bits that long (SOF and the ID's leading 0 bits; a single dominant
  bit at 500 kbit/s, 2 us, does not wake it); at an error flag, 3 us into the flag; for a bus
  stuck dominant with no frame in flight, at the tick the error flag starts (6 bit times after
  the bus went dominant: the bus model gives no earlier hook). The SOF is seen through
  ``pending()``, which the bus does not call for a
  node it counts bus-off: such a node wakes only on a stuck bus. Mode changes take effect at
  the next arbitration; a frame of this node already on the bus completes.

  Simplification: in standby the node stays attached to the bus, so the bus still counts it
  as a receiver (its REC follows the traffic). It does not acknowledge (``acknowledges``). The
  controller's error state
  (``on_state_change``) is still forwarded, as the controller mirrors the bus's counters.

TXD / RXD
---------
Frames go from the controller's TXD to the bus whole (``pending()``); RXD reaches the
controller as whole frames. :attr:`rxd` is only the static level: 0 while the bus is held
dominant, else 1. The 82C250 has **no TXD dominant time-out**: :meth:`stick_txd` (fault
injection) holds the whole bus dominant with ``CanBus.hold_dominant`` for as long as it lasts.
In standby the transmitter is off, so a stuck TXD does not hold the bus (entering standby
releases the hold; leaving it with TXD still stuck holds the bus again). Hold changes reach the
bus through a scheduler event at the same tick (after the current event), so the firmware may
call :meth:`standby` from an ISR running inside a bus callback.
"""
from __future__ import annotations

from enum import Enum
from typing import TYPE_CHECKING, Any, Callable, Protocol, final

from can_bus import physical
from can_bus.bits import wire_bits
from can_bus.bus import CanErrorEvent, ErrorState, NodeStatus
from can_bus.frames import CanFrame
from can_bus.node import CanNode, check_node
from can_bus.clock import Cancellable, Clock
from can_bus.physical import HIGH_SPEED_MAX_OHMS, MAX_BITRATE, loop_delay_s, slew_rate

__all__ = [
    "RsMode",
    "Transceiver82C250",
    "TransceiverBus",
    "HIGH_SPEED_MAX_OHMS",
    "SLOPE_MIN_OHMS",
    "SLOPE_MAX_OHMS",
    "MAX_BITRATE",
    "max_bitrate",
    "slew_rate",
]

WAKE_DOMINANT_S = 3e-6
"""A dominant bus level must last at least this long before the 82C250 in standby signals a
wake-up on RxD (Philips AN96116, PCA82C250/251 application note, §3.3 Stand-by Mode)."""

SLOPE_MIN_OHMS = 16_500
SLOPE_MAX_OHMS = 140_000
"""Slope-control resistor range given by AN96116 (10 uA < -I_Rs < 200 uA)."""


class RsMode(str, Enum):
    HIGH_SPEED = "high-speed"
    SLOPE_CONTROL = "slope-control"
    STANDBY = "standby"


HIGH_SPEED, SLOPE_CONTROL, STANDBY = RsMode.HIGH_SPEED, RsMode.SLOPE_CONTROL, RsMode.STANDBY


def max_bitrate(rs_ohms: int, length_m: float = physical.DEFAULT_LENGTH_M,
                timing: Any = None, rs_other: int = 0) -> int:
    """The highest bit rate (bit/s) at which an 82C250 with ``rs_ohms`` on Rs and one with
    ``rs_other`` meet the round-trip budget over ``length_m`` of bus, with the quanta split of
    ``timing`` (default: the default :class:`~can_bus.bits.BitTiming`, 16 quanta, tseg1 11,
    sjw 1). See :func:`can_bus.physical.max_bitrate`."""
    from can_bus.bits import BitTiming
    t = timing if timing is not None else BitTiming()
    return physical.max_bitrate(rs_ohms, length_m, 1 + t.tseg1 + t.tseg2, t.tseg1, t.sjw,
                                rs_other)


def _check_ohms(rs_ohms: int) -> int:
    if not isinstance(rs_ohms, int) or isinstance(rs_ohms, bool) or rs_ohms < 0:
        raise ValueError(f"rs_ohms must be an int >= 0, got {rs_ohms!r}")
    if HIGH_SPEED_MAX_OHMS <= rs_ohms < SLOPE_MIN_OHMS or rs_ohms > SLOPE_MAX_OHMS:
        raise ValueError(
            f"Rs resistor of {rs_ohms} Ohm: use < {HIGH_SPEED_MAX_OHMS} Ohm (high-speed) or "
            f"{SLOPE_MIN_OHMS}..{SLOPE_MAX_OHMS} Ohm (slope control)"
        )
    return rs_ohms


class TransceiverBus(Protocol):
    """What an 82C250 needs of the bus it sits on, in one place: the simulated
    :class:`~can_bus.bus.CanBus` and the python-can bridge (:mod:`can_bus.bridge`) both give
    it (tests/can_bus/test_transceiver.py holds both to this list, and this list to the source).

    Optional, looked up with ``getattr``: ``start_recovery(node)`` (a bus-off node counts
    its recovery on request), ``set_loop_delay(node, s)``, ``ack_budget_s`` and ``length_m``
    (the ACK timing a simulated bus keeps; a real bus has its own)."""

    sched: Clock
    timing: Any
    """The :class:`~can_bus.bits.BitTiming` (its ``tick_hz`` among others)."""

    def attach(self, node: Any) -> None: ...

    def request(self, node: Any, frame: Any = None) -> None: ...

    def status(self, node: Any) -> NodeStatus: ...

    def error_state(self, node: Any) -> ErrorState: ...

    def hold_dominant(self, node: Any, on: bool = True) -> None: ...

    @property
    def tpb(self) -> int:
        """Ticks per bit (read only: the bridge derives it from its timing)."""
        ...

    @property
    def idle(self) -> bool: ...

    @property
    def held(self) -> bool: ...

    @property
    def frame_on_air(self) -> tuple[CanFrame, int] | None: ...


if TYPE_CHECKING:
    # mypy holds both buses an 82C250 sits on to the list above: a member either lacks (the
    # bridge's error_state once) is a type error here, not a dead `rprs child --can`
    from can_bus.bridge import PythonCanBus
    from can_bus.bus import CanBus

    def _simulated_bus_is_a_port(bus: CanBus) -> TransceiverBus:
        return bus

    def _python_can_bridge_is_a_port(bus: PythonCanBus) -> TransceiverBus:
        return bus


@final
class Transceiver82C250(CanNode):
    """One 82C250 on ``bus``; ``rs_ohms`` is the resistor fitted between Rs and the port pin
    that drives it (0: high-speed). ``standby=True`` starts with the pin high."""

    __slots__ = (
        "bus", "sched", "name", "rs_ohms", "controller", "on_wake", "wakeups",
        "_standby", "_stuck", "_held", "_want_hold", "_hold_ev", "_wake_armed", "_sof_ev",
        "_c_pending", "_c_frame", "_c_tx_done", "_c_lost", "_c_error", "_c_state",
    )

    def __init__(self, bus: TransceiverBus, controller: Any = None, rs_ohms: int = 0,
                 standby: bool = False, name: str = "82C250") -> None:
        self.bus = bus
        self.sched = bus.sched
        self.name = name
        self.rs_ohms = _check_ohms(rs_ohms)
        self.on_wake: Callable[[int], None] | None = None
        self.wakeups = 0
        self._standby = bool(standby)
        self._stuck = False
        self._held = False
        self._want_hold = False
        self._hold_ev: Cancellable | None = None
        self._wake_armed = self._standby
        self._sof_ev: Cancellable | None = None
        self.controller = None
        self._c_pending = self._c_frame = self._c_tx_done = None
        self._c_lost = self._c_error = self._c_state = None
        bus.attach(self)
        self._tell_loop_delay()
        if controller is not None:
            self.connect(controller)

    def __repr__(self) -> str:
        return f"<{self.name} {self.mode.value}>"

    # ------------------------------------------------------------------ wiring
    def connect(self, controller: Any) -> None:
        """Wire ``controller`` to TXD/RXD (replacing any previous one). A controller with a
        misspelt hook is refused (:func:`can_bus.node.check_node`)."""
        check_node(controller)
        self.controller = controller
        self._c_pending = getattr(controller, "pending", None)
        self._c_frame = getattr(controller, "on_frame", None)
        self._c_tx_done = getattr(controller, "on_tx_done", None)
        self._c_lost = getattr(controller, "on_arbitration_lost", None)
        self._c_error = getattr(controller, "on_error", None)
        self._c_state = getattr(controller, "on_state_change", None)
        try:
            controller.transceiver = self
        except AttributeError:
            pass

    # ------------------------------------------------------------------ controller side
    @property
    def acknowledges(self) -> bool:
        """Can this node drive the ACK slot dominant? Not in standby (its transmitter is off,
        82C250 data sheet, standby mode), nor while its controller does not take part in bus
        traffic (``acknowledges`` False on the controller, e.g. the MB90F549 halted)."""
        return not self._standby and bool(getattr(self.controller, "acknowledges", True))

    @property
    def recovers_on_request(self) -> bool:
        """The bus asks at bus-off: does the controller behind this transceiver start its
        recovery count only when asked (``start_recovery``)?"""
        return bool(getattr(self.controller, "recovers_on_request", False))

    def start_recovery(self) -> None:
        """The controller asks to leave bus-off: the bus starts its 128 x 11 count now."""
        start = getattr(self.bus, "start_recovery", None)
        if start is not None:
            start(self)

    def request(self) -> None:
        """The controller has a (new) transmit request: wake the bus's arbitration."""
        if not self._standby:
            self.bus.request(self)

    def status(self) -> NodeStatus:
        """This node's TEC, REC and error state, as counted by the bus."""
        return self.bus.status(self)

    def error_state(self) -> ErrorState:
        """This node's error state, as counted by the bus (``status().state``, cheaper)."""
        return self.bus.error_state(self)

    @property
    def ticks_per_bit(self) -> int:
        return self.bus.tpb

    @property
    def bus_idle(self) -> bool:
        """No frame, error frame or stuck level on the bus now."""
        return self.bus.idle

    # ------------------------------------------------------------------ Rs pin
    @property
    def mode(self) -> RsMode:
        if self._standby:
            return STANDBY
        return HIGH_SPEED if self.rs_ohms < HIGH_SPEED_MAX_OHMS else SLOPE_CONTROL

    def standby(self, on: bool = True) -> None:
        """Drive the Rs port pin high (standby) or low (the resistor's normal mode)."""
        on = bool(on)
        if on == self._standby:
            return
        self._standby = on
        if on:
            self._wake_armed = True
        else:
            self._wake_armed = False
            if self._sof_ev is not None:
                self._sof_ev.cancel()
                self._sof_ev = None
        self._update_hold()
        if not on:
            self.bus.request(self)  # pending requests of the controller may go now

    def set_mode(self, mode: RsMode | str, rs_ohms: int | None = None) -> None:
        """Select a mode; ``rs_ohms`` changes the fitted resistor (needed for SLOPE_CONTROL
        when the current one is a high-speed value)."""
        mode = RsMode(mode)
        if rs_ohms is not None:
            self.rs_ohms = _check_ohms(rs_ohms)
        if mode is HIGH_SPEED and self.rs_ohms >= HIGH_SPEED_MAX_OHMS:
            self.rs_ohms = 0
        elif mode is SLOPE_CONTROL and self.rs_ohms < SLOPE_MIN_OHMS:
            raise ValueError(f"slope control needs {SLOPE_MIN_OHMS}..{SLOPE_MAX_OHMS} Ohm on Rs")
        self._tell_loop_delay()
        self.standby(mode is STANDBY)

    def _tell_loop_delay(self) -> None:
        # a simulated CanBus times the ACK with it; a real bus (can_bus.bridge) has its own
        # physics and no such setting
        tell = getattr(self.bus, "set_loop_delay", None)
        if tell is not None:
            tell(self, loop_delay_s(self.rs_ohms))

    @property
    def loop_delay_s(self) -> float:
        """TXD-to-RXD loop delay with the fitted resistor (s)."""
        return loop_delay_s(self.rs_ohms)

    @property
    def max_bitrate(self) -> int:
        """The highest bit rate (bit/s) at which this node and a high-speed peer meet the
        round-trip budget on this bus (its length, its bit timing's quanta split)."""
        return max_bitrate(self.rs_ohms, getattr(self.bus, "length_m", physical.DEFAULT_LENGTH_M),
                           self.bus.timing)

    @property
    def slope_limited(self) -> bool:
        """True when this node and a high-speed peer break the bus's round-trip budget: their
        ACKs to each other come back after the sample point."""
        budget = getattr(self.bus, "ack_budget_s", None)
        if budget is None:           # a real bus: the default length
            budget = physical.prop_time_s(self.bus.timing) - \
                2 * physical.DEFAULT_LENGTH_M * physical.LINE_DELAY_S_PER_M
        return self.loop_delay_s + loop_delay_s(0) > budget

    # ------------------------------------------------------------------ TXD fault, RXD
    def stick_txd(self, on: bool = True) -> None:
        """Fault injection: TXD stuck dominant (no time-out in the 82C250)."""
        self._stuck = bool(on)
        self._update_hold()

    @property
    def txd_stuck(self) -> bool:
        return self._stuck

    @property
    def holding_bus(self) -> bool:
        """True while this transceiver holds the bus dominant."""
        return self._held

    @property
    def rxd(self) -> int:
        """Static RXD level: 0 (dominant) while the bus is held dominant, else 1."""
        return 0 if self.bus.held else 1

    def _update_hold(self) -> None:
        # Applied by an event at the same tick: the firmware may switch to standby from an ISR
        # that runs inside a bus callback, and CanBus.hold_dominant is not re-entrant there.
        want = self._stuck and not self._standby
        if want != self._want_hold:
            self._want_hold = want
            if self._hold_ev is None:
                self._hold_ev = self.sched.at(self.sched.now, self._apply_hold)

    def _apply_hold(self) -> None:
        self._hold_ev = None
        want = self._want_hold
        if want != self._held:
            self._held = want
            self.bus.hold_dominant(self, want)

    # ------------------------------------------------------------------ wake-up
    def _sof_check(self) -> None:
        # Runs at the tick of an arbitration, after it: a frame started iff the bus is busy.
        # RxD wakes the MCU once the bus has been dominant for WAKE_DOMINANT_S: at the first
        # run of dominant bits in the frame that long (SOF and the leading 0 bits of the ID).
        self._sof_ev = None
        on_air = self.bus.frame_on_air
        if not self._wake_armed or on_air is None:
            return
        frame, sof = on_air
        tpb = self.bus.tpb
        need = self.wake_ticks
        run = 0
        for i, bit in enumerate(wire_bits(frame.id, frame.data, frame.rtr, frame.dlc)):
            run = run + 1 if bit == 0 else 0
            if run * tpb >= need:
                first = i - run + 1
                self._sof_ev = self.sched.at(sof + first * tpb + need, self._wake_at_tick)
                return

    @property
    def wake_ticks(self) -> int:
        """WAKE_DOMINANT_S in ticks of the bus's clock (rounded up)."""
        hz = self.bus.timing.tick_hz
        return -(-round(WAKE_DOMINANT_S * hz * 1000) // 1000)

    def _wake_at_tick(self) -> None:
        self._sof_ev = None
        if self._wake_armed and self._standby:
            self._wake(self.sched.now)

    def _wake(self, tick: int) -> None:
        self._wake_armed = False
        self.wakeups += 1
        if self.on_wake is not None:
            self.on_wake(tick)

    # ------------------------------------------------------------------ bus node interface
    def pending(self) -> CanFrame | None:
        if self._standby:
            if self._wake_armed and self._sof_ev is None:
                self._sof_ev = self.sched.at(self.sched.now, self._sof_check)
            return None
        fn = self._c_pending
        if fn is None:
            return None
        return fn()

    def on_frame(self, frame: CanFrame, start: int, end: int) -> None:
        if not self._standby and self._c_frame is not None:
            self._c_frame(frame, start, end)

    def on_tx_done(self, frame: CanFrame, end: int) -> None:
        # Sent before a switch to standby (the frame already on the bus completes).
        if self._c_tx_done is not None:
            self._c_tx_done(frame, end)

    def on_arbitration_lost(self, frame: CanFrame) -> None:
        if not self._standby and self._c_lost is not None:
            self._c_lost(frame)

    def on_error(self, ev: CanErrorEvent) -> None:
        if ev.transmitter:
            if self._c_error is not None:
                self._c_error(ev)  # our own frame failed: the controller must know
            return
        if self._standby:
            if self._wake_armed and self._sof_ev is None:
                # an error flag (6 dominant bits) of a frame that had not woken us yet; a
                # stuck bus has been dominant for 6 bit times already when its flag starts
                at = ev.tick if self.bus.held else ev.tick + self.wake_ticks
                if at <= self.sched.now:
                    self._wake(at)
                else:
                    self._sof_ev = self.sched.at(at, self._wake_at_tick)
            return
        if self._c_error is not None:
            self._c_error(ev)

    def on_state_change(self, old: ErrorState, new: ErrorState, tick: int) -> None:
        if self._c_state is not None:
            self._c_state(old, new, tick)
