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

// No hardware I2C: nothing is wired to it (the BMI055 is on SPI1). Without pins the port
// builds neither machine.I2C, I2CTarget nor pyb.I2C.
#undef MICROPY_HW_I2C1_SCL
#undef MICROPY_HW_I2C1_SDA
#undef MICROPY_HW_I2C2_SCL
#undef MICROPY_HW_I2C2_SDA
#undef MICROPY_HW_I2C3_SCL
#undef MICROPY_HW_I2C3_SDA

// USB: the REPL's CDC serial port only. No mass storage (the PC would mount /flash as a drive
// and write its FAT behind the firmware's and the tools' backs; the tools use the REPL) and
// no HID.
#define MICROPY_HW_USB_MSC          (0)
#define MICROPY_HW_USB_HID          (0)

// The MicroPython features the firmware and the board tools never use (docs/image.md)
#include "../ins_features.h"
// ... and the VM options the firmware's timing rests on
#include "../ins_vm.h"
