; C roundf(x) (IEEE-754 single; round half away from zero), the model firmware's library
; routine: a called routine, CALL ... RET counted.
; Algorithm: newlib's roundf, on the float's bits, no float arithmetic: k = the unbiased
; exponent; k < 0: 0 or 1 with x's sign; k >= 23: x is an integer (or Inf/NaN), as it is;
; else one half of the last integer place added to the bits (a carry into the exponent is
; right: 1.5 -> 2.0) and the fraction's bits cleared. (newlib first returns an x with no
; fraction bits as it is; the same arithmetic gives it back, so that test is left out.) With
; the fraction's top bit in the high word (k < 7), m = 7 - k is its fraction bits: 2^m from a
; ROM table of powers of 2 (MOVW A, @RW2+disp16), the half 2^(m-1) added, and the fraction
; cleared by ANDW with the mask -2^m (NEGW); the low word is all fraction: 0.
; Path charged: round(1.2345) (the avr-libc benchmark's operand): x = 0x3F9E0419, k = 0: the
; fraction's top bit in the high word (k < 7), m = 7: the whole low word and the high word's
; 7 low bits are fraction; 0x3F9E + 0x40 = 0x3FDE, AND 0xFF80 = 0x3F80; the low word 0.
; Result 1.0 = 0x3F800000.
; Data: a float in two words, the high word (sign, exponent, mantissa bits 22-16) and the low
; word; x in RW1:RW0 (RL0); the result in A (AH the high word, AL the low word). RW0-RW2 and
; RW4-RW7 are clobbered; RW3, the caller's frame pointer, is kept. pow2: 16 words, 2^0-2^15.
        CALL  f_round
; k = the exponent - 127
        MOVW  A, RW1
        LSLW  A                         ; the sign out
        SWAP                            ; AL's bytes exchanged: the exponent in the low byte
        ANDW  A, #0x00FF
        SUBW  A, #127
        BLT   below_one {not taken}     ; |x| < 1
        CMPW  A, #23
        BGE   integral {not taken}      ; |x| >= 2^23, Inf or NaN
        CMPW  A, #7
        BGE   half_in_low {not taken}   ; k >= 7: the half's bit in the low word
; m = 7 - k, the high word's fraction bits; 2^m
        NEGW  A
        ADDW  A, #7
        LSLW  A                         ; a word index
        MOVW  RW2, A
        MOVW  A, @RW2+disp16:pow2       ; 2^m = 0x0080
        MOVW  RW2, A
; + one half: 2^(m-1) in the high word (the low word's bits are all below it)
        LSRW  A
        ADDW  A, RW1                    ; 0x3F9E + 0x0040
; the fraction cleared: AND -2^m; the low word 0
        MOVW  A, RW2                    ; AH: the sum, AL: 2^m
        NEGW  A                         ; the mask 0xFF80
        ANDW  A                         ; AL = AH & AL = 0x3F80
        MOVW  A, #0                     ; AH: the high word, AL: the low word
        RET
