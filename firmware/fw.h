/*
 * ctdrill reference firmware: the device side of docs/protocol.md in portable C99.
 *
 * One core, no heap, no platform calls in the loop. The board supplies a table of hardware
 * functions (fw_hal); the core calls them and nothing else. The host build
 * (host/fw_host.c) implements them with the simulated master of haptics/plant.py, so the
 * same core runs under `ctdrill emulate --core c` and in the equality tests.
 *
 * Units: mm, mm/s, N, s (as the protocol). real_t is double unless FW_REAL_FLOAT is defined
 * (the single precision a Cortex-M4F's FPU computes).
 */
#ifndef CTDRILL_FW_H
#define CTDRILL_FW_H

#include <stddef.h>
#include <stdint.h>

#ifdef FW_REAL_FLOAT
typedef float real_t;
#define FW_REAL_IS_DOUBLE 0
#define R(x) ((real_t)(x##f))
#else
typedef double real_t;
#define FW_REAL_IS_DOUBLE 1
#define R(x) ((real_t)(x))
#endif

/* ------------------------------------------------------------------ protocol constants */
#define FW_PROTOCOL_VERSION 3u
#define FW_VERSION_MAJOR 0u
#define FW_VERSION_MINOR 1u
#define FW_VERSION_PATCH 0u
#define FW_TICK_HZ 10000u
#define FW_TELEMETRY_EVERY 10u
#define FW_HEADER_BYTES 18u
#define FW_MAX_DECODED 254u
#define FW_MAX_ENCODED (FW_MAX_DECODED + 2u)
#define FW_MAX_CHUNK_ROWS 16u
#define FW_MAX_PROFILE_STEPS 4096u
#define FW_WATCHDOG_TICKS 500u /* 50 ms at 10 kHz */
#define FW_WATCHDOG_MS 50u

enum fw_msg_type {
    FW_HELLO = 0x01, FW_VERSION = 0x02, FW_LIMITS = 0x03,
    FW_PROFILE_BEGIN = 0x10, FW_PROFILE_CHUNK = 0x11, FW_PROFILE_END = 0x12,
    FW_ARM = 0x20, FW_DISARM = 0x21, FW_HEARTBEAT = 0x22, FW_STOP = 0x23,
    FW_SIM_OPERATOR = 0x28, FW_SIM_RESET = 0x29,
    FW_TELEMETRY = 0x30, FW_FAULT = 0x31, FW_ACK = 0x40, FW_NAK = 0x41
};

enum fw_state { FW_IDLE = 0, FW_CUTTING = 1, FW_STOPPED = 2, FW_SAFE = 3 };

enum fw_fault {
    FW_F_WATCHDOG = 0x0001, FW_F_NONFINITE = 0x0002, FW_F_THERMAL_LIMIT = 0x0004,
    FW_F_PEAK_LIMIT = 0x0008, FW_F_HOST_STOP = 0x0010, FW_F_PROFILE_INVALID = 0x0020,
    FW_F_RESET = 0x0040, FW_F_TRAVEL_LIMIT = 0x0080
};

enum fw_nak {
    FW_NAK_NONE = 0, FW_NAK_BAD_FRAME = 1, FW_NAK_UNKNOWN_TYPE = 2, FW_NAK_BAD_LENGTH = 3,
    FW_NAK_BAD_VERSION = 4, FW_NAK_NOT_READY = 5, FW_NAK_PROFILE_CRC = 6,
    FW_NAK_PROFILE_ORDER = 7, FW_NAK_NONFINITE = 8, FW_NAK_PROFILE_TOO_LONG = 9,
    FW_NAK_BAD_VALUE = 10, FW_NAK_NOT_RETRACTED = 11, FW_NAK_BAD_SESSION = 12,
    FW_NAK_STALE_SEQUENCE = 13, FW_NAK_BAD_HEADER = 14
};

/* ------------------------------------------------------------------ the hardware table */
/*
 * What a board provides. The four hardware functions are required; random_u32 draws the
 * session nonce (a hardware random source). The sim_* hooks exist only in an emulator: NULL
 * on hardware, where SIM_OPERATOR and SIM_RESET are refused with NAK UNKNOWN_TYPE.
 */
typedef struct fw_hal {
    void *ctx;
    /* the encoder: master depth in counts of 0.1 um (+ into the patient) */
    int32_t (*encoder_counts)(void *ctx);
    /* the motor current for the next tick, A (held through the tick) */
    void (*current_out)(void *ctx, real_t amps);
    /* the UART: queue n bytes for transmission (never blocks; a full FIFO drops) */
    void (*uart_write)(void *ctx, const uint8_t *data, size_t n);
    /* the timer: start calling fw_tick at tick_hz (called once by fw_init) */
    void (*timer_start)(void *ctx, uint32_t tick_hz);
    /* a non-zero random u32 for each new session */
    uint32_t (*random_u32)(void *ctx);
    /* optional: the stage rests on a mechanical end stop (TRAVEL_LIMIT in telemetry) */
    int (*end_stop)(void *ctx);
    /* optional, emulator only: the simulated hand (returns a NAK reason or 0) and power-cycle */
    int (*sim_operator)(void *ctx, uint8_t kind, float value);
    void (*sim_reset)(void *ctx);
} fw_hal;

