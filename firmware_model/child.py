"""The child robot's firmware: radio station, dispatcher and the CAN driver (paper Fig. 4).

Wiring, as the MB90F549 runs it:

* UART0 + PTR2000 + reload timer 0: the radio station (``station.py``) and the MAC;
* messages the MAC delivers go to the dispatcher (``dispatcher.py``), which plans the motion
  (``kinematics.py``) and hands CAN frames to the CAN driver below;
* CAN controller 0 (``mcu/can_controller.py``) through a Philips 82C250;
* reload timer 1: the dispatcher's job deadlines and the CAN supervision.

CAN buffer allocation (the lowest buffer number wins among pending requests, and the buffers
follow identifier order, so the controller's priority is the bus's):

=========  ==================  =================================================
buffer     direction           frames
=========  ==================  =================================================
0          transmit            ESTOP 0x010
1-4        transmit            JOINT1-4_CMD 0x101-0x104
5, 6       transmit            WHEEL_CMD 0x105, PAW_CMD 0x106
8, 9       receive, AMR0       EVENT1-6 0x0C1-0x0C6 (mask 0x007)
10, 11     receive, AMR1       JOINT/WHEEL/PAW_STATUS 0x181-0x186 (mask 0x007)
=========  ==================  =================================================

Supervision (docs/dispatcher.md): bus-off fails the running jobs (code 40) and restarts the
controller after ``RESTART_DELAY``. A bus on which nothing has been received for ``BLOCKED``
while the controller is error-passive or bus-off is blocked (a stuck-dominant TXD: the 82C250
has no TXD time-out): the firmware reports code 41 and isolates itself by putting its 82C250 in
standby (Rs high turns the transmitter off, which releases a stuck TXD), then tries the bus
again every ``RETRY``.
"""
from __future__ import annotations

from typing import Any, Callable

from can_bus.bus import ErrorState
from can_bus.frames import CanFrame

from .cycle_costs import DEFAULT_COSTS, CycleCosts, message_cycles
from .dispatcher import (
    CODE_BLOCKED, CODE_BUS_OFF, CODE_NO_CAN, REQUEST_TYPES, Dispatcher, is_order,
)
from .mcu.can_controller import AMS_AMR0, AMS_AMR1, CSR_NIE, CSR_NT, CanController
from .interrupts import CAN0_RX, CAN0_TX_NS, DISPATCH_TASK, TMR1
from .mcu.cpu import Cpu
from .mcu.reload_timer import ReloadTimer
from .mcu.scheduler import Clock
from .radio.content import cmd
from .radio.frame import BROADCAST, FrameType
from .radio.mac import Deliver, Join, ModeChange, QueueFull
from .sequence import ActionSequence
from .station import RadioStation
from .timing import TICK_HZ

TX_BUFFERS = {0x010: 0, 0x101: 1, 0x102: 2, 0x103: 3, 0x104: 4, 0x105: 5, 0x106: 6}
RX_EVENT = (8, 9)
RX_STATUS = (10, 11)

_ACTIVE = ErrorState.ACTIVE

RESTART_DELAY = TICK_HZ // 10      # 100 ms after bus-off before clearing HALT
BLOCKED = TICK_HZ // 20            # 50 ms with nothing received while passive/bus-off
RETRY = TICK_HZ                    # leave standby and try the bus again every 1 s


