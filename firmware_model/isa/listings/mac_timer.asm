; Reload timer 0 (vector 17, level 3): the MAC's one deadline. An underflow with full
; periods still to count only counts one down; the last one is the deadline, and the MAC
; applies the rule of the phase it expired in (firmware_model/station.py `_on_timer`,
; radio/mac.py `on_timer`, radio/mac_deadlines.py `_deadline_wait`, radio/mac_turns.py
; `_next_turn` and `_my_turn`), then reprograms the timer.
; Path charged: the last underflow of a WAIT deadline (E + Tmax) in a ring of 7: nothing is
; being received and no start bit has begun, so the owner missed its turn (clause 24): its
; miss count goes up, not yet to MISS_LIMIT (3), no cut-off (clause 40); this robot is the
; silent owner's successor and takes the turn over: TXEN high, phase SWITCH, reload timer 0
; at Ttrans.
; Data as in mac_frame: robots (8-byte records by ID: +1 misses, +3 flags), ring[],
; ring_count, expected (the owner's index), my_index; the deframer's rx_state.
        .include isr_enter
        CLRB  I:TMCSR0:2                ; UF, the underflow flag
        MOV   A, S:timer_periods        ; full FFFF periods still to count
        BNE   count_down {not taken}    ; (one less, and back: not this path)
; the station: a frame coming in? (the deframer hunting: no frame, no partial Header)
        MOVW  RW4, #0                   ; busy
        MOVW  RW5, #0                   ; a Header's start bit began (0: none)
        MOVW  A, S:rx_state
        CMPW  A, #RX_HUNT
        BNE   receiving {not taken}
        BBS   I:EIRR:0, start_bit {not taken}         ; SIN0's falling edge (INT0): none
; the MAC: a failed frame's promised End is over
        MOV   S:mac_promised, #0
        MOV   A, S:mac_mode
        CMP   A, #MODE_LISTEN
        BEQ   claim {not taken}
        BBS   S:mac_flags:0, standby {not taken}      ; a standby PC's queue (never a child)
; the rule of the phase: a table of handlers
        MOV   A, S:mac_phase
        LSLW  A
        ADDW  A, #deadline_rules
        MOVW  RW1, A
        MOVW  A, @RW1+0
        JMP   @A
; WAIT: the owner, ring[expected] (none while resynchronising)
        MOV   A, S:expected
        CMP   A, #NO_OWNER
        BEQ   resync_wait {not taken}
        ADDW  A, #ring
        MOVW  RW2, A
        MOV   A, @RW2+0
        MOVW  RW0, A                    ; the owner's ID
; its Header coming? (a frame being received, or a start bit by E + Tmax): no
        MOVW  A, RW4
        BNE   header_coming {not taken}
        MOVW  A, RW5
        BNE   began {not taken}
; a miss: misses + 1
        MOVW  A, RW0
        LSLW  A
        LSLW  A
        LSLW  A                         ; 8 bytes a robot's record
        ADDW  A, #robots
        MOVW  RW3, A
        MOV   A, @RW3+1
        ADD   A, #1
        MOV   @RW3+1, A
        MOVW  RW6, A                    ; n
; counted for the cut-off unless the robot was never heard (the paper profile's)
        MOV   A, @RW3+3
        AND   A, #ROBOT_UNHEARD
        BNE   never_heard {not taken}
        MOV   A, S:silent
        ADD   A, #1
        MOV   S:silent, A
        SETB  S:mac_flags:2             ; our next frame tells our ring (rule R-view)
; a father PC's deafness rule (ID 0 only): not here
        MOV   A, S:my_id
        BNE   not_pc {taken}
not_pc:
; dropped at MISS_LIMIT: not yet
        MOVW  A, RW6
        CMP   A, #MISS_LIMIT
        BHS   drop {not taken}
; cut off? a ring of 2 or more, nothing heard for max(MISS_LIMIT, n - 1) misses: no
        MOV   A, S:ring_count
        CMP   A, #2
        BLO   small_ring {not taken}
        SUB   A, #1
        CMP   A, #MISS_LIMIT
        BLO   use_limit {not taken}
        MOV   A, S:silent               ; AH: the bound (6), AL: the misses unheard
        CMP   A
        BLS   cut_off {not taken}
; rule R-pair's floor only when nothing was heard since our own frame: heard
        BBC   S:mac_flags:1, unheard_since {not taken}
; the next turn: succ(owner), the ring's next index
        MOV   A, S:ring_count
        CMP   A, #1
        BEQ   lone {not taken}
        MOV   A, S:expected
        ADD   A, #1
        MOV   A, S:ring_count
        CMP   A
        BLT   no_wrap {taken}
no_wrap:
        SWAPW
        MOV   S:expected, A
        MOV   A, S:my_index
        CMP   A
        BNE   other_turn {not taken}    ; ours: take over
; our turn (a child: no standby, no ID 0 watch)
        BBS   S:mac_flags:0, watch {not taken}
        MOV   A, S:my_id
        BEQ   pc_watch {not taken}
        MOV   S:mac_phase, #PHASE_SWITCH
        MOVW  A, S:now_lo               ; the turn starts now
        MOVW  S:turn_start_lo, A
        MOVW  A, S:now_hi
        MOVW  S:turn_start_hi, A
        SETB  I:PDR1:0                  ; TXEN high: the PTR2000 to transmit
; reload timer 0: Ttrans from now (prescaler /2, one period)
        CLRB  I:TMCSR0:1                ; CNTE off while it is programmed
        MOVW  I:TMRLR0, #TTRANS_RELOAD
        MOVW  I:TMCSR0, #TMCSR_START    ; CSL /2, RELD, INTE, CNTE, TRG
        MOV   S:timer_periods, #0
        ; RETI: charged from cycle_costs.py `reti`, as the entry from `entry`
