/* Start-up of a Cortex-M4F: the vector table, .data and .bss, the FPU enabled, then main(). */
#include <stdint.h>

extern uint32_t _estack, _sidata, _sdata, _edata, _sbss, _ebss;
int main(void);
void Reset_Handler(void);
void Default_Handler(void);
void SysTick_Handler(void) __attribute__((weak, alias("Default_Handler")));
void USART_Handler(void) __attribute__((weak, alias("Default_Handler")));

void Default_Handler(void)
{
    for (;;) {
    }
}

/* the core exceptions, then 82 device interrupts (USART2 is IRQ 38 on an STM32F4); the first
 * entry is the initial stack pointer */
typedef union {
    void (*handler)(void);
    uint32_t *stack;
} vector_t;

__attribute__((section(".isr_vector"), used)) const vector_t vectors[16 + 82] = {
    {.stack = &_estack},       {.handler = Reset_Handler},   {.handler = Default_Handler},
    {.handler = Default_Handler}, {.handler = Default_Handler}, {.handler = Default_Handler},
    {.handler = Default_Handler}, {0}, {0}, {0}, {0}, {.handler = Default_Handler},
    {.handler = Default_Handler}, {0}, {.handler = Default_Handler},
    {.handler = SysTick_Handler}, [16 + 38] = {.handler = USART_Handler},
};

void Reset_Handler(void)
{
    uint32_t *src = &_sidata, *dst = &_sdata;
    while (dst < &_edata)
        *dst++ = *src++;
    for (dst = &_sbss; dst < &_ebss;)
        *dst++ = 0;
    *(volatile uint32_t *)0xE000ED88u |= 0xFu << 20; /* CPACR: CP10, CP11 full access */
    __asm volatile("dsb\n isb");
    main();
    for (;;) {
    }
}
