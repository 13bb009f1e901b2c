"""MB90F549 CAN controller (one of its two CAN interfaces), as the firmware sees it.

Register and bit names follow the Fujitsu F2MC-16LX hardware manual (CAN controller chapter) so
a reader can map the model to the hardware; each register is also reachable through a plain
Python API. The controller reaches the bus only through its transceiver (normally a
:class:`can_bus.transceiver.Transceiver82C250`, which sets ``self.transceiver`` when connected):
it implements the bus node interface of :mod:`can_bus.bus` (``pending``, ``on_frame``, ...), and
calls ``transceiver.request()`` / ``transceiver.status()``. All times are integer ticks.

Registers (16 message buffers, x = 0..15; bit x of a 16-bit register is buffer x)
---------------------------------------------------------------------------------
* ``CSR`` control status: ``HALT`` (bit 0, 1 = bus operation halted; 1 after reset),
  ``NIE`` (bit 2, 0x0004, node status transition interrupt enable, where the MB90540/545
  family's I/O header has CSR0's NIE; the model once had bit 1), ``TOE`` (bit 7, transmit
  output enable: 0 = the TX pin is a port, nothing is sent), ``NS1:NS0`` (bits 9:8, node
  status: 00 error active, 01 warning = error active with TEC or REC >= 96, 10 error passive,
  11 bus off),
  ``NT`` (bit 10, node status transition flag, cleared by writing 0). ``TS``/``RS`` (transmit /
  receive in progress) are not modelled (read 0).
* ``LEIR`` last event indicator: ``NTE`` (bit 7, node status transition), ``TCE`` (bit 6,
  transmit complete), ``RCE`` (bit 5, receive complete), ``MBP3-0`` (bits 3-0, the buffer of
  the last TX/RX event). Each event clears the other event bits.
* ``RTEC``: ``REC`` in bits 7-0 and ``TEC`` in bits 15-8 (Fujitsu F2MC-16LX MB90895-series
  hardware manual, CAN controller chapter, §16.3.4 "Receive/Transmit Error Counter (RTEC)",
  Figure 16.3-7, p. 493: the same CAN macro as the MB90F549's; the model once had the two
  bytes the other way round). Mirrors the bus's counters of this node, saturated at 255;
  ``tec``/``rec`` give the unsaturated values.
* ``BTR`` bit timing: ``TS2`` (bits 14-12) = tseg2-1, ``TS1`` (bits 11-8) = tseg1-1, ``RSJ``
  (bits 7-6) = sjw-1, ``PSC`` (bits 5-0) = prescaler-1 (machine-clock ticks per quantum); see
  :func:`btr_from_timing`. Writable only while HALT = 1. Clearing HALT checks that its bit
  time equals the bus's (a wrong bit rate would make every frame an error: rejected instead).
* ``BVALR`` buffer valid, ``TREQR`` transmit request (lowest requested buffer number goes
  first, whatever its ID), ``TCANR`` transmit cancel (reads the cancels still pending),
  ``TCR`` transmit complete, ``RCR`` receive complete, ``ROVRR`` receive overrun, ``RRTRR``
  remote frame received, ``TRTRR`` transmit a remote frame, ``TIER``/``RIER`` transmit /
  receive interrupt enable (the manual's IER pair). ``TCR``, ``RCR``, ``ROVRR`` bits are
  cleared by writing 0 (writing 1 leaves them).
* ``AMSR`` acceptance mask select, 2 bits a buffer (bits 2x+1:2x): ``AMS_FULL`` (00, every ID
  bit compared), ``AMS_ALL`` (01, full bit mask: accept all), ``AMS_AMR0`` (10), ``AMS_AMR1``
  (11) (use acceptance mask register 0 / 1). ``AMR0``/``AMR1``: 11-bit masks, bit = 1 means
  "do not compare this ID bit".
* ``IDR[x]`` (11-bit standard ID), ``DLCR[x]``, ``DTR[x]`` (8 bytes): read-only views here;
  write through :meth:`CanController.configure_tx` / :meth:`configure_rx` / :meth:`transmit`.

Model decisions
---------------
* Direction: each valid buffer is configured as transmit or receive (``tx_buffers`` bit
  mask, a model register). (The real controller receives into any valid buffer without a
  pending transmit request; here a transmit buffer never receives.)
* Reception (manual's rule): a received frame is compared with every valid receive buffer;
  among those whose ID matches under their mask it goes to the lowest-numbered one with RC = 0
  (a multi-level buffer when several share a filter); if all matching buffers are full and
  unread it overwrites the highest-numbered (lowest priority) of them and sets its ROVR bit.
  With one matching buffer: lowest-numbered match, overrun when full. IDR takes the received
  ID (the compared bits are unchanged). A remote frame sets RRTR and leaves DTR unchanged
  (automatic answers are not modelled). Frames are taken while the controller runs (HALT = 0,
  not bus-off), not while halted.
* Interrupts: ``on_tx_irq(buffer)`` / ``on_rx_irq(buffer)`` are called at the end tick of the
  frame on the bus (end of EOF), when the buffer's TIE / RIE bit is set; ``on_status_irq(ns)``
  when NT is set and NIE = 1. The flags (TCR/RCR/NT) stay set until the firmware clears them.
* Transmit: TREQ is kept after an error (automatic retransmission) and cleared with TC = 1 on
  success. ``cancel`` (TCANR) removes a request at once unless its frame may be on the bus now
  (offered at the last arbitration, bus busy): then it takes effect when that attempt ends
  (lost arbitration, error, or another node's frame), and is void if the frame completes
  (TC = 1). A cancel does not set TC.
* Error counters and state mirror the bus's (``CanBus.status`` of the transceiver). NT is set
  on transitions seen at frame / error / state-change callbacks (a warning level crossed
  during a stuck-dominant episode shows in NS at once but sets NT at the next callback).
* Bus-off: the controller sets HALT = 1 and NS = 11. As the manual has it (F2MC-16LX
  hardware manual, CAN controller, §21.4.3, Figure 21.4-3, the node status transition
  diagram, p. 456: bus-off ends after 0 is written to HALT and then 128 runs of 11 recessive
  bits are received), the count starts when the firmware clears HALT
  (``recovers_on_request``: the bus model counts for this node only from
  ``start_recovery``); the controller comes back (NS = 00, NT = 1, transmit requests
  resume) when the count is complete, at the earliest 1408 bit times after HALT was cleared
  (2.816 ms at 500 kbit/s). HALT reads 1 until then, though 0 was written (same figure: the
  controller leaves bus-off, HALT = 1, only once the 128 x 11 recessive bits have passed):
  firmware for this CAN macro clears HALT and polls ``while (CSR0_HALT);`` until the
  controller has rejoined, which reading 0 at once would end before it had (``halted`` is
  that read-back). While HALT = 1 it does not acknowledge others' frames (``acknowledges``).

Over 500 lines on purpose: it is one peripheral, register by register, as the MB90F549 manual's
CAN chapter describes it.
"""
from __future__ import annotations

