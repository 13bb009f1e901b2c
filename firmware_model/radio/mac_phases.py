"""The rotational MAC's modes and, while a member, its phases (``RotationalMac.mode`` and
``.phase``; the states of mac_table.py). Their values are what traces and tests read."""

# Modes.
LISTEN = "listen"    # not in a ring: waits for an invitation, or claims a silent channel
MEMBER = "member"    # in a ring: takes its turns

# Phases while MEMBER.
WAIT = "wait"        # waiting for the header of ``owner`` until ``deadline``
WINDOW = "window"    # a poll window for the invited ``owner`` until ``deadline``
HOLD = "hold"        # my turn starts at ``deadline`` (after a corrupted frame or a lone pause)
SWITCH = "switch"    # TXEN is high; my frame starts at ``deadline`` (= turn start + Ttrans)
SEND = "send"        # my frame is on air; ``on_tx_done`` ends the turn
QUIET = "quiet"      # a frame failed before its Length: wait for the channel to fall quiet
WATCH = "watch"      # hot standby: ID 0's turn; is the active PC's header coming?
