/*
 * The device: frames in, sessions and sequence numbers, the state machine, the profile
 * upload, the tick with its telemetry (docs/protocol.md sections 2-6; haptics/emulator.py is
 * the reference, message for message).
 */
#include <math.h>

#include "fw.h"
#include "fw_law.h"

/* ------------------------------------------------------------------ little-endian fields */
static uint16_t get_u16(const uint8_t *p) { return (uint16_t)(p[0] | (p[1] << 8)); }
static uint32_t get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}
static float get_f32(const uint8_t *p)
{
    union { uint32_t u; float f; } v;
    v.u = get_u32(p);
    return v.f;
}
static void put_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}
static void put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}
static void put_f32(uint8_t *p, real_t x)
{
    union { uint32_t u; float f; } v;
    v.f = (float)x;
    put_u32(p, v.u);
}
static int finite_f(float x)
{
    union { uint32_t u; float f; } v;
    v.f = x;
    return (v.u & 0x7F800000u) != 0x7F800000u;
}

/* ------------------------------------------------------------------ sending */
static void send(fw_device *dev, uint8_t type, const uint8_t *body, size_t n, uint32_t session)
{
    uint8_t out[FW_MAX_ENCODED + 1];
    size_t len;
    dev->seq += 1u;
    len = fw_encode_frame(type, dev->seq, session,
                          dev->ticks * (uint64_t)(1000000u / FW_TICK_HZ), body, n, out);
    dev->hal.uart_write(dev->hal.ctx, out, len);
}

static void send_ack(fw_device *dev, uint8_t type, uint32_t seq, uint32_t session)
{
    uint8_t b[5];
    b[0] = type;
    put_u32(b + 1, seq);
    send(dev, FW_ACK, b, 5, session);
}

static void send_nak(fw_device *dev, uint8_t type, uint32_t seq, uint8_t reason)
{
    uint8_t b[6];
    b[0] = type;
    put_u32(b + 1, seq);
    b[5] = reason;
    send(dev, FW_NAK, b, 6, dev->session);
}

static void report_faults(fw_device *dev)
{
    uint8_t b[3];
    put_u16(b, dev->r.new_faults);
    b[2] = dev->r.state;
    send(dev, FW_FAULT, b, 3, dev->session);
    dev->r.new_faults = 0;
}

static real_t counts_mm(int32_t counts)
{
#if FW_REAL_IS_DOUBLE
    return (real_t)counts * R(1e-7) * R(1e3); /* as haptics/plant.py: counts * 1e-7 m * 1e3 */
#else
    return (real_t)counts * R(1e-4); /* one rounding */
#endif
}

static real_t encoder_mm(const fw_device *dev)
{
    return counts_mm(dev->hal.encoder_counts(dev->hal.ctx));
}

static void telemetry(fw_device *dev)
{
    uint8_t b[33];
    uint16_t faults = (uint16_t)(dev->r.faults | dev->boot_fault);
    if (dev->hal.end_stop != NULL && dev->hal.end_stop(dev->hal.ctx))
        faults |= FW_F_TRAVEL_LIMIT;
    put_u32(b, (uint32_t)dev->ticks);
    put_f32(b + 4, encoder_mm(dev));
    put_f32(b + 8, dev->r.drill_mm);
    put_f32(b + 12, dev->c.velocity_mm_s);
    put_f32(b + 16, dev->r.force_cmd_n);
    put_f32(b + 20, dev->c.hand_est_n);
    b[24] = dev->r.state;
    put_u16(b + 25, faults);
    put_u16(b + 27, (uint16_t)(dev->overruns < 0xFFFFu ? dev->overruns : 0xFFFFu));
    put_u32(b + 29, dev->table_crc32);
    send(dev, FW_TELEMETRY, b, 33, dev->session);
}

/* ------------------------------------------------------------------ state changes */
static void disarm(fw_renderer *r)
{
    if (r->state != FW_SAFE)
        r->state = FW_IDLE;
    r->force_cmd_n = R(0.0);
}

