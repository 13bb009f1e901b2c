"""What people look at: VCD waveforms (``vcd``), plots of traces (``plot``) and the live
terminal monitor (``monitor``). May import ``hil.sim`` and ``hil.bench``, never ``hil.cli``."""
