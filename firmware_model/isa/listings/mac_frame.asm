; The MAC's rules on a whole received frame (docs/protocol.md §4), run at the end of UART0
; RX's handler (vector 37, level 1) once the deframer has taken a frame's End: the End byte's
; own step is `uart_rx_byte`, and so are the handler's entry and RETI. What it does is
; firmware_model/station.py `_on_rx` for a FrameReceived and radio/mac.py `on_frame`: the
; frame's fields read, its Content's commands sorted (application, ack, poll, ring), who is
; believed (phase, team, ring, owner, clause 48a), its Source's record (miss count, the
; duplicate table, the acknowledgement owed), a new message handed to the main loop's message
; ring, and the next turn: its owner, and reload timer 0 at E + Tmax.
; Path charged: a good frame from the member whose turn it was (WAIT, the owner we waited
; for), Destination this robot, Type '2', carrying a new message (not a duplicate, Number
; one on from the last), Content `joint(2,30)ack(4,17)` (an order, and an acknowledgement for
; another robot), in a ring of 7; the next turn is another member's. Default profile: no
; checksum, no authentication.
; Data: the frame as received at rx_frame (Header at +0, its digits at +3..+11, Content at
; rx_content = rx_frame + 12); MAC scalars in the direct page; per robot ID 0-6 a record of
; 8 bytes at robots: +0 in the ring, +1 misses, +2 the Number of the last message frame heard
; (the duplicate table, 0xFF none), +3 flags (ROBOT_ARMED, ROBOT_UNHEARD), +4 an ack owed,
; +5 its Number, +6 in the team. The ring: ring[] (IDs ascending), ring_count, expected (the
; owner's index), my_index.
        MOVW  RW1, #rx_frame
; the station: a good frame, a failed frame's promised End is void
        MOV   S:rx_promise, #0
; deaf while switching or sending
        MOV   A, S:mac_phase
        CMP   A, #PHASE_SWITCH
        BEQ   deaf {not taken}
        CMP   A, #PHASE_SEND
        BEQ   deaf {not taken}
        MOV   S:mac_promised, #0        ; a good frame: the turn is whoever sends it
        BBS   S:mac_cfg:0, paper {not taken}          ; the paper profile's own rules
        BBS   S:mac_flags:0, standby {not taken}      ; a standby PC (never a child)
        SETB  S:mac_flags:1             ; heard since our own last frame
; the frame's fields: Source, Destination, Type, Number (ASCII digits)
        MOV   A, @RW1+4
        SUB   A, #0x30
        MOVW  RW0, A                    ; Source
        MOV   A, @RW1+3
        SUB   A, #0x30
        MOV   S:rx_dst, A
        MOV   A, @RW1+7
        SUB   A, #0x30
        MOV   S:rx_type, A
        MOV   A, @RW1+5                 ; Number: tens x 10 + units
        SUB   A, #0x30
        LSLW  A                         ; x2
        MOVW  RW5, A
        LSLW  A
        LSLW  A                         ; x8
        ADDW  A, RW5                    ; x10
        MOVW  RW5, A
        MOV   A, @RW1+6
        SUB   A, #0x30
        ADDW  A, RW5
        MOV   S:rx_num, A
; the fast path is the owner's heartbeat (Type '3', no Content): not this frame
        MOV   A, S:expected             ; the owner: ring[expected]
        ADDW  A, #ring
        MOVW  RW2, A
        MOV   A, @RW2+0
        MOVW  RW7, A                    ; the owner's ID
        CMPW  A, RW0
        BNE   general {not taken}
        MOV   A, S:mac_phase
        CMP   A, #PHASE_WAIT
        BNE   general {not taken}
        MOV   A, S:rx_type
        CMP   A, #3
        BEQ   heartbeat {not taken}
; the general path: a good frame, so our radio hears (the cut-off count, clause 40)
        MOV   A, S:silent               ; (kept for a PC pair's rule, clause 50)
        MOV   S:silent, #0
        BBS   S:mac_cfg:1, auth {not taken}           ; authenticated: the tag first
        BBS   S:mac_cfg:2, checksum {not taken}       ; checksum extension: crc() first
        MOV   A, S:my_id
        CMPW  A, RW0
        BEQ   own_id {not taken}        ; our own ID from the air
; the Source's record
        MOVW  A, RW0
        LSLW  A
        LSLW  A
        LSLW  A                         ; 8 bytes a robot's record
        ADDW  A, #robots
        MOVW  RW3, A
        MOV   A, @RW3+6
        BEQ   foreign {not taken}       ; not in the team
; the Content: each command by its name's letters; where the application's commands end
        MOVW  RW2, #rx_content          ; the scan pointer
        MOVW  A, S:rx_content_end
        ADDW  A, #rx_frame
        MOVW  RW4, A                    ; the Content's end
        MOVW  RW5, A                    ; the application part's end (the first MAC command)
        MOVW  RW6, #0                   ; application commands
        MOV   S:mac_seen, #0            ; poll, ring, an ack for us: none yet
; joint(2,30): an application command
        MOVW  A, RW2
        CMPW  A, RW4
        BEQ   scan_done {not taken}
        MOV   A, @RW2+0                 ; the name's first letter
        CMP   A, #0x61                  ; 'a': act, ack, auth
        BEQ   name_a {not taken}
        CMP   A, #0x70                  ; 'p': paw, poll
        BEQ   name_p {not taken}
        CMP   A, #0x72                  ; 'r': ring
        BEQ   name_r {not taken}
        CMP   A, #0x63                  ; 'c': crc
        BEQ   name_c {not taken}
        INCW  RW6
        .repeat 10
skip1:
        MOV   A, @RW2+
        CBNE  A, #0x29, skip1 {taken}   ; to the command's ')'
        .endr
        MOV   A, @RW2+
        CBNE  A, #0x29, skip1 {not taken}
; ack(4,17): a MAC command
        MOVW  A, RW2
        CMPW  A, RW4
        BEQ   scan_done {not taken}
        MOV   A, @RW2+0
        CMP   A, #0x61                  ; 'a'
        BEQ   name_a {taken}
name_a:
        MOV   A, @RW2+2                 ; the third letter: 'k' ack, 't' act or auth
        CMP   A, #0x6B
        BNE   not_ack {not taken}
        MOVW  A, RW5
        CMPW  A, RW4
        BNE   app_end_known {not taken} ; the first MAC command: the application part ends here
        MOVW  A, RW2
        MOVW  RW5, A
        MOV   A, @RW2+4                 ; ack(src,num): src
        SUB   A, #0x30
        MOV   A, S:my_id                ; AH: src, AL: our ID
        CMP   A
        BEQ   ack_for_us {not taken}    ; another robot's acknowledgement
        .repeat 8
skip2:
        MOV   A, @RW2+
        CBNE  A, #0x29, skip2 {taken}
        .endr
        MOV   A, @RW2+
        CBNE  A, #0x29, skip2 {not taken}
        MOVW  A, RW2
        CMPW  A, RW4
        BEQ   scan_done {taken}         ; the Content's end
scan_done:
; an invited robot's answer? (WINDOW) no: WAIT
        MOV   A, S:mac_phase
        CMP   A, #PHASE_WINDOW
        BEQ   window {not taken}
; a member alone that hears another robot goes back to LISTEN: a ring of 7
        MOV   A, S:mac_mode
        CMP   A, #MODE_MEMBER
        BNE   listening {not taken}
        MOV   A, S:ring_count
        CMP   A, #1
        BEQ   lone {not taken}
; out of turn (clause 39)? a member, and the owner we waited for: no
        MOV   A, @RW3+0
        BEQ   outsider {not taken}
        MOVW  A, RW7
        CMPW  A, RW0
        BNE   out_of_turn {not taken}
; clause 48a: a Number 1-8 behind the last remembered from src?
        MOVW  A, RW6
        BEQ   no_message {not taken}
        MOV   A, @RW3+3
        AND   A, #ROBOT_ARMED
        BEQ   not_armed {not taken}
        BBS   S:mac_cfg:1, auth {not taken}
        MOV   A, @RW3+2                 ; the Number last remembered
        MOV   A, S:rx_num               ; AH: it, AL: this frame's
        SUBW  A                         ; (last - num) mod 100
        BNC   back_ok {not taken}
        ADDW  A, #100
        BEQ   not_behind {not taken}    ; 0: the same Number
        CMPW  A, #BEHIND_WINDOW
        BHI   not_behind {taken}        ; 99: the next one, not behind
not_behind:
; a poll mask that leaves us out, a ring mask to reconcile: neither in this frame
        BBS   S:mac_seen:0, polled {not taken}
        BBS   S:mac_seen:1, ring_view {not taken}
; accepted from a member: heard, its misses back to 0
        MOVW  A, RW0
        MOV   S:last_heard_src, A
        MOVW  A, S:rx_end_lo            ; the End's tick (the deframer's)
        MOVW  S:last_heard_lo, A
        MOVW  A, S:rx_end_hi
        MOVW  S:last_heard_hi, A
        MOV   A, #0
        MOV   @RW3+1, A                 ; misses
        MOV   S:silent, #0
        MOV   A, S:unheard              ; the paper profile's robots not heard yet: none
        BNE   unheard {not taken}
        MOV   A, S:fail_run             ; a member whose turns keep failing (clause 41a)
        CBNE  A, #NO_ROBOT, fail_run {not taken}
        MOV   A, S:rx_type
        CMP   A, #5
        BEQ   boot {not taken}
        CMP   A, #6
        BEQ   join {not taken}
        MOV   A, S:booting_peers
        BNE   booting {not taken}
        BBS   S:mac_seen:2, on_ack {not taken}        ; an ack for us: none
; the message: a PC on probation leaves it (never a child)
        MOVW  A, RW6
        BEQ   no_message {not taken}
        MOV   A, S:check_turns
        BNE   probation {not taken}
; the duplicate table: a new Number, remembered (clause 48)
        MOV   A, @RW3+2
        MOV   A, S:rx_num
        CMP   A
        BEQ   duplicate {not taken}
        MOV   @RW3+2, A
        MOV   A, @RW3+3
        OR    A, #ROBOT_ARMED
        MOV   @RW3+3, A
; for us (our ID; '7' every member): acknowledged in our next frame
        MOV   A, S:rx_dst
        MOV   A, S:my_id
        CMP   A
        BEQ   for_us {taken}
for_us:
        MOV   A, S:rx_num
        MOV   @RW3+5, A                 ; ack(src,num)
        MOV   A, @RW3+4
        BNE   owed_already {not taken}
        MOV   A, #1
        MOV   @RW3+4, A
        MOV   A, S:acks_owed
        ADD   A, #1
        MOV   S:acks_owed, A
        BBS   S:mac_flags:0, standby {not taken}      ; a standby PC delivers nothing
; deliver: the message to a slot of the main loop's message ring
        MOV   A, S:q_head
        ADD   A, #1
        CMP   A, #RING_SIZE
        BNE   q_no_wrap {taken}
q_no_wrap:
        MOV   A, S:q_tail               ; AH: the next head, AL: the tail
        CMP   A
        BEQ   q_full {not taken}
        SWAPW
        MOVW  RW4, A                    ; the next head
        MOV   A, S:q_head
        LSLW  A
        ADDW  A, #q_slots               ; the slots' addresses
        MOVW  RW1, A
        MOVW  A, @RW1+0
        MOVW  RW1, A                    ; the slot
        MOVW  A, RW0
        MOV   @RW1+0, A                 ; Source
        MOV   A, S:rx_dst
        MOV   @RW1+1, A
        MOV   A, S:rx_num
        MOV   @RW1+2, A
        MOV   A, S:rx_type
        MOV   @RW1+3, A
        MOVW  A, RW5
        MOVW  A, #rx_content
        SUBW  A                         ; the application part's length (11)
        MOVW  @RW1+4, A
        MOVW  RW7, A
        MOVW  A, RW1
        ADDW  A, #6
        MOVW  RW1, A
        MOVW  RW2, #rx_content
        .repeat 10
copy:
        MOV   A, @RW2+
        MOV   @RW1+, A
        DWBNZ RW7, copy {taken}
        .endr
        MOV   A, @RW2+
        MOV   @RW1+, A
        DWBNZ RW7, copy {not taken}
        MOVW  A, RW4
        MOV   S:q_head, A               ; the slot is the main loop's
        SETB  S:main_events:0           ; a message waits
; the next turn: an invitation's window? (a poll for a robot outside the ring) no
        BBS   S:mac_seen:0, window {not taken}
        MOV   A, S:ring_count
        BEQ   no_ring {not taken}
        CMP   A, #1
        BEQ   lone {not taken}
        MOV   A, S:expected             ; src is ring[expected]: succ(src) is the next index
        ADD   A, #1
        MOV   A, S:ring_count
        CMP   A
        BLT   succ_no_wrap {taken}
succ_no_wrap:
        SWAPW
        MOV   S:expected, A             ; the next turn's owner
        MOV   A, S:my_index
        CMP   A
        BEQ   my_turn {not taken}       ; another member's: WAIT for its Header
        MOV   S:mac_phase, #PHASE_WAIT
        MOVW  A, S:rx_end_lo            ; the turn began at E
        MOVW  S:turn_start_lo, A
        MOVW  A, S:rx_end_hi
        MOVW  S:turn_start_hi, A
; reload timer 0 at E + Tmax: its first period less the timer clocks since the End
        MOVW  A, S:now_lo
        MOVW  A, S:rx_end_lo
        SUBW  A                         ; ticks since the End
        LSRW  A                         ; timer clocks (machine clock / 2)
        MOVW  RW6, A
        MOVW  A, #TMAX_FIRST
        MOVW  A, RW6
        SUBW  A
        BC    first_short {not taken}   ; (past the first period: one full period less)
        CLRB  I:TMCSR0:1                ; CNTE off while it is programmed
        MOVW  I:TMRLR0, A
        MOVW  I:TMCSR0, #TMCSR_START    ; CSL /2, RELD, INTE, CNTE, TRG: TMRLR0 loaded, counting
        MOVW  I:TMRLR0, #0xFFFF         ; the full periods after it
        MOV   S:timer_periods, #TMAX_FULL_PERIODS
; the station: the frame is over, the receive watch off
        CLRB  I:OCS0:3                  ; IOE1
; (then the receive handler's RETI, counted with its entry: see uart_rx_byte)
