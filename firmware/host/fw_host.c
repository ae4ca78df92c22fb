/*
 * The host build's hardware: the simulated master of haptics/plant.py (a 0.5 kg stage with
 * Coulomb friction and end stops, integrated exactly under the held current), the simulated
 * hand of haptics/emulator.py (SIM_OPERATOR), a UART that collects the device's bytes, a
 * nonce queue the caller fills (so a seeded session matches the Python emulator's), and a
 * real-time loop on a file descriptor (`ctdrill emulate --core c`). Not part of the core:
 * this file may use the C library and the operating system.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <fenv.h>
#include <math.h>
#include <sched.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <time.h>
#include <unistd.h>

#include "../fw.h"

#define PLANT_MASS_KG 0.5
#define PLANT_KT 33.0
#define PLANT_COULOMB_N 1.0
#define ENCODER_M 0.1e-6
#define TRAVEL_LO_M (-20.0 * 1e-3)
#define TRAVEL_HI_M (60.0 * 1e-3)
#define HAND_K 5.0
#define HAND_B 0.05
#define HAND_MAX_N 78.0
#define HAND_MAX_FEED 200.0
#define OUT_CAP (1u << 20)
#define NONCES 512u
#define REC_COLS 6u
/* the pacer hands the host's bytes to the device only while the tick count is a multiple of
 * this (haptics/realtime.py RECEIVE_EVERY_TICKS: every ms, the same tick phase on either core) */
#define RECEIVE_EVERY_TICKS 10u

typedef struct fw_host {
    fw_device dev;
    /* plant (SI, double: the simulated hardware) */
    double x_m, v_m_s, current_a;
    int at_end_stop;
    /* hand */
    uint8_t op_kind;
    double op_value, feed_ref_mm, hand_n;
    /* uart */
    uint8_t out[OUT_CAP];
    size_t out_len;
    uint64_t out_dropped;
    /* nonces */
    uint32_t nonce[NONCES];
    unsigned nonce_head, nonce_tail;
    uint32_t xorshift;
    /* open-loop replay: encoder counts given per tick */
    const int32_t *replay;
    size_t replay_n, replay_i;
} fw_host;

static const double DT = 1.0 / FW_TICK_HZ;

static int32_t h_encoder(void *ctx)
{
    fw_host *h = (fw_host *)ctx;
    if (h->replay != NULL) {
        size_t i = h->replay_i < h->replay_n ? h->replay_i : h->replay_n - 1u;
        return h->replay[i];
    }
    return (int32_t)nearbyint(h->x_m / ENCODER_M);
}

static double hand_force(fw_host *h)
{
    if (h->op_kind == 1)
        return h->op_value;
    if (h->op_kind == 2) {
        double f;
        h->feed_ref_mm += h->op_value * DT;
        f = HAND_K * (h->feed_ref_mm - h->x_m * 1e3) + HAND_B * (h->op_value - h->v_m_s * 1e3);
        return f < -HAND_MAX_N ? -HAND_MAX_N : (f > HAND_MAX_N ? HAND_MAX_N : f);
    }
    return 0.0;
}

static void plant_step(fw_host *h, double current_a, double hand_n)
{
    double drive = PLANT_KT * current_a + hand_n;
    double v = h->v_m_s, fc = PLANT_COULOMB_N, friction, accel, v_new, x_new;
    if (v == 0.0) {
        if (-fc <= drive && drive <= fc)
            return; /* stiction */
        friction = drive > 0.0 ? fc : -fc;
    } else {
        friction = v > 0.0 ? fc : -fc;
    }
    accel = (drive - friction) / PLANT_MASS_KG;
    v_new = v + accel * DT;
    if (v != 0.0 && (v_new > 0.0) != (v > 0.0)) {
        x_new = h->x_m - 0.5 * v * v / accel;
        v_new = 0.0;
        if (fabs(drive) > fc) {
            double rest_s = DT + v / accel;
            accel = (drive - (drive > 0.0 ? fc : -fc)) / PLANT_MASS_KG;
            v_new = accel * rest_s;
            x_new += 0.5 * accel * rest_s * rest_s;
        }
    } else {
        x_new = h->x_m + v * DT + 0.5 * accel * DT * DT;
    }
    h->at_end_stop = 0;
    if (x_new < TRAVEL_LO_M) {
        x_new = TRAVEL_LO_M;
        v_new = 0.0;
        h->at_end_stop = 1;
    } else if (x_new > TRAVEL_HI_M) {
        x_new = TRAVEL_HI_M;
        v_new = 0.0;
        h->at_end_stop = 1;
    }
    h->x_m = x_new;
    h->v_m_s = v_new;
}

