"""The F2MC-16LX as the model firmware's handlers run on it: the instruction cycle table
(:mod:`.cycles`), the handlers as instruction listings (``listings/*.asm``) and the counter
that sums them (:mod:`.listing`), from which firmware_model/cycle_costs.py takes its handler
and float-library rows; :mod:`.execute` runs a listing's path on its data to check it."""
