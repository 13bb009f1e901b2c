; C hypotf(x, y) (IEEE-754 single), the model firmware's library routine: a called routine,
; CALL ... RET counted, its own instructions and, in place, the soft-float routines it calls
; (.include: each call counted at that routine's charged path).
; Algorithm: fdlibm's hypotf's frame (FreeBSD msun, newlib e_hypotf.c): a = |x|, b = |y|,
; a >= b (swapped if not); a/b > 2^30 (a + b), a > 2^50 (Inf/NaN, else scaled by 2^-68),
; b < 2^-50 (0, subnormal, else scaled by 2^+68) tested; then sqrtf(a a + b b), not fdlibm's
; split of a and b into high and low halves (that keeps the last bit exact; a float-only
; library's sum of two rounded squares is within an ulp); the scaling undone if any.
; Library calls, this path: f_mul 2, f_add 1, f_sqrt 1.
; Path charged: hypot(1.234, 5.678) (the avr-libc benchmark's operands): |y| the larger:
; swapped; no scaling; a a + b b = 33.76244, its square root 5.8105454. Each .include is
; charged its own path (1.234 + 5.678, 1.234 x 5.678, the square root hypot(1.234, 5.678)
; takes: f_sqrt's own).
; Data: x in RW1:RW0, y in RW5:RW4 (each: the high word sign, exponent, mantissa bits 22-16;
; the low word); the result in A (AH the high word, AL the low word); arguments to the
; soft-float routines in RW1:RW0 and RW5:RW4, their results in A. RW0-RW2 and RW4-RW7 are
; clobbered; RW3 is this routine's frame pointer (LINK), the caller's kept (UNLINK). Locals:
; b -4 (the disp8 is signed: 0xFC is -4), a a -8, k (the scaling's exponent) -10.
        CALL  f_hypot
        LINK  #10                       ; b -4, a a -8, k -10
        MOVW  A, #0
        MOVW  @RW3+0xF6, A              ; k = 0: no scaling (yet)
; a = |x|, b = |y|
        MOVW  A, RW1
        ANDW  A, #0x7FFF
        MOVW  RW1, A
        MOVW  A, RW5
        ANDW  A, #0x7FFF
        MOVW  RW5, A
; a >= b? (the high words, then the low words) 0x3F9D < 0x40B5: swap
        CMPW  A, RW1
        BLO   ordered {not taken}
        BNE   swap {taken}
swap:
        MOVL  A, RL0
        MOVW  RW0, RW4
        MOVW  RW1, RW5
        MOVL  RL2, A
; a/b > 2^30 (the exponents 30 apart: a + b)? a > 2^50? b < 2^-50? no
        MOVW  A, RW1
        SUBW  A, RW5                    ; a's high word - b's
        CMPW  A, #0x0F00
        BGT   far_apart {not taken}
        MOVW  A, RW1
        CMPW  A, #0x5880
        BHI   a_large {not taken}
        MOVW  A, RW5
        CMPW  A, #0x2680
        BLO   b_small {not taken}
; sqrtf(a a + b b)
        MOVL  A, RL2
        MOVL  @RW3+0xFC, A              ; b
        MOVW  RW4, RW0
        MOVW  RW5, RW1
        .include f_mul                  ; a a
        MOVL  @RW3+0xF8, A              ; a a
        MOVL  A, @RW3+0xFC              ; b
        MOVL  RL0, A
        MOVL  RL2, A
        .include f_mul                  ; b b
        MOVL  RL2, A
        MOVL  A, @RW3+0xF8              ; a a
        MOVL  RL0, A
        .include f_add                  ; a a + b b
        MOVL  RL0, A
        .include f_sqrt
; scaled? (k = 0: no)
        MOVL  RL0, A
        MOVW  A, @RW3+0xF6              ; k
        BNE   unscale {not taken}
        MOVL  A, RL0                    ; AH: the high word, AL: the low word
        UNLINK
        RET