static void h_current(void *ctx, real_t amps)
{
    fw_host *h = (fw_host *)ctx;
    h->current_a = (double)amps;
    if (h->replay != NULL) {
        h->replay_i++;
        return;
    }
    /* the current is held through the tick: the hand acts and the stage moves */
    h->hand_n = hand_force(h);
    plant_step(h, (double)amps, h->hand_n);
}

static void h_uart(void *ctx, const uint8_t *data, size_t n)
{
    fw_host *h = (fw_host *)ctx;
    if (h->out_len + n > OUT_CAP) {
        h->out_dropped += n;
        return;
    }
    memcpy(h->out + h->out_len, data, n);
    h->out_len += n;
}

static uint32_t h_random(void *ctx)
{
    fw_host *h = (fw_host *)ctx;
    uint32_t x;
    if (h->nonce_head != h->nonce_tail) {
        x = h->nonce[h->nonce_head % NONCES];
        h->nonce_head++;
        return x;
    }
    x = h->xorshift; /* the queue ran dry: a local generator */
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    h->xorshift = x;
    return x ? x : 1u;
}

static int h_end_stop(void *ctx) { return ((fw_host *)ctx)->at_end_stop; }

static int h_sim_operator(void *ctx, uint8_t kind, float value)
{
    fw_host *h = (fw_host *)ctx;
    double v = (double)value, limit;
    if (kind > 2)
        return FW_NAK_BAD_VALUE;
    if (!isfinite(v))
        return FW_NAK_NONFINITE;
    if (kind == 2 && (h->op_kind != 2 || v != h->op_value))
        h->feed_ref_mm = h->x_m * 1e3;
    h->op_kind = kind;
    limit = kind == 1 ? HAND_MAX_N : HAND_MAX_FEED;
    h->op_value = v < -limit ? -limit : (v > limit ? limit : v);
    return 0;
}

static void h_sim_reset(void *ctx) { (void)ctx; }

fw_host *fw_host_new(double start_mm, uint32_t seed)
{
    fw_hal hal;
    fw_host *h = (fw_host *)calloc(1, sizeof(fw_host));
    if (h == NULL)
        return NULL;
    h->x_m = start_mm * 1e-3;
    h->xorshift = seed ? seed : 0x9E3779B9u;
    memset(&hal, 0, sizeof hal);
    hal.ctx = h;
    hal.encoder_counts = h_encoder;
    hal.current_out = h_current;
    hal.uart_write = h_uart;
    hal.random_u32 = h_random;
    hal.end_stop = h_end_stop;
    hal.sim_operator = h_sim_operator;
    hal.sim_reset = h_sim_reset;
    fw_init(&h->dev, &hal);
    /* as haptics/emulator.py: the controller starts at the stage's true position */
    fw_control_init(&h->dev.c, (real_t)start_mm, h_encoder(h));
    return h;
}

void fw_host_free(fw_host *h) { free(h); }

size_t fw_host_sizeof_device(void) { return sizeof(fw_device); }

int fw_host_real_is_double(void) { return FW_REAL_IS_DOUBLE; }

void fw_host_push_nonce(fw_host *h, uint32_t nonce)
{
    if (h->nonce_tail - h->nonce_head < NONCES) {
        h->nonce[h->nonce_tail % NONCES] = nonce;
        h->nonce_tail++;
    }
}

unsigned fw_host_nonces_queued(const fw_host *h) { return h->nonce_tail - h->nonce_head; }

/* floating-point exceptions raised inside the core's calls (invalid, divide by zero, overflow) */
static int fe_raised;
#define FE_WATCHED (FE_INVALID | FE_DIVBYZERO | FE_OVERFLOW)

int fw_host_fe_raised(void)
{
    int r = fe_raised;
    fe_raised = 0;
    return r;
}

void fw_host_receive(fw_host *h, const uint8_t *data, size_t n)
{
    feclearexcept(FE_ALL_EXCEPT);
    fw_receive(&h->dev, data, n);
    fe_raised |= fetestexcept(FE_WATCHED);
}

size_t fw_host_take(fw_host *h, uint8_t *out, size_t cap)
{
    size_t n = h->out_len < cap ? h->out_len : cap;
    memcpy(out, h->out, n);
    memmove(h->out, h->out + n, h->out_len - n);
    h->out_len -= n;
    return n;
}

