; C acosf(x) (IEEE-754 single), the model firmware's library routine: a called routine, CALL
; ... RET counted, its own instructions and, in place, the soft-float routines it calls
; (.include: each call counted at that routine's charged path).
; Algorithm: fdlibm's acosf as FreeBSD's msun (e_acosf.c) and musl have it for float (newlib's
; e_acosf.c is the same code with fdlibm's double-precision rational, 6 + 4 coefficients):
; |x| >= 1 (0, pi or NaN), |x| < 0.5 (pi/2 - (x + x R(x^2))), x < -0.5 tested; x > 0.5:
; z = (1 - x)/2, s = sqrtf(z), df = s with its low 12 bits cleared, c = (z - df^2)/(s + df),
; acos(x) = 2 (df + (R(z) s + c)), R(z) = p/q, p = z (pS0 + z (pS1 + z pS2)), q = 1 + z qS1
; (3 + 1 coefficients: single precision on [0, 0.25]).
; Library calls, this path: f_sqrt 1, f_div 2, f_mul 8, f_add 8 (two of them subtractions:
; the sign flipped, f_add).
; Path charged: acos(0.54321) (the avr-libc benchmark's operand): x > 0.5: z = 0.228395, s =
; 0.477907. Result 0.99654 (the float the routines give). Each .include is charged its own
; path (1.234 + 5.678, 1.234 x 5.678, 1.234 / 5.678, the square root hypot(1.234, 5.678)
; takes), not this routine's operands.
; Data: x in RW1:RW0 (the high word: sign, exponent, mantissa bits 22-16); the result in A
; (AH the high word, AL the low word); arguments to the soft-float routines in RW1:RW0 and
; RW5:RW4, their results in A. RW0-RW2 and RW4-RW7 are clobbered; RW3 is this routine's frame
; pointer (LINK), the caller's kept (UNLINK). Locals at negative displacements from RW3 (the
; disp8 is signed: 0xFC is -4): z -4, s -8, df -12, c -16, p -20.
        CALL  f_acos
        LINK  #20
; |x| >= 1? |x| < 0.5? x < -0.5? (0x3F0B0FD0: none)
        MOVW  A, RW1
        ANDW  A, #0x7FFF
        CMPW  A, #0x3F80
        BHS   one_or_more {not taken}   ; |x| = 1: 0 or pi; above: NaN
        CMPW  A, #0x3F00
        BLO   below_half {not taken}
        MOVW  A, RW1
        BN    below_minus_half {not taken}
; z = (1 - x) 0.5
        XORW  A, #0x8000                ; -x's high word
        MOVW  RW5, A
        MOVW  RW4, RW0
        MOVW  RW0, #0x0000              ; 1.0 = 0x3F800000
        MOVW  RW1, #0x3F80
        .include f_add                  ; 1 - x
        MOVL  RL0, A
        MOVW  RW4, #0x0000              ; 0.5 = 0x3F000000
        MOVW  RW5, #0x3F00
        .include f_mul                  ; z
        MOVL  RL0, A
        MOVL  @RW3+0xFC, A              ; z
        .include f_sqrt                 ; s = sqrtf(z)
        MOVL  @RW3+0xF8, A              ; s
; df = s, its low 12 bits cleared
        ANDW  A, #0xF000
        MOVL  RL0, A
        MOVL  RL2, A
        MOVL  @RW3+0xF4, A              ; df
        .include f_mul                  ; df df
; c = (z - df df) / (s + df)
        MOVW  RW4, A
        SWAPW
        XORW  A, #0x8000                ; the sign flipped
        MOVW  RW5, A
        MOVL  A, @RW3+0xFC              ; z
        MOVL  RL0, A
        .include f_add                  ; z - df df
        MOVL  @RW3+0xF0, A              ; the numerator, for now
        MOVL  A, @RW3+0xF8              ; s
        MOVL  RL0, A
        MOVL  A, @RW3+0xF4              ; df
        MOVL  RL2, A
        .include f_add                  ; s + df
        MOVL  RL2, A
        MOVL  A, @RW3+0xF0              ; the numerator
        MOVL  RL0, A
        .include f_div                  ; c
        MOVL  @RW3+0xF0, A              ; c
; p = z (pS0 + z (pS1 + z pS2))
        MOVL  A, @RW3+0xFC              ; z
        MOVL  RL0, A
        MOVW  RW4, #0xD36B              ; pS2 = -8.656363e-3 = 0xBC0DD36B
        MOVW  RW5, #0xBC0D
        .include f_mul                  ; z pS2
        MOVL  RL0, A
        MOVW  RW4, #0x13BA              ; pS1 = -4.274342e-2 = 0xBD2F13BA
        MOVW  RW5, #0xBD2F
        .include f_add                  ; + pS1
        MOVL  RL0, A
        MOVL  A, @RW3+0xFC              ; z
        MOVL  RL2, A
        .include f_mul                  ; (...) z
        MOVL  RL0, A
        MOVW  RW4, #0xAA75              ; pS0 = 1.666659e-1 = 0x3E2AAA75
        MOVW  RW5, #0x3E2A
        .include f_add                  ; + pS0
        MOVL  RL0, A
        MOVL  A, @RW3+0xFC              ; z
        MOVL  RL2, A
        .include f_mul                  ; p
        MOVL  @RW3+0xEC, A              ; p
; q = 1 + z qS1
        MOVL  A, @RW3+0xFC              ; z
        MOVL  RL0, A
        MOVW  RW4, #0xE5AE              ; qS1 = -7.066296e-1 = 0xBF34E5AE
        MOVW  RW5, #0xBF34
        .include f_mul                  ; z qS1
        MOVL  RL2, A
        MOVW  RW0, #0x0000              ; 1.0 = 0x3F800000
        MOVW  RW1, #0x3F80
        .include f_add                  ; q
; R(z) = p / q; w = R s + c
        MOVL  RL2, A
        MOVL  A, @RW3+0xEC              ; p
        MOVL  RL0, A
        .include f_div                  ; R(z)
        MOVL  RL0, A
        MOVL  A, @RW3+0xF8              ; s
        MOVL  RL2, A
        .include f_mul                  ; R s
        MOVL  RL0, A
        MOVL  A, @RW3+0xF0              ; c
        MOVL  RL2, A
        .include f_add                  ; w
; 2 (df + w)
        MOVL  RL0, A
        MOVL  A, @RW3+0xF4              ; df
        MOVL  RL2, A
        .include f_add                  ; df + w
        MOVL  RL0, A
        MOVW  RW4, #0x0000              ; 2.0 = 0x40000000
        MOVW  RW5, #0x4000
        .include f_mul                  ; 2 (df + w)
        UNLINK
        RET
