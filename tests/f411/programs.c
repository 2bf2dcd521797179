/* Small bare-metal programs for the emulated STM32F411's own tests (tests/f411): each one
 * exercises a part of the twin the way the image does, and leaves its results in RAM
 * (the `result` and `data` globals) for the test to read. Built by conftest.py with the
 * Debian arm-none-eabi-gcc, one binary per program (-DPROGRAM_<NAME>). */
#include <stdint.h>
#include "stm32f411xe.h"

extern uint32_t _estack, _sidata, _sdata, _edata, _sbss, _ebss;
volatile uint32_t result;
volatile uint32_t data[64];
volatile uint32_t counter;
volatile uint32_t done;
__attribute__((section(".noinit"))) volatile uint32_t boots;  /* survive a reset */
__attribute__((section(".noinit"))) volatile uint32_t csr_at_boot[4];
__attribute__((section(".noinit"))) volatile uint32_t kept[8];

int main(void);
void Reset_Handler(void) {
    uint32_t *s = &_sidata, *d = &_sdata;
    while (d < &_edata) {
        *d++ = *s++;
    }
    for (d = &_sbss; d < &_ebss;) {
        *d++ = 0;
    }
    SCB->CPACR |= (0xFu << 20); /* FPU on, as the port's SystemInit does */
    main();
    for (;;) {
        __WFI();
    }
}

void Default_Handler(void) {
    result = 0xDEAD0000u | (SCB->ICSR & 0x1FF);
    for (;;) {
    }
}

void SysTick_Handler(void);
void IRQ0_Handler(void);
void IRQ1_Handler(void);
void IRQ2_Handler(void);
__attribute__((section(".isr_vector"))) void (*const vectors[16 + 86])(void) = {
    [0] = (void (*)(void))&_estack,
    [1] = Reset_Handler,
    [2 ... 14] = Default_Handler,
    [15] = SysTick_Handler,
    [16] = IRQ0_Handler,
    [17] = IRQ1_Handler,
    [18] = IRQ2_Handler,
    [19 ... 101] = Default_Handler,
};

static void systick_start(uint32_t load) {
    SysTick->LOAD = load;
    SysTick->VAL = 0;
    SysTick->CTRL = SysTick_CTRL_CLKSOURCE_Msk | SysTick_CTRL_TICKINT_Msk |
                    SysTick_CTRL_ENABLE_Msk;
}

#if defined(PROGRAM_SYSTICK)
/* SysTick at 1 kHz on the 16 MHz HSI; the core sleeps in WFI between ticks */
void SysTick_Handler(void) {
    counter++;
}
void IRQ0_Handler(void) {}
void IRQ1_Handler(void) {}
void IRQ2_Handler(void) {}
int main(void) {
    systick_start(16000 - 1);
    for (;;) {
        __WFI();
        data[counter & 63] = SysTick->VAL;
    }
}

#elif defined(PROGRAM_PRESERVE)
/* Interrupts every few hundred cycles whose handler clobbers the caller-saved registers,
 * integer and floating point, while the main loop computes with them. */
void SysTick_Handler(void) {
    counter++;
    __asm volatile(
        "mov r0, #0x55\n mov r1, #0x55\n mov r2, #0x55\n mov r3, #0x55\n mov r12, r0\n"
        "vmov s0, r0\n vmov s1, r0\n vmov s2, r0\n vmov s3, r0\n vmov s8, r0\n vmov s15, r0\n"
        "vmsr fpscr, r0\n" ::: "r0", "r1", "r2", "r3", "r12", "s0", "s1", "s2", "s3", "s8",
        "s15");
}
void IRQ0_Handler(void) {}
void IRQ1_Handler(void) {}
void IRQ2_Handler(void) {}
int main(void) {
    systick_start(399);
    float acc = 0.0f;
    uint32_t sum = 0;
    for (uint32_t i = 1; i <= 20000; i++) {
        acc = acc * 0.5f + (float)i;
        sum += i ^ (sum << 1);
    }
    SysTick->CTRL = 0;
    float expect = 0.0f;
    uint32_t sum2 = 0;
    for (uint32_t i = 1; i <= 20000; i++) {
        expect = expect * 0.5f + (float)i;
        sum2 += i ^ (sum2 << 1);
    }
    data[0] = counter;
    result = (acc == expect && sum == sum2) ? 1 : 2;
    done = 1;
    for (;;) {
        __WFI();
    }
}

