; UART0 RX (vector 37, level 1): a received byte, read and fed to the deframer.
; Path charged: a byte inside a frame's Content, no framing error or overrun (the path of
; nearly every byte; a frame's End byte adds the MAC's rules, `mac_frame`).
        .include isr_enter
        MOV   A, I:SSR0                 ; status: PE, ORE, FRE, RDRF
        AND   A, #0x70                  ; PE | ORE | FRE
        BNE   rx_error {not taken}
        MOV   A, I:SIDR0                ; the byte (the read clears RDRF)
        MOV   R0, A
        CLRB  I:EIRR:0                  ; INT0's edge flag (SIN0's falling edges): the next
                                        ; edge is the next byte's (read by mac_timer)
; the receive watch: output compare 1 at now + the stall gap
        MOVW  A, I:TCDT
        ADDW  A, #STALL_GAP
        MOVW  I:OCCP1, A
        CLRB  I:OCS0:5                  ; its flag, IOP1
; the deframer: dispatch on its state
        MOVW  A, S:rx_state
        LSLW  A
        ADDW  A, #rx_states             ; the state's entry in the jump table
        MOVW  RW1, A
        MOVW  A, @RW1+0
        JMP   @A
; state CONTENT: store the byte, count it down, fold it into the frame's check
        MOVW  A, S:rx_index
        MOVW  RW2, A
        ADDW  A, #rx_frame
        MOVW  RW3, A
        MOV   A, R0
        MOV   @RW3+0, A
        INCW  RW2
        MOVW  A, RW2
        MOVW  S:rx_index, A
        MOVW  A, S:rx_check             ; the running check of the covered bytes
        MOV   A, R0                     ; AH: the check, AL: the byte
        ADDW  A
        MOVW  S:rx_check, A
        MOVW  A, S:rx_content_end
        CMPW  A, RW2
        BEQ   content_done {not taken}  ; the last Content byte: the End comes next
        ; RETI: charged from cycle_costs.py `reti`, as the entry from `entry`