/* ------------------------------------------------------------------ device state */
typedef struct fw_renderer {
    uint8_t state;
    uint16_t faults, new_faults;
    real_t front_mm, drill_mm, force_cmd_n, hand_n;
    real_t thermal_n2_s;
    uint8_t thermal_limited;
    uint64_t last_host_tick, arm_tick;
    real_t ke, w1, w2, f1_hz, f2_hz, stop_depth_mm, stop_anchor_mm, inv_step;
    real_t contact_n; /* the coupling's force when the hand met the wall short of the stop */
    int32_t last; /* index of the last row, -1 without a table */
    real_t last_v_mm_s;   /* the last velocity estimate (the hand reading's lag correction) */
    uint8_t release_on;   /* the release damper's gate */
    uint16_t pull_ticks;  /* ticks in a row the hand reading has pulled past the gate's off */
#if !FW_REAL_IS_DOUBLE
    real_t turn1, turn2; /* vibration phases in turns since ARM */
    real_t turn1_step, turn2_step; /* f T modulo 1: turns a tick */
    real_t glide_from;   /* float: the anchor where its glide began, and the ticks since */
    uint32_t glide_n;
    real_t thermal_lo;   /* compensation of the I2t sum (Kahan): float keeps its threshold tick */
    real_t front_lo;     /* the front is front_mm + front_lo: its sub-ulp steps add up */
    real_t inv_step_lo;  /* 1 / step = inv_step + inv_step_lo */
    real_t master_lo;    /* this tick's encoder depth is master_mm + master_lo (set by fw_tick) */
#endif
} fw_renderer;

typedef struct fw_controller {
    real_t zv, yd, yr, velocity_mm_s, hand_est_n, current_a;
#if !FW_REAL_IS_DOUBLE
    /* float: the velocity filter's residual x - zv (m) and the last count, so the filter
     * works on differences (a float zv near 20 mm stalls within 5 ulp of x: a bias) */
    real_t resid_m;
    int32_t last_counts;
#endif
} fw_controller;

/* a received frame, decoded and checked (or its refusal), waiting for fw_poll */
#define FW_RXQ 4u
typedef struct fw_packet {
    uint8_t nak;        /* a refusal to send (a NAK reason), or 0: a packet to handle */
    uint8_t type;
    uint8_t time_nonzero;
    uint8_t body_len;
    uint32_t seq, session;
    uint8_t body[FW_MAX_DECODED - FW_HEADER_BYTES - 4u];
} fw_packet;

typedef struct fw_device {
    fw_hal hal;
    uint64_t ticks;
    uint32_t seq;          /* the device's frame counter since power-on */
    uint32_t session;      /* 0: none since power-on */
    uint32_t host_seq;     /* last accepted host seq of this session */
    uint32_t table_crc32, table_session;
    uint16_t boot_fault;
    uint32_t overruns;
    uint32_t frames_rejected;
    /* upload in progress */
    uint8_t uploading;
    uint16_t upload_n, upload_rows;
    uint32_t upload_crc;   /* running CRC-32 of BEGIN body + rows */
    float up_step, up_ke, up_f1, up_f2, up_stop;
    /* receiver */
    uint8_t rx[FW_MAX_ENCODED + 1];
    uint16_t rx_len;
    uint8_t rx_overflow;
    uint8_t reset_pending; /* SIM_RESET: drop the partial frame at the end of this chunk */
    /* deferred handling (a board): fw_receive decodes into this queue in the background,
     * fw_poll handles it in the tick's context; 0 (the host build): handled at once */
    uint8_t defer;
    uint32_t rxq_head, rxq_tail, rxq_dropped;
    fw_packet rxq[FW_RXQ];
    fw_renderer r;
    fw_controller c;
    float s0[FW_MAX_PROFILE_STEPS], s1[FW_MAX_PROFILE_STEPS], s2[FW_MAX_PROFILE_STEPS];
} fw_device;

/* ------------------------------------------------------------------ the core's API */
void fw_init(fw_device *dev, const fw_hal *hal);
/* power-cycle the core (what SIM_RESET does after its ACK): table, session, state lost */
void fw_reset(fw_device *dev);
/* bytes from the UART: frames decoded and checked, then handled at the current device time
 * (dev->defer == 0) or queued for fw_poll (dev->defer == 1: fw_receive may run in the
 * background while fw_poll and fw_tick run in the tick's interrupt) */
void fw_receive(fw_device *dev, const uint8_t *data, size_t n);
/* handle up to max queued frames (their replies, their commands); returns how many */
unsigned fw_poll(fw_device *dev, unsigned max);
/* one 10 kHz control tick: renderer, force controller, faults, telemetry */
void fw_tick(fw_device *dev);
/* the board saw a late tick */
void fw_note_overrun(fw_device *dev);

/* the per-tick law alone (exposed for tests): renderer and force controller */
real_t fw_render_tick(fw_device *dev, real_t master_mm, real_t v_mm_s, real_t hand_n);
real_t fw_control_update(fw_controller *c, int32_t counts, real_t encoder_mm, real_t force_cmd_n);
real_t fw_control_idle(fw_controller *c, int32_t counts, real_t encoder_mm);
void fw_control_init(fw_controller *c, real_t start_mm, int32_t counts);
void fw_render_init(fw_renderer *r);

/* framing (pure) */
uint32_t fw_crc32c(const uint8_t *data, size_t n);
uint32_t fw_crc32(uint32_t crc, const uint8_t *data, size_t n);
/* COBS: returns the output length; decode returns -1 on malformed input */
size_t fw_cobs_encode(const uint8_t *in, size_t n, uint8_t *out);
int fw_cobs_decode(const uint8_t *in, size_t n, uint8_t *out, size_t cap);
/* encode one frame (header, body, CRC-32C, COBS, 0x00) into out (>= FW_MAX_ENCODED + 1) */
size_t fw_encode_frame(uint8_t type, uint32_t seq, uint32_t session, uint64_t time_us,
                       const uint8_t *body, size_t body_len, uint8_t *out);

int fw_seq_after(uint32_t seq, uint32_t last);

#endif
