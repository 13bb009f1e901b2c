; CAN0 TX/NS (vector 12, level 4), a transmission complete: the buffer's TCR bit cleared,
; its software queue's head dropped, and the next command loaded if one waits.
; Path charged: a command frame sent from transmit buffer 1 (joint 1's), its queue empty
; after it (the usual case: a newer command for the same node waits for the older).
        .include isr_enter
        MOVW  A, CSR
        MOVW  S:csr_copy, A             ; NT is bit 10: S:csr_hi bit 2
        BBS   S:csr_hi:2, node_status {not taken}   ; NT set: the node status cause
        MOVW  A, TCR
        ANDW  A, #TX_MASK
        MOVW  S:tcr_copy, A
        MOVW  RW1, #0                   ; buffer number
        BBC   S:tcr_copy:0, next_buf {taken}          ; buffer 0 (the broadcast stop) idle
        INCW  RW1
        BBC   S:tcr_copy:1, next_buf {not taken}
        MOVW  A, #TCR_KEEP_OTHERS       ; TCR bit cleared
        MOVW  TCR, A
; the buffer's queue: pop its head
        MOVW  A, RW1
        LSLW  A
        LSLW  A
        ADDW  A, #tx_queues             ; head, count
        MOVW  RW2, A
        MOVW  A, @RW2+2
        ADDW  A, #0xFFFF                ; count - 1
        MOVW  @RW2+2, A
        BEQ   queue_empty {taken}
queue_empty:
        ; RETI: charged from cycle_costs.py `reti`, as the entry from `entry`
