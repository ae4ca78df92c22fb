/*
 * How long one tick takes on a Cortex-M4F: the board's tick (fw_poll, then fw_tick)
 * run under QEMU's netduinoplus2 (an STM32F405 Cortex-M4F at 168 MHz) with -icount shift=0,
 * where every instruction advances the virtual clock by 1 ns; the free-running SysTick, on the
 * 168 MHz processor clock of that virtual time, brackets each tick. `make firmware-cycles`
 * prints the instructions per tick (calibrated on a loop of known length) and what they cost.
 *
 * The session: HELLO, a 64-row table uploaded in four 16-row chunks (the longest frames),
 * ARM, then the master driven into the material at 50 mm/s to the stop, held 0.3 mm into the
 * wall (cutting with vibration, the stop, the wall, the thermal limit), a HEARTBEAT every
 * 10 ms and a refused 16-row chunk (a longest frame decoded in a tick) every 5 ms, telemetry
 * every 10 ticks.
 */
#include <stdint.h>

#include "../fw.h"

void board_start(void);
void board_tick(void);
void board_receive(void);
void board_uart_rx_byte(uint8_t b);
const fw_device *board_device(void);

#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)

static int32_t encoder;
int32_t board_encoder_counts(void) { return encoder; }
uint32_t board_random_u32(void) { return 0x2545F491u; }

static void semihost(int op, const void *arg)
{
    register int r0 __asm("r0") = op;
    register const void *r1 __asm("r1") = arg;
    __asm volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
}

static void say(const char *s) { semihost(0x04, s); }

static void say_u(const char *label, uint32_t v)
{
    char buf[16];
    int i = 15;
    buf[i] = 0;
    do {
        buf[--i] = (char)('0' + v % 10u);
        v /= 10u;
    } while (v && i > 0);
    say(label);
    say(buf + i);
    say("\n");
}

static uint32_t seq;
/* the host's bytes, delivered at 2 Mbaud: 20 a tick */
static uint8_t line[8192];
static uint32_t line_len, line_at;

static void send(uint8_t type, const uint8_t *body, size_t n, uint32_t session)
{
    uint8_t out[FW_MAX_ENCODED + 1];
    size_t len = fw_encode_frame(type, ++seq, session, 0, body, n, out), i;
    for (i = 0; i < len && line_len < sizeof line; i++)
        line[line_len++] = out[i];
}

static uint32_t worst_receive;

/* 20 bytes off the line into the UART ring and decoded in the background (measured apart) */
static void uart_tick(void)
{
    uint32_t k, a, b;
    for (k = 0; k < 20u && line_at < line_len; k++)
        board_uart_rx_byte(line[line_at++]);
    if (line_at == line_len)
        line_at = line_len = 0;
    a = SYST_CVR;
    board_receive();
    b = SYST_CVR;
    if (((a - b) & 0xFFFFFFu) > worst_receive)
        worst_receive = (a - b) & 0xFFFFFFu;
}

static void put_f32(uint8_t *p, float f)
{
    union { float f; uint32_t u; } v;
    v.f = f;
    p[0] = (uint8_t)v.u;
    p[1] = (uint8_t)(v.u >> 8);
    p[2] = (uint8_t)(v.u >> 16);
    p[3] = (uint8_t)(v.u >> 24);
}

static uint32_t measure(void)
{
    uint32_t a = SYST_CVR, b;
    board_tick();
    b = SYST_CVR;
    return (a - b) & 0xFFFFFFu;
}

static uint32_t calibrate(void)
{
    /* 1000 iterations of 4 instructions (3 adds and the branch) plus the loop's setup */
    uint32_t a, b, n = 1000u;
    a = SYST_CVR;
    __asm volatile("1: adds %0, %0, #0\n adds %0, %0, #0\n subs %0, %0, #1\n bne 1b\n"
                   : "+r"(n));
    b = SYST_CVR;
    return (a - b) & 0xFFFFFFu; /* SysTick counts for about 4000 instructions */
}