#elif defined(PROGRAM_NESTING)
/* IRQ0 (low priority) pends IRQ2 (high) and IRQ1 (same as its own): IRQ2 preempts it at
 * once, IRQ1 waits for it to return. Then BASEPRI at IRQ2's priority holds it back until
 * BASEPRI is raised above it, and PRIMASK with WFI: the pending interrupt ends the sleep but
 * runs only after CPSIE. */
static volatile uint32_t n;
void SysTick_Handler(void) {}
void IRQ0_Handler(void) {
    data[n++] = 0x10;
    NVIC->STIR = 2;
    data[n++] = 0x11;
    NVIC->ISPR[0] = 1u << 1;
    data[n++] = 0x12;
}
void IRQ1_Handler(void) {
    data[n++] = 0x20;
}
void IRQ2_Handler(void) {
    data[n++] = 0x30;
}
int main(void) {
    NVIC_SetPriorityGrouping(3);
    NVIC_SetPriority(0, 8);
    NVIC_SetPriority(1, 8);
    NVIC_SetPriority(2, 2);
    NVIC->ISER[0] = 7;
    NVIC->STIR = 0;
    data[n++] = 0x01;
    __set_BASEPRI(2 << 4);
    NVIC->STIR = 2;
    data[n++] = 0x02;
    __set_BASEPRI(3 << 4);
    data[n++] = 0x03;
    __set_BASEPRI(0);
    __disable_irq();
    NVIC->STIR = 1;
    __WFI();
    data[n++] = 0x05;
    __enable_irq();
    data[n++] = 0x06;
    result = n;
    done = 1;
    for (;;) {
        __WFI();
    }
}

#elif defined(PROGRAM_UNMODELLED)
void SysTick_Handler(void) {}
void IRQ0_Handler(void) {}
void IRQ1_Handler(void) {}
void IRQ2_Handler(void) {}
__attribute__((noinline)) uint32_t read_timer(void) {
    RCC->APB1ENR |= RCC_APB1ENR_TIM2EN;
    return TIM2->CNT;
}
__attribute__((noinline)) uint32_t read_rcc_reserved(void) {
    return *(volatile uint32_t *)(RCC_BASE + 0xA0);
}
int main(void) {
    result = data[0] ? read_rcc_reserved() : read_timer();
    done = 1;
    return 0;
}

#elif defined(PROGRAM_USART)
/* USART1 at 9600 baud from the 16 MHz HSI, ten characters polled on TXE, then TC */
void SysTick_Handler(void) {}
void IRQ0_Handler(void) {}
void IRQ1_Handler(void) {}
void IRQ2_Handler(void) {}
int main(void) {
    RCC->APB2ENR |= RCC_APB2ENR_USART1EN;
    USART1->BRR = 16000000 / 9600;
    USART1->CR1 = USART_CR1_UE | USART_CR1_TE;
    for (int i = 0; i < 10; i++) {
        while (!(USART1->SR & USART_SR_TXE)) {
        }
        USART1->DR = 'a' + i;
    }
    while (!(USART1->SR & USART_SR_TC)) {
    }
    done = 1;
    for (;;) {
        __WFI();
    }
}