size_t fw_host_pending(const fw_host *h) { return h->out_len; }

/* one row per tick: x (plant, mm), force_cmd_n, drill_mm, current_a, hand_est_n, state */
static void record(const fw_host *h, double *rec)
{
    rec[0] = h->x_m * 1e3;
    rec[1] = (double)h->dev.r.force_cmd_n;
    rec[2] = (double)h->dev.r.drill_mm;
    rec[3] = h->current_a;
    rec[4] = (double)h->dev.c.hand_est_n;
    rec[5] = (double)(h->dev.r.state | (h->dev.r.faults << 8));
}

void fw_host_run(fw_host *h, size_t n, double *rec)
{
    size_t i;
    feclearexcept(FE_ALL_EXCEPT);
    for (i = 0; i < n; i++) {
        fw_tick(&h->dev);
        if (rec != NULL)
            record(h, rec + REC_COLS * i);
    }
    fe_raised |= fetestexcept(FE_WATCHED);
}

/* the core on given encoder readings (open loop): counts[i] is tick i's, counts[i+1] what
 * its telemetry reads */
void fw_host_replay(fw_host *h, const int32_t *counts, size_t n, double *rec)
{
    size_t i;
    h->replay = counts;
    h->replay_n = n + 1u;
    for (i = 0; i < n; i++) {
        h->replay_i = i;
        fw_tick(&h->dev);
        if (rec != NULL) {
            record(h, rec + REC_COLS * i);
            rec[REC_COLS * i] = (double)counts[i] * ENCODER_M * 1e3;
        }
    }
    h->replay = NULL;
    h->x_m = (double)counts[n] * ENCODER_M; /* the stage stays where the recording left it */
    h->v_m_s = 0.0;
}

/* the board's split: frames decoded by fw_receive, handled by fw_poll (the tick's context) */
void fw_host_set_defer(fw_host *h, int on) { h->dev.defer = (uint8_t)(on != 0); }
unsigned fw_host_poll(fw_host *h, unsigned max) { return fw_poll(&h->dev, max); }
uint32_t fw_host_frames_dropped(const fw_host *h) { return h->dev.rxq_dropped; }

uint64_t fw_host_ticks(const fw_host *h) { return h->dev.ticks; }
uint32_t fw_host_overruns(const fw_host *h) { return h->dev.overruns; }
void fw_host_set_overruns(fw_host *h, uint32_t n) { h->dev.overruns = n; }
void fw_host_set_device_seq(fw_host *h, uint32_t seq) { h->dev.seq = seq; }
uint32_t fw_host_frames_rejected(const fw_host *h) { return h->dev.frames_rejected; }
uint32_t fw_host_session(const fw_host *h) { return h->dev.session; }
int fw_host_state(const fw_host *h) { return h->dev.r.state; }
double fw_host_position_mm(const fw_host *h) { return h->x_m * 1e3; }

/* ------------------------------------------------------------------ the real-time loop */

typedef struct fw_rt_stats {
    uint64_t wakeups, ticks, overruns, resyncs, dropped_bytes;
    double slipped_s, busy_s, late_max_s;
    int64_t t0_ns;   /* device time origin on CLOCK_MONOTONIC (tick n is due at t0 + n T) */
    int32_t started; /* t0 set */
    int32_t realtime; /* SCHED_FIFO obtained (1), refused (0) */
    uint64_t *late_bins;
    uint32_t n_bins;
    uint8_t pending[65536];
    uint32_t pending_len;
} fw_rt_stats;

size_t fw_rt_stats_size(void) { return sizeof(fw_rt_stats); }

static int64_t now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000000 + ts.tv_nsec;
}

static void record_late(fw_rt_stats *st, double late_s)
{
    /* 10 us bins: haptics/realtime.py LATE_BIN_S (tests/firmware/test_c_emulate.py checks) */
    uint64_t i = late_s > 0.0 ? (uint64_t)(late_s / 10e-6) : 0u;
    st->late_bins[i < st->n_bins ? i : st->n_bins - 1u] += 1u;
    if (late_s > st->late_max_s)
        st->late_max_s = late_s;
}

/* the host's bytes, all that have arrived, to the device */
static void take_in(fw_host *h, int fd)
{
    uint8_t buf[4096];
    ssize_t got;
    for (;;) {
        got = read(fd, buf, sizeof buf);
        if (got <= 0)
            break;
        fw_receive(&h->dev, buf, (size_t)got);
    }
}

