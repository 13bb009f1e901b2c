"""The MAC as the firmware's radio station drives it: the seam between them.

:class:`~firmware_model.station.RadioStation` (and the child beside it) sees its MAC only
through :class:`StationMac`: events in (a frame heard, garbage, a broken frame, the timer, the
end of its own transmission, a resync after a stall), actions out (lists of
:mod:`firmware_model.radio.mac` actions: ``TxEnable``, ``Transmit``, ``Deliver``, ...), and
the deadline it wants its timer at. The paper's :class:`~firmware_model.radio.mac.RotationalMac`
and the peer MACs of :mod:`firmware_model.radio.peer_macs` (ALOHA, slotted ALOHA, CSMA) both
are one, so any of them plugs into the same station; mypy holds both to this list
(``make_mac`` returns a ``StationMac``).
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any, Iterable, Protocol, Sequence

if TYPE_CHECKING:
    from .content import Command
    from .frame import Frame
    from .mac import MacConfig, Message

__all__ = ["StationMac"]


class StationMac(Protocol):
    """What :mod:`firmware_model.station` and :mod:`firmware_model.child` use of a MAC. Each
    ``on_*`` method and ``power_on``, ``resync`` and ``force_turn`` returns the actions the
    station carries out, in order; afterwards the station arms its timer at ``deadline``."""

    @property
    def cfg(self) -> MacConfig:
        """The configuration (Tmax, the team, the profile, the checksum, the key)."""
        ...

    @property
    def phase(self) -> str:
        """Where the MAC is in its turn; ``"send"`` while its frame is on the air."""
        ...

    @property
    def deadline(self) -> int | None:
        """The tick it wants ``on_timer`` at, or None."""
        ...

    @property
    def ring(self) -> tuple[int, ...]:
        """The robots it knows on the channel, itself included."""
        ...

    # what the simulator's ledger and load generators read (hil/sim)
    @property
    def mode(self) -> str:
        """Its place on the channel: listening, joining, a member."""
        ...

    @property
    def pending(self) -> int:
        """Messages submitted and not yet ended (queued or awaiting acknowledgement)."""
        ...

    @property
    def max_content(self) -> int:
        """The largest frame content it sends, in bytes."""
        ...

    @property
    def frames_sent(self) -> int:
        """Frames it has put on the air."""
        ...

    def power_on(self, now: int) -> Sequence[Any]: ...

    def submit(self, dst: int, commands: Iterable[Command], now: int,
               type: int = ...) -> Message:
        """Queue a message; raises SubmitError (QueueFull, ...) if it cannot be sent."""
        ...

    def on_frame(self, frame: Frame, first: int, end: int, now: int) -> Sequence[Any]: ...

    def on_garbage(self, first: int, last: int, now: int) -> Sequence[Any]: ...

    def on_corrupt(self, first: int, src: int | None, expected_end: int | None,
                   now: int) -> Sequence[Any]: ...

    def on_frame_over(self, now: int) -> Sequence[Any]: ...

    def on_timer(self, now: int, rx_busy: bool = ..., last_rx: int | None = ...,
                 rx_began: int | None = ...) -> Sequence[Any]: ...

    def on_tx_done(self, now: int) -> Sequence[Any]: ...

    def resync(self, now: int) -> Sequence[Any]:
        """The station was not running for longer than the margins allow: what the MAC
        knew of the air is stale."""
        ...

    def force_turn(self, now: int) -> Sequence[Any]:
        """Fault injection: take the turn now (a MAC without turns does nothing)."""
        ...