static void host_stop(fw_renderer *r)
{
    if (!(r->faults & FW_F_HOST_STOP))
        r->new_faults |= FW_F_HOST_STOP;
    r->faults |= FW_F_HOST_STOP;
    r->state = FW_SAFE;
    r->force_cmd_n = R(0.0);
}

static void clear_table(fw_device *dev)
{
    dev->r.last = -1;
    dev->r.front_mm = R(0.0);
#if !FW_REAL_IS_DOUBLE
    dev->r.front_lo = R(0.0);
#endif
    disarm(&dev->r);
}

static uint8_t arm(fw_device *dev)
{
    fw_renderer *r = &dev->r;
    real_t master = encoder_mm(dev);
    if (r->last < 0)
        return FW_NAK_NOT_READY;
    if (K_N_PER_MM * (master - r->front_mm) > ARM_MAX_FORCE_N)
        return FW_NAK_NOT_RETRACTED;
    r->state = r->front_mm >= r->stop_depth_mm ? FW_STOPPED : FW_CUTTING;
    r->faults = 0;
    r->new_faults = 0;
    r->hand_n = R(0.0);
    r->release_on = 1;
    r->pull_ticks = 0;
    r->last_host_tick = dev->ticks;
    r->arm_tick = dev->ticks;
#if !FW_REAL_IS_DOUBLE
    r->turn1 = r->turn2 = R(0.0);
#endif
    return FW_NAK_NONE;
}

#if !FW_REAL_IS_DOUBLE
/* x modulo 1 for x >= 0 (the vibration's turns a tick) without a float-to-int overflow */
static real_t frac_turns(real_t x)
{
    if (x >= R(8388608.0)) /* 2^23: every float this large is a whole number */
        return R(0.0);
    return x - (real_t)(int32_t)x;
}
#endif

static void install_table(fw_device *dev)
{
    fw_renderer *r = &dev->r;
#if FW_REAL_IS_DOUBLE
    r->inv_step = R(1.0) / (real_t)dev->up_step;
#else
    /* a step below 1e-30 mm would overflow its inverse: every depth is then off the table */
    r->inv_step = dev->up_step < 1e-30f ? R(1e30) : R(1.0) / dev->up_step;
    /* 1 / step = inv_step + inv_step_lo (to a float's rounding of the low part) */
    r->inv_step_lo =
        dev->up_step < 1e-30f ? R(0.0) : r->inv_step * fmaf(-dev->up_step, r->inv_step, R(1.0));
    r->turn1_step = frac_turns((real_t)dev->up_f1 * (real_t)(1.0 / FW_TICK_HZ));
    r->turn2_step = frac_turns((real_t)dev->up_f2 * (real_t)(1.0 / FW_TICK_HZ));
#endif
    r->last = (int32_t)dev->upload_n - 1;
    r->ke = (real_t)dev->up_ke;
    r->f1_hz = (real_t)dev->up_f1;
    r->f2_hz = (real_t)dev->up_f2;
    r->w1 = (real_t)(2.0 * 3.141592653589793) * (real_t)dev->up_f1;
    r->w2 = (real_t)(2.0 * 3.141592653589793) * (real_t)dev->up_f2;
    r->stop_depth_mm = (real_t)dev->up_stop;
    r->stop_anchor_mm = (real_t)INFINITY;
    r->front_mm = R(0.0);
#if !FW_REAL_IS_DOUBLE
    r->front_lo = R(0.0);
#endif
    disarm(r);
}