static void flush_out(fw_host *h, int fd, fw_rt_stats *st)
{
    size_t room = sizeof st->pending - st->pending_len;
    ssize_t w;
    if (h->out_len > room) { /* the host is not reading: dropped, like a full UART FIFO */
        st->dropped_bytes += st->pending_len + h->out_len;
        st->pending_len = 0;
        h->out_len = 0;
        return;
    }
    memcpy(st->pending + st->pending_len, h->out, h->out_len);
    st->pending_len += (uint32_t)h->out_len;
    h->out_len = 0;
    if (st->pending_len == 0)
        return;
    w = write(fd, st->pending, st->pending_len);
    if (w < 0)
        w = (errno == EAGAIN || errno == EINTR) ? 0 : (ssize_t)st->pending_len; /* nobody listens */
    memmove(st->pending, st->pending + w, st->pending_len - (size_t)w);
    st->pending_len -= (uint32_t)w;
}

/*
 * Serve the device on fd (non-blocking) until CLOCK_MONOTONIC reaches until_ns or a signal
 * interrupts a sleep; returns 1 when interrupted. Each wakeup runs the ticks that have come
 * due (each one's lateness measured; the host's bytes handed in while the tick count is a
 * multiple of RECEIVE_EVERY_TICKS), writes the device's frames and sleeps to the next tick's
 * due time (timer slack 1 ns). A wakeup finding more than 5 ms
 * of ticks due is an overrun; over 20 ms the clock slips instead of replaying the backlog.
 */
int fw_host_serve(fw_host *h, int fd, int64_t until_ns, fw_rt_stats *st, int want_realtime)
{
    const int64_t tick_ns = 1000000000 / FW_TICK_HZ;
    prctl(PR_SET_TIMERSLACK, 1UL, 0, 0, 0);
    if (!st->started) {
        /* the lowest real-time priority where the system grants it (root, CAP_SYS_NICE,
         * an rtprio limit): a sleeping 10 kHz pacer then wakes on time on a loaded machine;
         * it uses a few per cent of a core, and the kernel's throttling bounds it anyway */
        struct sched_param sp;
        sp.sched_priority = 1;
        st->realtime = want_realtime && sched_setscheduler(0, SCHED_FIFO, &sp) == 0;
        st->t0_ns = now_ns() - (int64_t)h->dev.ticks * tick_ns;
        st->started = 1;
    }
    for (;;) {
        int64_t now = now_ns(), due_ns, next;
        int64_t due;
        struct timespec ts;
        if (now >= until_ns)
            return 0;
        st->wakeups++;
        if (h->dev.ticks % RECEIVE_EVERY_TICKS == 0u)
            take_in(h, fd);
        due = (now - st->t0_ns) / tick_ns - (int64_t)h->dev.ticks;
        if (due > 0) {
            double late = (double)(now - (st->t0_ns + ((int64_t)h->dev.ticks + 1) * tick_ns)) * 1e-9;
            double stall = 0.0;
            int64_t k, start, end;
            if (late > 0.005) {
                st->overruns++;
                h->dev.overruns++;
            }
            if (late > 0.020) {
                st->resyncs++;
                st->slipped_s += late;
                stall = late;
                st->t0_ns = now - ((int64_t)h->dev.ticks + 1) * tick_ns;
                due = 1;
            }
            for (k = 0; k < due; k++) {
                start = now_ns();
                record_late(st, stall > 0.0 ? stall
                                            : (double)(start - (st->t0_ns + ((int64_t)h->dev.ticks + 1) * tick_ns)) * 1e-9);
                fw_tick(&h->dev);
                if (h->dev.ticks % RECEIVE_EVERY_TICKS == 0u)
                    take_in(h, fd);
                end = now_ns();
                st->busy_s += (double)(end - start) * 1e-9;
                if (h->out_len > OUT_CAP / 2u)
                    flush_out(h, fd, st);
            }
            st->ticks += (uint64_t)due;
        }
        flush_out(h, fd, st);
        due_ns = st->t0_ns + ((int64_t)h->dev.ticks + 1) * tick_ns;
        next = due_ns < until_ns ? due_ns : until_ns;
        if (next > now_ns()) {
            ts.tv_sec = (time_t)(next / 1000000000);
            ts.tv_nsec = (long)(next % 1000000000);
            if (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL) == EINTR)
                return 1;
        }
    }
}
