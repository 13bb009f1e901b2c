; One CAN command frame written (main loop): its transmit buffer's data and DLC, and its
; transmit request. The scaling of its signals (two MULUW and a DIVUW) is charged from the
; mul16 and div32 rows. Called per frame: CALL ... RET counted.
; Path charged: a joint command (8 data bytes) whose buffer is free (no request pending).
        CALL  can_send
        LINK  #0
        MOVW  A, RW0                    ; the buffer number (an argument in RW0)
        LSLW  A
        LSLW  A
        LSLW  A
        ADDW  A, #DTR_BASE
        MOVW  RW2, A
        MOVW  A, TREQR                  ; a request still pending? then it waits its turn
        MOVW  S:treqr_copy, A
        BBS   S:treqr_copy:1, busy {not taken}
; pack: angle (16 bits), speed (16 bits), seq (8 bits), mode (8 bits), 16 bits spare
        MOVW  A, S:cmd_angle
        MOVW  @RW2+0, A {can}
        MOVW  A, S:cmd_speed
        MOVW  @RW2+2, A {can}
        MOV   A, S:cmd_seq
        MOV   A, S:cmd_mode             ; AH: seq, AL: mode
        SWAP                            ; AL: mode << 8
        ORW   A                         ; AL = AH | AL: seq | mode << 8
        MOVW  @RW2+4, A {can}
        MOVW  A, #0
        MOVW  @RW2+6, A {can}
        MOVW  A, RW0
        LSLW  A
        ADDW  A, #DLCR_BASE
        MOVW  RW4, A                    ; (RW3 is the frame pointer)
        MOVW  A, #8
        MOVW  @RW4+0, A {can}           ; DLC 8
        MOVW  A, TREQR                  ; request it
        ORW   A, #TREQ_BIT
        MOVW  TREQR, A
        UNLINK
        RET
