"""One simulation run's settings (:class:`SimConfig`) and all of their checks: a setting that
cannot work, or settings that do not go together, are a :class:`ConfigError` before anything is
built. ``rprs sim``'s options map onto it (hil/cli/sim.py); the campaign and the soak build it
too, and the world (hil/sim/world.py) runs it."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from firmware_model.radio.frame import MAX_CONTENT
from firmware_model.radio.mac import MacConfig
from firmware_model.timing import s_to_ticks

from .faults import CAN_KINDS, Fault, FaultError, check_skew, parse_fault

if TYPE_CHECKING:
    from firmware_model.cycle_costs import CycleCosts
    from firmware_model.radio.peer_macs import PeerConfig



MAX_DURATION_S = 1e9
"""The longest run (simulated s, about 31 years; 1.6e16 ticks): the idle ring leaps a day in
a fraction of a second, and a duration of 1e300 s ran with float ticks."""

class ConfigError(ValueError):
    """A simulation setting that cannot work (bad robot list, fault time, load ...)."""


LOAD_MAX = 1000.0
"""Messages/s per robot: the highest load rate taken (tens of times what the whole channel
carries; a rate far above that is ``saturate``, and costs the simulator each message)."""
PAYLOAD_MIN = 8
"""Content bytes of the smallest message ``payload`` may ask for (``movex(1)``): an empty
Content is a heartbeat, which nobody acknowledges (docs/protocol.md clause 21)."""
FLAGS = ("noise", "byte_by_byte", "can", "fast_paths", "can_sleep", "keep_records",
         "ring_sleep", "realtime", "father_standby")
"""SimConfig's switches: True or False, nothing that is merely truthy ("no" is)."""