from typing import Any, Callable, final

from can_bus.bits import BitTiming
from can_bus.bus import CanErrorEvent, ErrorState
from can_bus.frames import CanFrame
from can_bus.node import CanNode

from ..timing import TICK_HZ

__all__ = [
    "CanController",
    "NBUF",
    "AMS_FULL", "AMS_ALL", "AMS_AMR0", "AMS_AMR1",
    "CSR_HALT", "CSR_NIE", "CSR_TOE", "CSR_NS0", "CSR_NS1", "CSR_NT", "CSR_RS", "CSR_TS",
    "LEIR_NTE", "LEIR_TCE", "LEIR_RCE", "LEIR_MBP",
    "NS_ACTIVE", "NS_WARNING", "NS_PASSIVE", "NS_BUS_OFF",
    "btr_from_timing", "timing_from_btr",
]

NBUF = 16
_ALL = (1 << NBUF) - 1
_IDMASK = 0x7FF

AMS_FULL, AMS_ALL, AMS_AMR0, AMS_AMR1 = 0b00, 0b01, 0b10, 0b11

CSR_HALT = 0x0001
CSR_NIE = 0x0004
CSR_TOE = 0x0080
CSR_NS0 = 0x0100
CSR_NS1 = 0x0200
CSR_NT = 0x0400
CSR_RS = 0x4000
CSR_TS = 0x8000
_CSR_WRITABLE = CSR_HALT | CSR_NIE | CSR_TOE