/* ------------------------------------------------------------------ commands */
static uint8_t profile_begin(fw_device *dev, const uint8_t *b)
{
    uint16_t n = get_u16(b);
    float step = get_f32(b + 2), ke = get_f32(b + 6), f1 = get_f32(b + 10), f2 = get_f32(b + 14);
    float stop = get_f32(b + 18);
    dev->uploading = 0;
    if (!(finite_f(step) && finite_f(ke) && finite_f(f1) && finite_f(f2) && finite_f(stop)))
        return FW_NAK_NONFINITE;
    if (n < 1u || n > FW_MAX_PROFILE_STEPS)
        return FW_NAK_PROFILE_TOO_LONG;
    if (step <= 0.0f || ke < 0.0f || f1 < 0.0f || f2 < 0.0f || stop < 0.0f)
        return FW_NAK_BAD_VALUE;
    clear_table(dev);
    dev->table_crc32 = dev->table_session = 0;
    dev->uploading = 1;
    dev->upload_n = n;
    dev->upload_rows = 0;
    dev->upload_crc = fw_crc32(0u, b, 22);
    dev->up_step = step;
    dev->up_ke = ke;
    dev->up_f1 = f1;
    dev->up_f2 = f2;
    dev->up_stop = stop;
    return FW_NAK_NONE;
}

static uint8_t profile_chunk(fw_device *dev, const uint8_t *b)
{
    uint16_t first = get_u16(b);
    uint8_t count = b[2], k;
    if (!dev->uploading || first != dev->upload_rows) {
        dev->uploading = 0;
        return FW_NAK_PROFILE_ORDER;
    }
    if ((uint32_t)dev->upload_rows + count > dev->upload_n) {
        dev->uploading = 0;
        return FW_NAK_PROFILE_TOO_LONG;
    }
    for (k = 0; k < count; k++) {
        const uint8_t *row = b + 3 + 12u * k;
        float s0 = get_f32(row), s1 = get_f32(row + 4), s2 = get_f32(row + 8);
        if (!(finite_f(s0) && finite_f(s1) && finite_f(s2))) {
            dev->uploading = 0;
            return FW_NAK_NONFINITE;
        }
        if (s0 < 0.0f) {
            dev->uploading = 0;
            return FW_NAK_BAD_VALUE;
        }
    }
    for (k = 0; k < count; k++) {
        const uint8_t *row = b + 3 + 12u * k;
        uint16_t i = (uint16_t)(dev->upload_rows + k);
        dev->s0[i] = get_f32(row);
        dev->s1[i] = get_f32(row + 4);
        dev->s2[i] = get_f32(row + 8);
    }
    dev->upload_crc = fw_crc32(dev->upload_crc, b + 3, 12u * count);
    dev->upload_rows = (uint16_t)(dev->upload_rows + count);
    return FW_NAK_NONE;
}

static uint8_t profile_end(fw_device *dev, const uint8_t *b)
{
    uint16_t n = get_u16(b);
    uint32_t crc = get_u32(b + 2);
    int was = dev->uploading;
    dev->uploading = 0;
    if (!was || n != dev->upload_n || dev->upload_rows != dev->upload_n)
        return FW_NAK_PROFILE_ORDER;
    if (dev->upload_crc != crc)
        return FW_NAK_PROFILE_CRC;
    install_table(dev);
    dev->table_crc32 = crc;
    dev->table_session = dev->session;
    return FW_NAK_NONE;
}

static uint8_t command(fw_device *dev, uint8_t type, const uint8_t *b)
{
    uint8_t reason;
    switch (type) {
    case FW_PROFILE_BEGIN:
        return profile_begin(dev, b);
    case FW_PROFILE_CHUNK:
        return profile_chunk(dev, b);
    case FW_PROFILE_END:
        return profile_end(dev, b);
    case FW_ARM:
        if (dev->r.last < 0 || dev->table_session != dev->session)
            return FW_NAK_NOT_READY;
        if (get_u32(b) != dev->table_crc32)
            return FW_NAK_PROFILE_CRC;
        reason = arm(dev);
        if (reason == FW_NAK_NONE)
            dev->boot_fault = 0;
        return reason;
    case FW_DISARM:
        disarm(&dev->r);
        return FW_NAK_NONE;
    case FW_STOP:
        host_stop(&dev->r);
        return FW_NAK_NONE;
    default:
        return FW_NAK_UNKNOWN_TYPE;
    }
}