@dataclass
class SimConfig:
    """One simulation run. Times in seconds; IDs 0 (father) to 6."""

    robots: tuple[int, ...] = (1, 2, 3, 4)
    duration: float = 10.0
    seed: int = 0
    faults: tuple[Fault, ...] = ()
    ber: float = 0.0
    noise: bool = False
    load: str | float = "idle"
    payload: int | None = None
    """Content bytes of each message under ``load='saturate'`` (default: as large as a turn
    allows, less the MAC's reserve)."""
    load_until: float | None = None
    """No new messages after this many seconds (lets a run drain its queues)."""
    power_on: dict[int, float] = field(default_factory=dict)
    byte_by_byte: bool = False
    mac: MacConfig | None = None
    can: bool = False
    """Give every child its CAN side: controller, 82C250, dispatcher and six submodules."""
    fast_paths: bool = True
    """The one switch of the simulator's fast paths (docs/fast-paths.md): the ring's leaps
    (``ring_sleep``), the CAN sides' sleep (``can_sleep``) and the MAC's heartbeat short path
    (``MacConfig.fast_path``). The run is the same to the tick either way (the trace digests
    are checked both ways); False runs every frame the slow way, to show that
    (``rprs sim --every-frame``)."""
    can_sleep: bool = True
    """A child's CAN side that only repeats itself is moved on in whole periods instead of
    frame by frame (hil/sim/quiet_can.py). The run is the same to the tick either way;
    False (or ``fast_paths=False``) is slower and exists to show that."""
    keep_records: bool = False
    """Keep every message submitted, every outcome, every delivery and every dispatcher
    latency (``World.messages``, ``outcomes``, ``deliveries``, ``dispatch_latency``), for a
    program that reads them after the run. Without it the run keeps counts and histograms
    (hil/sim/ledger.py), so its memory does not grow with simulated time; the summary is the
    same either way."""
    ring_sleep: bool = True
    """A ring that only repeats itself (idle, nothing watching its frames) is moved on in whole
    cycles instead of frame by frame (hil/sim/quiet_ring.py). The run is the same to the tick
    either way; False (or ``fast_paths=False``) is slower and exists to show that."""
    sequence: tuple[tuple[int, ...], int] | None = None
    """(row order, cycles): the children run the paper's action sequence (needs ``can``)."""
    realtime: bool = False
    """Run on the wall clock (hil.sim.realtime) instead of as fast as the CPU goes."""
    father_standby: bool = False
    """A second father PC (PC2) as hot standby for ID 0 (needs 0 in ``robots``)."""
    mac_kind: str = "rotational"
    """The MAC every robot runs: the paper's rotational MAC, or a peer for comparison
    (aloha, slotted, csma; firmware_model/radio/peer_macs.py)."""
    peer: PeerConfig | None = None
    """PeerConfig for the peer MACs."""
    extra: tuple[tuple[int, float, tuple[int, ...] | None], ...] = ()
    """More robots on the same air, outside ``robots``: (ID, power-on seconds, team or None for
    the run's). An ID of ``robots`` again is a twin (two robots with one ID, docs/protocol.md
    clause 38.2); another team is a co-channel ring (clause 38.1). Their events carry
    ``"extra": k`` (1 for the first) in the trace; they get no load."""
    cpu: CycleCosts | None = None
    """A cycle-cost table (firmware_model.cycle_costs.CycleCosts): every child's firmware runs
    on the MB90F549 CPU model, its handlers taking the time the table gives. None: the ideal
    CPU, every handler in zero time (the paper's timing). The command line's default is the
    model with ``DEFAULT_COSTS`` (``--cpu ideal`` gives None; docs/cpu.md)."""
    radio_switch: dict[int, tuple[int, int]] = field(default_factory=dict)
    """Per robot ID, its PTR2000's (TX-ready, RX-ready) switch times in ticks; robots not named
    get the nRF401 data sheet's, 1 ms and 3 ms (firmware_model/mcu/ptr2000.py). Not the MAC's
    Ttrans, which stays the protocol's 5 ms guard."""

    def validate(self) -> None:
        """A ConfigError for the first setting that cannot work. The settings that do not
        go together come first (:meth:`_check_together`), then each setting alone."""
        self._check_types()
        self._check_together()
        if not self.robots:
            raise ConfigError("no robots: give at least one ID with --robots")
        for r in self.robots:
            if isinstance(r, bool) or not isinstance(r, int) or not 0 <= r <= 6:
                raise ConfigError(f"robot ID {r!r} is not 0-6 (0 is the father, 1-6 children)")
        if len(set(self.robots)) != len(self.robots):
            raise ConfigError(f"robot IDs repeat in {list(self.robots)}")
        if not self.duration > 0:
            raise ConfigError(f"duration must be positive, got {self.duration}")
        if self.duration > MAX_DURATION_S:
            raise ConfigError(f"duration {self.duration:g} s is more than {MAX_DURATION_S:.0e} s "
                              f"(about 31 years), the longest run simulated")
        if s_to_ticks(self.duration) < 1:
            raise ConfigError(f"duration {self.duration:g} s is shorter than one tick (62.5 ns): "
                              f"nothing would run")
        if not 0.0 <= self.ber < 1.0:
            raise ConfigError(f"byte error rate must be in [0, 1), got {self.ber}")
        if self.sequence is not None:
            order, cycles = self.sequence
            if not self.can:
                raise ConfigError("the action sequence needs the children's CAN side (can)")
            if not order or any(r not in self.robots or r == 0 for r in order):
                raise ConfigError(f"the action-sequence row {list(order)} must be children "
                                  f"of the ring {list(self.robots)}")
            if cycles < 1:
                raise ConfigError(f"cycles must be at least 1, got {cycles}")
        if self.mac_kind != "rotational" and (self.father_standby or self.sequence):
            raise ConfigError("the standby father and the action sequence need the rotational "
                              "MAC")
        if self.father_standby and 0 not in self.robots:
            raise ConfigError("a standby father PC needs the father (ID 0) in the ring")
        skews: dict[int | None, Fault] = {}
        for f in self.faults:
            if f.kind == "skew":
                first = skews.setdefault(f.robot, f)
                if first is not f:
                    raise ConfigError(f"faults {first.spec()} and {f.spec()}: a robot has one "
                                      f"clock, give it one skew")
            if f.robot is not None and f.robot not in self.robots:
                raise ConfigError(f"fault {f.spec()} names robot {f.robot}, which is not in the "
                                  f"ring {list(self.robots)}")
            if f.kind in CAN_KINDS and not self.can:
                raise ConfigError(f"fault {f.spec()} needs the children's CAN side (--can)")
            if f.kind == "skew":
                assert f.value is not None     # (a skew is its fraction)
                try:
                    check_skew(f.value)
                except FaultError as exc:
                    raise ConfigError(f"fault {f.spec()}: {exc}") from None
        if isinstance(self.load, str):
            if self.load not in ("idle", "saturate"):
                raise ConfigError(f"load must be idle, saturate or a rate, got {self.load!r}")
        elif isinstance(self.load, bool) or not isinstance(self.load, (int, float)):
            raise ConfigError(f"load must be idle, saturate or a rate, got {self.load!r}")
        elif not self.load > 0:
            raise ConfigError(f"load rate must be positive messages/s, got {self.load}")
        elif not self.load <= LOAD_MAX:
            raise ConfigError(f"load rate {self.load:g} messages/s per robot is more than "
                              f"{LOAD_MAX:g}: the channel carries a few dozen short messages a "
                              f"second in all; any rate far above that is 'saturate'")
        if self.payload is not None and not PAYLOAD_MIN <= self.payload <= MAX_CONTENT:
            raise ConfigError(f"payload must be {PAYLOAD_MIN}-{MAX_CONTENT} Content bytes (an "
                              f"empty Content is a heartbeat, which nobody acknowledges), got "
                              f"{self.payload}")
        for r, t in self.power_on.items():
            if r not in self.robots:
                raise ConfigError(f"a power-on time for robot {r}, which is not in the ring "
                                  f"{list(self.robots)}")
            if not t >= 0:
                raise ConfigError(f"bad power-on time {t} for robot {r}: seconds >= 0")
        for r, sw in self.radio_switch.items():
            if r not in self.robots:
                raise ConfigError(f"radio switch times for robot {r}, which is not in the ring "
                                  f"{list(self.robots)}")
            if len(sw) != 2 or any(isinstance(v, bool) or not isinstance(v, int) or v < 0
                                   for v in sw):
                raise ConfigError(f"robot {r}'s radio switch times {sw!r} must be two whole "
                                  f"tick counts >= 0 (TX-ready, RX-ready)")
        for r, t, team in self.extra:
            if not isinstance(r, int) or not 0 <= r <= 6:
                raise ConfigError(f"extra robot ID {r!r} is not 0-6")
            if not t >= 0:
                raise ConfigError(f"bad power-on time {t} for extra robot {r}")
            if team is not None and (not team or any(not 0 <= i <= 6 for i in team)):
                raise ConfigError(f"extra robot {r}'s team {list(team)} must be IDs 0-6")
            if team is None and r not in self.robots:
                raise ConfigError(f"extra robot {r} is no twin of a robot of the ring "
                                  f"{list(self.robots)}: give its team ({r}@{t:g}:TEAM)")
        if self.extra and self.mac_kind != "rotational":
            raise ConfigError("extra robots need the rotational MAC")

    def _check_types(self) -> None:
        """Settings given in Python with a type they cannot have: a ConfigError naming the
        setting, not a TypeError, a hang or a silent misreading deep in the run (the command
        line's options come typed; a program's SimConfig does not)."""
        from firmware_model.cycle_costs import CycleCosts
        from firmware_model.radio.peer_macs import PeerConfig

        def number(name: str, v: object) -> None:
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ConfigError(f"{name} must be a finite number, got {v!r}")

        if not isinstance(self.robots, (tuple, list)):
            raise ConfigError(f"robots must be a tuple of IDs 0-6, got {self.robots!r}")
        number("duration", self.duration)
        number("ber", self.ber)
        if isinstance(self.seed, bool) or not isinstance(self.seed, int):
            raise ConfigError(f"seed must be an int, got {self.seed!r}")
        for name in FLAGS:
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"{name} must be True or False, got {getattr(self, name)!r}")
        if not isinstance(self.faults, (tuple, list)):
            raise ConfigError(f"faults must be a tuple of Fault, got {self.faults!r}")
        for f in self.faults:
            if not isinstance(f, Fault):
                raise ConfigError(f"faults must be Fault objects (hil.sim.faults.parse_fault "
                                  f"reads a spec such as 'fail:1@5'), got {f!r}")
            if f.kind != "skew":
                number(f"fault {f.kind}'s time", f.at)
                if f.at < 0:
                    raise ConfigError(f"fault {f.spec()}: time must not be negative")
            try:        # every check the command line's spec gets
                text = f.spec()
            except (AssertionError, TypeError, ValueError):
                raise ConfigError(f"{f!r}: not a fault the command line could give (a skew "
                                  f"needs its fraction, numbers must be numbers)") from None
            try:
                parse_fault(text)
            except FaultError as exc:
                raise ConfigError(f"fault {text}: {exc}") from None
        if not isinstance(self.power_on, dict):
            raise ConfigError(f"power_on must be a dict of robot ID to seconds, got "
                              f"{self.power_on!r}")
        for r, t in self.power_on.items():
            number(f"robot {r}'s power-on time", t)
        if not isinstance(self.load, str):
            number("load", self.load)
        if self.load_until is not None:
            number("load_until", self.load_until)
        if self.payload is not None and (isinstance(self.payload, bool)
                                         or not isinstance(self.payload, int)):
            raise ConfigError(f"payload must be a whole number of bytes, got {self.payload!r}")
        for name, v, kind in (("mac", self.mac, MacConfig), ("peer", self.peer, PeerConfig),
                              ("cpu", self.cpu, CycleCosts)):
            if v is not None and not isinstance(v, kind):
                raise ConfigError(f"{name} must be a {kind.__name__} or None, got {v!r}" + (
                    " (firmware_model.cycle_costs.DEFAULT_COSTS is --cpu estimated, None the "
                    "ideal CPU)" if kind is CycleCosts else ""))
        if self.sequence is not None:
            seq = self.sequence
            if not (isinstance(seq, tuple) and len(seq) == 2 and isinstance(seq[0], tuple)
                    and isinstance(seq[1], int) and not isinstance(seq[1], bool)):
                raise ConfigError(f"sequence must be ((row of robot IDs), cycles), got {seq!r}")
        for x in self.extra:
            if not (isinstance(x, tuple) and len(x) == 3):
                raise ConfigError(f"each extra robot must be (ID, power-on seconds, team or "
                                  f"None), got {x!r}")
            number(f"extra robot {x[0]!r}'s power-on time", x[1])

    def _check_together(self) -> None:
        """Settings that do not go together: the paper profile has no standby PC, and an
        option that only the rotational MAC acts on, given with a peer MAC, where it would be
        taken and do nothing. The peer MACs do use the checksum (their frames are sealed and
        checked), the air's and CAN faults, skew, the load and the CAN side; they have no
        turns (``steal``: ``force_turn`` does nothing), no standby PC, and never read the
        profile (they acknowledge and retransmit whatever it says). The messages name the
        ``rprs sim`` options, which is how the settings are mostly given."""
        from firmware_model.radio.peer_macs import KINDS as MAC_KINDS
        if self.mac_kind not in MAC_KINDS:
            raise ConfigError(f"unknown MAC {self.mac_kind!r}; one of {', '.join(MAC_KINDS)}")
        mac = self.mac if self.mac is not None else MacConfig()
        if mac.profile == "paper" and self.father_standby:
            raise ConfigError("--profile paper has no standby PC (--father-standby is this "
                              "project's extension)")
        kind = self.mac_kind
        if kind != "rotational":
            if mac.auth is not None:
                raise ConfigError(f"--auth-key: --mac {kind} has no authenticated profile (it "
                                  f"is the rotational MAC's)")
            steal = next((f for f in self.faults if f.kind == "steal"), None)
            if steal is not None:
                raise ConfigError(f"--fault {steal.spec()}: --mac {kind} has no turns to "
                                  f"steal (steal is a fault of the rotational MAC)")
            if mac.profile != "rprs":
                raise ConfigError(f"--profile {mac.profile} is a profile of the rotational "
                                  f"MAC (docs/protocol.md §9); --mac {kind} does not follow it")
            if self.father_standby:
                raise ConfigError(f"--father-standby needs the rotational MAC: the standby PC "
                                  f"takes ID 0's turn, and --mac {kind} has no turns")
        elif self.peer is not None:
            raise ConfigError("--frame-bytes sizes the peer MACs' frames (--mac aloha|slotted|"
                              "csma); the rotational MAC's frames are as long as their Content")