int main(void)
{
    const uint32_t session = 0x2545F491u;
    uint8_t body[FW_MAX_DECODED];
    uint32_t k, tick, per4000, worst = 0, worst_armed = 0, sum_armed = 0, n_armed = 0;
    uint32_t crc;
    board_start();
    SYST_CSR = 0u; /* no tick interrupt here: the loop below calls the tick itself */
    SYST_RVR = 0xFFFFFFu;
    SYST_CVR = 0u;
    SYST_CSR = 5u; /* processor clock, free-running */
    per4000 = calibrate();

    body[0] = 3; body[1] = 1; body[2] = body[3] = body[4] = 0;
    send(FW_HELLO, body, 5, 0);
    body[0] = 64; body[1] = 0;
    put_f32(body + 2, 0.1f); put_f32(body + 6, 0.25f); put_f32(body + 10, 30.0f);
    put_f32(body + 14, 60.0f); put_f32(body + 18, 5.0f);
    crc = fw_crc32(0u, body, 22);
    send(FW_PROFILE_BEGIN, body, 22, session);
    for (k = 0; k < 4u; k++) {
        uint32_t r;
        body[0] = (uint8_t)(16u * k); body[1] = 0; body[2] = 16;
        for (r = 0; r < 16u; r++) {
            put_f32(body + 3 + 12u * r, 4.0f);
            put_f32(body + 7 + 12u * r, 0.5f);
            put_f32(body + 11 + 12u * r, 0.2f);
        }
        crc = fw_crc32(crc, body + 3, 192);
        send(FW_PROFILE_CHUNK, body, 195, session);
    }
    body[0] = 64; body[1] = 0;
    body[2] = (uint8_t)crc; body[3] = (uint8_t)(crc >> 8);
    body[4] = (uint8_t)(crc >> 16); body[5] = (uint8_t)(crc >> 24);
    send(FW_PROFILE_END, body, 6, session);
    body[0] = (uint8_t)crc; body[1] = (uint8_t)(crc >> 8);
    body[2] = (uint8_t)(crc >> 16); body[3] = (uint8_t)(crc >> 24);
    send(FW_ARM, body, 4, session);

    for (tick = 0; tick < 30000u; tick++) {
        uint32_t c;
        int armed = tick >= 200u;
        if (armed && encoder < 53000) /* 50 mm/s to 0.3 mm past the 5 mm stop */
            encoder += 50;
        if (tick % 100u == 0u)
            send(FW_HEARTBEAT, body, 0, session);
        if (armed && tick % 50u == 25u) {
            body[0] = 0; body[1] = 1; body[2] = 16; /* refused: no upload open */
            send(FW_PROFILE_CHUNK, body, 195, session);
        }
        uart_tick();
        c = measure();
        if (c > worst)
            worst = c;
        if (armed) {
            if (c > worst_armed)
                worst_armed = c;
            sum_armed += c;
            n_armed++;
        }
    }
    say_u("calibration systick counts per 4000 instructions: ", per4000);
    say_u("worst tick systick counts: ", worst);
    say_u("worst armed tick systick counts: ", worst_armed);
    say_u("mean armed tick systick counts x100: ", (uint32_t)((100ull * sum_armed) / n_armed));
    say_u("armed ticks: ", n_armed);
    say_u("worst background decode systick counts: ", worst_receive);
    {
        const fw_device *d = board_device();
        say_u("final state: ", d->r.state);
        say_u("faults since ARM: ", d->r.faults);
        say_u("drill um: ", (uint32_t)(d->r.drill_mm * 1000.0f));
        say_u("frames refused: ", d->frames_rejected);
        say_u("frames dropped: ", d->rxq_dropped);
        say_u("device frames sent: ", d->seq);
    }
    semihost(0x18, (const void *)0x20026u); /* SYS_EXIT: ADP_Stopped_ApplicationExit */
    for (;;) {
    }
}