#elif defined(PROGRAM_FLASH)
/* Erase sector 2, program two words into it; data[0] = what a store without PG leaves */
void SysTick_Handler(void) {}
void IRQ0_Handler(void) {}
void IRQ1_Handler(void) {}
void IRQ2_Handler(void) {}
#define WORD0 (*(volatile uint32_t *)0x08008000)
#define WORD1 (*(volatile uint32_t *)0x08008004)
int main(void) {
    FLASH->KEYR = 0x45670123;
    FLASH->KEYR = 0xCDEF89AB;
    FLASH->CR = FLASH_CR_SER | (2 << FLASH_CR_SNB_Pos) | FLASH_CR_PSIZE_1;
    FLASH->CR |= FLASH_CR_STRT;
    while (FLASH->SR & FLASH_SR_BSY) {
    }
    data[1] = WORD0;
    FLASH->CR = FLASH_CR_PG | FLASH_CR_PSIZE_1;
    WORD0 = 0x12345678;
    while (FLASH->SR & FLASH_SR_BSY) {
    }
    WORD1 = 0x9ABCDEF0;
    while (FLASH->SR & FLASH_SR_BSY) {
    }
    FLASH->CR = FLASH_CR_LOCK;
    data[2] = WORD0;
    data[3] = WORD1;
    done = 1;
    if (result == 7) {
        WORD1 = 0; /* without PG: the twin stops here */
    }
    for (;;) {
        __WFI();
    }
}

#elif defined(PROGRAM_IWDG)
/* The independent watchdog at 10 ms, fed `counter` times on the first boot, then not: it
 * resets the chip; the second boot reads why (RCC_CSR) and stops. */
void SysTick_Handler(void) {}
void IRQ0_Handler(void) {}
void IRQ1_Handler(void) {}
void IRQ2_Handler(void) {}
int main(void) {
    boots++;
    csr_at_boot[boots & 3] = RCC->CSR;
    if (boots > 1) {
        done = 1;
        for (;;) {
            __WFI();
        }
    }
    RCC->CSR |= RCC_CSR_RMVF;
    IWDG->KR = 0xCCCC;
    IWDG->KR = 0x5555;
    IWDG->PR = 0;   /* LSI / 4 */
    IWDG->RLR = 79; /* 80 counts: 10 ms */
    while (IWDG->SR) {
    }
    IWDG->KR = 0xAAAA;
    for (;;) {
    }
}
#elif defined(PROGRAM_BACKUP)
/* The RTC backup register BKP18R (the firmware's maintenance marker) across a system reset: a
 * write without PWR_CR.DBP is ignored; one with it survives SYSRESETREQ, which clears DBP
 * (PWR is reset, its clock too). The reset comes with interrupts masked and SysTick running:
 * the core starts again with PRIMASK and BASEPRI clear, and no SysTick interrupt of the old
 * count follows. kept[] (.noinit) carries the readings across the reset. */
void SysTick_Handler(void) {
    counter++;
}
void IRQ0_Handler(void) {}
void IRQ1_Handler(void) {}
void IRQ2_Handler(void) {}
int main(void) {
    boots++;
    if (boots == 1) {
        RTC->BKP18R = 0x1111; /* DBP clear: ignored */
        kept[0] = RTC->BKP18R;
        RCC->APB1ENR |= RCC_APB1ENR_PWREN;
        PWR->CR |= PWR_CR_DBP;
        RTC->BKP18R = 0x2222;
        kept[1] = RTC->BKP18R;
        systick_start(1599); /* every 100 us at 16 MHz */
        __set_BASEPRI(0x40);
        __disable_irq();
        NVIC_SystemReset();
    }
    kept[5] = __get_PRIMASK();
    kept[6] = __get_BASEPRI();
    kept[2] = RTC->BKP18R;
    RCC->APB1ENR |= RCC_APB1ENR_PWREN;
    kept[3] = PWR->CR & PWR_CR_DBP;
    RTC->BKP18R = 0x3333; /* DBP clear again: ignored */
    kept[4] = RTC->BKP18R;
    for (volatile uint32_t i = 0; i < 2000; i++) { /* ~1 ms: ten periods of the old SysTick */
    }
    kept[7] = counter;
    done = 1;
    for (;;) {
        __WFI();
    }
}
#else
#error "no PROGRAM_ defined"
#endif
