; C sinf(x) (IEEE-754 single), the model firmware's library routine: a called routine, CALL
; ... RET counted, its own instructions and, in place, the soft-float routines it calls
; (.include: each call counted at that routine's charged path).
; Algorithm: Cephes sinf with a reduction by pi/2: x < 0 (sign), x < pi/4 (no reduction) and
; x >= 8192 (precision lost; Inf, NaN) tested; j = rint(x 2/pi) by adding and subtracting
; 1.5 x 2^23 (musl's __rem_pio2f), its low bits the quadrant; r = (x - j C1) - j C2
; (Cody-Waite, 2 constants: C1 = 1.5703125, C2 = pi/2 - C1); z = r^2; j even: sin(r) =
; r + r z (s1 + z (s2 + z s3)); j odd: cos(r) = 1 - z/2 + z^2 (c1 + z (c2 + z c3)) (Cephes
; sinf's coefficients: degree 7 and 8, single precision on |r| <= pi/4); j & 2: negated.
; Library calls, this path: f_mul 9, f_add 8 (reduction: 3 f_mul, 4 f_add; z: 1 f_mul; cos
; kernel: 5 f_mul, 4 f_add).
; Path charged: sin(1.2345) (the avr-libc benchmark's operand): x 2/pi = 0.786, j = 1: r =
; 1.2345 - pi/2 = -0.3363, quadrant 1: sin(x) = cos(r), not negated. Result 0.94398 (the
; float the routines give). Each .include is charged its own path (1.234 + 5.678, 1.234 x
; 5.678), not this routine's operands.
; Data: x in RW1:RW0 (the high word: sign, exponent, mantissa bits 22-16); the result in A
; (AH the high word, AL the low word); arguments to the soft-float routines in RW1:RW0 and
; RW5:RW4, their results in A. RW0-RW2 and RW4-RW7 are clobbered; RW3 is this routine's frame
; pointer (LINK), the caller's kept (UNLINK). Locals at negative displacements from RW3 (the
; disp8 is signed: 0xFC is -4): x -4, y = (float)j -8, r -12, z -16, t -20, j -22.
        CALL  f_sin
        LINK  #22                       ; locals: x -4, y -8, r -12, z -16, t -20, j -22
        MOVL  A, RL0
        MOVL  @RW3+0xFC, A              ; x (the disp8 is signed: 0xFC is -4)
        BN    negative {not taken}    ; x < 0: sin(-x) = -sin(x)
        SWAPW                           ; AL: x's high word
        CMPW  A, #0x3F49
        BLO   small {not taken}         ; x < 0.785 (pi/4): the kernel without reduction
        CMPW  A, #0x4600
        BHS   too_large {not taken}     ; x >= 8192 (Inf, NaN): no precision left
        .include f_reduce_pio2          ; j, y, r and z (f_reduce_pio2.asm)
; the quadrant: j odd, the cosine kernel
        MOVW  A, @RW3+0xEA              ; j
        ANDW  A, #0x0001
        BEQ   sin_kernel {not taken}
; cos(r) = 1 - z/2 + z^2 (c1 + z (c2 + z c3)), Cephes sinf's coefficients
        MOVL  A, @RW3+0xF0              ; z
        MOVL  RL0, A
        MOVW  RW4, #0xF5CE              ; c3 = 2.443316e-5 = 0x37CCF5CE
        MOVW  RW5, #0x37CC
        .include f_mul                  ; z c3
        MOVL  RL0, A
        MOVW  RW4, #0x061A              ; c2 = -1.388732e-3 = 0xBAB6061A
        MOVW  RW5, #0xBAB6
        .include f_add                  ; + c2
        MOVL  RL0, A
        MOVL  A, @RW3+0xF0              ; z
        MOVL  RL2, A
        .include f_mul                  ; (...) z
        MOVL  RL0, A
        MOVW  RW4, #0xAAA5              ; c1 = 4.166665e-2 = 0x3D2AAAA5
        MOVW  RW5, #0x3D2A
        .include f_add                  ; + c1: t
        MOVL  @RW3+0xEC, A              ; t
        MOVL  A, @RW3+0xF0              ; z
        MOVL  RL0, A
        MOVL  RL2, A
        .include f_mul                  ; z^2
        MOVL  RL2, A
        MOVL  A, @RW3+0xEC              ; t
        MOVL  RL0, A
        .include f_mul                  ; t z^2
        MOVL  @RW3+0xEC, A              ; t z^2
        MOVL  A, @RW3+0xF0              ; z
        MOVL  RL0, A
        MOVW  RW4, #0x0000              ; -0.5 = 0xBF000000
        MOVW  RW5, #0xBF00
        .include f_mul                  ; -z/2
        MOVL  RL2, A
        MOVW  RW0, #0x0000              ; 1.0 = 0x3F800000
        MOVW  RW1, #0x3F80
        .include f_add                  ; 1 - z/2
        MOVL  RL0, A
        MOVL  A, @RW3+0xEC              ; t z^2
        MOVL  RL2, A
        .include f_add                  ; + t z^2
; the sign: j & 2 (j = 1: +)
        MOVL  RL0, A
        MOVW  A, @RW3+0xEA
        ANDW  A, #0x0002
        BNE   negate {not taken}
        MOVL  A, RL0                    ; AH: the high word, AL: the low word
        UNLINK
        RET
