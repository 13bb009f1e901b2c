"""The real-time bench: the pty radio hub (``radio_hub``), the runner that puts the same
firmware on real or virtual serial ports and CAN buses (``runner``), serial radios with TXEN on
RTS/DTR (``serial_radio``), bench scripts (``scripts``) and the acceptance plugin
(``acceptance``). May import ``hil.sim`` (the hub plays the air with ``hil.sim.air``), never
``hil.view`` or ``hil.cli``."""
