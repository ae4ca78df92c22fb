"""The 10 kHz teleoperation loop: hand, master, channel, slave, environment, estimator.

Every tick ``k`` (time ``t = k dt``):

1. each servo reads its encoder (0.1 um) and updates velocity, DOB and RFOB;
2. each side sends ``(x, v, F)`` over its channel and reads the other side's newest packet;
3. the four-channel law (:class:`~ctdrill.haptics.bilateral.params.Gains`) gives each side its
   acceleration; its DOB turns it into a current within the limit;
4. the hand's force (operator and impedance) acts on the master, the environment's on the slave
   (:class:`~ctdrill.haptics.bilateral.environment.CuttingEnvironment`); both plants
   (:class:`ctdrill.haptics.plant.MasterPlant`, the slave with its own mass and friction) move
   exactly over the tick;
5. the slave's estimator reads its force estimate and feed; the plan's stop (the front at the
   plan's stop depth) and the force-based stop brake the slave.

The energy flowing into the two-port (robots, controllers, channel) from the hand and the
environment is booked per tick with held forces, ``E += F_h dx_m - F_e dx_s`` (the passivity
observer of Hannaford and Ryu): a passive two-port never has ``E < 0``.

Everything is plain floats and :class:`random.Random` seeded from ``seed``: a run replays bit
for bit.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, field

import numpy as np

from ctdrill.haptics.bilateral.channel import Channel
from ctdrill.haptics.bilateral.environment import CuttingEnvironment
from ctdrill.haptics.bilateral.estimator import HuEstimator
from ctdrill.haptics.bilateral.params import (
    HAND_FEED_STIFFNESS_N_PER_M,
    ChannelSpec,
    EnvSpec,
    Gains,
    HandSpec,
    SlaveSpec,
)
from ctdrill.haptics.bilateral.prior import Prior
from ctdrill.haptics.bilateral.servo import Servo
from ctdrill.haptics.plant import (
    COULOMB_N,
    CURRENT_LIMIT_A,
    KT_N_PER_A,
    MASS_KG,
    MasterPlant,
)
from ctdrill.haptics.session import Operator
from ctdrill.haptics.tick import TICK_HZ
from ctdrill.model.calibration import Calibration
from ctdrill.model.profile import Profile

#: States of a sample.
FREE, CUTTING, STOPPED = 0, 1, 2
STATE_NAMES = ("free", "cutting", "stopped")
#: A ``human`` operator's push noise changes at this rate, Hz.
HAND_NOISE_HZ = 100.0
#: Travel of both stages, mm.
TRAVEL_MM = (-20.0, 60.0)


@dataclass(frozen=True)
class TeleopSetup:
    """Everything but the material and the operator.

    Attributes
    ----------
    duration_s : float
    seed : int
        Seeds the channels' jitter and loss and a ``human`` hand's noise.
    start_mm : float
        Both robots start at rest here (slave depth; the master at ``start / alpha``), mm.
    plan_stop_mm : float
        The plan's stop depth in slave depth, mm (inf: none).
    force_stop : bool
        Whether the force-based stop may brake the slave.
    record_every : int
        Record one sample every this many ticks.
    """

    duration_s: float
    seed: int = 0
    start_mm: float = 0.0
    plan_stop_mm: float = math.inf
    force_stop: bool = True
    record_every: int = 10
    tick_hz: float = TICK_HZ
    gains: Gains = field(default_factory=Gains)
    slave: SlaveSpec = field(default_factory=SlaveSpec)
    channel: ChannelSpec = field(default_factory=ChannelSpec)
    hand: HandSpec = field(default_factory=HandSpec)
    env: EnvSpec = field(default_factory=EnvSpec)


@dataclass(frozen=True, eq=False)
class TeleopRun:
    """One run, recorded every ``record_every`` ticks (arrays of one length).

    Positions in mm (true, not the encoders'), forces in N (``env_force_n``, ``fe_est_n`` and
    ``felt_n`` positive against the advance; ``hand_n`` positive pushing in), energy in J.
    ``hu_est`` is NaN before the estimator's first valid tick; ``hu_valid`` marks new
    estimates. ``stop_*`` say where and why the slave was braked (``stop_reason`` None: it was
    not). ``energy_min_j`` is the passivity observer's minimum over every tick.
    """

    time_s: np.ndarray
    master_mm: np.ndarray
    slave_mm: np.ndarray
    front_mm: np.ndarray
    env_force_n: np.ndarray
    hand_n: np.ndarray
    felt_n: np.ndarray
    fh_est_n: np.ndarray
    fe_est_n: np.ndarray
    force_lp_n: np.ndarray
    hu_ct: np.ndarray
    hu_est: np.ndarray
    hu_valid: np.ndarray
    gain: np.ndarray
    state: np.ndarray
    energy_j: np.ndarray
    energy_min_j: float
    stop_reason: str | None
    stop_time_s: float
    stop_depth_mm: float
    deepest_front_mm: float
    force_scale: float
    packets_lost: int
    window_s: float


def _push_at(op: Operator, t_s: float) -> float:
    if op.kind == "feed":
        return 0.0
    return op.force_at_n(t_s)


def simulate_teleop(
    env_profile: Profile,
    env_origin_mm: float,
    calibration: Calibration,
    prior: Prior,
    operator: Operator,
    setup: TeleopSetup,
    *,
    tip_length_mm: float,
) -> TeleopRun:
    """Run the loop for ``setup.duration_s`` (module docstring).

    Parameters
    ----------
    env_profile : Profile
        The true CT's profile along the slave's axis (what the slave cuts).
    env_origin_mm : float
        Slave depth of ``env_profile``'s depth 0, mm.
    calibration : Calibration
        The force law the estimator assumes.
    prior : Prior
        The plan's CT along the path (:func:`~ctdrill.haptics.bilateral.estimator.plan_prior`).
    operator : Operator
        ``push``, ``feed``, ``script`` or ``human`` (:func:`ctdrill.haptics.session.
        parse_operator`); a human lets go ``react_ms`` after the slave is braked.
    setup : TeleopSetup
    tip_length_mm : float
        The drill's lip length, mm.
    """
    g = setup.gains
    dt = 1.0 / setup.tick_hz
    alpha = g.position_scale
    beta = g.force_scale
    hand = setup.hand
    k_hand = hand.stiffness_n_per_m
    if operator.kind == "feed" and k_hand == 0.0:
        k_hand = HAND_FEED_STIFFNESS_N_PER_M
    feed_ref_m_s = operator.value * 1e-3 if operator.kind == "feed" else 0.0
    b_hand = hand.damping_n_s_per_m
    xm0 = setup.start_mm / alpha
    master = MasterPlant(start_mm=xm0, mass_kg=MASS_KG + hand.mass_kg, travel_mm=TRAVEL_MM)
    sl = setup.slave
    slave = MasterPlant(
        start_mm=setup.start_mm,
        mass_kg=sl.mass_kg,
        kt_n_per_a=sl.kt_n_per_a,
        coulomb_n=sl.coulomb_n,
        travel_mm=(TRAVEL_MM[0] * alpha, TRAVEL_MM[1] * alpha),
    )
    common = {"g_dob": g.g_dob, "g_rfob": g.g_rfob, "g_vel": g.g_vel, "dt_s": dt}
    m_servo = Servo(
        mass_kg=MASS_KG,
        kt_n_per_a=KT_N_PER_A,
        coulomb_n=COULOMB_N,
        current_limit_a=CURRENT_LIMIT_A,
        start_mm=xm0,
        **common,
    )
    s_servo = Servo(
        mass_kg=sl.mass_kg,
        kt_n_per_a=sl.kt_n_per_a,
        coulomb_n=sl.coulomb_n,
        current_limit_a=sl.current_limit_a,
        start_mm=setup.start_mm,
        **common,
    )
    env = CuttingEnvironment(env_profile, env_origin_mm, setup.env)
    f1 = float(env_profile.freqs_hz[0]) if env_profile.freqs_hz.size else 30.0
    est = HuEstimator(
        calibration,
        prior,
        tip_length_mm=tip_length_mm,
        window_ticks=round(setup.tick_hz / f1),
        tick_s=dt,
        rfob_gain_rad_s=g.g_rfob,
    )
    to_slave = Channel(setup.channel, setup.tick_hz, 2 * setup.seed + 1, (xm0, 0.0, 0.0))
    to_master = Channel(
        setup.channel, setup.tick_hz, 2 * setup.seed + 2, (setup.start_mm, 0.0, 0.0)
    )
    noise_rng = random.Random(setup.seed)
    human = operator.human
    noise_sd = human.noise_n if human is not None else 0.0
    react_s = human.react_ms * 1e-3 if human is not None else math.inf
    noise = 0.0
    noise_index = -1
    kp, kv, kf_m = g.kp_per_s2, g.kv_per_s, g.kf / g.force_mass_kg
    n = round(setup.duration_s * setup.tick_hz)
    every = max(1, setup.record_every)
    rows: list[tuple[float, ...]] = []
    energy = 0.0
    energy_min = 0.0
    stop_reason: str | None = None
    stop_time = math.nan
    stop_depth = math.nan
    release_s = math.inf
    plan_stop = setup.plan_stop_mm
    resistance = 0.0
    hand_f = 0.0
    for k in range(n):
        t = k * dt
        m_servo.observe(master.encoder_mm())
        s_servo.observe(slave.encoder_mm())
        vm = m_servo.velocity_m_s
        vs = s_servo.velocity_m_s
        fh = m_servo.external_n
        fe = s_servo.external_n
        xm_e = m_servo.position_m
        xs_e = s_servo.position_m
        to_slave.send(k, (xm_e, vm, fh))
        to_master.send(k, (xs_e, vs, fe))
        rxs, rvs, rfe = to_master.receive(k)
        rxm, rvm, rfh = to_slave.receive(k)
        # master: own state, the slave's (scaled to master units) from the channel
        a_d = kp * (rxs / alpha - xm_e) + kv * (rvs / alpha - vm)
        a_c = kf_m * (fh + beta * rfe)
        i_m = m_servo.command(0.5 * (a_c + a_d))
        # slave: own state, the master's from the channel
        a_d = kp * (xs_e / alpha - rxm) + kv * (vs / alpha - rvm)
        a_c = kf_m * (rfh + beta * fe)
        i_s = s_servo.command(alpha * 0.5 * (a_c - a_d))
        # the hand
        if human is not None:
            idx = math.floor(t * HAND_NOISE_HZ + 1e-9)
            if idx != noise_index and noise_sd > 0.0:
                noise_index = idx
                noise = noise_rng.gauss(0.0, noise_sd)
            push = human.force_n + noise if t < release_s else 0.0
        else:
            push = _push_at(operator, t)
        x_m = master.x_m
        v_m = master.v_m_s
        hand_f = push - b_hand * (v_m - feed_ref_m_s)
        if k_hand > 0.0:
            hand_f += k_hand * (xm0 * 1e-3 + feed_ref_m_s * t - x_m)
        x_s = slave.x_m
        resistance = env.force_n(x_s * 1e3, slave.v_m_s * 1e3, t, dt)
        master.step(i_m, hand_f, dt)
        slave.step(i_s, -resistance, dt)
        energy += hand_f * (master.x_m - x_m) - resistance * (slave.x_m - x_s)
        if energy < energy_min:
            energy_min = energy
        est.update(slave.encoder_mm(), -s_servo.external_n)
        if stop_reason is None:
            reason = None
            if env.front_mm >= plan_stop:
                reason = "plan_stop"
            elif setup.force_stop and est.stop_reason is not None:
                reason = est.stop_reason
            if reason is not None:
                stop_reason = reason
                stop_time = t + dt
                stop_depth = slave.x_m * 1e3
                env.stop(stop_depth)
                release_s = stop_time + react_s
        if k % every == every - 1:
            state = STOPPED if stop_reason else (CUTTING if resistance > 0.0 else FREE)
            rows.append(
                (
                    t + dt,
                    master.x_m * 1e3,
                    slave.x_m * 1e3,
                    env.front_mm,
                    resistance,
                    hand_f,
                    -KT_N_PER_A * i_m,
                    m_servo.external_n,
                    -s_servo.external_n,
                    est.force_lp_n,
                    env.hu_mn(env.front_mm),
                    est.hu,
                    1.0 if est.valid else 0.0,
                    10.0**est.log10_gain,
                    float(state),
                    energy,
                )
            )
    a = np.array(rows, dtype=np.float64).reshape(-1, 16)
    return TeleopRun(
        time_s=a[:, 0],
        master_mm=a[:, 1],
        slave_mm=a[:, 2],
        front_mm=a[:, 3],
        env_force_n=a[:, 4],
        hand_n=a[:, 5],
        felt_n=a[:, 6],
        fh_est_n=a[:, 7],
        fe_est_n=a[:, 8],
        force_lp_n=a[:, 9],
        hu_ct=a[:, 10],
        hu_est=a[:, 11],
        hu_valid=a[:, 12] > 0.5,
        gain=a[:, 13],
        state=a[:, 14].astype(np.int8),
        energy_j=a[:, 15],
        energy_min_j=energy_min,
        stop_reason=stop_reason,
        stop_time_s=stop_time,
        stop_depth_mm=stop_depth,
        deepest_front_mm=env.front_mm,
        force_scale=beta,
        packets_lost=to_slave.lost + to_master.lost,
        window_s=est.n_win * dt,
    )
