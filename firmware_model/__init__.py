"""Tick-exact model of the RPRS child firmware (Fujitsu MB90F549, F2MC-16LX).

Layering (see docs/architecture.md): ``firmware_model.mcu`` holds the peripheral models,
``firmware_model.radio`` the wire format and the rotational MAC (sans-IO), and the top-level
modules the child firmware that wires them together. Nothing here imports ``hil``: the firmware
does not know which world it runs in.
"""
