/*
 * The per-tick law (docs/protocol.md section 6): the renderer of haptics/renderer.py and the
 * force controller of haptics/plant.py, operation for operation (the double build reproduces
 * them to the last bit; the float build is what a Cortex-M4F computes).
 */
#include <math.h>

#include "fw.h"
#include "fw_law.h"

#define TWO_PI R(6.283185307179586)
#if FW_REAL_IS_DOUBLE
#define COPYSIGN copysign
#else
#define COPYSIGN copysignf
#endif

static const real_t DT_S = (real_t)(1.0 / FW_TICK_HZ);
/* the hand reading low-passed at 1000 rad/s: min(1, g T) */
#define HAND_GAIN (G_RFOB * DT_S)

static int finite_r(real_t x)
{
    /* by the exponent bits: no arithmetic or ordered comparison that could raise FE_INVALID */
#if FW_REAL_IS_DOUBLE
    union { double d; uint64_t u; } v;
    v.d = x;
    return (v.u & 0x7FF0000000000000u) != 0x7FF0000000000000u;
#else
    union { float f; uint32_t u; } v;
    v.f = x;
    return (v.u & 0x7F800000u) != 0x7F800000u;
#endif
}

void fw_render_init(fw_renderer *r)
{
    r->state = FW_IDLE;
    r->faults = 0;
    r->new_faults = 0;
    r->front_mm = R(0.0);
    r->drill_mm = R(0.0);
    r->force_cmd_n = R(0.0);
    r->hand_n = R(0.0);
    r->thermal_n2_s = R(0.0);
    r->thermal_limited = 0;
    r->last_host_tick = 0;
    r->arm_tick = 0;
    r->ke = r->w1 = r->w2 = r->f1_hz = r->f2_hz = R(0.0);
    r->stop_depth_mm = R(0.0);
    r->stop_anchor_mm = (real_t)INFINITY;
    r->contact_n = R(0.0);
    r->inv_step = R(0.0);
    r->last = -1;
    r->release_on = 1;
    r->pull_ticks = 0;
    r->last_v_mm_s = R(0.0);
#if !FW_REAL_IS_DOUBLE
    r->front_lo = R(0.0);
    r->turn1 = r->turn2 = R(0.0);
    r->turn1_step = r->turn2_step = R(0.0);
    r->thermal_lo = R(0.0);
    r->glide_from = (real_t)INFINITY;
    r->glide_n = 0;
#endif
}

/* the I2t state plus inc, never below 0 (compensated in float: a plain float sum drifts by
 * more than the increment of a tick over a thermal budget's 10^4 ticks) */
static void thermal_add(fw_renderer *r, real_t inc)
{
#if FW_REAL_IS_DOUBLE
    real_t sum = r->thermal_n2_s + inc;
    r->thermal_n2_s = sum > R(0.0) ? sum : R(0.0);
#else
    real_t y = inc - r->thermal_lo;
    real_t sum = r->thermal_n2_s + y;
    r->thermal_lo = (sum - r->thermal_n2_s) - y;
    if (sum > R(0.0)) {
        r->thermal_n2_s = sum;
    } else {
        r->thermal_n2_s = R(0.0);
        r->thermal_lo = R(0.0);
    }
#endif
}

static void raise_fault(fw_renderer *r, uint16_t fault)
{
    if (!(r->faults & fault))
        r->new_faults |= fault;
    r->faults |= fault;
}

static real_t go_safe(fw_renderer *r, uint16_t fault)
{
    raise_fault(r, fault);
    r->state = FW_SAFE;
    r->force_cmd_n = R(0.0);
    return R(0.0);
}

