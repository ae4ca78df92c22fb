/*
 * The device's constants, once for the core (internal header). Each is a translation of its
 * owner in the Python device, named beside it; tests/firmware/test_c_constants.py checks every
 * value against that owner.
 */
#ifndef CTDRILL_FW_LAW_H
#define CTDRILL_FW_LAW_H

#include "fw.h"

/* device limits and the rendering's constants (haptics/renderer.py, model/cutting.py) */
#define PEAK_FORCE_N R(78.0)
#define CONTINUOUS_FORCE_N R(20.0)
#define THERMAL_BUDGET_N2_S R(5684.0) /* 78^2 - 20^2: one second at the peak force */
#define ARM_MAX_FORCE_N R(5.0)
#define K_N_PER_MM R(11.0)
#define B_N_S_PER_MM R(0.08)
#define K_STOP_N_PER_MM R(200.0)
#define B_STOP_N_S_PER_MM R(0.4)
#define STOP_GLIDE_MM_S R(20.0)
#define B_RELEASE_N_S_PER_MM R(0.4)
#define RELEASE_PULL_N R(1.0)
#define RELEASE_MAX_N R(20.0)
#define RELEASE_OFF_PULL_N R(2.0)
#define RELEASE_HOLD_TICKS 80u
/* the force controller (paper Table 4) */
#define MASS_KG R(0.5)
#define KT_N_PER_A R(33.0)
#define COULOMB_N R(1.0)
#define KF R(1.2)
#define G_DOB R(1000.0)
#define G_RFOB R(1000.0)
#define G_VEL R(1000.0)
#define FRICTION_VEL_M_S R(0.1e-3)
/* the master's travel (haptics/plant.py TRAVEL_MM), reported in LIMITS */
#define TRAVEL_MIN_MM R(-20.0)
#define TRAVEL_MAX_MM R(60.0)

#endif
