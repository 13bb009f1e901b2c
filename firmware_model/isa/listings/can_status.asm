; CAN0 TX/NS (vector 12, level 4), a node status transition: NT cleared, the error state
; read, and on bus-off the fault noted and the restart armed.
; Path charged: the transition to bus-off (the one that does the most).
        .include isr_enter
        MOVW  A, CSR
        MOVW  RW0, A
        MOVW  S:csr_copy, A             ; NT is bit 10: S:csr_hi bit 2
        BBC   S:csr_hi:2, tx_done {not taken}       ; NT set: this cause
        ANDW  A, #CSR_NOT_NT            ; NT written 0
        MOVW  CSR, A
        MOVW  A, RTEC                   ; TEC:REC, for the status reply
        MOVW  S:rtec_copy, A
        MOVW  A, RW0
        ANDW  A, #CSR_NS                ; NS1:NS0
        CMPW  A, #NS_BUS_OFF
        BNE   not_bus_off {not taken}
        INCW  @RW3+0                    ; bus-off count (RW3: the CAN driver's record)
        MOV   A, #CODE_BUS_OFF          ; the fault, queued for the next status reply
        MOV   @RW3+4, A
        MOVW  A, S:now_lo               ; restart at now + RESTART_DELAY (32 bits)
        ADDW  A, #RESTART_LO
        MOVW  @RW3+6, A
        MOVW  A, S:now_hi
        ADDW  A, #RESTART_HI
        MOVW  @RW3+8, A
        SETB  S:can_flags:1             ; the restart is armed
        SETB  S:can_flags:2             ; the blocked-bus watch starts
        ; RETI: charged from cycle_costs.py `reti`, as the entry from `entry`