static void coefficients(const fw_device *dev, real_t depth_mm, real_t depth_lo, real_t *s0,
                         real_t *s1, real_t *s2)
{
    const fw_renderer *r = &dev->r;
    real_t pos = depth_mm * r->inv_step, frac;
    int32_t i;
#if FW_REAL_IS_DOUBLE
    (void)depth_lo;
#endif
    if (!(R(0.0) <= pos && pos <= (real_t)r->last)) {
        *s0 = *s1 = *s2 = R(0.0);
        return;
    }
    i = (int32_t)pos;
    if (i >= r->last) {
        *s0 = (real_t)dev->s0[r->last];
        *s1 = (real_t)dev->s1[r->last];
        *s2 = (real_t)dev->s2[r->last];
        return;
    }
    frac = pos - (real_t)i;
#if FW_REAL_IS_DOUBLE
    *s0 = (real_t)dev->s0[i] + frac * ((real_t)dev->s0[i + 1] - (real_t)dev->s0[i]);
    *s1 = (real_t)dev->s1[i] + frac * ((real_t)dev->s1[i + 1] - (real_t)dev->s1[i]);
    *s2 = (real_t)dev->s2[i] + frac * ((real_t)dev->s2[i + 1] - (real_t)dev->s2[i]);
#else
    /* the roundings of pos (of the product, of 1 / step) and the front's low part, added to
     * frac: a breakthrough's S0 is the small end of a row (S0 -> 0), the front's step goes as
     * 1 / S0, and frac's error is its relative error there */
    frac += fmaf(depth_mm, r->inv_step, -pos) + depth_mm * r->inv_step_lo + depth_lo * r->inv_step;
    frac = frac > R(0.0) ? (frac < R(1.0) ? frac : R(1.0)) : R(0.0);
    /* weighted, so that rows near the float range cannot overflow their difference */
    *s0 = dev->s0[i] * (R(1.0) - frac) + dev->s0[i + 1] * frac;
    *s1 = dev->s1[i] * (R(1.0) - frac) + dev->s1[i + 1] * frac;
    *s2 = dev->s2[i] * (R(1.0) - frac) + dev->s2[i + 1] * frac;
#endif
}

/* the release damper's switch, once a tick from the hand reading: on while the hand pulls
 * less than 1 N; off after RELEASE_HOLD_TICKS ticks in a row of more than RELEASE_OFF_PULL_N
 * (past the dip and the bias its own force makes in the reading); between, as it was */
static void release_gate(fw_renderer *r)
{
    if (r->hand_n > -RELEASE_PULL_N) {
        r->release_on = 1;
        r->pull_ticks = 0;
    } else if (r->hand_n < -RELEASE_OFF_PULL_N) {
        if (r->pull_ticks < RELEASE_HOLD_TICKS)
            r->pull_ticks++;
        if (r->pull_ticks >= RELEASE_HOLD_TICKS)
            r->release_on = 0;
    } else {
        r->pull_ticks = 0;
    }
}

