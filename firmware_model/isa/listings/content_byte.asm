; The Content parser, one byte (main loop): classify it and take a name's letter or a
; number's digit.
; Path charged: a digit of a number (value = value x 10 + digit, by shifts and adds).
        MOV   A, @RW0+0                 ; the byte (RW0: the parse pointer)
        INCW  RW0
        MOV   R2, A
        SUB   A, #0x30                  ; '0'
        CMP   A, #10
        BNC   not_digit {not taken}
        MOV   R3, A
        MOVW  A, RW4                    ; the number so far
        LSLW  A                         ; x2
        MOVW  RW5, A
        LSLW  A
        LSLW  A                         ; x8
        ADDW  A, RW5                    ; x10
        MOVW  RW4, A
        MOV   A, R3
        ADDW  A, RW4                    ; + the digit
        MOVW  RW4, A
        DWBNZ RW6, parse_next {taken}   ; bytes left