class CanDriver:
    """The firmware's CAN driver: a software queue per transmit buffer, receive ISRs, and the
    bus supervision. ``on_frame(frame, now)`` gets every received frame. ``cpu``: what its
    interrupts are raised on (a :class:`Cpu`, or anything with its ``irq`` and ``settle``),
    an ideal CPU on ``sched`` if None."""

    def __init__(self, sched: Clock, controller: CanController, transceiver: Any,
                 on_frame: Callable[[CanFrame, int], None],
                 on_fault: Callable[[int, int], None],
                 on_status: Callable[[], None] = lambda: None, cpu: Any = None,
                 costs: CycleCosts | None = None) -> None:
        self.sched = sched
        self.cpu = cpu if cpu is not None else Cpu(sched)
        costs = costs or DEFAULT_COSTS
        self._cycles = {"rx": costs.can_rx.cycles, "tx": costs.can_tx.cycles,
                        "status": costs.can_status.cycles}
        self._read: list[CanFrame] = []
        self.on_status = on_status
        self.can = controller
        self.xcvr = transceiver
        self.on_frame = on_frame
        self.on_fault = on_fault
        self._queue: dict[int, list[CanFrame]] = {b: [] for b in TX_BUFFERS.values()}
        self.last_rx: int | None = None
        self.isolated = False
        self.bus_offs = 0
        self.isolations = 0
        self._restart_at: int | None = None
        self._restarted = 0                # the tick of the last bus-off restart
        self._kept: dict[int, CanFrame] = {}   # heads left by drop_requests, maybe on the wire
        self._retry_at: int | None = None
        self.on_back: Callable[[int], None] = lambda now: None
        """Called when the node leaves standby to try the bus again (``isolate``'s retry)."""
        c = controller
        for can_id, buf in TX_BUFFERS.items():
            c.configure_tx(buf, can_id)
        c.set_masks(amr0=0x007, amr1=0x007)
        for b in RX_EVENT:
            c.configure_rx(b, 0x0C0, AMS_AMR0)
        for b in RX_STATUS:
            c.configure_rx(b, 0x180, AMS_AMR1)
        mask_tx = sum(1 << b for b in TX_BUFFERS.values())
        mask_rx = sum(1 << b for b in RX_EVENT + RX_STATUS)
        c.enable_irq(tx=mask_tx, rx=mask_rx)
        cpu, cyc = self.cpu, self._cycles
        # its entry reads the buffer (RCR cleared), which only the next frame for it looks at
        # (before_rx): it may run alone (Cpu.irq)
        c.on_rx_irq = lambda buf: cpu.irq(CAN0_RX, cyc["rx"], self._rx_body,
                                          enter=lambda: self._rx_read(buf), alone=True)
        c.before_rx = lambda: cpu.settle(read=False)
        # one vector for a finished transmission and a node status transition (interrupts.py):
        # its handler serves one cause an entry, at that cause's cost
        c.on_tx_irq = lambda buf: cpu.irq(CAN0_TX_NS, cyc["tx"], self._tx_irq, buf,
                                          alone=True)
        c.on_status_irq = lambda ns: cpu.irq(CAN0_TX_NS, cyc["status"], self._status_irq, ns,
                                             alone=True)
        c.CSR = c.CSR | CSR_NIE
        c.start()

    # -- sending ----------------------------------------------------------------------------

    def send(self, frame: CanFrame) -> None:
        """Queue ``frame`` on its identifier's buffer (a newer command waits for the older)."""
        buf = TX_BUFFERS.get(frame.id)
        if buf is None:
            raise ValueError(f"no transmit buffer for CAN id {frame.id:#05x}")
        q = self._queue[buf]
        q.append(frame)
        if len(q) == 1 and not self.isolated:
            self._load(buf)

    def _load(self, buf: int) -> None:
        """Put the head of ``buf``'s queue in the buffer and request it, unless the buffer
        still holds a request (TREQR): that is the head already, waiting for the bus."""
        if self.can.TREQR >> buf & 1:
            return
        f = self._queue[buf][0]
        self.can.transmit(buf, f.data, len(f.data))

    def _tx_irq(self, buf: int) -> None:
        self.can.clear_tc(buf)
        q = self._queue[buf]
        if q:
            if self._kept.get(buf) is q[0]:
                del self._kept[buf]
            q.pop(0)
        if q and not self.isolated:
            self._load(buf)

    # -- receiving --------------------------------------------------------------------------

    def _rx_read(self, buf: int) -> None:
        """The handler's first reads: the buffer's identifier, DLC and data; RCR cleared."""
        frame = self.can.take(buf)
        if frame is not None:
            self._read.append(frame)

    def _rx_body(self) -> None:
        if not self._read:
            return
        frame = self._read.pop(0)
        self.last_rx = now = self.sched.now
        self.on_frame(frame, now)

    # -- supervision ------------------------------------------------------------------------

    def _status_irq(self, ns: int) -> None:
        c = self.can
        c.CSR = c.CSR & ~CSR_NT            # clear the node status transition flag
        if c.bus_off:
            self.bus_offs += 1
            self._restart_at = self.sched.now + RESTART_DELAY
            self.drop_requests()
            self.on_fault(CODE_BUS_OFF, self.sched.now)
        self.on_status()            # error-passive or bus-off: the blocked-bus watch starts

    def deadline(self) -> int | None:
        """When the supervision next needs the timer."""
        best = self._restart_at
        retry = self._retry_at
        if retry is not None and (best is None or retry < best):
            best = retry
        if self._watching():
            blocked = max(self.last_rx or 0, self._restarted) + BLOCKED
            if best is None or blocked < best:
                best = blocked
        return best

    def _watching(self) -> bool:
        """The blocked-bus watch runs: on the bus, not error-active, and not waiting for the
        bus-off restart (a halted controller hears nothing: that is no blocked bus, and its
        restart, RESTART_DELAY after the bus-off, comes later than BLOCKED)."""
        return not self.isolated and self._restart_at is None and \
            self.can.error_state is not _ACTIVE

    def on_timer(self, now: int) -> None:
        c = self.can
        if self._restart_at is not None and now >= self._restart_at:
            self._restart_at = None
            self._restarted = now          # the watch counts from the restart
            if c.halted:
                c.start()
            if not self.isolated:
                self._resume()
        if self._retry_at is not None and now >= self._retry_at:
            self._retry_at = None
            self.isolated = False
            self.last_rx = now
            self.xcvr.standby(False)
            if c.halted:
                c.start()
            self._resume()
            self.on_back(now)
        if self._watching() and now - max(self.last_rx or 0, self._restarted) >= BLOCKED:
            self.isolate(now)

    def drop_requests(self) -> None:
        """Every frame waiting to be sent is dropped (the jobs they were for failed: a fault
        reported must not be followed by the order carried out after all); one that may be
        on the wire now stays at the head of its queue until its attempt ends: sent (its
        transmit interrupt takes it off) or cancelled (:meth:`_resume` takes it off)."""
        for buf, q in self._queue.items():
            if q and not self.can.cancel(buf):
                del q[1:]
                self._kept[buf] = q[0]
            else:
                q.clear()

    def _resume(self) -> None:
        """Back on the bus (the bus-off restart, the retry after standby): a head kept by
        :meth:`drop_requests` whose request is gone was cancelled, and goes; then each
        queue's head is requested (a newer command waits for the older)."""
        for buf, f in list(self._kept.items()):
            q = self._queue[buf]
            if not (q and q[0] is f):
                del self._kept[buf]
            elif not self.can.TREQR >> buf & 1:
                q.pop(0)
                del self._kept[buf]
        for buf, q in self._queue.items():
            if q:
                self._load(buf)

    def isolate(self, now: int) -> None:
        """Report the blocked bus and take this node off it (82C250 standby)."""
        self.isolated = True
        self.isolations += 1
        # Standby takes the transmitter off the bus; the requests of the jobs that fail now
        # are dropped (one that may be on the wire cannot be cancelled: it ends its attempt)
        self.xcvr.standby(True)
        self.drop_requests()
        self.on_fault(CODE_BLOCKED, now)
        self._retry_at = now + RETRY


