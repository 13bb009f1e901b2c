; Soft-float addition, C float x + y (IEEE-754 single, __addsf3), the model firmware's library
; routine: a called routine, CALL ... RET counted.
; Algorithm: the signs' XOR picks add or subtract; the exponents unpacked (zero/subnormal and
; Inf/NaN tested), the operand with the larger exponent kept whole in RL3 (its sign, exponent
; and mantissa field), the other's 24-bit mantissa (the hidden bit set) shifted right by the
; exponent difference d (LSRL A, R0) and added to it: the sum's mantissa field carries into
; the exponent field on its own, so the result is packed as it is added; a carry out of the
; mantissa (the exponent field changed) shifts it right instead. The bits the alignment shifts
; out make the guard word (the smaller's low word : 0 shifted by d: its bit 15 the round bit,
; the rest sticky; d > 16 takes another path); round to nearest even on it.
; Path charged: 1.234 + 5.678 (the avr-libc benchmark's operands): x = 0x3F9DF3B6 (exponent
; 127), y = 0x40B5B22D (exponent 129): y's the larger, so it is the one kept whole; the same
; signs: an addition; d = 2: the guard word 0x8000, the smaller mantissa 0x9DF3B6 shifted to
; 0x277CED; 0x40B5B22D + 0x277CED = 0x40DD2F1A (1.728 x 4: no carry out of the mantissa); the
; guard word exactly half, a tie, and the mantissa even: it stays. Result 6.912 = 0x40DD2F1A.
; Data (every soft-float routine): a float in two words, the high word (sign, exponent, mantissa
; bits 22-16) and the low word (mantissa bits 15-0); x in RW1:RW0 (RL0), y in RW5:RW4 (RL2);
; the result in A (AH the high word, AL the low word). RW0-RW2 and RW4-RW7 are clobbered; RW3,
; the caller's frame pointer, is kept. R0 (the shift count) is RW4's low byte.
        CALL  f_add
; add or subtract? (the signs differ: the subtraction, the same steps with the aligned
; mantissa subtracted and the difference normalised left)
        MOVW  A, RW1
        XORW  A, RW5
        BN    subtract {not taken}
; the exponent fields (exponent << 7): 0 is zero (subnormals flushed), 0x7F80 Inf or NaN
        MOVW  A, RW1
        ANDW  A, #0x7F80
        BEQ   x_zero {not taken}        ; x = 0: the result is y
        CWBNE A, #0x7F80, x_finite {taken}
x_finite:
        MOVW  A, RW5                    ; AH: ex
        ANDW  A, #0x7F80
        BEQ   y_zero {not taken}        ; y = 0: the result is x
        CWBNE A, #0x7F80, y_finite {taken}
y_finite:
        SUBW  A                         ; ex - ey (0x80 an exponent step)
        BGE   x_larger {not taken}      ; (there: x into RL3, y into RL0)
; y the larger: kept whole in RL3; x, the smaller, stays in RL0
        MOVW  RW6, RW4
        MOVW  RW7, RW5
        NEGW  A                         ; ey - ex
; the shift count d: the difference >> 7
        LSLW  A
        SWAP                            ; AL's bytes exchanged: d in the low byte
        ANDW  A, #0x00FF
        CMPW  A, #17
        BHS   far {not taken}           ; d > 16 (beyond 25 the smaller is below the round bit)
        MOVW  RW4, A                    ; R0 = d = 2
; the guard word: the smaller's low word : 0 shifted right by d, the bits the alignment
; shifts out at the top of AL
        MOVW  A, RW0
        MOVW  A, #0
        LSRL  A, R0 {bits 2}            ; 0xF3B6:0000 -> AL 0x8000
        MOVW  RW2, A
; the smaller's mantissa (its hidden bit set), aligned
        MOVW  A, RW1
        ANDW  A, #0x007F
        ORW   A, #0x0080
        MOVW  RW1, A
        MOVL  A, RL0                    ; 0x009DF3B6
        LSRL  A, R0 {bits 2}            ; 0x00277CED
; the sum: the larger whole + the aligned mantissa
        ADDL  A, RL3                    ; 0x40B5B22D + 0x00277CED = 0x40DD2F1A
        MOVL  RL0, A
; a carry out of the mantissa (the exponent field changed)? then it shifts right
        SWAPW                           ; AL: the sum's high word
        XORW  A, RW7
        ANDW  A, #0xFF80
        BNE   carry_out {not taken}
; round to nearest even: the guard word against half
        MOVW  A, RW2
        CWBNE A, #0x8000, not_tie {not taken}   ; exactly half: a tie
        MOVW  A, RW0
        ANDW  A, #0x0001
        BEQ   rounded {taken}           ; the mantissa even: it stays
rounded:
        MOVL  A, RL0                    ; AH: the high word, AL: the low word
        RET
