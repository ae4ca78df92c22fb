/*
 * The firmware on a Cortex-M4F board at 168 MHz: the core's hardware table over a few board
 * functions, the 10 kHz tick on SysTick, the UART through two rings.
 *
 * What a lab writes for its board (weak stubs here, so the image links and runs in QEMU):
 *   board_init()            clocks (168 MHz), the encoder timer, the current amplifier's
 *                           DAC/PWM, the UART at 2 Mbaud 8N1 with its RX interrupt, the RNG
 *   board_encoder_counts()  the master's depth in counts of 0.1 um (+ into the patient)
 *   board_current_out(A)    the motor current command, held until the next tick
 *   board_uart_kick_tx()    start sending (enable the TX-empty interrupt, or a DMA transfer)
 *                           of the bytes board_uart_tx_byte() hands out
 *   board_random_u32()      a hardware random number (the session nonce)
 * and, from its UART interrupt, board_uart_rx_byte(b) for each byte received and
 * board_uart_tx_byte(&b) for each byte to send. The main loop decodes the received bytes in
 * the background (COBS, CRC-32C: fw_receive queues the checked frames); the tick interrupt
 * handles at most POLL_PER_TICK of them (fw_poll: sessions, commands, replies) and runs the
 * control tick (fw_tick), so a tick's time does not grow with the frames on the line.
 */
#include <stdint.h>

#include "../fw.h"

#define SYSCLK_HZ 168000000u
#define RX_CHUNK 64u
#define POLL_PER_TICK 2u

__attribute__((weak)) void board_init(void) {}
__attribute__((weak)) int32_t board_encoder_counts(void) { return 0; }
__attribute__((weak)) void board_current_out(float amps) { (void)amps; }
__attribute__((weak)) void board_uart_kick_tx(void) {}
__attribute__((weak)) uint32_t board_random_u32(void) { return 0x2545F491u; }
__attribute__((weak)) int board_end_stop(void) { return 0; }

/* single-producer single-consumer rings (the UART interrupt on one side, the tick on the other) */
static volatile uint8_t rx_ring[1024];
static volatile uint32_t rx_head, rx_tail;
static volatile uint8_t tx_ring[4096];
static volatile uint32_t tx_head, tx_tail;

void board_uart_rx_byte(uint8_t b)
{
    uint32_t h = rx_head;
    if (h - rx_tail < sizeof rx_ring) { /* full: the byte is lost, like an overrun */
        rx_ring[h % sizeof rx_ring] = b;
        rx_head = h + 1u;
    }
}

int board_uart_tx_byte(uint8_t *b)
{
    uint32_t t = tx_tail;
    if (t == tx_head)
        return 0;
    *b = tx_ring[t % sizeof tx_ring];
    tx_tail = t + 1u;
    return 1;
}

static int32_t hal_encoder(void *ctx)
{
    (void)ctx;
    return board_encoder_counts();
}

static void hal_current(void *ctx, real_t amps)
{
    (void)ctx;
    board_current_out((float)amps);
}

static void hal_uart(void *ctx, const uint8_t *data, size_t n)
{
    size_t i;
    uint32_t h = tx_head;
    (void)ctx;
    if (h - tx_tail + n > sizeof tx_ring)
        return; /* the host is not reading: dropped, like a full FIFO */
    for (i = 0; i < n; i++)
        tx_ring[(h + i) % sizeof tx_ring] = data[i];
    tx_head = h + (uint32_t)n;
    board_uart_kick_tx();
}

static void hal_timer(void *ctx, uint32_t tick_hz)
{
    (void)ctx;
    *(volatile uint32_t *)0xE000E014u = SYSCLK_HZ / tick_hz - 1u; /* SYST_RVR */
    *(volatile uint32_t *)0xE000E018u = 0u;                     /* SYST_CVR */
    *(volatile uint32_t *)0xE000E010u = 7u; /* SYST_CSR: processor clock, interrupt, enable */
}

static uint32_t hal_random(void *ctx)
{
    (void)ctx;
    return board_random_u32();
}

static int hal_end_stop(void *ctx)
{
    (void)ctx;
    return board_end_stop();
}

static fw_device device;

const fw_device *board_device(void) { return &device; }

/* one tick (the SysTick interrupt): the frames decoded since, then the control tick */
void board_tick(void)
{
    fw_poll(&device, POLL_PER_TICK);
    fw_tick(&device);
}

/* the background (main loop): decode what the UART brought */
void board_receive(void)
{
    uint8_t buf[RX_CHUNK];
    uint32_t n = 0, t = rx_tail;
    while (n < RX_CHUNK && t != rx_head) {
        buf[n++] = rx_ring[t % sizeof rx_ring];
        t++;
    }
    rx_tail = t;
    if (n)
        fw_receive(&device, buf, n);
}

void SysTick_Handler(void) { board_tick(); }

void board_start(void)
{
    fw_hal hal = {0};
    hal.encoder_counts = hal_encoder;
    hal.current_out = hal_current;
    hal.uart_write = hal_uart;
    hal.timer_start = hal_timer;
    hal.random_u32 = hal_random;
    hal.end_stop = hal_end_stop;
    board_init();
    fw_init(&device, &hal);
    device.defer = 1; /* frames decoded in the background, handled in the tick */
}

#ifndef FW_NO_MAIN
int main(void)
{
    board_start();
    for (;;) {
        board_receive();
        __asm volatile("wfi"); /* until the next byte or tick */
    }
}
#endif