class ChildFirmware:
    """A child robot: the radio station and, through the dispatcher, its CAN side."""

    def __init__(self, station: RadioStation, controller: CanController,
                 transceiver: Any, costs: CycleCosts | None = None,
                 clock: Clock | None = None,
                 can_cpu: Callable[[Cpu], Any] | None = None) -> None:
        """``costs`` runs the firmware on the CPU model with that cycle-cost table (radio
        handlers included); None is the ideal CPU (every handler in zero time). ``clock``:
        what the CAN side (driver, dispatcher timer, ideal CPU) schedules on, by default the
        station's scheduler (a caller may give the CAN side a clock of its own: it must tell
        the station's tick, as the CPU model runs on the station's scheduler). ``can_cpu(cpu)``
        gives what the CAN driver raises its interrupts on (``irq`` and ``settle`` as the
        CPU's), by default the CPU itself (a simulator may stand something in between)."""
        self.station = station
        self.sched = clock if clock is not None else station.sched
        self.id = station.id
        self.costs = costs
        # the CPU model times the radio's handlers too: it runs on the station's scheduler
        self.cpu = Cpu(self.sched if costs is None else station.sched, costs,
                       name=f"MB90F549-R{self.id}", order=self.id)
        if costs is not None:
            station.run_on(self.cpu, costs)
        self.dispatcher = Dispatcher(self.id)
        # done() notices are this project's (protocol 2.1); the paper profile sends none
        self.dispatcher.report_done = station.mac.cfg.profile != "paper"
        self.can = CanDriver(self.sched, controller, transceiver, self._on_can, self._on_fault,
                             self._pump, costs=costs,
                             cpu=self.cpu if can_cpu is None else can_cpu(self.cpu))
        self.can.on_back = self.dispatcher.on_bus_back
        self.latency_from: tuple[int, int, bytes] | None = None
        """(End tick of a radio order's frame, CAN id and data of the first frame the order
        produced) until that frame reaches the bus: the world measures the dispatcher's
        latency from it."""
        timer_cycles = (costs or DEFAULT_COSTS).dispatcher_timer.cycles
        self.timer = ReloadTimer(self.sched, self._raise_timer, name="TMR1")
        self._timer_cycles = timer_cycles
        self.cpu_work = 0
        """Work of the CAN side's that the CPU holds and has not done yet (ticks: none):
        messages handed to the main loop, the dispatcher timer's interrupt. A simulator
        does not put the CAN side to sleep while there is any."""
        station.add_app(self._on_message)
        self.sequence: ActionSequence | None = None
        self.on_action: Callable[[int, int, str, int], None] | None = None
        self.dispatcher.on_notice = self._on_notice
        self.dispatcher.on_action = self._on_action
        def observe(st: RadioStation, a: object, now: int) -> None:
            if type(a) in (Join, ModeChange) and self.sequence is not None:
                self._kickoff()
                self._pump()
        station.add_observer(observe)

    def run_sequence(self, order: tuple[int, ...], cycles: int) -> None:
        """Take part in the paper's action-sequence experiment (firmware_model/sequence.py)."""
        self.sequence = ActionSequence(self.id, tuple(order), cycles)
        self._kickoff()

    def _kickoff(self) -> None:
        seq = self.sequence
        if seq is not None and not seq.started:
            n = seq.kickoff(self.station.mac.ring)
            if n is not None:
                self.dispatcher.start_action(n, self.sched.now)

    def _on_notice(self, src: int, action: int, now: int) -> None:
        if self.sequence is not None:
            n = self.sequence.on_done(src, action)
            if n is not None:
                self.dispatcher.start_action(n, now)

    def _on_action(self, action: int, phase: str, now: int) -> None:
        if self.on_action is not None:
            self.on_action(self.id, action, phase, now)
        if phase == "done":
            self._on_notice(self.id, action, now)

    def _on_message(self, d: Deliver, now: int) -> None:
        """The radio handler hands the message to the main loop, which parses and plans it."""
        end = self.station.deframer.last_tick
        # (the ideal CPU runs it in zero time: its cycles need no counting)
        body = 0 if self.cpu.ideal else message_cycles(d.commands, self.costs or DEFAULT_COSTS)
        self.cpu_work += 1
        self.cpu.task(DISPATCH_TASK, body, self._dispatch, d, end)

    def _dispatch(self, d: Deliver, end: int | None) -> None:
        self.cpu_work -= 1
        now = self.sched.now
        self.dispatcher.on_message(d.src, d.dst, d.commands, now, d.type)
        self._kickoff()
        self._pump(end)

    def _on_can(self, frame: CanFrame, now: int) -> None:
        self.dispatcher.on_can(frame, now)
        self._pump()

    def _on_fault(self, code: int, now: int) -> None:
        self.dispatcher.on_bus_fault(code, now)
        self._pump()

    def on_stall(self, late: int) -> None:
        """The process did not run for ``late`` ticks (the real-time runner's stall watch,
        docs/guarantees.md): the dispatcher's and the blocked-bus watch's clocks of silence
        skip it (the frames that came meanwhile are read next), and the timer is re-armed."""
        self.dispatcher.on_stall(late)
        if self.can.last_rx is not None:
            self.can.last_rx += late
        self._pump()

    def _raise_timer(self, now: int) -> None:
        self.cpu_work += 1
        self.cpu.irq(TMR1, self._timer_cycles, self._on_timer_isr)

    def _on_timer_isr(self) -> None:
        self.cpu_work -= 1
        self._on_timer(self.sched.now)

    def _on_timer(self, now: int) -> None:
        self.dispatcher.on_timer(now)
        self.can.on_timer(now)
        self._pump()

    def start_action(self, n: int) -> None:
        """Start preset action ``n`` (paper §V.B) as if commanded locally."""
        self.dispatcher.start_action(n, self.sched.now)
        self._pump()

    def _pump(self, cause: int | None = None) -> None:
        d = self.dispatcher
        if d.has_output():               # (most received frames produce none)
            frames = d.take_can()
            if frames and cause is not None and self.latency_from is None:
                self.latency_from = (cause, frames[0].id, bytes(frames[0].data))
            for f in frames:
                self.can.send(f)
            radio = d.take_radio()
            for i, (dst, commands, type_) in enumerate(radio):
                try:
                    self.station.submit(dst, commands, type_)
                except QueueFull:
                    # the queue drains only in turns: the rest would be refused as well; they
                    # are dropped, counted and noted (they were dropped unsaid)
                    d.not_taken(radio[i:], self.sched.now)
                    break
                except ValueError:
                    pass  # refused (destination not valid): nothing else to do here
        when = d.deadline                # the earlier of the two deadlines (ticks), if any
        can = self.can.deadline()
        if when is None or (can is not None and can < when):
            when = can
        if when is not None:
            self.timer.arm_at(when)
        else:
            self.timer.stop()


