; The main loop's dispatch of one parsed command (firmware_model/dispatcher.py `on_message`,
; `_cmd_joint`, `refusal`, `_next_seq`, the job `_drive_joints` records, `_update_deadline`;
; child.py `_pump`'s reload timer 1): the command's name looked up in the table of names, its
; arguments checked, its job recorded, the dispatcher's next deadline and reload timer 1.
; Not the kinematics, the motion plan (its planned time arrives in plan_lo/plan_hi) nor the
; CAN frame: rows of their own. Called per command: CALL ... RET counted.
; Path charged: `joint(2,30)` in an order (Type '2') to this robot; its name the 6th of the
; table (movex, movey, movez, moveto, act, joint, wheel, paw, stop, status); 2 arguments,
; joint 2, 30 deg within its limits (-10..120), not its commanded angle already; no job
; running (none superseded, it is job 0); its silence limit (now + 300 ms) is the next
; deadline: reload timer 1 programmed; the CAN side healthy.
; Data: the parser's command record (RW0): +0 the name's address, +2 the argument count,
; +4, +6, +8 the arguments (int as is, num in hundredths of its unit, the dispatcher's
; resolution). nodes: 16 bytes a submodule (+0 last_seen 32 bits, +12 heard, +13 the last
; command seq sent). jobs: 32 bytes a job (+0 the nodes waited for, a bit each, +1 the
; requester, +2 the act(n) notice, +4 deadline, +8 start, both 32 bits, +11 + n the seq
; awaited from node n, +18 the order's name number, +19 its argument count, +20 its
; arguments), n_jobs of them.
        CALL  dispatch_command
        LINK  #0
; an order? Types '0'-'2'; in a broadcast, act and fail are notices
        MOV   A, S:msg_type
        CMP   A, #3
        BHS   information {not taken}
        MOV   A, S:msg_dst
        CMP   A, #7
        BEQ   broadcast {not taken}
