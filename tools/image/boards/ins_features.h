// The MicroPython features both board definitions leave out (included by each board's
// mpconfigboard.h): what neither the firmware (firmware/**/*.py, main.py) nor the board tools
// (tools/flash: deploy, config, console, the maintenance start, mpremote's raw REPL and file
// calls) use. docs/image.md lists what the image carries against what they use, and what each
// of these gave. Everything they use stays: machine's Pin (with irq), SPI, UART, Timer, WDT,
// reset, bootloader, disable_irq/enable_irq, idle; stm.mem32; uctypes.addressof; struct;
// array; math.sqrt; binascii.crc32 (which needs deflate); gc; micropython; sys; time; os and
// the FAT filesystem; the raw REPL; loading the native module lib/navk.mpy.

// The native code emitters (@micropython.native, @micropython.viper, @micropython.asm_thumb):
// nothing is compiled by them. Loading a native .mpy (lib/navk.mpy) is separate and stays:
// with it on, sys.implementation._mpy still names the armv7emsp architecture.
#define MICROPY_EMIT_THUMB                  (0)
#define MICROPY_EMIT_INLINE_THUMB           (0)
#define MICROPY_PERSISTENT_CODE_LOAD_NATIVE (1)

// Modules nothing imports
#define MICROPY_PY_FRAMEBUF                 (0)
#define MICROPY_PY_HEAPQ                    (0)
#define MICROPY_PY_RE                       (0)
#define MICROPY_PY_JSON                     (0)
#define MICROPY_PY_HASHLIB                  (0) // mpremote hashes on the host without it
#define MICROPY_PY_RANDOM                   (0)
#define MICROPY_PY_CMATH                    (0)
#define MICROPY_PY_BUILTINS_COMPLEX         (0)
#define MICROPY_PY_ASYNCIO                  (0)
#define MICROPY_PY_SELECT                   (0)
#define MICROPY_PY_NETWORK                  (0) // and with it socket: the F411 has no NIC
#define MICROPY_PY_ONEWIRE                  (0)
// math keeps what the firmware and float parsing need (sqrt; pow, used by float literals)
#define MICROPY_PY_MATH_SPECIAL_FUNCTIONS   (0) // erf, erfc, gamma, lgamma
#define MICROPY_PY_MATH_FACTORIAL           (0)
// stm.mem32 stays (the maintenance marker, uart_dma.py's DMA registers); the named register
// constants (stm.GPIOA, stm.RCC_APB1ENR, ...) go: the firmware and the tools use addresses
#define MICROPY_PY_STM_CONST                (0)

// machine: the port's own set (ports/stm32/mpconfigport.h, used when a board defines none)
// without ADC, PWM, SoftI2C, bitstream, DHT and time_pulse_us (SoftSPI stays: the port's
// machine.SPI refers to it for the legacy SPI(-1)); I2C goes with the
// board's I2C pins (hardware I2C and I2CTarget exist only for pins a board defines)
#define MICROPY_PY_MACHINE                  (1)
#define MICROPY_PY_MACHINE_INCLUDEFILE      "ports/stm32/modmachine.c"
#define MICROPY_PY_MACHINE_RESET            (1)
#define MICROPY_PY_MACHINE_BARE_METAL_FUNCS (1)
#define MICROPY_PY_MACHINE_FREQ_NUM_ARGS_MAX (4)
#define MICROPY_PY_MACHINE_BOOTLOADER       (1) // machine.bootloader(): DFU mode from the REPL
#define MICROPY_PY_MACHINE_ADC              (0)
#define MICROPY_PY_MACHINE_BITSTREAM        (0)
#define MICROPY_PY_MACHINE_CAN              (0)
#define MICROPY_PY_MACHINE_DHT_READINTO     (0)
#define MICROPY_PY_MACHINE_PULSE            (0)
#define MICROPY_PY_MACHINE_PIN_MAKE_NEW     mp_pin_make_new
#define MICROPY_PY_MACHINE_I2C              (MICROPY_HW_ENABLE_HW_I2C)
#define MICROPY_PY_MACHINE_I2C_TARGET       (MICROPY_HW_ENABLE_HW_I2C_TARGET)
#define MICROPY_PY_MACHINE_I2C_TARGET_INCLUDEFILE "ports/stm32/machine_i2c_target.c"
#define MICROPY_PY_MACHINE_I2C_TARGET_MAX   (4)
#define MICROPY_PY_MACHINE_I2C_TARGET_HARD_IRQ (1)
#define MICROPY_PY_MACHINE_SOFTI2C          (0)
#define MICROPY_PY_MACHINE_PWM              (0)
#define MICROPY_PY_MACHINE_SPI              (1)
#define MICROPY_PY_MACHINE_SPI_MSB          (SPI_FIRSTBIT_MSB)
#define MICROPY_PY_MACHINE_SPI_LSB          (SPI_FIRSTBIT_LSB)
#define MICROPY_PY_MACHINE_SOFTSPI          (1) // the port's machine.SPI(-1) needs it
#define MICROPY_PY_MACHINE_TIMER            (1)
#define MICROPY_PY_MACHINE_UART             (1)
#define MICROPY_PY_MACHINE_UART_INCLUDEFILE "ports/stm32/machine_uart.c"
#define MICROPY_PY_MACHINE_UART_IRQ         (1)
#define MICROPY_PY_MACHINE_UART_READCHAR_WRITECHAR (1)
#define MICROPY_PY_MACHINE_UART_SENDBREAK   (1)
#define MICROPY_PY_MACHINE_WDT              (1)
#define MICROPY_PY_MACHINE_WDT_INCLUDEFILE  "ports/stm32/machine_wdt.c"
