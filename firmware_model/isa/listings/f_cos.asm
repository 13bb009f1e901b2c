; C cosf(x) (IEEE-754 single), the model firmware's library routine: a called routine, CALL
; ... RET counted, its own instructions and, in place, the soft-float routines it calls
; (.include: each call counted at that routine's charged path).
; Algorithm: Cephes cosf with a reduction by pi/2, as f_sin: x < 0 (cos(-x) = cos(x)), x <
; pi/4 (no reduction) and x >= 8192 (precision lost; Inf, NaN) tested; j = rint(x 2/pi) by
; adding and subtracting 1.5 x 2^23 (musl's __rem_pio2f), its low bits the quadrant; r =
; (x - j C1) - j C2 (Cody-Waite, 2 constants: C1 = 1.5703125, C2 = pi/2 - C1); z = r^2; j
; even: cos(r) = 1 - z/2 + z^2 (c1 + z (c2 + z c3)); j odd: sin(r) = r + r z (s1 + z (s2 +
; z s3)) (Cephes sinf's coefficients: degree 8 and 7, single precision on |r| <= pi/4);
; (j + 1) & 2: negated.
; Library calls, this path: f_mul 8, f_add 7 (reduction: 3 f_mul, 4 f_add; z: 1 f_mul; sin
; kernel: 4 f_mul, 3 f_add).
; Path charged: cos(1.2345) (the avr-libc benchmark's operand): x 2/pi = 0.786, j = 1: r =
; 1.2345 - pi/2 = -0.3363, quadrant 1: cos(x) = -sin(r), negated (the sign bit flipped).
; Result 0.32999 (the float the routines give). Each .include is charged its own path
; (1.234 + 5.678, 1.234 x 5.678), not this routine's operands.
; Data: x in RW1:RW0 (the high word: sign, exponent, mantissa bits 22-16); the result in A
; (AH the high word, AL the low word); arguments to the soft-float routines in RW1:RW0 and
; RW5:RW4, their results in A. RW0-RW2 and RW4-RW7 are clobbered; RW3 is this routine's frame
; pointer (LINK), the caller's kept (UNLINK). Locals at negative displacements from RW3 (the
; disp8 is signed: 0xFC is -4): x -4, y = (float)j -8, r -12, z -16, t -20, j -22.
        CALL  f_cos
        LINK  #22                       ; locals: x -4, y -8, r -12, z -16, t -20, j -22
        MOVL  A, RL0
        MOVL  @RW3+0xFC, A              ; x (the disp8 is signed: 0xFC is -4)
        BN    negative {not taken}    ; x < 0: cos(-x) = cos(x)
        SWAPW                           ; AL: x's high word
        CMPW  A, #0x3F49
        BLO   small {not taken}         ; x < 0.785 (pi/4): the kernel without reduction
        CMPW  A, #0x4600
        BHS   too_large {not taken}     ; x >= 8192 (Inf, NaN): no precision left
        .include f_reduce_pio2          ; j, y, r and z (f_reduce_pio2.asm)
; the quadrant: j odd, the sine kernel
        MOVW  A, @RW3+0xEA              ; j
        ANDW  A, #0x0001
        BNE   sin_kernel {taken}
sin_kernel:
; sin(r) = r + r z (s1 + z (s2 + z s3)), Cephes sinf's coefficients
        MOVL  A, @RW3+0xF0              ; z
        MOVL  RL0, A
        MOVW  RW4, #0xA1F9              ; s3 = -1.951530e-4 = 0xB94CA1F9
        MOVW  RW5, #0xB94C
        .include f_mul                  ; z s3
        MOVL  RL0, A
        MOVW  RW4, #0x839E              ; s2 = 8.332161e-3 = 0x3C08839E
        MOVW  RW5, #0x3C08
        .include f_add                  ; + s2
        MOVL  RL0, A
        MOVL  A, @RW3+0xF0              ; z
        MOVL  RL2, A
        .include f_mul                  ; (...) z
        MOVL  RL0, A
        MOVW  RW4, #0xAAA3              ; s1 = -1.666665e-1 = 0xBE2AAAA3
        MOVW  RW5, #0xBE2A
        .include f_add                  ; + s1
        MOVL  RL0, A
        MOVL  A, @RW3+0xF0              ; z
        MOVL  RL2, A
        .include f_mul                  ; (...) z
        MOVL  RL0, A
        MOVL  A, @RW3+0xF4              ; r
        MOVL  RL2, A
        .include f_mul                  ; (...) r
        MOVL  RL2, A
        MOVL  A, @RW3+0xF4              ; r
        MOVL  RL0, A
        .include f_add                  ; r + r z (...)
; the sign: (j + 1) & 2 (j = 1: -), the sign bit flipped
        MOVL  RL0, A
        MOVW  A, @RW3+0xEA
        ADDW  A, #1
        ANDW  A, #0x0002
        BEQ   positive {not taken}
        MOVW  A, RW1
        XORW  A, #0x8000                ; the high word, its sign flipped
        MOVW  A, RW0                    ; AH: the high word, AL: the low word
        UNLINK
        RET
