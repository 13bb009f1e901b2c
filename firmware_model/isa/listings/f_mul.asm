; Soft-float multiplication, C float x * y (IEEE-754 single, __mulsf3), the model firmware's
; library routine: a called routine, CALL ... RET counted.
; Algorithm: the exponent fields (exponent << 7) tested for zero/subnormal and Inf/NaN and
; added, less the bias (and less the hidden bit's 0x80: the pack adds the mantissa's high
; byte, hidden bit and all), checked to be clear of the range's ends (else the careful path);
; the sign the XOR of the signs, with the exponent on the stack; the 24-bit mantissas (a high
; byte with the hidden bit, a low word) multiplied by four MULUW (xl*yl, xh*yl, xl*yh, xh*yh)
; into the product's top 32 bits w2:w1 (the partial products summed with ADDL), xl*yl's low
; word w0 kept only as a sticky bit; a product below 2 shifted left one bit (ADDL to itself;
; else the exponent + 1); round to nearest even at bit 7 (half a unit added, the lowest bit
; cleared again on a tie); pack from the mantissa's bytes (MOVL into RL3, MOV A, R4-R7).
; Path charged: 1.234 x 5.678 (the avr-libc benchmark's operands): x = 0x3F9DF3B6, y =
; 0x40B5B22D; mantissas 0x9DF3B6 x 0xB5B22D = 0x701B3EE662FE (1.7517: below 2, shifted left
; one bit: 0xE0367DCC); the bits below the mantissa (0xCC) above half: rounded up (0xE0367E),
; no carry out of the mantissa. Result 7.006652 = 0x40E0367E.
; Data: a float in two words, the high word (sign, exponent, mantissa bits 22-16) and the low
; word; x in RW1:RW0 (RL0), y in RW5:RW4 (RL2); the result in A (AH the high word, AL the low
; word). RW0-RW2 and RW4-RW7 are clobbered; RW3, the caller's frame pointer, is kept.
        CALL  f_mul
; the exponent fields: 0 is zero (subnormals flushed), 0x7F80 Inf or NaN
        MOVW  A, RW1
        ANDW  A, #0x7F80
        BEQ   x_zero {not taken}        ; the result is 0 (NaN for 0 x Inf)
        CWBNE A, #0x7F80, x_finite {taken}
x_finite:
        MOVW  A, RW5                    ; AH: ex
        ANDW  A, #0x7F80
        BEQ   y_zero {not taken}
        CWBNE A, #0x7F80, y_finite {taken}
y_finite:
        ADDW  A                         ; ex + ey
        SUBW  A, #0x4000                ; - 127 << 7 - 0x80: 0x4000
        CMPW  A, #0x7D80
        BHI   near_limits {not taken}   ; an overflow or underflow possible: the careful path
        MOVW  RW2, A
; the sign, with the exponent: on the stack
        MOVW  A, RW1
        XORW  A, RW5
        ANDW  A, #0x8000
        ORW   A, RW2
        PUSHW A
; the mantissas: the high byte with the hidden bit, the low word
        MOVW  A, RW1
        ANDW  A, #0x007F
        ORW   A, #0x0080
        MOVW  RW1, A                    ; xh
        MOVW  A, RW5
        ANDW  A, #0x007F
        ORW   A, #0x0080
        MOVW  RW5, A                    ; yh
; the product's top 32 bits: xl yl's high word + xh yl + xl yh + xh yh << 16
        MOVW  A, RW0
        MULUW A, RW4                    ; xl * yl
        MOVW  RW2, A                    ; w0: only whether it is 0 counts (the sticky bit)
        SWAPW
        ZEXTW                           ; 0 : xl yl's high word
        MOVL  RL3, A
        MOVW  A, RW1
        MULUW A, RW4                    ; xh * yl (24 bits)
        ADDL  A, RL3
        MOVL  RL3, A
        MOVW  A, RW0
        MULUW A, RW5                    ; xl * yh (24 bits)
        ADDL  A, RL3
        MOVL  RL3, A
        MOVW  A, RW1
        MULUW A, RW5                    ; xh * yh (16 bits)
        SWAPW                           ; << 16
        ADDL  A, RL3                    ; w2:w1 = 0x701B3EE6
        BN    two_or_more {not taken}   ; bit 31 clear: the product is below 2
; normalise: << 1 (w0's top bit, below the round bit, is among the sticky bits)
        MOVL  RL3, A
        ADDL  A, RL3                    ; 0xE0367DCC
; round to nearest even: half a unit in the last place (bit 8) added
        ADDL  A, #0x00000080            ; 0xE0367E4C
        BC    round_carry {not taken}   ; the mantissa all ones: 2^24, the exponent + 1
        CBNE  A, #0x00, not_tie {taken} ; the low byte 0: it was half (a tie if w0 is 0)
not_tie:
; pack: the mantissa is the top 24 bits, R7 R6 R5 once in RL3
        MOVL  RL3, A
        MOV   A, R5
        MOV   A, R6                     ; AH: R5, AL: R6
        SWAP                            ; AL: R6 << 8
        ORW   A                         ; the low word: R6 R5
        MOVW  RW0, A
        MOV   A, R7                     ; the mantissa's high byte, the hidden bit its bit 7
        POPW  A                         ; AH: it, AL: the sign and the exponent (less 0x80)
        ADDW  A                         ; the high word
        MOVW  A, RW0                    ; AH: the high word, AL: the low word
        RET
