"""The interrupt plan (firmware_model/interrupts.py): the part's vectors, one level an ICR."""
from __future__ import annotations

import pytest

from firmware_model import interrupts as irq
from firmware_model.mcu.cpu import Vector


def test_the_plan_uses_the_parts_vectors_one_level_an_icr():
    numbers = [v.number for v in irq.ALL]
    assert len(set(numbers)) == len(numbers)
    by_icr: dict[int, set[int]] = {}
    for v in irq.ALL:
        by_icr.setdefault(irq.icr_of(v.number), set()).add(v.level)
    assert all(len(levels) == 1 for levels in by_icr.values())
    assert irq.icr_of(irq.UART0_RX.number) == irq.icr_of(irq.UART0_TX.number) == 13
    assert irq.icr_of(irq.CAN0_RX.number) == irq.icr_of(irq.CAN0_TX_NS.number) == 0
    assert (irq.icr_of(11), irq.icr_of(12), irq.icr_of(41), irq.icr_of(42)) == (0, 0, 15, 15)


def test_a_plan_the_part_cannot_hold_is_refused():
    with pytest.raises(ValueError, match="share ICR13: one level, not 3 and 1"):
        irq.check_plan((irq.UART0_RX, Vector("UART0 TX", level=3, number=38)))
    with pytest.raises(ValueError, match="both vector 37"):
        irq.check_plan((irq.UART0_RX, Vector("again", level=1, number=37)))
    with pytest.raises(ValueError, match="vector 5 is no resource interrupt"):
        irq.check_plan((Vector("invented", level=2, number=5),))


def test_can0_transmissions_and_node_status_share_one_handler():
    """A bus-off and the frames sent around it: both causes on vector 12, one handler's
    calls (its cost the cause's: can_tx or can_status)."""
    from firmware_model.cycle_costs import DEFAULT_COSTS
    from hil.sim.faults import parse_fault
    from hil.sim.world import SimConfig, World
    w = World(SimConfig(robots=(0, 1), duration=3.0, seed=1, can=True, load=2.0,
                        cpu=DEFAULT_COSTS, faults=(parse_fault("busoff:1@1.5"),)))
    w.run()
    stats = w.cpus[1].stats
    assert "CAN0 TX/NS" in stats and not {"CAN TX", "CAN status"} & set(stats)
    h = stats["CAN0 TX/NS"]
    c = DEFAULT_COSTS
    tx, status = (c.entry.cycles + body + c.reti.cycles
                  for body in (c.can_tx.cycles, c.can_status.cycles))
    n_status, rest = divmod(h.busy - tx * h.calls, status - tx)
    assert rest == 0 and n_status >= 1 and h.calls - n_status > 10, (h.busy, h.calls)
    assert w.children[1].can.bus_offs >= 1 and h.level == 4
