// ST NUCLEO-F411RE (board MB1136) for MicroPython's stm32 port, kept in this repository
// because the vendored MicroPython tree carries only WEACT_F411_BLACKPILL's board folder.
// Facts from the board: the F411's HSE input (PH0) is driven by the 8 MHz MCO output of the
// on-board ST-LINK (crystal X3 not fitted), so HSE runs in bypass mode; USART2 (PA2/PA3) goes
// to the ST-LINK's virtual COM port, the only link to a PC (the F411's own USB pins PA11/PA12
// reach the morpho header but no connector); LD2 (green, active high) is on PA5, which is
// also Arduino D13 = SPI1 SCK; the blue button B1 pulls PC13 low.

#define MICROPY_HW_BOARD_NAME       "NUCLEO-F411RE"
#define MICROPY_HW_MCU_NAME         "STM32F411xE"
#define MICROPY_HW_FLASH_FS_LABEL   "NUCLEO_F411RE"

#define MICROPY_HW_HAS_SWITCH       (1)
#define MICROPY_HW_HAS_FLASH        (1)
#define MICROPY_HW_ENABLE_RTC       (1)
#define MICROPY_HW_ENABLE_USB       (0) // no USB connector on the F411 side

// Clock: 8 MHz from the ST-LINK's MCO (bypass) -> PLL: /8 * 192 = 192 MHz VCO,
// /2 = 96 MHz SYSCLK, /4 = 48 MHz for the USB/SDIO domain. 96 MHz at 3.3 V needs 3 wait
// states (RM0383, table 6: 90 < HCLK <= 100 MHz).
#define MICROPY_HW_CLK_USE_BYPASS   (1)
#define MICROPY_HW_CLK_PLLM         (8)
#define MICROPY_HW_CLK_PLLN         (192)
#define MICROPY_HW_CLK_PLLP         (RCC_PLLP_DIV2)
#define MICROPY_HW_CLK_PLLQ         (4)
#define MICROPY_HW_FLASH_LATENCY    (FLASH_LATENCY_3)

// The RTC runs from the LSI: the 32.768 kHz crystal X2 is missing on early board revisions.
#define MICROPY_HW_RTC_USE_LSE      (0)

// UARTs: USART2 is the REPL through the ST-LINK's virtual COM port.
#define MICROPY_HW_UART1_TX         (pin_A9)  // Arduino D8
#define MICROPY_HW_UART1_RX         (pin_A10) // Arduino D2
#define MICROPY_HW_UART2_TX         (pin_A2)  // ST-LINK VCP (Arduino D1 only with SB62/SB63)
#define MICROPY_HW_UART2_RX         (pin_A3)  // ST-LINK VCP (Arduino D0 only with SB62/SB63)
#define MICROPY_HW_UART6_TX         (pin_C6)  // morpho CN10 pin 4
#define MICROPY_HW_UART6_RX         (pin_C7)  // Arduino D9
#define MICROPY_HW_UART_REPL        (PYB_UART_2)
#define MICROPY_HW_UART_REPL_BAUD   (115200)

// No I2C buses: nothing is wired to them (the BMI055 is on SPI1); without pins the port
// builds neither machine.I2C, I2CTarget nor pyb.I2C (Arduino D14/D15 are PB9/PB8).

// SPI buses
#define MICROPY_HW_SPI1_NSS         (pin_A4)  // Arduino A2
#define MICROPY_HW_SPI1_SCK         (pin_A5)  // Arduino D13 (also LD2)
#define MICROPY_HW_SPI1_MISO        (pin_A6)  // Arduino D12
#define MICROPY_HW_SPI1_MOSI        (pin_A7)  // Arduino D11
#define MICROPY_HW_SPI2_NSS         (pin_B12)
#define MICROPY_HW_SPI2_SCK         (pin_B13)
#define MICROPY_HW_SPI2_MISO        (pin_B14)
#define MICROPY_HW_SPI2_MOSI        (pin_B15)
#define MICROPY_HW_SPI3_NSS         (pin_A15)
#define MICROPY_HW_SPI3_SCK         (pin_C10)
#define MICROPY_HW_SPI3_MISO        (pin_C11)
#define MICROPY_HW_SPI3_MOSI        (pin_C12)

// User button B1: external pull-up, pressed = low
#define MICROPY_HW_USRSW_PIN        (pin_C13)
#define MICROPY_HW_USRSW_PULL       (GPIO_NOPULL)
#define MICROPY_HW_USRSW_EXTI_MODE  (GPIO_MODE_IT_FALLING)
#define MICROPY_HW_USRSW_PRESSED    (0)

// LED LD2 (green), active high
#define MICROPY_HW_LED1             (pin_A5)
#define MICROPY_HW_LED_ON(pin)      (mp_hal_pin_high(pin))
#define MICROPY_HW_LED_OFF(pin)     (mp_hal_pin_low(pin))

// The MicroPython features the firmware and the board tools never use (docs/image.md)
#include "../ins_features.h"
// ... and the VM options the firmware's timing rests on
#include "../ins_vm.h"
