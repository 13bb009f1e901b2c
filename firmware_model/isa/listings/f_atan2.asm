; C atan2f(y, x) (IEEE-754 single), the model firmware's library routine: a called routine,
; CALL ... RET counted, its own instructions and, in place, the soft-float routines it calls
; (.include: each call counted at that routine's charged path).
; Algorithm: fdlibm's atan2f and atanf as FreeBSD's msun and musl have them for float
; (newlib's are the same code with atanf's 11 double-precision coefficients): x or y NaN/Inf,
; x = 1 (atanf(y)), m = 2 sign(x) + sign(y), y = 0, x = 0, x Inf, |y/x| > 2^26, x < 0 with
; |y/x| < 2^-26 tested; z = atanf(|y/x|) (the quotient one f_div; atanf a called function of
; its own, CALL ... RET, LINK frame); atanf: |t| >= 2^26, the reduction (|t| >= 7/16: t
; against 11/16, 19/16, 39/16, reduced by atanhi/atanlo with f_add/f_div), |t| < 2^-12
; tested; the polynomial in z = t^2, w = z^2, odd and even parts: s1 = z (aT0 + w (aT2 + w
; aT4)), s2 = w (aT1 + w aT3) (5 coefficients: degree 11 in t, single precision on
; [0, 7/16]); t - t (s1 + s2); the quadrant by m (0: z; 1: -z; 2: pi - (z - pi_lo); 3:
; (z - pi_lo) - pi).
; Library calls, this path: f_div 1, f_mul 8, f_add 5 (a subtraction: the sign flipped, f_add).
; Path charged: atan2(1.234, 5.678) (the avr-libc benchmark's operands): m = 0; |y/x| =
; 0.21733 < 7/16: no reduction (id = -1); z = 0.21400 returned as it is. Each .include is
; charged its own path (1.234 + 5.678, 1.234 x 5.678, 1.234 / 5.678), not this routine's
; operands.
; Data: y in RW1:RW0, x in RW5:RW4 (each: the high word sign, exponent, mantissa bits 22-16;
; the low word); the result in A (AH the high word, AL the low word); arguments to the
; soft-float routines in RW1:RW0 and RW5:RW4, their results in A. RW0-RW2 and RW4-RW7 are
; clobbered; RW3 is the frame pointer (LINK), the caller's kept (UNLINK). atan2f's local:
; m -2; atanf's: t -4, z -8, w -12, s1 -16 (the disp8 is signed: 0xFE is -2).
        CALL  f_atan2
        LINK  #2                        ; m -2
; NaN or Inf (the exponent field 0x7F80)? x, y: neither
        MOVW  A, RW5
        ANDW  A, #0x7F80
        CWBNE A, #0x7F80, x_finite {taken}
x_finite:
        MOVW  A, RW1
        ANDW  A, #0x7F80
        CWBNE A, #0x7F80, y_finite {taken}
y_finite:
; x = 1.0: atanf(y)? no
        MOVW  A, RW5
        CWBNE A, #0x3F80, x_not_one {taken}
x_not_one:
; m = 2 sign(x) + sign(y): 0
        MOVW  RW7, #0
        MOVW  A, RW1
        BP    y_positive {taken}
y_positive:
        MOVW  A, RW5
        BP    x_positive {taken}
x_positive:
        MOVW  A, RW7
        MOVW  @RW3+0xFE, A              ; m
; |y| = 0? |x| = 0? |x| Inf? no (their high words are not 0)
        MOVW  A, RW1
        ANDW  A, #0x7FFF
        MOVW  RW2, A                    ; |y|'s high word
        BNE   y_not_zero {taken}
y_not_zero:
        MOVW  A, RW5
        ANDW  A, #0x7FFF
        BNE   x_not_zero {taken}
x_not_zero:
        CWBNE A, #0x7F80, x_not_inf {taken}
x_not_inf:
; |y/x| > 2^26: |x| + 26 << 23 < |y|? no
        ADDW  A, #0x0D00
        CMPW  A, RW2
        BLO   huge {not taken}
; x < 0 and |y/x| < 2^-26 (then z = 0)? x > 0
        MOVW  A, RW7
        ANDW  A, #0x0002
        BNE   x_negative {not taken}
; z = atanf(|y/x|)
        .include f_div                  ; y / x
        MOVW  RW0, A
        SWAPW
        ANDW  A, #0x7FFF                ; fabsf
        MOVW  RW1, A
; atanf(t), t in RW1:RW0: a called function
        CALL  f_atanf
        LINK  #16                       ; t -4, z -8, w -12, s1 -16
        MOVL  A, RL0
        MOVL  @RW3+0xFC, A              ; t
        SWAPW
        ANDW  A, #0x7FFF                ; |t|'s high word (sign: t >= 0 here)
        CMPW  A, #0x4C80
        BHS   atan_big {not taken}      ; |t| >= 2^26: +-pi/2
        CMPW  A, #0x3EE0
        BHS   atan_reduce {not taken}   ; |t| >= 7/16: reduced
        CMPW  A, #0x3980
        BLO   atan_tiny {not taken}     ; |t| < 2^-12: t
; z = t^2, w = z^2
        MOVW  RW4, RW0
        MOVW  RW5, RW1
        .include f_mul                  ; z = t t
        MOVL  RL0, A
        MOVL  RL2, A
        MOVL  @RW3+0xF8, A              ; z
        .include f_mul                  ; w = z z
        MOVL  RL0, A
        MOVL  @RW3+0xF4, A              ; w
; s1 = z (aT0 + w (aT2 + w aT4))
        MOVW  RW4, #0xAC25              ; aT4 = 6.168761e-2 = 0x3D7CAC25
        MOVW  RW5, #0x3D7C
        .include f_mul                  ; w aT4
        MOVL  RL0, A
        MOVW  RW4, #0xF50D              ; aT2 = 1.425364e-1 = 0x3E11F50D
        MOVW  RW5, #0x3E11
        .include f_add                  ; + aT2
        MOVL  RL0, A
        MOVL  A, @RW3+0xF4              ; w
        MOVL  RL2, A
        .include f_mul                  ; (...) w
        MOVL  RL0, A
        MOVW  RW4, #0xAAA9              ; aT0 = 3.333333e-1 = 0x3EAAAAA9
        MOVW  RW5, #0x3EAA
        .include f_add                  ; + aT0
        MOVL  RL0, A
        MOVL  A, @RW3+0xF8              ; z
        MOVL  RL2, A
        .include f_mul                  ; s1
        MOVL  @RW3+0xF0, A              ; s1
; s2 = w (aT1 + w aT3)
        MOVL  A, @RW3+0xF4              ; w
        MOVL  RL0, A
        MOVW  RW4, #0x1247              ; aT3 = -1.064802e-1 = 0xBDDA1247
        MOVW  RW5, #0xBDDA
        .include f_mul                  ; w aT3
        MOVL  RL0, A
        MOVW  RW4, #0xCA98              ; aT1 = -1.999916e-1 = 0xBE4CCA98
        MOVW  RW5, #0xBE4C
        .include f_add                  ; + aT1
        MOVL  RL0, A
        MOVL  A, @RW3+0xF4              ; w
        MOVL  RL2, A
        .include f_mul                  ; s2
; t - t (s1 + s2)
        MOVL  RL0, A
        MOVL  A, @RW3+0xF0              ; s1
        MOVL  RL2, A
        .include f_add                  ; s1 + s2
        MOVL  RL0, A
        MOVL  A, @RW3+0xFC              ; t
        MOVL  RL2, A
        .include f_mul                  ; t (s1 + s2)
        MOVW  RW4, A
        SWAPW
        XORW  A, #0x8000                ; the sign flipped
        MOVW  RW5, A
        MOVL  A, @RW3+0xFC              ; t
        MOVL  RL0, A
        .include f_add                  ; t - t (s1 + s2)
        UNLINK
        RET                             ; (atanf's)
; the quadrant: m = 0, z as it is
        MOVL  RL0, A
        MOVW  A, @RW3+0xFE              ; m
        BNE   m_not_zero {not taken}
        MOVL  A, RL0                    ; AH: the high word, AL: the low word
        UNLINK
        RET
