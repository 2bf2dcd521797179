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

// USART6 for the UsartGPU screen (firmware/board.py's display_uart; docs/display.md). The
// F411CE's 48-pin package brings USART6 out only on PA11 (TX) and PA12 (RX), the USB pins:
// the firmware opens it only with its `display` setting on, and then the board has no USB
// console once the loop starts. Without these the port has no UART(6) at all.
#define MICROPY_HW_UART6_TX     (pin_A11)
#define MICROPY_HW_UART6_RX     (pin_A12)

// MicroPython's count of the bytes allocated (micropython.mem_total): the firmware looks at the
// heap (a scan of ~140,000 instructions) only when what its rare allocating steps took may have
// brought it near its low water mark (firmware/app.py, _heap_room). The count needs the sizes
// at every free.
#define MICROPY_MEM_STATS                   (1)
#define MICROPY_MALLOC_USES_ALLOCATED_SIZE  (1)