; the name: its letters against each entry of the table of names (entries: the name's
; address, its handler's), until one matches; movex, movey, movez, moveto, act: no
        MOVW  RW3, #command_names
        .repeat 5
next_name:
        MOVW  A, @RW3+0                 ; the entry's name
        BEQ   unknown {not taken}       ; the table's end
        MOVW  RW2, A
        MOVW  A, @RW0+0                 ; the command's name
        MOVW  RW1, A
        MOV   A, @RW1+
        MOV   A, @RW2+                  ; AH: the command's letter, AL: the entry's
        CMP   A
        BNE   differ {taken}
differ:
        MOVW  A, RW3
        ADDW  A, #4
        MOVW  RW3, A
        .endr
; joint: every letter the same, up to the '(' that ends both
        MOVW  A, @RW3+0
        BEQ   unknown {not taken}
        MOVW  RW2, A
        MOVW  A, @RW0+0
        MOVW  RW1, A
        .repeat 5
same:
        MOV   A, @RW1+
        MOV   A, @RW2+
        CMP   A
        BNE   differ {not taken}
        CBNE  A, #0x28, same {taken}
        .endr
        MOV   A, @RW1+
        MOV   A, @RW2+
        CMP   A
        BNE   differ {not taken}
        CBNE  A, #0x28, same {not taken}              ; '(': found
        MOVW  A, @RW3+2                 ; the handler: joint's case
        JMP   @A
; joint(i,deg): two arguments (code 3), i 1-4 (code 3), the angle within joint i's limits
; (code 2)
        MOV   A, @RW0+2
        CMP   A, #2
        BNE   bad_count {not taken}
        MOVW  A, @RW0+4                 ; i
        CMPW  A, #1
        BLT   bad_joint {not taken}
        CMPW  A, #4
        BGT   bad_joint {not taken}
        LSLW  A
        LSLW  A                         ; 4 bytes a joint's limits: lo, hi (hundredths)
        ADDW  A, #joint_limits-4
        MOVW  RW2, A
        MOVW  A, @RW0+6                 ; the angle (hundredths of a degree)
        CMPW  A, @RW2+0
        BLT   beyond {not taken}
        CMPW  A, @RW2+2
        BGT   beyond {not taken}
; the joint moves? its commanded angle differs (else no job)
        MOVW  A, @RW0+4
        LSLW  A
        ADDW  A, #target-2              ; the commanded angles (hundredths)
        MOVW  RW4, A
        MOVW  A, @RW0+6
        CMPW  A, @RW4+0
        BEQ   no_move {not taken}
; the node's next command seq (mod 256); jobs waiting for the node are superseded: none
        MOVW  A, @RW0+4
        LSLW  A
        LSLW  A
        LSLW  A
        LSLW  A                         ; 16 bytes a node's record
        ADDW  A, #nodes
        MOVW  RW1, A
        MOV   A, @RW1+13
        ADD   A, #1
        MOV   @RW1+13, A
        MOVW  RW5, A                    ; seq
        MOV   A, S:n_jobs
        BNE   supersede {not taken}     ; (a walk of the jobs: none running)
; the job: jobs[n_jobs]
        MOV   A, S:n_jobs
        LSLW  A
        LSLW  A
        LSLW  A
        LSLW  A
        LSLW  A                         ; 32 bytes a job
        ADDW  A, #jobs
        MOVW  RW2, A
        MOVW  A, @RW0+4
        ADDW  A, #node_bits             ; bit n for node n (a table)
        MOVW  RW3, A
        MOV   A, @RW3+0
        MOV   @RW2+0, A                 ; waiting for node i
        MOV   A, S:msg_src
        MOV   @RW2+1, A                 ; the requester
        MOV   A, #NO_NOTICE
        MOV   @RW2+2, A
        MOVW  A, @RW0+4
        ADDW  A, RW2
        MOVW  RW3, A
        MOVW  A, RW5
        MOV   @RW3+11, A                ; the seq its done() must carry
; deadline: now + the planned time x 2 + 2 x MARGIN (32 bits)
        MOVW  A, S:plan_lo
        MOVW  A, S:now_lo
        ADDW  A
        BC    carry1 {not taken}
        ADDW  A, #MARGIN2_LO
        BC    carry2 {not taken}
        MOVW  @RW2+4, A
        MOVW  A, S:plan_hi
        MOVW  A, S:now_hi
        ADDW  A
        ADDW  A, #MARGIN2_HI
        MOVW  @RW2+6, A
        MOVW  A, S:now_lo               ; started
        MOVW  @RW2+8, A
        MOVW  A, S:now_hi
        MOVW  @RW2+10, A
; the order, kept to quote back in done() or fail()
        MOV   A, #CMD_JOINT
        MOV   @RW2+18, A
        MOV   A, @RW0+2
        MOV   @RW2+19, A
        MOVW  A, @RW0+4
        MOVW  @RW2+20, A
        MOVW  A, @RW0+6
        MOVW  @RW2+22, A
        MOVW  A, @RW0+8
        MOVW  @RW2+24, A
        MOV   A, S:n_jobs
        ADD   A, #1
        MOV   S:n_jobs, A
        SETB  S:jobs_open:0
        MOVW  A, @RW0+6                 ; the commanded angle
        MOVW  @RW4+0, A
; the next deadline: the earliest job deadline or silence limit, over the jobs (one)
        MOVW  RW6, #0xFFFF              ; the earliest so far (RW7:RW6), none
        MOVW  RW7, #0xFFFF
        MOVW  RW2, #jobs
        MOV   A, S:n_jobs
        MOVW  RW5, A
        .include job_deadline           ; its deadline and its first node (job_deadline.asm)
        MOVW  A, @RW1+2                 ; last_seen against the start: the later
        CMPW  A, @RW2+10
        BHI   seen_later {not taken}
        BNE   start_later {taken}
start_later:
        MOVW  A, @RW2+8                 ; start + SILENCE
        ADDW  A, #SILENCE_LO
        BC    carry3 {not taken}
        MOVW  RW0, A
        MOVW  A, @RW2+10
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
; the CAN side's own deadline: none (no restart or retry armed, error active)
        BBS   S:can_flags:1, restart {not taken}
        BBS   S:can_flags:3, retry {not taken}
        BBS   S:can_flags:0, isolated {not taken}
        MOVW  A, CSR
        MOVW  S:csr_copy, A
        BBS   S:csr_hi:1, passive {not taken}         ; NS1 (CSR bit 9)
; reload timer 1 at the deadline: delay = it - now; (delay - 1) / 2 timer clocks, split
; into the first period's TMRLR1 (low word) and full FFFF periods (high word)
        MOVW  A, RW6
        MOVW  A, S:now_lo
        SUBW  A
        BC    borrow1 {not taken}
        ADDW  A, #0xFFFF                ; - 1
        BNC   borrow2 {not taken}
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
        UNLINK
        RET
