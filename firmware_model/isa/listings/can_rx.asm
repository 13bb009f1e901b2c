; CAN0 RX (vector 11, level 4): a received frame read from its message buffer, decoded and
; noted in the dispatcher's table.
; Path charged: a submodule's status frame (every submodule sends one each 100 ms; an event
; frame's ack for a job costs about as much) in receive buffer 10, the first of the status
; buffers; its 8 data bytes read as 4 words. Message buffer accesses are marked {can}: each
; may wait while the controller uses the buffer (the worst case counts it).
        .include isr_enter
; which buffer: the lowest set bit of RCR among the receive buffers 8-11
        MOVW  A, RCR
        ANDW  A, #RX_MASK
        MOVW  S:rcr_copy, A             ; bits 8-15: S:rcr_hi
        MOVW  RW1, #8                   ; buffer number
.repeat 2
        BBC   S:rcr_hi:0, next_buf {taken}   ; (buffers 8 and 9: event buffers, empty)
        INCW  RW1
.endr
        BBC   S:rcr_hi:2, next_buf {not taken}
; the buffer's address: IDR, DLCR and DTR of buffer RW1
        MOVW  A, RW1
        LSLW  A
        LSLW  A
        LSLW  A                         ; 8 bytes a buffer's data
        ADDW  A, #DTR_BASE
        MOVW  RW2, A
        MOVW  A, RW1
        LSLW  A
        LSLW  A
        ADDW  A, #IDR_BASE
        MOVW  RW3, A
        MOVW  A, @RW3+0 {can}           ; IDR: the identifier's high bits
        MOVW  RW4, A
        MOVW  A, @RW3+2 {can}           ; IDR: the rest
        MOVW  A, RW1
        LSLW  A
        ADDW  A, #DLCR_BASE
        MOVW  RW5, A
        MOVW  A, @RW5+0 {can}           ; DLC
        MOVW  A, @RW2+0 {can}           ; the data, 4 words, to the frame record
        MOVW  S:rx_data0, A
        MOVW  A, @RW2+2 {can}
        MOVW  S:rx_data1, A
        MOVW  A, @RW2+4 {can}
        MOVW  S:rx_data2, A
        MOVW  A, @RW2+6 {can}
        MOVW  S:rx_data3, A
        MOVW  A, #RCR_KEEP_OTHERS       ; RCR bit cleared (0 written, 1s keep the others)
        MOVW  RCR, A
; decode: the identifier's node number (status ids 0x181-0x186) and its signals
        MOVW  A, RW4
        LSRW  A
        LSRW  A
        LSRW  A
        LSRW  A
        LSRW  A
        ANDW  A, #7                     ; the submodule
        MOVW  RW6, A
        LSLW  A
        LSLW  A
        LSLW  A
        LSLW  A                         ; 16 bytes a node record
        ADDW  A, #nodes
        MOVW  RW7, A
        MOVW  A, S:now_lo               ; last_seen = now (32 bits)
        MOVW  @RW7+0, A
        MOVW  A, S:now_hi
        MOVW  @RW7+2, A
        MOV   A, S:rx_data0             ; state: bits 0-3 of byte 0
        AND   A, #0x0F
        MOV   @RW7+4, A
        MOVW  A, S:rx_data0             ; seq: byte 1
        SWAP
        MOV   @RW7+5, A
        MOVW  A, S:rx_data1             ; the value: a 16-bit raw field
        MOVW  @RW7+6, A
        MOVW  A, S:rx_data2             ; the rest, kept for the status reply
        MOVW  @RW7+8, A
        MOVW  A, S:rx_data3
        MOVW  @RW7+10, A
; the dispatcher's next deadline: unchanged by a status frame
        BBS   S:jobs_open:0, deadline {not taken}
        ; RETI: charged from cycle_costs.py `reti`, as the entry from `entry`
