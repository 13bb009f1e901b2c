; The reduction sinf and cosf share (inline in each; Cephes with musl's rounding trick): from
; x (at the frame's -4), j = rint(x 2/pi) by adding and subtracting 1.5 x 2^23, the quadrant
; j mod 4 (-22), y = (float)j (-8), r = (x - y C1) - y C2 by Cody-Waite (C1 = 1.5703125,
; C2 = pi/2 - C1; -12) and z = r x r (-16). Library calls: f_mul 4, f_add 4.
; Path charged: x = 1.2345 (x 2/pi = 0.786, j = 1, r = -0.3363); each .include at its own
; charged path.
; Data: as the including routine's header (its LINK frame, RW3 the frame pointer).
; j = rint(x x 2/pi): x 2/pi + 1.5 x 2^23 rounds to an integer whose low word is j
; (x 2/pi = 0.786, j = 1); y = that - 1.5 x 2^23 = (float)j
        MOVW  RW4, #0xF983              ; 2/pi = 0x3F22F983
        MOVW  RW5, #0x3F22
        .include f_mul                  ; x 2/pi
        MOVL  RL0, A
        MOVW  RW4, #0x0000              ; 1.5 x 2^23 = 0x4B400000
        MOVW  RW5, #0x4B40
        .include f_add                  ; rounded to an integer
        MOVL  RL0, A
        ANDW  A, #0x0003
        MOVW  @RW3+0xEA, A              ; j mod 4: the quadrant
        MOVW  RW4, #0x0000              ; -1.5 x 2^23 = 0xCB400000
        MOVW  RW5, #0xCB40
        .include f_add                  ; y = (float)j = 1.0
; r = (x - y C1) - y C2, Cody-Waite: C1 = 1.5703125 (8 bits: y C1 exact), C2 = pi/2 - C1
        MOVL  RL0, A
        MOVL  @RW3+0xF8, A              ; y
        MOVW  RW4, #0x0000              ; -C1 = 0xBFC90000
        MOVW  RW5, #0xBFC9
        .include f_mul                  ; y x -C1
        MOVL  RL2, A
        MOVL  A, @RW3+0xFC              ; x
        MOVL  RL0, A
        .include f_add                  ; x - y C1
        MOVL  @RW3+0xF4, A              ; r so far
        MOVL  A, @RW3+0xF8              ; y
        MOVL  RL0, A
        MOVW  RW4, #0xAA22              ; -C2 = 0xB9FDAA22
        MOVW  RW5, #0xB9FD
        .include f_mul                  ; y x -C2
        MOVL  RL2, A
        MOVL  A, @RW3+0xF4              ; r so far
        MOVL  RL0, A
        .include f_add                  ; r = -0.3363
        MOVL  @RW3+0xF4, A              ; r
; z = r x r
        MOVL  RL0, A
        MOVL  RL2, A
        .include f_mul                  ; z
        MOVL  @RW3+0xF0, A              ; z
