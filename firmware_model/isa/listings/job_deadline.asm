; A job's part of the dispatcher's next deadline (dispatcher.py `_update_deadline`; command and
; the reload timer 1 handler both walk it): the job's deadline against the earliest so far
; (RW7:RW6), then its nodes (a bit each in the job's +0, node n bit n) to the first it waits
; for, whose record (RW1) is checked for a status ever heard.
; Path charged: job 0, `joint(2,30)`'s, waiting for node 2 (nodes 0 and 1 skipped), its
; deadline the earliest; node 2 heard.
; Data: RW2 the job's record (+0 nodes, +4/+6 deadline, +10 start), nodes: 16 bytes a node
; (+12 heard).
        MOVW  A, @RW2+6                 ; the job's deadline
        CMPW  A, RW7
        BLO   earlier1 {taken}
earlier1:
        MOVW  RW7, A
        MOVW  A, @RW2+4
        MOVW  RW6, A
; its nodes: a bit each (bit n, node n), node 2's
        MOV   A, @RW2+0
        MOVW  RW3, A
        MOVW  RW1, #nodes
        .repeat 2
next_node:
        MOVW  A, RW3
        LSRW  A
        MOVW  RW3, A
        BC    waits {not taken}         ; nodes 0 (none) and 1: not waited for
        MOVW  A, RW1
        ADDW  A, #16
        MOVW  RW1, A
        MOVW  A, RW3
        BNE   next_node {taken}
        .endr
        MOVW  A, RW3
        LSRW  A
        MOVW  RW3, A
        BC    waits {taken}             ; node 2
waits:
        MOV   A, @RW1+12
        BEQ   never_heard {not taken}
