; Soft-float square root, C sqrtf(x) (IEEE-754 single), the model firmware's library routine
; (hypotf's and acosf's): a called routine, CALL ... RET counted.
; Algorithm: GCC soft-fp's _FP_SQRT_MEAT, a restoring root a bit an iteration (no hardware
; does a root; soft-fp takes it so): x < 0, 0, Inf/NaN tested; the root's exponent
; (e + 127) >> 1; X = the 24-bit mantissa << 3 (<< 4, doubled, for an odd e - 127), S = 0;
; for q = 2^26 down to 2^3 (24 iterations, one root bit each): T = S + q; if T <= X then
; S = T + q, X = X - T; X <<= 1. S is twice the root (the root's bits need no word of their
; own). While q is in the high word (11 iterations) T's low word is 0: one word compared and
; subtracted (SUBW RW1, A); then two (SUBW, SUBCW: the borrow). X <<= 1 doubles its words
; (ADDW RW0, A; ADDCW: the carry). After the loop the root's next bit (S < X) is the round
; bit; a square root is never exactly half way, so no tie test. The mantissa S >> 4 (two
; MULUW by 2^12), pack.
; Path charged: the square root hypot(1.234, 5.678) takes, of 1.234^2 + 5.678^2 =
; 33.76244 = 0x42070CBD: e = 132, e - 127 odd: X = 0x870CBD << 4; the root's bits
; 101110011110 111111111101 (0xB9EFFD): one .repeat a run of iterations the same way;
; the round bit 0. Result 5.8105454 = 0x40B9EFFD.
; Data: a float in two words, the high word (sign, exponent, mantissa bits 22-16) and the low
; word; x in RW1:RW0 (RL0); the result in A (AH the high word, AL the low word). RW0-RW2 and
; RW4-RW7 are clobbered; RW3, the caller's frame pointer, is kept. X: RW1:RW0, S: RW5:RW4,
; q: RW2 (its high word, then its low word), T's low word: RW7 (q in the low word).
        CALL  f_sqrt
        MOVW  A, RW1
        BN    negative {not taken}      ; x < 0: NaN (-0: -0)
        ANDW  A, #0x7F80
        BEQ   zero {not taken}          ; 0 (subnormals flushed): 0
        CWBNE A, #0x7F80, finite {taken}
finite:
; the root's exponent field ((e + 127) >> 1) << 7; e + 127 odd: the mantissa doubled
        ADDW  A, #0x3F80
        LSRW  A                         ; (e + 127) << 6: bit 6 the parity
        MOVW  RW6, A
        MOVW  RW2, #8                   ; 2^3
        ANDW  A, #0x0040
        BEQ   even {not taken}          ; e = 132: e + 127 odd
        MOVW  RW2, #16                  ; 2^4
even:
        MOVW  A, RW6
        ANDW  A, #0x7F80
        MOVW  RW6, A
; X = the mantissa << 4: the low word by MULUW, the high byte with the hidden bit likewise
        MOVW  A, RW0
        MULUW A, RW2
        MOVW  RW0, A
        SWAPW
        MOVW  RW7, A                    ; the low word's top bits
        MOVW  A, RW1
        ANDW  A, #0x007F
        ORW   A, #0x0080
        MULUW A, RW2
        ADDW  A, RW7
        MOVW  RW1, A                    ; X = 0x0870CBD0
        MOVW  RW4, #0                   ; S = 0
        MOVW  RW5, #0
        MOVW  RW2, #0x0400              ; q = 2^26: its high word
; q = 0x0400 (q's high word): bit 1
sq1:
        MOVW  A, RW5                    ; S's high word
        ADDW  A, RW2                    ; T = S + q
        CMPW  A, RW1                    ; against X's high word (T's low word is 0)
        BHI   sq1_0 {not taken}         ; T <= X: a 1 bit
        SUBW  RW1, A                    ; X - T
        ADDW  A, RW2
        MOVW  RW5, A                    ; S = T + q
sq1_0:
        MOVW  A, RW0
        ADDW  RW0, A                    ; X << 1: the low word doubled, its top bit in C
        MOVW  A, RW1
        ADDCW A, RW1                    ; the high word doubled, + C
        MOVW  RW1, A
        MOVW  A, RW2
        LSRW  A
        MOVW  RW2, A                    ; q >> 1
        BNE   sq1 {taken}