static void handle(fw_device *dev, uint8_t type, uint32_t seq, const uint8_t *b)
{
    uint8_t reason;
    if (type == FW_HEARTBEAT)
        return;
    if (type == FW_SIM_OPERATOR || type == FW_SIM_RESET) {
        if (dev->hal.sim_operator == NULL || dev->hal.sim_reset == NULL) {
            send_nak(dev, type, seq, FW_NAK_UNKNOWN_TYPE); /* hardware: no simulated hand */
            return;
        }
        if (type == FW_SIM_OPERATOR) {
            reason = (uint8_t)dev->hal.sim_operator(dev->hal.ctx, b[0], get_f32(b + 1));
            if (reason != FW_NAK_NONE)
                send_nak(dev, type, seq, reason);
            return;
        }
        send_ack(dev, type, seq, dev->session); /* the last frame of the session */
        dev->hal.sim_reset(dev->hal.ctx);
        fw_reset(dev);
        dev->reset_pending = 1;
        return;
    }
    reason = command(dev, type, b);
    if (reason == FW_NAK_NONE)
        send_ack(dev, type, seq, dev->session);
    else
        send_nak(dev, type, seq, reason);
    if (dev->r.new_faults)
        report_faults(dev);
}

static void hello(fw_device *dev, uint32_t seq, const uint8_t *b)
{
    uint8_t v[12], l[24];
    uint32_t nonce;
    if (b[0] != FW_PROTOCOL_VERSION) {
        dev->frames_rejected++;
        send_nak(dev, FW_HELLO, seq, FW_NAK_BAD_VERSION);
        return;
    }
    nonce = dev->hal.random_u32(dev->hal.ctx);
    dev->session = nonce != 0u ? nonce : 1u;
    dev->host_seq = seq;
    dev->uploading = 0;
    disarm(&dev->r);
    dev->r.last_host_tick = dev->ticks;
    v[0] = (uint8_t)FW_PROTOCOL_VERSION;
    v[1] = FW_VERSION_MAJOR;
    v[2] = FW_VERSION_MINOR;
    v[3] = FW_VERSION_PATCH;
    put_u32(v + 4, FW_TICK_HZ);
    put_u32(v + 8, get_u32(b + 1));
    send(dev, FW_VERSION, v, 12, dev->session);
    put_f32(l, PEAK_FORCE_N);
    put_f32(l + 4, CONTINUOUS_FORCE_N);
    put_f32(l + 8, THERMAL_BUDGET_N2_S);
    put_u16(l + 12, FW_WATCHDOG_MS);
    put_u16(l + 14, FW_MAX_PROFILE_STEPS);
    put_f32(l + 16, TRAVEL_MIN_MM);
    put_f32(l + 20, TRAVEL_MAX_MM);
    send(dev, FW_LIMITS, l, 24, dev->session);
}

/* body size of each type (-1: undefined, -2: PROFILE_CHUNK, sized by its count) */
static int body_size(uint8_t type)
{
    switch (type) {
    case FW_HELLO: return 5;
    case FW_VERSION: return 12;
    case FW_LIMITS: return 24;
    case FW_PROFILE_BEGIN: return 22;
    case FW_PROFILE_CHUNK: return -2;
    case FW_PROFILE_END: return 6;
    case FW_ARM: return 4;
    case FW_DISARM: case FW_HEARTBEAT: case FW_STOP: case FW_SIM_RESET: return 0;
    case FW_SIM_OPERATOR: return 5;
    case FW_TELEMETRY: return 33;
    case FW_FAULT: return 3;
    case FW_ACK: return 5;
    case FW_NAK: return 6;
    default: return -1;
    }
}

static int device_type(uint8_t type)
{
    return type == FW_VERSION || type == FW_LIMITS || type == FW_TELEMETRY || type == FW_FAULT ||
           type == FW_ACK || type == FW_NAK;
}

/* a frame's fate after decoding: handled at once, or queued for fw_poll */
static void dispatch(fw_device *dev, const fw_packet *p);

static void deliver(fw_device *dev, fw_packet *p)
{
    if (!dev->defer) {
        dispatch(dev, p);
        return;
    }
    if (dev->rxq_head - dev->rxq_tail >= FW_RXQ) {
        dev->rxq_dropped++; /* the tick has not caught up: lost, like a UART overrun */
        return;
    }
    dev->rxq[dev->rxq_head % FW_RXQ] = *p;
    dev->rxq_head++; /* published after the copy (a single producer, a single consumer) */
}

