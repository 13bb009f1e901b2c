; The body's first instruction in every interrupt handler of the model firmware: switch to
; the handler's own register bank. The hardware entry (24 cycles, cycle_costs.py `entry`) has
; saved PS (ILM, RP, CCR), PC, PCB, DTB, ADB, DPR and A; RETI restores them, RP with PS, so a
; handler that keeps its work in its own bank saves and restores nothing else.
; (A C compiler that saves the registers it uses instead would add PUSHW/POPW rlst.)
        MOV   RP, #BANK                 ; one bank a level: a handler never clobbers the
                                        ; registers of one it interrupted