; q = 0x0200 (q's high word): bit 0
sq1:
        MOVW  A, RW5                    ; S's high word
        ADDW  A, RW2                    ; T = S + q
        CMPW  A, RW1                    ; against X's high word (T's low word is 0)
        BHI   sq1_0 {taken}             ; T > X: a 0 bit
sq1_0:
        MOVW  A, RW0
        ADDW  RW0, A                    ; X << 1: the low word doubled, its top bit in C
        MOVW  A, RW1
        ADDCW A, RW1                    ; the high word doubled, + C
        MOVW  RW1, A
        MOVW  A, RW2
        LSRW  A
        MOVW  RW2, A                    ; q >> 1
        BNE   sq1 {taken}
; q = 0x0100, 0x0080, 0x0040 (q's high word): bits 111
        .repeat 3
sq1:
        MOVW  A, RW5                    ; S's high word
        ADDW  A, RW2                    ; T = S + q
        CMPW  A, RW1                    ; against X's high word (T's low word is 0)
        BHI   sq1_0 {not taken}         ; T <= X: a 1 bit
        SUBW  RW1, A                    ; X - T
        ADDW  A, RW2
        MOVW  RW5, A                    ; S = T + q
sq1_0:
        MOVW  A, RW0
        ADDW  RW0, A                    ; X << 1: the low word doubled, its top bit in C
        MOVW  A, RW1
        ADDCW A, RW1                    ; the high word doubled, + C
        MOVW  RW1, A
        MOVW  A, RW2
        LSRW  A
        MOVW  RW2, A                    ; q >> 1
        BNE   sq1 {taken}
        .endr
; q = 0x0020, 0x0010 (q's high word): bits 00
        .repeat 2
sq1:
        MOVW  A, RW5                    ; S's high word
        ADDW  A, RW2                    ; T = S + q
        CMPW  A, RW1                    ; against X's high word (T's low word is 0)
        BHI   sq1_0 {taken}             ; T > X: a 0 bit
sq1_0:
        MOVW  A, RW0
        ADDW  RW0, A                    ; X << 1: the low word doubled, its top bit in C
        MOVW  A, RW1
        ADDCW A, RW1                    ; the high word doubled, + C
        MOVW  RW1, A
        MOVW  A, RW2
        LSRW  A
        MOVW  RW2, A                    ; q >> 1
        BNE   sq1 {taken}
        .endr
; q = 0x0008, 0x0004, 0x0002 (q's high word): bits 111
        .repeat 3
sq1:
        MOVW  A, RW5                    ; S's high word
        ADDW  A, RW2                    ; T = S + q
        CMPW  A, RW1                    ; against X's high word (T's low word is 0)
        BHI   sq1_0 {not taken}         ; T <= X: a 1 bit
        SUBW  RW1, A                    ; X - T
        ADDW  A, RW2
        MOVW  RW5, A                    ; S = T + q
sq1_0:
        MOVW  A, RW0
        ADDW  RW0, A                    ; X << 1: the low word doubled, its top bit in C
        MOVW  A, RW1
        ADDCW A, RW1                    ; the high word doubled, + C
        MOVW  RW1, A
        MOVW  A, RW2
        LSRW  A
        MOVW  RW2, A                    ; q >> 1
        BNE   sq1 {taken}
        .endr
; q = 0x0001 (q's high word): bit 1
sq1:
        MOVW  A, RW5                    ; S's high word
        ADDW  A, RW2                    ; T = S + q
        CMPW  A, RW1                    ; against X's high word (T's low word is 0)
        BHI   sq1_0 {not taken}         ; T <= X: a 1 bit
        SUBW  RW1, A                    ; X - T
        ADDW  A, RW2
        MOVW  RW5, A                    ; S = T + q
sq1_0:
        MOVW  A, RW0
        ADDW  RW0, A                    ; X << 1: the low word doubled, its top bit in C
        MOVW  A, RW1
        ADDCW A, RW1                    ; the high word doubled, + C
        MOVW  RW1, A
        MOVW  A, RW2
        LSRW  A
        MOVW  RW2, A                    ; q >> 1
        BNE   sq1 {not taken}
        MOVW  RW2, #0x8000              ; q = 2^15: its low word
; q = 0x8000 (q's low word): bit 0
sq2:
        MOVW  A, RW5                    ; S's high word (T's: S + q carries nothing)
        CMPW  A, RW1                    ; against X's
        BLO   sq2_1 {not taken}
        BNE   sq2_0 {taken}