static void refuse(fw_device *dev, uint8_t type, uint32_t seq, uint8_t reason)
{
    fw_packet p;
    p.nak = reason;
    p.type = type;
    p.seq = seq;
    p.session = 0;
    p.time_nonzero = 0;
    p.body_len = 0;
    deliver(dev, &p);
}

/* one frame between delimiters (COBS bytes, 1..256 of them): decoded and checked */
static void frame(fw_device *dev, const uint8_t *enc, size_t n)
{
    uint8_t raw[FW_MAX_ENCODED];
    int len = fw_cobs_decode(enc, n, raw, sizeof raw);
    uint8_t type;
    uint32_t seq;
    size_t body_len, i;
    int want;
    fw_packet p;
    if (len < 0 || len > (int)FW_MAX_DECODED || len < (int)(FW_HEADER_BYTES + 4u) ||
        get_u32(raw + len - 4) != fw_crc32c(raw, (size_t)len - 4u)) {
        refuse(dev, 0, 0, FW_NAK_BAD_FRAME);
        return;
    }
    if (raw[0] != FW_PROTOCOL_VERSION) {
        refuse(dev, 0, 0, FW_NAK_BAD_VERSION);
        return;
    }
    type = raw[1];
    seq = get_u32(raw + 2);
    body_len = (size_t)len - FW_HEADER_BYTES - 4u;
    want = body_size(type);
    if (want == -1) {
        refuse(dev, type, seq, FW_NAK_UNKNOWN_TYPE);
        return;
    }
    if (want == -2) {
        int count = body_len >= 3u ? raw[FW_HEADER_BYTES + 2] : -1;
        if (count < 1 || count > (int)FW_MAX_CHUNK_ROWS || body_len != 3u + 12u * (size_t)count)
            want = -3;
        else
            want = (int)body_len;
    }
    if (want != (int)body_len || device_type(type)) {
        /* a device->host type is looped back: dropped without a reply (section 2.3) */
        if (device_type(type))
            dev->frames_rejected++;
        else
            refuse(dev, type, seq, FW_NAK_BAD_LENGTH);
        return;
    }
    p.nak = 0;
    p.type = type;
    p.seq = seq;
    p.session = get_u32(raw + 6);
    p.time_nonzero = (get_u32(raw + 10) | get_u32(raw + 14)) != 0u;
    p.body_len = (uint8_t)body_len;
    for (i = 0; i < body_len; i++)
        p.body[i] = raw[FW_HEADER_BYTES + i];
    deliver(dev, &p);
}

/* what a checked frame does: session and sequence rules, then its command (tick context) */
static void dispatch(fw_device *dev, const fw_packet *p)
{
    uint8_t type = p->type;
    uint32_t seq = p->seq, session = p->session;
    const uint8_t *body = p->body;
    if (p->nak) {
        dev->frames_rejected++;
        send_nak(dev, type, seq, p->nak);
        return;
    }
    if (p->time_nonzero) {
        dev->frames_rejected++;
        send_nak(dev, type, seq, FW_NAK_BAD_HEADER);
        return;
    }
    if (type == FW_HELLO) {
        hello(dev, seq, body);
        return;
    }
    if (dev->session != 0u && session == dev->session && fw_seq_after(seq, dev->host_seq)) {
        dev->host_seq = seq;
        dev->r.last_host_tick = dev->ticks;
        handle(dev, type, seq, body);
        return;
    }
    if (type == FW_STOP || type == FW_DISARM) {
        /* the safe direction: from any host and any seq, acknowledged in its own session */
        if (type == FW_STOP)
            host_stop(&dev->r);
        else
            disarm(&dev->r);
        send_ack(dev, type, seq, session);
        if (dev->r.new_faults)
            report_faults(dev);
        return;
    }
    dev->frames_rejected++;
    send_nak(dev, type, seq,
             (dev->session != 0u && session == dev->session) ? FW_NAK_STALE_SEQUENCE
                                                             : FW_NAK_BAD_SESSION);
}