class RadioOnlyChild:
    """A child with a radio and no CAN side (``rprs child`` without ``--can``). It takes part
    in the ring, and answers every order addressed to it (``joint``, ``status``, ...), and every
    broadcast order a child with its CAN side would carry out, with a failure, Type '4'
    ``fail(42)`` and the order (docs/dispatcher.md): a father owes each robot's answer to a
    broadcast to it, not to a later order of its own."""


    def __init__(self, station: RadioStation) -> None:
        self.station = station
        self.refused = 0
        self.replies_dropped = 0
        """Failures not sent, the radio's queue full (as a CAN child's dispatcher counts)."""
        station.add_app(self._on_message)

    def _on_message(self, d: Deliver, now: int) -> None:
        if d.type not in REQUEST_TYPES:
            return                  # news (a reply, a failure, a notice) is not an order
        # what the dispatcher would carry out (a broadcast's too, as it does; a broadcast act
        # is a notice, clause 19a); a fail() report is news, not an order: answering it could
        # bounce failures between two robots for ever
        order = next((c for c in d.commands if is_order(c)
                      and not (d.dst == BROADCAST and c.name == "act")), None)
        if order is None:
            return
        self.refused += 1
        try:
            self.station.submit(d.src, (cmd("fail", CODE_NO_CAN), order),
                                int(FrameType.FAILURE))
        except QueueFull:
            self.replies_dropped += 1     # counted and said (rprs child's closing line)
        except ValueError:
            pass  # refused (destination not in the ring): nothing else to do
