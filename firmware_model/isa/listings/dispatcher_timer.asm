; Reload timer 1 (vector 36, level 5): the dispatcher's deadlines and the CAN supervision
; (firmware_model/child.py `_on_timer`: dispatcher.py `on_timer` and `_update_deadline`,
; CanDriver `on_timer`, then `_pump`'s deadline and timer). An underflow with full periods
; still to count only counts one down; on the last: each job is late if now has passed its
; deadline or a node it waits for has sent no status for SILENCE (300 ms) since the job
; began; the earliest next deadline is found in the same walk (the model walks twice); the
; CAN side: a bus-off restart due? a retry of an isolated bus due? a bus with nothing
; received for BLOCKED while error passive? Then reload timer 1 at the earliest deadline.
; Path charged: no deadline due, CAN healthy (error active, no restart or retry armed,
; nothing to send): one job running (`joint(2,30)`'s, waiting for node 2), its deadline not
; passed, node 2 heard 50 ms ago (fresh); the next deadline is node 2's silence limit
; (its last status + 300 ms).
; Data as in command: jobs (32 bytes each, n_jobs of them: +0 the nodes waited for, a bit
; each, +4 deadline, +8 start, 32 bits), nodes (16 bytes each: +0 last_seen, 32 bits, +12
; heard); now in now_lo/now_hi.
        .include isr_enter
        CLRB  I:TMCSR1:2                ; UF, the underflow flag
        MOVW  A, S:tmr1_periods         ; full FFFF periods still to count
        BNE   count_down {not taken}    ; (one less, and back: not this path)
; the jobs; the earliest deadline so far (RW7:RW6): none
        MOVW  RW6, #0xFFFF
        MOVW  RW7, #0xFFFF
        MOVW  RW2, #jobs
        MOV   A, S:n_jobs
        BEQ   no_jobs {not taken}
        MOVW  RW5, A
next_job:
; late: now past the deadline? (the high words decide)
        MOVW  A, S:now_hi
        CMPW  A, @RW2+6
        BHI   late {not taken}
        BNE   not_due {taken}
not_due:
        .include job_deadline           ; its deadline and its first node (job_deadline.asm)
; silent? now - last_seen >= SILENCE (32 bits; then now - start too)
        MOVW  A, S:now_lo
        MOVW  A, @RW1+0
        SUBW  A
        BC    borrow1 {not taken}
        MOVW  RW0, A
        MOVW  A, S:now_hi
        MOVW  A, @RW1+2
        SUBW  A
        CMPW  A, #SILENCE_HI
        BLO   fresh {taken}             ; 50 ms: fresh
fresh:
; the earliest: its silence limit, the later of last_seen and the start, + SILENCE
        MOVW  A, @RW1+2
        CMPW  A, @RW2+10
        BHI   seen_later {taken}
seen_later:
        MOVW  A, @RW1+0
        ADDW  A, #SILENCE_LO
        BC    carry1 {not taken}
        MOVW  RW0, A
        MOVW  A, @RW1+2
        ADDW  A, #SILENCE_HI
        CMPW  A, RW7
        BLO   earlier2 {taken}
earlier2:
        MOVW  RW7, A
        MOVW  A, RW0
        MOVW  RW6, A
        MOVW  A, RW1
        ADDW  A, #16
        MOVW  RW1, A
        MOVW  A, RW3
        BNE   next_node {not taken}     ; no more nodes
        MOVW  A, RW2
        ADDW  A, #32
        MOVW  RW2, A
        DWBNZ RW5, next_job {not taken} ; no more jobs
        MOVW  A, RW6
        MOVW  S:disp_dl_lo, A
        MOVW  A, RW7
        MOVW  S:disp_dl_hi, A
; the CAN supervision: a restart due? a retry due? a blocked bus (error passive, nothing
; received for BLOCKED)? none armed, and the controller error active
        BBS   S:can_flags:1, restart {not taken}      ; a bus-off restart armed (can_status)
        BBS   S:can_flags:3, retry {not taken}        ; an isolated bus's retry armed
        BBS   S:can_flags:0, isolated {not taken}
        MOVW  A, CSR
        MOVW  S:csr_copy, A
        BBS   S:csr_hi:1, passive {not taken}         ; NS1 (CSR bit 9): passive or bus-off
; the main loop's output: CAN frames or radio messages to take? none
        MOV   A, S:can_out_n
        BNE   frames_out {not taken}
        MOV   A, S:radio_out_n
        BNE   radio_out {not taken}
; the next deadline: the dispatcher's; the CAN side's (CanDriver.deadline): none
        BBS   S:can_flags:1, restart_at {not taken}
        BBS   S:can_flags:3, retry_at {not taken}
        BBS   S:can_flags:0, no_watch {not taken}
        MOVW  A, CSR
        MOVW  S:csr_copy, A
        BBS   S:csr_hi:1, blocked_at {not taken}
; reload timer 1 at the deadline: delay = it - now; (delay - 1) / 2 timer clocks, split
; into the first period's TMRLR1 (low word) and full FFFF periods (high word)
        MOVW  A, RW6
        MOVW  A, S:now_lo
        SUBW  A
        BC    borrow2 {not taken}
        ADDW  A, #0xFFFF                ; - 1
        BNC   borrow3 {not taken}
        MOVW  RW4, A
        MOVW  A, RW7
        MOVW  A, S:now_hi
        SUBW  A
        LSRW  A                         ; / 2, the high word's low bit into C
        MOVW  RW5, A
        BNC   even {not taken}
        MOVW  A, RW4
        LSRW  A
        ORW   A, #0x8000
        CLRB  I:TMCSR1:1                ; CNTE off while it is programmed
        MOVW  I:TMRLR1, A
        MOVW  I:TMCSR1, #TMCSR_START    ; CSL /2, RELD, INTE, CNTE, TRG
        MOVW  A, RW5
        MOVW  S:tmr1_periods, A
        BEQ   one_period {not taken}
        MOVW  I:TMRLR1, #0xFFFF
        ; RETI: charged from cycle_costs.py `reti`, as the entry from `entry`