unsigned fw_poll(fw_device *dev, unsigned max)
{
    unsigned done = 0;
    while (done < max && dev->rxq_tail != dev->rxq_head) {
        dispatch(dev, &dev->rxq[dev->rxq_tail % FW_RXQ]);
        dev->rxq_tail++;
        done++;
    }
    return done;
}

void fw_receive(fw_device *dev, const uint8_t *data, size_t n)
{
    size_t i;
    dev->reset_pending = 0;
    for (i = 0; i < n; i++) {
        uint8_t byte = data[i];
        if (byte == 0) {
            if (dev->rx_overflow)
                dev->rx_overflow = 0;
            else if (dev->rx_len > 0)
                frame(dev, dev->rx, dev->rx_len);
            dev->rx_len = 0;
            continue;
        }
        if (dev->rx_overflow)
            continue;
        dev->rx[dev->rx_len++] = byte;
        if (dev->rx_len > FW_MAX_ENCODED) {
            /* a run longer than any frame: dropped up to the next delimiter, one NAK */
            dev->rx_len = 0;
            dev->rx_overflow = 1;
            refuse(dev, 0, 0, FW_NAK_BAD_FRAME);
        }
    }
    if (dev->reset_pending) {
        /* a power-cycle drops the partial frame it interrupted */
        dev->rx_len = 0;
        dev->rx_overflow = 0;
        dev->reset_pending = 0;
    }
}

/* ------------------------------------------------------------------ tick */
void fw_tick(fw_device *dev)
{
    real_t x, force, current;
    int32_t counts;
    dev->ticks += 1u;
    counts = dev->hal.encoder_counts(dev->hal.ctx);
    x = counts_mm(counts);
#if !FW_REAL_IS_DOUBLE
    /* the float's rounding of counts * 0.1 um (up to 1 nm at 20 mm): the breakthrough's 1 / S0
     * would amplify it */
    dev->r.master_lo = fmaf((real_t)counts, R(1e-4), -x) + (real_t)counts * (real_t)(1e-4 - (double)1e-4f);
#endif
    /* the velocity and hand estimates are the previous tick's */
    force = fw_render_tick(dev, x, dev->c.velocity_mm_s, dev->c.hand_est_n);
    if (dev->r.state == FW_CUTTING || dev->r.state == FW_STOPPED)
        current = fw_control_update(&dev->c, counts, x, force);
    else
        current = fw_control_idle(&dev->c, counts, x);
    dev->hal.current_out(dev->hal.ctx, current);
    if (dev->r.new_faults)
        report_faults(dev);
    if (dev->ticks % FW_TELEMETRY_EVERY == 0u)
        telemetry(dev);
}

void fw_note_overrun(fw_device *dev) { dev->overruns++; }

void fw_reset(fw_device *dev)
{
    /* the stage stays where it is; the controller starts from the encoder */
    fw_render_init(&dev->r);
    {
        int32_t counts = dev->hal.encoder_counts(dev->hal.ctx);
        fw_control_init(&dev->c, counts_mm(counts), counts);
    }
    dev->uploading = 0;
    dev->rx_len = 0;
    dev->rx_overflow = 0;
    dev->boot_fault = FW_F_RESET;
    dev->session = 0;
    dev->host_seq = 0;
    dev->seq = 0;
    dev->table_crc32 = dev->table_session = 0;
}

void fw_init(fw_device *dev, const fw_hal *hal)
{
    dev->hal = *hal;
    dev->ticks = 0;
    dev->overruns = 0;
    dev->defer = 0;
    dev->rxq_head = dev->rxq_tail = dev->rxq_dropped = 0;
    (void)fw_crc32(0u, NULL, 0); /* the CRC tables built here, not in a tick */
    dev->frames_rejected = 0;
    dev->reset_pending = 0;
    fw_reset(dev);
    if (dev->hal.timer_start != NULL)
        dev->hal.timer_start(dev->hal.ctx, FW_TICK_HZ);
}