sq2_0:
        MOVW  A, RW0
        ADDW  RW0, A                    ; X << 1: the low word doubled, its top bit in C
        MOVW  A, RW1
        ADDCW A, RW1                    ; the high word doubled, + C
        MOVW  RW1, A
        MOVW  A, RW2
        LSRW  A
        MOVW  RW2, A                    ; q >> 1
        CWBNE A, #0x0004, sq2 {taken}
; q = 0x4000, 0x2000, 0x1000, 0x0800, 0x0400, 0x0200, 0x0100, 0x0080, 0x0040, 0x0020 (q's low
; word): bits 1111111111
        .repeat 10
sq2:
        MOVW  A, RW5                    ; S's high word (T's: S + q carries nothing)
        CMPW  A, RW1                    ; against X's
        BLO   sq2_1 {taken}
sq2_1:
        MOVW  A, RW4
        ADDW  A, RW2                    ; T's low word = S's + q
        SUBW  RW0, A                    ; X - T: the low words (C the borrow)
        MOVW  RW7, A
        MOVW  A, RW1
        SUBCW A, RW5                    ; the high words, less the borrow
        MOVW  RW1, A
        MOVW  A, RW7
        ADDW  A, RW2
        MOVW  RW4, A                    ; S = T + q
        BNC   sq2_c {taken}
sq2_c:
sq2_0:
        MOVW  A, RW0
        ADDW  RW0, A                    ; X << 1: the low word doubled, its top bit in C
        MOVW  A, RW1
        ADDCW A, RW1                    ; the high word doubled, + C
        MOVW  RW1, A
        MOVW  A, RW2
        LSRW  A
        MOVW  RW2, A                    ; q >> 1
        CWBNE A, #0x0004, sq2 {taken}
        .endr
; q = 0x0010 (q's low word): bit 0
sq2:
        MOVW  A, RW5                    ; S's high word (T's: S + q carries nothing)
        CMPW  A, RW1                    ; against X's
        BLO   sq2_1 {not taken}
        BNE   sq2_0 {taken}
sq2_0:
        MOVW  A, RW0
        ADDW  RW0, A                    ; X << 1: the low word doubled, its top bit in C
        MOVW  A, RW1
        ADDCW A, RW1                    ; the high word doubled, + C
        MOVW  RW1, A
        MOVW  A, RW2
        LSRW  A
        MOVW  RW2, A                    ; q >> 1
        CWBNE A, #0x0004, sq2 {taken}
; q = 0x0008 (q's low word): bit 1
sq2:
        MOVW  A, RW5                    ; S's high word (T's: S + q carries nothing)
        CMPW  A, RW1                    ; against X's
        BLO   sq2_1 {taken}
sq2_1:
        MOVW  A, RW4
        ADDW  A, RW2                    ; T's low word = S's + q
        SUBW  RW0, A                    ; X - T: the low words (C the borrow)
        MOVW  RW7, A
        MOVW  A, RW1
        SUBCW A, RW5                    ; the high words, less the borrow
        MOVW  RW1, A
        MOVW  A, RW7
        ADDW  A, RW2
        MOVW  RW4, A                    ; S = T + q
        BNC   sq2_c {taken}
sq2_c:
sq2_0:
        MOVW  A, RW0
        ADDW  RW0, A                    ; X << 1: the low word doubled, its top bit in C
        MOVW  A, RW1
        ADDCW A, RW1                    ; the high word doubled, + C
        MOVW  RW1, A
        MOVW  A, RW2
        LSRW  A
        MOVW  RW2, A                    ; q >> 1
        CWBNE A, #0x0004, sq2 {not taken}
; the round bit: the root's next bit, S < X? (S = 0x0B9EFFD0, X = 0x05B9FF70: no)
        MOVW  A, RW5
        CMPW  A, RW1
        BLO   round_up {not taken}
        BNE   rounded {taken}           ; S's high word above X's
rounded:
; the mantissa S >> 4: S's words x 2^12 (MULUW), the high word's product split across AH:AL
        MOVW  RW2, #0x1000
        MOVW  A, RW4
        MULUW A, RW2
        SWAPW
        MOVW  RW4, A                    ; S's low word >> 4
        MOVW  A, RW5
        MULUW A, RW2                    ; AH: S's high word >> 4, AL: its low 4 bits << 12
        ADDW  A, RW4
        MOVW  RW0, A                    ; the low word
        SWAPW
        ANDW  A, #0x007F                ; mantissa bits 22-16
        ADDW  A, RW6                    ; the exponent (the sign +)
        MOVW  A, RW0                    ; AH: the high word, AL: the low word
        RET
