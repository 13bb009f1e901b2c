; Soft-float division, C float x / y (IEEE-754 single, __divsf3), the model firmware's library
; routine: a called routine, CALL ... RET counted.
; Algorithm: the sign the XOR of the signs (kept on the stack); the exponent fields tested
; (y = 0, Inf/NaN; x = 0) and subtracted, plus the bias (for a quotient below 1, N < D; the
; other case adds 0x80 back), less the hidden bit's 0x80 (the pack adds the quotient's high
; byte, hidden bit and all), on the stack; the mantissas normalised to 32 bits (<< 8: the
; divisor's top bit at bit 31, as the hardware divide's quotient estimate needs) from their
; bytes (MOV A, Ri: y's in R0-R3, x's once copied into RL3), the dividend halved if not below
; the divisor (CMPL), so the quotient x/y x 2^32 has its top bit at bit 31; that quotient in
; two 16-bit digits by schoolbook long division with the 32/16 hardware divide (Knuth's
; algorithm D, as GCC's soft-fp does with udiv_qrnnd): each digit's estimate DIVUW (the
; dividend's top two words / the divisor's high word), its product with the divisor's low word
; subtracted from the remainder (SUBL), and a negative remainder corrected (estimate - 1,
; divisor added back with ADDL; twice at most); the final remainder's zero-ness the sticky
; bit; round to nearest even at the quotient's bit 7; pack from the quotient's bytes; the
; exponent's range checked.
; Path charged: 1.234 / 5.678 (the avr-libc benchmark's operands): x = 0x3F9DF3B6, y =
; 0x40B5B22D; N = 0x9DF3B600 below D = 0xB5B22D00 (exponent - 1); digit 1: DIVUW
; 0x9DF3B600 / 0xB5B2 = 0xDE8B, remainder positive after its product with 0x2D00 (no
; correction); digit 2: DIVUW 0x8B3B9100 / 0xB5B2 = 0xC42C, one too large (its remainder
; negative): 0xC42B, the divisor added back once; the quotient 0xDE8BC42B, its low byte
; below half: truncated.
; Result 0.21733004 = 0x3E5E8BC4.
; Data: a float in two words, the high word (sign, exponent, mantissa bits 22-16) and the low
; word; x in RW1:RW0 (RL0), y in RW5:RW4 (RL2); the result in A (AH the high word, AL the low
; word). RW0-RW2 and RW4-RW7 are clobbered; RW3, the caller's frame pointer, is kept. R0-R3
; are RW4's and RW5's bytes, R4-R7 RW6's and RW7's (low byte first).
        CALL  f_div
; the sign, on the stack
        MOVW  A, RW1
        XORW  A, RW5
        ANDW  A, #0x8000
        PUSHW A
; the exponent fields: y = 0 (Inf, or NaN for 0/0), Inf/NaN; x = 0 (the result 0)
        MOVW  A, RW5
        ANDW  A, #0x7F80
        BEQ   by_zero {not taken}
        CWBNE A, #0x7F80, y_finite {taken}
y_finite:
        MOVW  A, RW1                    ; AH: ey
        ANDW  A, #0x7F80
        BEQ   x_zero {not taken}
        CWBNE A, #0x7F80, x_finite {taken}
x_finite:
        SUBW  A                         ; ey - ex
        NEGW  A                         ; ex - ey
        ADDW  A, #0x3E80                ; + 127 << 7, - 0x80 (N < D), - 0x80 (the hidden bit)
        PUSHW A
; D = y's mantissa << 8: D1 (RW5) = yh << 8 | yl >> 8, D0 (RW4) = yl << 8: y's bytes R3 R2 R1 R0
        MOV   A, R1                     ; yl's high byte
        MOV   A, R2                     ; AH: it, AL: y's high word's low byte
        OR    A, #0x80                  ; the hidden bit (in the exponent's bit 0's place)
        SWAP                            ; AL: yh << 8
        ORW   A                         ; D1 = 0xB5B2
        MOVW  RW5, A
        MOV   A, R0
        SWAP
        MOVW  RW4, A                    ; D0 = 0x2D00
; N = x's mantissa << 8, the same way, in A: x's bytes R7 R6 R5 R4 once copied into RL3
        MOVL  A, RL0
        MOVL  RL3, A
        MOV   A, R5
        MOV   A, R6
        OR    A, #0x80
        SWAP
        ORW   A                         ; N1 = 0x9DF3
        MOV   A, R4
        SWAP                            ; A = N1:N0 = 0x9DF3B600
; N < D? (yes) the quotient is below 1: N as it is (the exponent pushed for it)
        CMPL  A, RL2
        BHS   n_not_below {not taken}   ; (there: N halved, the exponent + 1)
; digit 1: (N1:N0:0) / (D1:D0)
        MOVW  RW2, RW5                  ; D1, the divide's remainder register
        DIVUW A, RW2                    ; the estimate; its remainder in RW2
        MOVW  RW7, A                    ; q1
        MULUW A, RW4                    ; q1 x D0
        MOVL  RL0, A
        MOVW  A, RW2
        MOVW  A, #0                     ; the remainder : 0
        SUBL  A, RL0                    ; - q1 x D0
        BC    fix1 {not taken}          ; not negative: q1 stands
; digit 2: (R1:R0:0) / (D1:D0)
        SWAPW
        CMPW  A, RW5
        BEQ   q_max {not taken}         ; R1 = D1: the estimate would overflow
        SWAPW
        MOVW  RW2, RW5
        DIVUW A, RW2
        MOVW  RW6, A                    ; q0
        MULUW A, RW4
        MOVL  RL0, A
        MOVW  A, RW2
        MOVW  A, #0
        SUBL  A, RL0
        BC    fix2 {taken}              ; negative: q0 one too large
fix2:
        DECW  RW6                       ; q0 - 1
        ADDL  A, RL2                    ; the remainder + D
        BNC   fix2_again {not taken}    ; a carry out: the remainder is positive again
; round to nearest even: the mantissa is q1 and q0's high byte; q0's low byte the round bit
; and seven sticky bits (with the remainder's)
        MOVW  A, RW6
        CBNE  A, #0x80, not_half {taken}
not_half:
        BLO   rounded {taken}           ; below half: truncated
rounded:
; pack: the quotient q1:q0 is RL3, its bytes R7 R6 R5 R4: the low word R6 R5
        MOV   A, R5
        MOV   A, R6                     ; AH: R5, AL: R6
        SWAP                            ; AL: R6 << 8
        ORW   A                         ; the low word
        MOVW  RW0, A
        MOV   A, R7                     ; the mantissa's high byte, the hidden bit its bit 7
        POPW  A                         ; AH: it, AL: the exponent (less 0x80)
        ADDW  A                         ; the high word, its sign apart
; the exponent in range (1-254)? yes
        SUBW  A, #0x0080
        CMPW  A, #0x7EFF
        BHI   out_of_range {not taken}  ; overflow (Inf) or underflow (0)
        ADDW  A, #0x0080
        POPW  A                         ; AH: the high word, AL: the sign
        ORW   A
        MOVW  A, RW0                    ; AH: the high word, AL: the low word
        RET