LEIR_NTE = 0x80
LEIR_TCE = 0x40
LEIR_RCE = 0x20
LEIR_MBP = 0x0F

NS_ACTIVE, NS_WARNING, NS_PASSIVE, NS_BUS_OFF = 0, 1, 2, 3
WARNING_LIMIT = 96

_ACTIVE, _PASSIVE, _BUS_OFF = ErrorState.ACTIVE, ErrorState.PASSIVE, ErrorState.BUS_OFF


def btr_from_timing(t: BitTiming) -> int:
    """BTR value for a :class:`BitTiming`."""
    return ((t.tseg2 - 1) << 12) | ((t.tseg1 - 1) << 8) | ((t.sjw - 1) << 6) | (t.prescaler - 1)


def timing_from_btr(btr: int) -> BitTiming:
    """The :class:`BitTiming` a BTR value selects (ValueError if invalid)."""
    return BitTiming(prescaler=(btr & 0x3F) + 1, tseg1=((btr >> 8) & 0xF) + 1,
                     tseg2=((btr >> 12) & 0x7) + 1, sjw=((btr >> 6) & 0x3) + 1,
                     tick_hz=TICK_HZ)


def _ns_of(tec: int, rec: int, state: ErrorState) -> int:
    if state is _BUS_OFF:
        return NS_BUS_OFF
    if state is _PASSIVE:
        return NS_PASSIVE
    return NS_WARNING if tec >= WARNING_LIMIT or rec >= WARNING_LIMIT else NS_ACTIVE


def _check_buf(buf: int) -> int:
    if not isinstance(buf, int) or not 0 <= buf < NBUF:
        raise ValueError(f"message buffer must be 0..{NBUF - 1}, got {buf!r}")
    return buf


def _check_id(can_id: int) -> int:
    if not isinstance(can_id, int) or isinstance(can_id, bool) or not 0 <= can_id <= _IDMASK:
        raise ValueError(f"standard CAN id must be 0..0x7FF, got {can_id!r}")
    return can_id


