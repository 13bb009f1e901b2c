"""The worlds the child firmware runs in, and what people use to drive and watch them.

Rooms, each with what it may import (tests/test_layering.py enforces it):

* ``hil.sim``: the simulated world: the air, robots with their CAN sides, faults, soak,
  traces, the lock-step search, and the clocks a world runs on. Imports the firmware only.
* ``hil.bench``: the real-time bench: the pty radio hub, the runner that puts the firmware on
  real or virtual ports and CAN buses, serial radios, bench scripts, the acceptance plugin.
  May import ``hil.sim``.
* ``hil.view``: what people look at: VCD waveforms, plots, the live monitor. May import
  ``hil.sim`` and ``hil.bench``.
* ``hil.cli``: the ``rprs`` command, one module per command. May import every room.
"""
