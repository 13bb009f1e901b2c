; TX END (output compare 0, vector 32, level 2): the End's stop bit has gone; the radio back
; to receiving and the MAC's end-of-frame rules.
; Path charged: the end of a frame this robot sent in its turn (the MAC then waits for the
; next sender's Header).
        .include isr_enter
        CLRB  I:PDR1:0                  ; TXEN low: the PTR2000 back to receiving
        CLRB  I:OCS0:4                  ; IOP0, the compare's flag
        CLRB  I:OCS0:2                  ; IOE0: no more compare interrupts
; the MAC: our turn is over; the next sender's place in the ring
        MOV   A, #PHASE_WAIT
        MOV   S:mac_phase, A
        MOV   A, S:my_index
        ADD   A, #1
        MOV   A, S:ring_count           ; AH: our place + 1, AL: the ring's size
        CMP   A
        BLT   no_wrap {taken}
no_wrap:
        SWAPW                           ; our place + 1 back in AL
        MOV   S:expected, A
        MOVW  A, S:tx_count
        ADDW  A, #1
        MOVW  S:tx_count, A             ; frames sent, for the status reply
; reload timer 0: Tmax for the next sender's Header (prescaler /2, its first period)
        CLRB  I:TMCSR0:1                ; CNTE off while it is programmed
        MOVW  A, #TMAX_FIRST
        MOVW  I:TMRLR0, A
        MOVW  A, #TMCSR_TMAX            ; CSL, MOD, RELD, INTE, CNTE, TRG
        MOVW  I:TMCSR0, A
        MOVW  A, #0xFFFF                ; the reloads after the first period: full ones
        MOVW  I:TMRLR0, A
        MOV   A, #TMAX_FULL_PERIODS
        MOV   S:timer_periods, A
        ; RETI: charged from cycle_costs.py `reti`, as the entry from `entry`