@final
class CanController(CanNode):
    """One MB90F549 CAN interface. Reset state: HALT = 1, TOE = 0, every buffer invalid."""

    STEADY_COUNTERS = ("frames_received", "frames_sent")
    """Frames it stored and sent: counts only (hil/sim/steady.py)."""

    recovers_on_request = True
    """Bus-off recovery starts when the firmware clears HALT (the bus asks, see can_bus.bus)."""

    @property
    def acknowledges(self) -> bool:
        """A halted controller (HALT = 1) takes no frames and cannot drive the ACK slot of
        another node's frame (the bus asks at each frame, see can_bus.bus). Simplification:
        the bus still counts it a receiver for its error counters, so an error frame while it
        is halted moves its REC, which the MB90F549's would not."""
        return not self._csr & CSR_HALT

    __slots__ = (
        "sched", "name", "transceiver", "on_rx_irq", "on_tx_irq", "on_status_irq", "before_rx",
        "_csr", "_leir", "_btr", "_timing",
        "_bval", "_txdir", "_treq", "_tcan", "_tc", "_rc", "_rovr", "_rrtr", "_trtr",
        "TIER", "RIER", "_amsr", "_amr0", "_amr1",
        "_id", "_dlc", "_dtr", "_txframe", "_rxframe", "_filters",
        "_offered", "_busoff", "_ns", "_run",
        "frames_sent", "frames_received", "overruns",
    )

    def __init__(self, sched: Any, timing: BitTiming | None = None, name: str = "CAN0") -> None:
        self.sched = sched
        self.name = name
        self.transceiver: Any = None
        self.on_rx_irq: Callable[[int], None] | None = None
        self.before_rx: Callable[[], None] | None = None
        """Called before a received frame looks for a free buffer (RCR): a receive handler
        that reads its buffer on entry and may run alone (Cpu.irq) has done so by then, or
        not, as on the general path (Cpu.settle)."""
        self.on_tx_irq: Callable[[int], None] | None = None
        self.on_status_irq: Callable[[int], None] | None = None
        self._csr = CSR_HALT
        self._leir = 0
        self._timing = timing if timing is not None else BitTiming()
        self._btr = btr_from_timing(self._timing)
        self._bval = self._txdir = self._treq = self._tcan = 0
        self._tc = self._rc = self._rovr = self._rrtr = self._trtr = 0
        self.TIER = 0
        self.RIER = 0
        self._amsr = 0
        self._amr0 = self._amr1 = 0
        self._id = [0] * NBUF
        self._dlc = [0] * NBUF
        self._dtr = [bytes(8)] * NBUF
        self._txframe: list[CanFrame | None] = [None] * NBUF
        self._rxframe: list[CanFrame | None] = [None] * NBUF
        self._filters: tuple[tuple[int, int, int], ...] = ()
        self._offered = -1
        self._busoff = False
        self._ns = NS_ACTIVE
        self._run = False
        self.frames_sent = 0
        self.frames_received = 0
        self.overruns = 0

    def __repr__(self) -> str:
        return f"<CanController {self.name} CSR={self.CSR:#06x}>"

    # ================================================================== firmware API
    # ---------------------------------------------------------------- run control
    def start(self) -> None:
        """Set TOE and clear HALT (the usual end of initialisation)."""
        self.CSR = (self._csr | CSR_TOE) & ~CSR_HALT

    def halt(self) -> None:
        """Set HALT: no new transmission, no reception (a frame on the bus completes)."""
        self.CSR = self._csr | CSR_HALT

    @property
    def halted(self) -> bool:
        """HALT as the firmware reads it: 1 while bus-off, also after 0 was written, until the
        bus-off recovery is complete (the module docstring)."""
        return bool(self._csr & CSR_HALT) or self._busoff

    @property
    def bus_off(self) -> bool:
        """The controller is (still) bus-off: NS = 11."""
        return self._busoff

    @property
    def timing(self) -> BitTiming:
        return self._timing

    # ---------------------------------------------------------------- buffers
    def configure_tx(self, buf: int, can_id: int, rtr: bool = False) -> None:
        """Make ``buf`` a valid transmit buffer for ``can_id`` (TRTR = ``rtr``)."""
        _check_buf(buf)
        self._id[buf] = _check_id(can_id)
        bit = 1 << buf
        self._abort(bit)
        self._txdir |= bit
        self._trtr = (self._trtr | bit) if rtr else (self._trtr & ~bit)
        self._bval |= bit
        self._refilter()

    def configure_rx(self, buf: int, can_id: int, ams: int = AMS_FULL) -> None:
        """Make ``buf`` a valid receive buffer: acceptance code ``can_id``, AMS ``ams``."""
        _check_buf(buf)
        if ams not in (AMS_FULL, AMS_ALL, AMS_AMR0, AMS_AMR1):
            raise ValueError(f"AMS must be AMS_FULL, AMS_ALL, AMS_AMR0 or AMS_AMR1, got {ams!r}")
        self._id[buf] = _check_id(can_id)
        bit = 1 << buf
        self._abort(bit)
        self._txdir &= ~bit
        self._amsr = (self._amsr & ~(3 << 2 * buf)) | (ams << 2 * buf)
        self._bval |= bit
        self._refilter()

    def disable(self, buf: int) -> None:
        """BVAL = 0: the buffer takes no part (its request, if any, is dropped)."""
        bit = 1 << _check_buf(buf)
        self._abort(bit)
        self._bval &= ~bit
        self._refilter()

    def set_masks(self, amr0: int | None = None, amr1: int | None = None) -> None:
        """Write AMR0 / AMR1 (bit = 1: ID bit not compared)."""
        if amr0 is not None:
            self._amr0 = _check_id(amr0)
        if amr1 is not None:
            self._amr1 = _check_id(amr1)
        self._refilter()

    def transmit(self, buf: int, data: bytes = b"", dlc: int | None = None) -> None:
        """Write DTR/DLCR of transmit buffer ``buf`` and set its TREQ."""
        bit = 1 << _check_buf(buf)
        if not (self._bval & self._txdir & bit):
            raise RuntimeError(f"{self.name}: buffer {buf} is not a valid transmit buffer")
        if self._treq & bit:
            raise RuntimeError(f"{self.name}: buffer {buf} has a transmit request pending")
        rtr = bool(self._trtr & bit)
        frame = CanFrame(self._id[buf], b"" if rtr else bytes(data), rtr, dlc)
        self._dlc[buf] = frame.dlc  # type: ignore[assignment]  # an int after __post_init__
        if not rtr:
            self._dtr[buf] = frame.data + self._dtr[buf][len(frame.data):]
        self._txframe[buf] = frame
        self._treq |= bit
        self._tc &= ~bit
        if self._run and self.transceiver is not None:
            self.transceiver.request()

    def request(self, buf: int) -> None:
        """Set TREQ of ``buf`` with the DTR/DLCR already in it."""
        self.transmit(buf, self._dtr[buf][: _dlc_len(self._dlc[buf])], self._dlc[buf])

    def cancel(self, buf: int) -> bool:
        """TCANR: drop the transmit request of ``buf``. True if it is gone now, False if the
        frame may be on the bus (the cancel then resolves when that attempt ends)."""
        bit = 1 << _check_buf(buf)
        if not self._treq & bit:
            return True
        if buf == self._offered and self.transceiver is not None and not self.transceiver.bus_idle:
            self._tcan |= bit
            return False
        self._treq &= ~bit
        self._tcan &= ~bit
        return True

    def read(self, buf: int) -> CanFrame | None:
        """The frame last stored in receive buffer ``buf`` (None if none yet)."""
        return self._rxframe[_check_buf(buf)]

    def take(self, buf: int) -> CanFrame | None:
        """Read receive buffer ``buf`` and clear its RC (the usual ISR sequence)."""
        f = self._rxframe[_check_buf(buf)]
        self._rc &= ~(1 << buf)
        return f

    def clear_rc(self, buf: int) -> None:
        self._rc &= ~(1 << _check_buf(buf))

    def clear_tc(self, buf: int) -> None:
        self._tc &= ~(1 << _check_buf(buf))

    def clear_rovr(self, buf: int) -> None:
        self._rovr &= ~(1 << _check_buf(buf))

    def enable_irq(self, tx: int | None = None, rx: int | None = None) -> None:
        """Write TIER / RIER (bit masks of buffers)."""
        if tx is not None:
            self.TIER = tx & _ALL
        if rx is not None:
            self.RIER = rx & _ALL

    # ---------------------------------------------------------------- status
    def _status(self) -> tuple[int, int, ErrorState]:
        x = self.transceiver
        if x is None:
            return 0, 0, _ACTIVE
        s = x.status()
        return s.tec, s.rec, s.state

    @property
    def tec(self) -> int:
        return self._status()[0]

    @property
    def rec(self) -> int:
        return self._status()[1]

    @property
    def error_state(self) -> ErrorState:
        """The bus's view of this node (error-active / error-passive / bus-off)."""
        x = self.transceiver
        return _ACTIVE if x is None else x.error_state()

    @property
    def node_status(self) -> int:
        """NS1:NS0: 0 active, 1 warning, 2 passive, 3 bus-off."""
        if self._busoff:
            return NS_BUS_OFF
        return _ns_of(*self._status())

    # ================================================================== registers
    @property
    def CSR(self) -> int:
        halt = CSR_HALT if self._busoff else 0      # reads 1 until recovered (docstring)
        return (self._csr & (_CSR_WRITABLE | CSR_NT)) | halt | (self.node_status << 8)

    @CSR.setter
    def CSR(self, value: int) -> None:
        old = self._csr
        new = (old & ~_CSR_WRITABLE) | (value & _CSR_WRITABLE)
        if not value & CSR_NT:
            new &= ~CSR_NT
        if old & CSR_HALT and not new & CSR_HALT:
            x = self.transceiver
            if x is not None and x.ticks_per_bit != self._timing.ticks_per_bit:
                raise ValueError(
                    f"{self.name}: BTR gives {self._timing.ticks_per_bit} ticks a bit but the bus "
                    f"runs at {x.ticks_per_bit}")
        self._csr = new
        if old & CSR_HALT and not new & CSR_HALT and self._busoff:
            tec, rec, state = self._status()
            if state is not _BUS_OFF:  # the bus already recovered (a controller on a bus
                self._busoff = False   # model that counts from the error)
                self._set_ns(_ns_of(tec, rec, state))
            elif self.transceiver is not None and \
                    hasattr(self.transceiver, "start_recovery"):
                self.transceiver.start_recovery()   # the 128 x 11 count starts now
        self._update_run()

    @property
    def LEIR(self) -> int:
        return self._leir

    @LEIR.setter
    def LEIR(self, value: int) -> None:
        self._leir = value & 0xEF

    @property
    def RTEC(self) -> int:
        tec, rec, _ = self._status()
        return min(rec, 255) | (min(tec, 255) << 8)

    @property
    def BTR(self) -> int:
        return self._btr

    @BTR.setter
    def BTR(self, value: int) -> None:
        if not self._csr & CSR_HALT:
            raise RuntimeError(f"{self.name}: BTR is writable only while CSR.HALT = 1")
        self._timing = timing_from_btr(value)
        self._btr = value & 0x7FFF

    def set_timing(self, timing: BitTiming) -> None:
        self.BTR = btr_from_timing(timing)

    @property
    def BVALR(self) -> int:
        return self._bval

    @BVALR.setter
    def BVALR(self, value: int) -> None:
        self._abort(self._bval & ~value)
        self._bval = value & _ALL
        self._refilter()

    @property
    def TREQR(self) -> int:
        return self._treq

    @TREQR.setter
    def TREQR(self, value: int) -> None:
        """Writing 1 requests transmission of that buffer; 0 has no effect."""
        new = value & ~self._treq & _ALL
        for buf in range(NBUF):
            if new >> buf & 1:
                self.request(buf)

    @property
    def TCANR(self) -> int:
        return self._tcan

    @TCANR.setter
    def TCANR(self, value: int) -> None:
        for buf in range(NBUF):
            if value >> buf & 1:
                self.cancel(buf)

    @property
    def TCR(self) -> int:
        return self._tc

    @TCR.setter
    def TCR(self, value: int) -> None:
        self._tc &= value

    @property
    def RCR(self) -> int:
        return self._rc

    @RCR.setter
    def RCR(self, value: int) -> None:
        self._rc &= value

    @property
    def ROVRR(self) -> int:
        return self._rovr

    @ROVRR.setter
    def ROVRR(self, value: int) -> None:
        self._rovr &= value

    @property
    def RRTRR(self) -> int:
        return self._rrtr

    @RRTRR.setter
    def RRTRR(self, value: int) -> None:
        self._rrtr &= value

    @property
    def TRTRR(self) -> int:
        return self._trtr

    @property
    def tx_buffers(self) -> int:
        """Model register: bit x = 1 if buffer x is configured for transmission."""
        return self._txdir

    @property
    def AMSR(self) -> int:
        return self._amsr

    @AMSR.setter
    def AMSR(self, value: int) -> None:
        self._amsr = value & 0xFFFFFFFF
        self._refilter()

    @property
    def AMR0(self) -> int:
        return self._amr0

    @AMR0.setter
    def AMR0(self, value: int) -> None:
        self.set_masks(amr0=value)

    @property
    def AMR1(self) -> int:
        return self._amr1

    @AMR1.setter
    def AMR1(self, value: int) -> None:
        self.set_masks(amr1=value)

    @property
    def IDR(self) -> tuple[int, ...]:
        return tuple(self._id)

    @property
    def DLCR(self) -> tuple[int, ...]:
        return tuple(self._dlc)

    @property
    def DTR(self) -> tuple[bytes, ...]:
        return tuple(self._dtr)

    # ================================================================== internals
    def _update_run(self) -> None:
        run = not (self._csr & CSR_HALT) and bool(self._csr & CSR_TOE) and not self._busoff
        was = self._run
        self._run = run
        if run and not was and self._treq and self.transceiver is not None:
            self.transceiver.request()

    def _abort(self, bits: int) -> None:
        """Drop requests of buffers being reconfigured or invalidated."""
        self._treq &= ~bits
        self._tcan &= ~bits
        if self._offered >= 0 and bits >> self._offered & 1:
            self._offered = -1

    def _refilter(self) -> None:
        filters = []
        rx = self._bval & ~self._txdir
        for buf in range(NBUF):
            if rx >> buf & 1:
                ams = self._amsr >> 2 * buf & 3
                if ams == AMS_FULL:
                    m = _IDMASK
                elif ams == AMS_ALL:
                    m = 0
                elif ams == AMS_AMR0:
                    m = ~self._amr0 & _IDMASK
                else:
                    m = ~self._amr1 & _IDMASK
                filters.append((buf, m, self._id[buf] & m))
        self._filters = tuple(filters)

    def _set_ns(self, ns: int) -> None:
        if ns != self._ns:
            self._ns = ns
            self._csr |= CSR_NT
            self._leir = (self._leir & LEIR_MBP) | LEIR_NTE
            if self._csr & CSR_NIE and self.on_status_irq is not None:
                self.on_status_irq(ns)

    def _resolve_cancel(self) -> None:
        if self._tcan:
            self._treq &= ~self._tcan
            self._tcan = 0
        self._offered = -1

    # ================================================================== bus node interface
    def pending(self) -> CanFrame | None:
        t = self._treq
        if not t or not self._run:
            return None
        buf = (t & -t).bit_length() - 1
        self._offered = buf
        return self._txframe[buf]

    def on_tx_done(self, frame: CanFrame, end: int) -> None:
        buf = self._offered
        if buf < 0 or not self._treq >> buf & 1 or self._txframe[buf] != frame:
            buf = next((b for b in range(NBUF)
                        if self._treq >> b & 1 and self._txframe[b] == frame), -1)
        self._offered = -1
        if buf < 0:
            return  # its buffer was reconfigured while the frame was on the bus
        bit = 1 << buf
        self._treq &= ~bit
        self._tcan &= ~bit
        self._tc |= bit
        self._leir = LEIR_TCE | buf
        self.frames_sent += 1
        if self._ns == NS_WARNING:
            self._set_ns(_ns_of(*self._status()))
        if self.TIER & bit and self.on_tx_irq is not None:
            self.on_tx_irq(buf)

    def on_arbitration_lost(self, frame: CanFrame) -> None:
        self._resolve_cancel()

    def on_frame(self, frame: CanFrame, start: int, end: int) -> None:
        if self._offered >= 0:
            self._resolve_cancel()
        if self._ns == NS_WARNING:
            self._set_ns(_ns_of(*self._status()))
        if self._csr & CSR_HALT:
            return
        if self.before_rx is not None:
            self.before_rx()
        fid = frame.id
        first = -1
        last = -1
        rc = self._rc
        for buf, m, c in self._filters:
            if fid & m == c:
                if not rc >> buf & 1:
                    first = buf
                    break
                last = buf
        if first < 0:
            if last < 0:
                return
            first = last
            self._rovr |= 1 << last
            self.overruns += 1
        buf = first
        bit = 1 << buf
        self._rc = rc | bit
        self._rxframe[buf] = frame
        self._id[buf] = fid
        self._dlc[buf] = frame.dlc  # type: ignore[assignment]  # an int after __post_init__
        if frame.rtr:
            self._rrtr |= bit
        else:
            self._rrtr &= ~bit
            d = frame.data
            if len(d) < 8:
                d = d + self._dtr[buf][len(d):]
            self._dtr[buf] = d
        self._leir = LEIR_RCE | buf
        self.frames_received += 1
        if self.RIER & bit and self.on_rx_irq is not None:
            self.on_rx_irq(buf)

    def on_error(self, ev: CanErrorEvent) -> None:
        if ev.transmitter or self._offered >= 0:
            self._resolve_cancel()
        if not self._busoff:
            self._set_ns(_ns_of(ev.tec, ev.rec, ev.state))

    def on_state_change(self, old: ErrorState, new: ErrorState, tick: int) -> None:
        if new is _BUS_OFF:
            self._busoff = True
            self._csr |= CSR_HALT
            self._run = False
            self._set_ns(NS_BUS_OFF)
        elif old is _BUS_OFF:
            # The bus's 128 x 11 recovery is complete; the controller follows once HALT = 0.
            if not self._csr & CSR_HALT:
                self._busoff = False
                self._set_ns(_ns_of(*self._status()))
                self._update_run()
        elif not self._busoff:
            self._set_ns(_ns_of(*self._status()))


def _dlc_len(dlc: int) -> int:
    return dlc if dlc <= 8 else 8
