"""The simulated world: the shared air (``air``), robots with their firmware and CAN sides
(``world``), the one fault mechanism (``faults``), the soak (``soak``), the lock-step search
(``lockstep``), the JSON Lines trace (``trace``) and the wall-clock scheduler a world can run
on (``realtime``). Imports ``firmware_model`` and ``can_bus`` only, no other room of ``hil``."""
