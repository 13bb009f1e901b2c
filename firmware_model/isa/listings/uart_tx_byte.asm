; UART0 TX (vector 38, level 1): TDRE, SODR0 is empty; write the frame's next byte.
; Path charged: a byte in the middle of a frame (not the last).
        .include isr_enter
        MOVW  A, S:tx_index             ; offset of the next byte in the frame buffer
        MOVW  RW0, A
        MOVW  A, #tx_frame
        ADDW  A, RW0                    ; its address
        MOVW  RW1, A
        MOV   A, @RW1+0                 ; the byte
        MOV   I:SODR0, A                ; to the UART (clears TDRE)
        INCW  RW0
        MOVW  A, RW0
        MOVW  S:tx_index, A
        MOVW  A, S:tx_length
        CMPW  A, RW0
        BEQ   last {not taken}          ; the last byte: clear TIE, arm TX END (not this path)
        ; RETI: charged from cycle_costs.py `reti`, as the entry from `entry`
