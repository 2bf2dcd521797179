// The WeAct Black Pill exactly as MicroPython's own board folder defines it
// (ports/stm32/boards/WEACT_F411_BLACKPILL, included from the MicroPython tree), with one
// change for this firmware: no REPL on USART1. The firmware drives USART1 (PA9/PA10) as its
// RS485 output at 460800 baud; with the port's UART REPL there, console text would go out on
// the RS485 bus between the binary frames, and a 0x03 byte received on PA10 would stop the
// loop (KeyboardInterrupt). The REPL stays on USB (CDC), where tools.flash and a terminal
// reach it.
#include "boards/WEACT_F411_BLACKPILL/mpconfigboard.h"

#undef MICROPY_HW_UART_REPL
#undef MICROPY_HW_UART_REPL_BAUD