/* model/cutting.py cut_step: the yielding front and the coupling force it sustained */
static real_t cut_step(real_t front, real_t *front_lo, real_t master, real_t master_lo,
                       real_t s0, real_t ke, real_t limit, real_t *coupling)
{
#if FW_REAL_IS_DOUBLE
    real_t e = master - front, e_star, room, step, new_front, e_after;
    (void)front_lo;
    (void)master_lo;
#else
    /* the front is front + *front_lo (a float's 1 ulp at 12 mm is 1 nm; the steps of a slow
     * cut are 0.1-1 um: summed plainly, their roundings walk the front off by tens of nm and
     * the breakthrough's 1/S0 amplifies that) */
    real_t e = (master - front) + (master_lo - *front_lo), e_star, room, step, new_front, e_after, sum, lo;
#endif
    int free_ = 0;
    if (e <= R(0.0) || front >= limit) {
        *coupling = e > R(0.0) ? K_N_PER_MM * e : R(0.0);
        return front;
    }
    e_star = s0 <= R(0.0) ? R(0.0) : s0 / K_N_PER_MM;
    if (e <= e_star) {
        *coupling = K_N_PER_MM * e;
        return front;
    }
    room = e - e_star;
#if FW_REAL_IS_DOUBLE
    if (s0 <= R(0.0) || ke <= R(0.0)) {
#else
    /* below 1e-30 (N, per mm/s) the step is the whole room in double too; float would
     * overflow on the way there */
    if (s0 <= R(1e-30) || ke <= R(1e-30)) {
#endif
        step = room;
    } else {
#if FW_REAL_IS_DOUBLE
        step = (K_N_PER_MM * e / s0 - R(1.0)) / ke * DT_S;
#else
        /* / 10^4, not * 1e-4f: the float 1e-4 is 2.5e-8 short, a bias the front's steps sum
         * (0.2 nm over 8 mm of cut, amplified by 1 / S0 at a breakthrough) */
        step = (K_N_PER_MM * e / s0 - R(1.0)) / ke / (real_t)FW_TICK_HZ;
#endif
        free_ = step < room;
        if (!free_)
            step = room;
    }
#if FW_REAL_IS_DOUBLE
    new_front = front + step;
#else
    /* two-sum: new_front + lo is front + front_lo + step to a float's rounding of lo */
    sum = *front_lo + step;
    new_front = front + sum;
    {
        real_t bp = new_front - front;
        lo = (front - (new_front - bp)) + (sum - bp);
    }
    *front_lo = lo;
#endif
    if (new_front >= limit) {
        new_front = limit;
#if !FW_REAL_IS_DOUBLE
        *front_lo = R(0.0);
#endif
        free_ = 0;
    }
    if (free_) {
        *coupling = K_N_PER_MM * e;
        return new_front;
    }
#if FW_REAL_IS_DOUBLE
    e_after = master - new_front;
#else
    e_after = (master - new_front) + (master_lo - *front_lo);
#endif
    *coupling = e_after > R(0.0) ? K_N_PER_MM * e_after : R(0.0);
    return new_front;
}

real_t fw_render_tick(fw_device *dev, real_t master_mm, real_t v_mm_s, real_t hand_n)
{
    fw_renderer *r = &dev->r;
    real_t front, stop, s0, s1, s2, new_front, coupling, front_v, vib, force, anchor, back_v;
    real_t glided, spring, damper, fc, drive_mm, push;
    if (finite_r(hand_n) && finite_r(v_mm_s)) {
        /* the observer reads a steady acceleration a as a push of -G_RFOB T Mn a (its step
         * lags a tick): added back from the change of the velocity estimate */
        real_t accel = (v_mm_s - r->last_v_mm_s) * (real_t)FW_TICK_HZ;
        real_t reading = hand_n + G_RFOB * DT_S * MASS_KG * R(1e-3) * accel;
        r->hand_n += HAND_GAIN * (reading - r->hand_n);
        r->last_v_mm_s = v_mm_s;
    }
    release_gate(r);
    if (r->state == FW_IDLE || r->state == FW_SAFE) {
        r->force_cmd_n = R(0.0);
        thermal_add(r, -(CONTINUOUS_FORCE_N * CONTINUOUS_FORCE_N * DT_S));
        if (master_mm == master_mm)
            r->drill_mm = master_mm < r->front_mm ? master_mm : r->front_mm;
        return R(0.0);
    }
    /* the watchdog counts ticks: no accepted host frame for more than 50 ms */
    if (dev->ticks - r->last_host_tick > FW_WATCHDOG_TICKS)
        return go_safe(r, FW_F_WATCHDOG);
    if (!(finite_r(master_mm) && finite_r(v_mm_s) && finite_r(hand_n)))
        return go_safe(r, FW_F_NONFINITE);
    front = r->front_mm;
    stop = r->stop_depth_mm;
    anchor = r->stop_anchor_mm;
    back_v = v_mm_s; /* the master's motion away from what it presses on */
#if FW_REAL_IS_DOUBLE
    if (anchor == (real_t)INFINITY && (front >= stop || master_mm >= stop)) {
        /* the wall stands at the stop depth from the hand's first touch of it */
        anchor = master_mm > stop ? master_mm : stop;
    } else if (anchor != (real_t)INFINITY) {
        /* glides to the stop (the hand is carried to the drill), or follows a faster retreat */
        glided = anchor - STOP_GLIDE_MM_S * DT_S;
        if (master_mm < glided) {
            anchor = master_mm > stop ? master_mm : stop;
        } else if (anchor > stop) {
            anchor = glided > stop ? glided : stop;
            back_v = v_mm_s + (r->stop_anchor_mm - anchor) / DT_S;
        }
    }
#else
    /* the same glide, each position computed from where it began (a float anchor stepped
     * by 2 um a tick would drift by its rounding: 0.01 N on the wall within 0.05 s) */
    if (anchor == (real_t)INFINITY && (front >= stop || master_mm >= stop)) {
        anchor = master_mm > stop ? master_mm : stop;
        r->glide_from = anchor;
        r->glide_n = 0;
    } else if (anchor != (real_t)INFINITY) {
        glided = r->glide_from - (real_t)(r->glide_n + 1u) * (STOP_GLIDE_MM_S * DT_S);
        if (master_mm < glided) {
            anchor = master_mm > stop ? master_mm : stop;
            r->glide_from = anchor;
            r->glide_n = 0;
        } else if (anchor > stop) {
            if (glided > stop) {
                anchor = glided;
                r->glide_n++;
                back_v = v_mm_s + STOP_GLIDE_MM_S;
            } else {
                back_v = v_mm_s + (anchor - stop) / DT_S;
                anchor = stop;
            }
        }
    }
#endif
    r->stop_anchor_mm = anchor;
    spring = master_mm > anchor ? K_STOP_N_PER_MM * (master_mm - anchor) : R(0.0);
#if FW_REAL_IS_DOUBLE
    coefficients(dev, front, R(0.0), &s0, &s1, &s2);
#else
    coefficients(dev, front, r->front_lo, &s0, &s1, &s2);
#endif
    /* short of the stop the front is driven by the whole force the hand meets (coupling and
     * wall): the drill cuts on to the stop behind a hand the wall holds */
    drive_mm = master_mm;
    if (front < stop && spring > R(0.0)) {
        if (r->contact_n == R(0.0)) /* the hand meets the wall: the push it cut with */
            r->contact_n = K_N_PER_MM * (master_mm - front);
        push = K_N_PER_MM * (master_mm - front) + spring;
        push = push > r->contact_n ? push : r->contact_n;
        push = push < PEAK_FORCE_N ? push : PEAK_FORCE_N;
        drive_mm = front + push / K_N_PER_MM;
    } else {
        r->contact_n = R(0.0);
    }
#if FW_REAL_IS_DOUBLE
    new_front = cut_step(front, NULL, drive_mm, R(0.0), s0, r->ke, stop, &coupling);
    front_v = (new_front - front) / DT_S;
#else
    {
        real_t lo0 = r->front_lo;
        /* driven by the wall, the drive is the front plus the push's stretch */
        real_t drive_lo = drive_mm != master_mm ? lo0 : r->master_lo;
        new_front = cut_step(front, &r->front_lo, drive_mm, drive_lo, s0, r->ke, stop, &coupling);
        front_v = ((new_front - front) + (r->front_lo - lo0)) / DT_S;
    }
#endif
    if (drive_mm != master_mm) /* the coupling's own share of the force */
        coupling -= K_N_PER_MM * (drive_mm - master_mm);
    vib = R(0.0);
#if !FW_REAL_IS_DOUBLE
    /* phases kept in turns (exact enough in float over any session's length) */
    r->turn1 += r->turn1_step;
    r->turn1 -= r->turn1 >= R(1.0) ? R(1.0) : R(0.0);
    r->turn2 += r->turn2_step;
    r->turn2 -= r->turn2 >= R(1.0) ? R(1.0) : R(0.0);
#endif
    if (new_front > front) {
#if FW_REAL_IS_DOUBLE
        double t = (double)dev->ticks * (1.0 / FW_TICK_HZ) - (double)r->arm_tick * (1.0 / FW_TICK_HZ);
        vib = s1 * sin(r->w1 * t) + s2 * sin(r->w2 * t);
#else
        /* each term within 1e30 N: the sum cannot overflow, and the force is clipped to
         * the peak (or to 0) long before */
        real_t v1 = s1 * sinf(TWO_PI * r->turn1), v2 = s2 * sinf(TWO_PI * r->turn2);
        v1 = v1 < R(1e30) ? (v1 > R(-1e30) ? v1 : R(-1e30)) : R(1e30);
        v2 = v2 < R(1e30) ? (v2 > R(-1e30) ? v2 : R(-1e30)) : R(1e30);
        vib = v1 + v2;
#endif
    }
    /* model/cutting.py resistance_n */
    if (coupling <= R(0.0)) {
        force = R(0.0);
    } else {
        force = coupling + B_N_S_PER_MM * (v_mm_s - front_v) + vib;
        force = force > R(0.0) ? force : R(0.0);
    }
    if (spring > R(0.0)) {
        /* spring and damper, the damper within the spring's force: the wall starts from 0 on
         * contact at any speed, and never pulls */
        damper = B_STOP_N_S_PER_MM * v_mm_s;
        if (-spring < damper && damper < spring)
            force += spring + damper;
        else
            force += spring + COPYSIGN(spring, damper);
    }
    if (back_v < R(0.0)) {
        force += B_RELEASE_N_S_PER_MM * (r->release_on ? R(1.0) : R(0.0)) * back_v;
        if (force < -RELEASE_MAX_N)
            force = -RELEASE_MAX_N;
    }
    r->front_mm = new_front;
    r->drill_mm = master_mm < new_front ? master_mm : new_front;
    r->state = new_front >= stop ? FW_STOPPED : FW_CUTTING;
    if (!finite_r(force))
        return go_safe(r, FW_F_NONFINITE);
    if (force > PEAK_FORCE_N) {
        force = PEAK_FORCE_N;
        raise_fault(r, FW_F_PEAK_LIMIT);
    }
    fc = CONTINUOUS_FORCE_N;
    if (r->thermal_limited && force > fc) {
        force = fc;
        raise_fault(r, FW_F_THERMAL_LIMIT);
    }
    thermal_add(r, (force * force - fc * fc) * DT_S);
    if (r->thermal_n2_s >= THERMAL_BUDGET_N2_S)
        r->thermal_limited = 1;
    else if (r->thermal_n2_s < R(0.5) * THERMAL_BUDGET_N2_S)
        r->thermal_limited = 0;
    r->force_cmd_n = force;
    return force;
}

/* ------------------------------------------------------------------ the force controller */

void fw_control_init(fw_controller *c, real_t start_mm, int32_t counts)
{
    c->zv = start_mm * R(1e-3);
    c->yd = c->yr = R(0.0);
    c->velocity_mm_s = c->hand_est_n = c->current_a = R(0.0);
#if !FW_REAL_IS_DOUBLE
    c->last_counts = counts;
    c->resid_m = (real_t)counts * R(1e-7) - c->zv;
#else
    (void)counts;
#endif
}

static real_t friction_model(real_t v)
{
    real_t r = v / FRICTION_VEL_M_S;
    r = r < R(1.0) ? r : R(1.0);
    r = r > R(-1.0) ? r : R(-1.0);
    return COULOMB_N * r;
}

/* the pseudo-differentiator: v = g (x - zv), zv += v T (1000 rad/s) */
static real_t velocity(fw_controller *c, int32_t counts, real_t encoder_mm)
{
    real_t v;
#if FW_REAL_IS_DOUBLE
    real_t x = encoder_mm * R(1e-3);
    (void)counts;
    v = G_VEL * (x - c->zv);
    c->zv += v * DT_S;
#else
    /* the same filter on differences: x - zv = (x - x_last) + (x_last - zv) */
    real_t dxz = (real_t)(counts - c->last_counts) * R(1e-7) + c->resid_m;
    (void)encoder_mm;
    v = G_VEL * dxz;
    c->resid_m = dxz - v * DT_S;
    if (c->resid_m < R(1e-20) && c->resid_m > R(-1e-20))
        c->resid_m = R(0.0); /* at rest: no subnormal tail (slow on some FPUs), 1e-20 m is 0 */
    c->last_counts = counts;
    c->zv = (real_t)counts * R(1e-7) - c->resid_m;
#endif
    return v;
}

real_t fw_control_update(fw_controller *c, int32_t counts, real_t encoder_mm, real_t force_cmd_n)
{
    real_t v = velocity(c, counts, encoder_mm);
    real_t ti, d_hat, hand, a_ref, i;
    const real_t i_max = R(80.0) / KT_N_PER_A;
    ti = KT_N_PER_A * c->current_a;
    /* DOB: everything that is not the motor, low-passed at G_DOB */
    c->yd += DT_S * G_DOB * (ti + MASS_KG * G_DOB * v - c->yd);
    d_hat = c->yd - MASS_KG * G_DOB * v;
    /* RFOB: the hand's force, the friction model removed */
    c->yr += DT_S * G_RFOB * (ti + MASS_KG * G_RFOB * v - c->yr);
    hand = -(c->yr - MASS_KG * G_RFOB * v) + friction_model(v);
    a_ref = KF * (hand - force_cmd_n) / MASS_KG;
    i = (MASS_KG * a_ref + d_hat) / KT_N_PER_A;
    if (!finite_r(i))
        i = R(0.0);
    i = i < i_max ? i : i_max;
    i = i > -i_max ? i : -i_max;
    c->current_a = i;
    c->velocity_mm_s = v * R(1e3);
    c->hand_est_n = hand;
    return i;
}

real_t fw_control_idle(fw_controller *c, int32_t counts, real_t encoder_mm)
{
    real_t v = velocity(c, counts, encoder_mm);
    real_t ti = KT_N_PER_A * c->current_a;
    c->yd += DT_S * G_DOB * (ti + MASS_KG * G_DOB * v - c->yd);
    c->yr += DT_S * G_RFOB * (ti + MASS_KG * G_RFOB * v - c->yr);
    c->hand_est_n = -(c->yr - MASS_KG * G_RFOB * v) + friction_model(v);
    c->velocity_mm_s = v * R(1e3);
    c->current_a = R(0.0);
    return R(0.0);
}
