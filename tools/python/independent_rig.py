#!/usr/bin/env python3
"""An independent elbow-exoskeleton identification rig: writes contract recordings.

It simulates the identification protocol of He, Huang, Thomas and Sentis
(IEEE TNSRE 2020, Table I) with its own physics (numpy only) and writes the
result as an exo recording (MCAP, ros2msg schemas, CDR; see
docs/recording-format.md, the contract). Nothing of exo's is used: not the
Rust simulator, not fit_frf.py, not write_recording.py. It exists so that
`exo fit` is checked against data exo's own simulator did not write.

    independent_rig.py OUT.mcap --seed N [--subject NAME] [--experiments 1,2,...]
        [--periods 10] [--truth TRUTH.json] [--noise-scale X] [--random-subject]
        [--params PARAMS.json] [--damping viscous|two-point] [--twitch S] [--pre-window S]
        [--writer own|mcap] [--k3 K3] [--k2 K2] [--b3 B3] [--horizontal] [--exo-spring K] [--k-drift RHO] [--lash RAD]
        [--rate-hz 500|1000] [--cuff-delay S] [--sea-delay S] [--encoder-delay S] [--encoder-bits N]
        [--cuff-compliance K [--cuff-damping B]] [--posture-shift E:RAD,...] [--mass-scale X]
        [--sea-hz F] [--sea-zeta Z] [--sea-model lowpass|tustin] [--saturation NM]
        [--protocol sines|multisine [--ms-band LO,HI] [--ms-lines L] [--ms-period S]
         [--ms-settle-periods N] [--ms-periods N]] [--damping prony]
    independent_rig.py --monte-carlo N --out-dir DIR --seed S0 [--experiments 1,3] [the options of the last two lines]
        (N recordings DIR/mc000.mcap, ... with seeds S0+i, plus DIR/truth.json)

Model (linear about the operating point except gravity; rad, Nm, s, kg m^2):

* human: M_h th'' = tau_c - B th' - K (th - th_p(t)) + tau_tw(t), so that
  tau_c = S_h th + (voluntary terms) with S_h = K - M_h w^2 + j B w. The
  hysteretic damping H is an equivalent viscous B = H / w_k at the period's
  excitation frequency w_k: exact at w_k. The arm's natural mode
  w_n = sqrt(K / (M_h + M_e / alpha)) is then lightly damped when w_k > w_n
  (the human alone gives zeta down to ~0.05; the SEA lag in the amplification
  loop takes more away), so it rings after the ramp and the sine's start and
  some of that ringing is still in the analysis window. For some random
  subjects in experiments 6, 8, 9 the mode is unstable (named on stderr).
  --damping two-point adds a Maxwell element so that the loss is H also at
  w_n, still exactly K - M_h w_k^2 + j H at w_k (see human_realisation).
  th_p is the subject's posture reference (rest ~0.3 rad -> 45 deg +- 2 deg,
  minimum jerk over the 5 s ramp-in, offset so that the arm settles at its
  goal against the bias torque; the subject's own arm weight is part of this
  voluntary torque and not modelled); tau_tw is one short "twitch" (a 20 ms
  voluntary torque pulse of random sign and size) at a random time in the
  first second of every analysis window, so a little ringing of the natural
  mode is in every window.
* exoskeleton: M_e th'' = tau_s - tau_c - tau_g(th), M_e = 0.1 + load 0.45^2,
  tau_g = g (1.5 kg * 0.2 m + load * 0.45 m) sin th (th = 0 hanging down).
* SEA: tau_s follows tau_d through a 10 Hz, zeta 0.7 second-order low pass
  (--sea-hz, --sea-zeta), integrated with the plant (--sea-model lowpass);
  --sea-model tustin: the same low pass discretised by the bilinear transform
  pre-warped at its natural frequency, run at the control rate, the torque
  ramping over each tick to that tick's output (half a tick more lag).
  --saturation NM: the drive's current limit, the SEA follows
  clip(tau_d, -NM, NM) while the recorded tau_d is the unclipped command.
* cuff: rigid (forearm and arm one body) unless --cuff-compliance K: then
  the forearm has its own angle th_h and inertia M_h (the human terms above
  act on it), tau_c = K (th - th_h) + B (th' - th_h') (--cuff-damping B,
  default 2 Nm s/rad), M_e th'' = tau_s - tau_c - tau_g(th).
* off-nominal subject: --mass-scale X multiplies M_h (the realisation is
  built for the scaled M_h, the truth file holds it); --posture-shift E:RAD
  adds RAD to th_p in experiment E (re-seated; the controller's plan and
  bias stay), so the arm settles RAD / (1 - dg cos th / (alpha k0)) away
  (dg: the gravity model's excess torque, k0 the realisation's static
  stiffness).
* concealed physics outside exo's catalogue (off by default): --k3 a cubic
  human spring, --k2 a stiffness that depends on posture (K2/2 (th - plan)^2),
  --b3 a cubic human damper (B3 th'^3), --exo-spring a spring in the exoskeleton joint, --k-drift
  the human's stiffness drifting within each experiment, --lash backlash in
  the joint's gear mesh (tau_s then drives a motor side of 0.02 kg m^2,
  part of the arm's inertia, which pushes the arm only beyond the lost
  motion; see simulate()).
* controller (500 Hz, or 1000 Hz with --rate-hz 1000; zero-order hold, from
  the measured signals):
  tau_d = tau_gravity(th_meas) - (alpha - 1) tau_c_meas + bias(t) + tau_x(t);
  the gravity compensation uses +3 % arm mass and +2 % load mass.
* sensors: tau_c, tau_s + white noise (0.05 Nm per sample at either rate);
  encoder + white noise (2e-5 rad) then 17-bit quantisation (--encoder-bits);
  omega_e = finite difference of the measured angle through a 40 Hz
  first-order low pass; status 0. --cuff-delay, --sea-delay, --encoder-delay
  S (s, 0-0.05): the reading at t is the true value at t - S, linearly
  interpolated between the two ticks around it (DelayLine), before the noise
  and the quantisation; the controller uses the delayed angle and cuff torque.
* stability: each period's linearised closed loop as sampled (delays, cuff,
  gravity, SEA; sampled_loop) is checked and an unstable one named on stderr.

Protocol of each period (local time): 0-5 s ramp-in (phase 1: bias ramped in
with a raised cosine, arm raised), 5-10 s settling (phase 2, sine on, starting
at phase 0), 10-15 s analysis (phase 3), 15-20 s ramp-out (phase 4), 20-25 s
rest (phase 5; the paper rests 40 s). Each period is simulated from rest at
the start of its ramp-in to the end of its analysis window. Samples (sensor
and command, seq +1 per written sample) are written from 1 s
(--pre-window) before each analysis window to its end (inclusive); protocol
states at every change and once a second throughout, idle (0) before and
after the protocol.

--protocol multisine (issue 34): one protocol period per experiment whose
excitation is a periodic multisine of this script's own design
(multisine_design: L lines log-spaced over a band, rounded to the bins of a
period of S seconds, flat amplitudes, phases the best crest factor of
Schroeder's and 400 seeded random draws), playing from the settling phase's
first tick: --ms-settle-periods periods of settling, then --ms-periods of
analysis. The recording names its lines in the exo metadata
(docs/recording-format.md: excitation, multisine_period_samples, _bins,
_amplitudes, _phases_rad) and its protocol states say omega 0 (broadband)
with the peak torque as amplitude. Its human is --damping prony: a causal
hysteretic joint, a static spring k0 beside a bank of Maxwell elements
whose relaxation rates are spread evenly in log over [LO/2, 2 HI], each
holding the same stiffness, so the loss is close to H across the band;
k0 is set so that Re S_h = K at the band's geometric centre. A causal
constant loss makes Re S_h rise with frequency (Kramers-Kronig: about
(2/pi) H per e-fold), so no causal human is the paper's M2 at every line;
the truth file gives S_h(j w) exactly at every excited line
(experiments.E.lines) for checking the estimate line by line, and the M2
that fits those values (experiments.E.m2_of_lines). --damping prony also
runs with the sine steps (each period's S_h in the truth), so both
protocols can be held to one human.

Randomness: the subject's parameters come from default_rng([seed, 0x5B])
(--random-subject, and Monte Carlo), each period's posture, twitch and noise
from default_rng([seed, 1, experiment, period]); so a Monte-Carlo recording
is byte-identical to the single recording with the same seed, subject name,
experiments and --random-subject.

The MCAP file is written by a small numpy writer of its own (chunked, zstd,
message and chunk indexes, statistics, summary offsets, CRCs): the mcap
library's Writer costs ~3.4 us a message, too slow for the Monte-Carlo set;
--writer mcap writes the same messages through it, for cross-checks.
"""

import argparse
import collections
import json
import math
import os
import struct
import sys
import time
import zlib

import numpy as np

SOFTWARE = "independent_rig.py"

# ---------------------------------------------------------------- rig constants
RATE_HZ = 500  # default control and sample rate, Hz (--rate-hz)
RATES_HZ = (500, 1000)
G = 9.81
ARM_INERTIA = 0.1  # kg m^2, exoskeleton without load
LEVER = 0.45  # m, load lever arm
ARM_MASS, ARM_COM = 1.5, 0.2  # kg, m: exoskeleton arm weight
COMP_ARM_MASS_FACTOR = 1.03  # the controller's gravity model is off-nominal
COMP_LOAD_MASS_FACTOR = 1.02
SEA_HZ, SEA_ZETA = 10.0, 0.7  # defaults of --sea-hz, --sea-zeta
ENC_BITS = 17  # default of --encoder-bits
OMEGA_FILTER_HZ = 40.0
SIGMA_TAU_C = 0.05  # Nm, per sample at any rate
SIGMA_TAU_S = 0.05  # Nm
SIGMA_ENC = 2e-5  # rad
TWITCH_S = 0.02  # the twitch: a 20 ms pulse
TWITCH_IMPULSE_SIGMA = 0.004  # N m s (default; --twitch overrides)
# --lash: the drive's output (motor side) between the SEA and the gear mesh
# to the arm; its inertia is a part of ARM_INERTIA.
MOTOR_SIDE_INERTIA = 0.02  # kg m^2
MESH_STIFFNESS = 2.0e4  # N m / rad, in contact
MESH_DAMPING = 8.0  # N m s / rad, in contact
MESH_STEP_S = 2e-4  # RK4 step with a lash (the mesh's mode: 1000 rad/s); 10 steps a tick at 500 Hz
# --cuff-compliance: the cuff (strap and soft tissue) between the exoskeleton
# and the forearm as a spring-damper.
CUFF_DAMPING = 2.0  # N m s / rad, default of --cuff-damping
CUFF_STEP_BOUND = 0.5  # RK4 substeps so that (B/m_r + sqrt(K/m_r)) h <= this
MAX_SENSOR_DELAY_S = 0.05

# ---------------------------------------------------------------- protocol (Table I)
GROUPS = [  # (grip kg, bias Nm, omega_0 rad/s)
    (10.0, 0.0, 2.0),
    (14.0, 4.0, 3.0),
    (27.0, 8.0, 4.0),
]
ALPHAS = [1.0, 2.0, 4.0]
LOAD_KG = 4.5
AMPLITUDE = 2.0
AMP_BOOST_FROM = 8  # 1-based period from which the amplitude is x 10^0.2
N_PERIODS = 10

RAMP_IN_S, SETTLE_S, ANALYSIS_S, RAMP_OUT_S, REST_S = 5.0, 5.0, 5.0, 5.0, 5.0
# --protocol multisine defaults (issue 34): the band of the sine steps, 12
# lines, 10 s periods, one of settling and three analysed, the peak the sine
# steps' largest amplitude.
MS_BAND = (2.0, 32.0)
MS_LINES = 12
MS_PERIOD_S = 10.0
MS_SETTLE_PERIODS = 1
MS_PERIODS = 3
MS_RANDOM_DRAWS = 400
# --damping prony: Maxwell elements per decade of relaxation rate.
PRONY_PER_DECADE = 5
PRE_WINDOW_S = 1.0


class Timing:
    """The protocol in ticks at one control rate (Hz): the sample period dt
    (s), the stamp step tick_ns, and a period's phase boundaries (local
    ticks)."""

    def __init__(self, rate_hz=RATE_HZ, settle_s=SETTLE_S, analysis_s=ANALYSIS_S):
        self.rate_hz = rate_hz
        self.dt = 1.0 / rate_hz
        self.tick_ns = 1_000_000_000 // rate_hz
        self.lead_ticks = rate_hz  # 1 s of idle before the first period
        self.t_sine = self.ticks(RAMP_IN_S)  # local tick the sine starts (phase 2)
        self.t_analysis = self.t_sine + self.ticks(settle_s)  # phase 3
        self.t_ramp_out = self.t_analysis + self.ticks(analysis_s)  # phase 4
        self.t_rest = self.t_ramp_out + self.ticks(RAMP_OUT_S)  # phase 5
        self.t_period = self.t_rest + self.ticks(REST_S)
        self.n_sim = self.t_ramp_out + 1  # simulated ticks 0..t_ramp_out inclusive
        self.twitch_ticks = self.ticks(TWITCH_S)
        self.mesh_substeps = max(1, int(round(self.dt / MESH_STEP_S)))  # RK4 steps a tick with a lash

    def ticks(self, s):
        return int(round(s * self.rate_hz))


class Rig:
    """The rig's settings that the command line can move off nominal (the
    defaults are the nominal rig): rate_hz, encoder_bits, the SEA's low pass
    (sea_hz, sea_zeta, sea_model lowpass|tustin), the drive's current limit
    saturation_nm (0 = none), the sensors' pure delays (s), the cuff's
    stiffness cuff_k (Nm/rad, 0 = rigid) and damping cuff_b (Nm s/rad);
    multisine: None (the sine steps) or multisine_design()'s dict, whose
    settling and analysed periods then set the timing; prony_band (rad/s):
    the band of --damping prony's loss."""

    def __init__(self, rate_hz=RATE_HZ, encoder_bits=ENC_BITS, sea_hz=SEA_HZ, sea_zeta=SEA_ZETA,
                 sea_model="lowpass", saturation_nm=0.0, cuff_delay_s=0.0, sea_delay_s=0.0,
                 encoder_delay_s=0.0, cuff_k=0.0, cuff_b=CUFF_DAMPING, multisine=None, prony_band=MS_BAND):
        self.multisine = multisine
        self.prony_band = prony_band
        if multisine:
            per_s = multisine["n"] / rate_hz
            self.tm = Timing(rate_hz, multisine["settle_periods"] * per_s, multisine["periods"] * per_s)
        else:
            self.tm = Timing(rate_hz)
        self.encoder_bits = encoder_bits
        self.enc_q = 2.0 * math.pi / 2**encoder_bits
        self.sea_hz, self.sea_zeta, self.sea_model = sea_hz, sea_zeta, sea_model
        self.saturation_nm = saturation_nm
        self.cuff_delay_s, self.sea_delay_s, self.encoder_delay_s = cuff_delay_s, sea_delay_s, encoder_delay_s
        self.cuff_k, self.cuff_b = cuff_k, cuff_b


NOMINAL = Rig()


def multisine_design(rate_hz, band, lines, period_s, settle_periods, periods, peak_nm):
    """This rig's periodic multisine: `lines` frequencies log-spaced over
    band (rad/s), each rounded to the nearest bin of a period of period_s
    seconds (a bin taken twice moves up to the next free one), equal
    amplitudes, and the phases of the lowest crest factor among Schroeder's
    (phi_l = -pi l (l - 1) / L) and MS_RANDOM_DRAWS uniform draws from a
    fixed stream. Returns n (samples a period), bins, the amplitudes over
    the peak (so that the period's largest |value| is 1), the phases (rad)
    at a period's sample 0, the period's waveform of unit peak (cosines),
    its crest factor, and the peak torque (Nm)."""
    n = int(round(period_s * rate_hz))
    if abs(n - period_s * rate_hz) > 1e-9 * n:
        raise SystemExit(f"--ms-period {period_s!r} s is not a whole number of samples at {rate_hz} Hz")
    lo, hi = band
    bins = []
    for w in np.geomspace(lo, hi, lines):
        b = max(1, int(round(w * period_s / (2.0 * math.pi))))
        while b in bins:
            b += 1
        bins.append(b)
    if bins[-1] >= n // 2:
        raise SystemExit(f"--ms-band {lo:g},{hi:g}: bin {bins[-1]} is not below Nyquist ({n // 2})")
    b = np.array(bins, dtype=float)
    m = np.arange(n, dtype=float)
    arg = 2.0 * math.pi * np.outer(b, m) / n

    def wave(phi):
        return np.cos(arg + phi[:, None]).sum(axis=0)

    def crest(x):
        return float(np.max(np.abs(x)) / math.sqrt(np.mean(x * x)))

    ell = np.arange(1, lines + 1, dtype=float)
    best = -math.pi * ell * (ell - 1.0) / lines
    best_cf = crest(wave(best))
    rng = np.random.default_rng([lines, n, 0x3A])
    for _ in range(MS_RANDOM_DRAWS):
        phi = rng.uniform(-math.pi, math.pi, lines)
        cf = crest(wave(phi))
        if cf < best_cf:
            best, best_cf = phi, cf
    x = wave(best)
    top = float(np.max(np.abs(x)))
    phases = (best + math.pi) % (2.0 * math.pi) - math.pi
    return dict(n=n, bins=bins, amplitudes=[1.0 / top] * lines, phases=[float(p) for p in phases],
                wave=x / top, crest=best_cf, peak_nm=peak_nm, settle_periods=settle_periods, periods=periods,
                omega=[2.0 * math.pi * bb / period_s for bb in bins], band=(lo, hi))


def prony_realisation(k, h, band):
    """A causal hysteretic joint for broadband excitation: k0 + b0 s +
    sum_i km_i tau_i s / (1 + tau_i s), b0 = 0, relaxation rates 1/tau_i
    spread evenly in log over [lo/2, 2 hi] (PRONY_PER_DECADE a decade), each
    km_i = (2 H / pi) d(ln rate) so the loss is about H across the band (a
    flat relaxation spectrum gives (pi/2) times its density), and k0 such
    that Re S_h = K at sqrt(lo hi)."""
    lo, hi = band
    r_lo, r_hi = 0.5 * lo, 2.0 * hi
    m = max(2, int(math.ceil(PRONY_PER_DECADE * math.log10(r_hi / r_lo)))) + 1
    rates = np.geomspace(r_lo, r_hi, m)
    km = np.full(m, 2.0 * h / math.pi * math.log(rates[1] / rates[0]))
    wc = math.sqrt(lo * hi)
    k0 = k - float(np.sum(km * wc * wc / (wc * wc + rates * rates)))
    if k0 <= 0.0:
        raise SystemExit(f"--damping prony: K {k:.3g} is too small for H {h:.3g} over the band "
                         "(the static spring would be negative)")
    return dict(k0=k0, b0=0.0, km=[float(x) for x in km], tau_m=[float(1.0 / r) for r in rates])


def human_response(sp, w):
    """The realisation's S_h(j w) = k0 - M_h w^2 + j w b0 + sum km_i j w tau_i
    / (1 + j w tau_i) (complex, Nm/rad), exactly."""
    s = 1j * w
    km, tau = np.atleast_1d(sp["km"]), np.atleast_1d(sp["tau_m"])
    return complex(sp["k0"] - sp["m_h"] * w * w + sp["b0"] * s + np.sum(km * tau * s / (1.0 + tau * s)))


def m2_of(ws, values):
    """The paper's M2 (K - M w^2 + j H) that fits the complex values at ws
    by least squares, each real and imaginary part weighted alike: (K, H,
    M)."""
    ws = np.asarray(ws, dtype=float)
    v = np.asarray(values, dtype=complex)
    a = np.zeros((2 * len(ws), 3))
    a[:len(ws), 0], a[:len(ws), 2] = 1.0, -ws * ws
    a[len(ws):, 1] = 1.0
    x = np.linalg.lstsq(a, np.concatenate([v.real, v.imag]), rcond=None)[0]
    return float(x[0]), float(x[1]), float(x[2])


def experiment_settings(e):
    grip, bias, w0 = GROUPS[(e - 1) // 3]
    return dict(alpha=ALPHAS[(e - 1) % 3], load_kg=LOAD_KG, grip_kg=grip, bias_nm=bias, omega0=w0)


def period_omega(e, k):  # k = 0..9
    return experiment_settings(e)["omega0"] * 10.0 ** (0.1 * k)


def period_amplitude(k):
    return AMPLITUDE * (10.0**0.2 if k + 1 >= AMP_BOOST_FROM else 1.0)


def m_e(load_kg):
    return ARM_INERTIA + load_kg * LEVER**2


# ---------------------------------------------------------------- subjects
# Our own table (not exo's configs): K rises with the group (grip and bias),
# with a spread inside each group; H = 10^b0 K^b1 times a small scatter.
TABLE_M_H = 0.13
TABLE_K = [14.0, 17.5, 21.0, 33.0, 40.0, 47.0, 62.0, 71.0, 80.0]
TABLE_BETA0, TABLE_BETA1 = -0.3, 0.95
TABLE_H_SCATTER = [1.04, 0.95, 1.02, 0.97, 1.05, 0.98, 1.03, 0.96, 1.01]


def table_subject():
    k = list(TABLE_K)
    h = [10.0**TABLE_BETA0 * kk**TABLE_BETA1 * s for kk, s in zip(k, TABLE_H_SCATTER)]
    return dict(m_h=TABLE_M_H, k=k, h=h, beta0=TABLE_BETA0, beta1=TABLE_BETA1, source="table")


def random_subject(seed):
    """A subject drawn from seed: M_h in [0.10, 0.16], K = table x lognormal(0.15),
    H = 10^b0 K^b1 x lognormal(0.06), b0 ~ -0.3 +- 0.05, b1 ~ 0.95 +- 0.03."""
    rng = np.random.default_rng([seed, 0x5B])
    m_h = float(rng.uniform(0.10, 0.16))
    b0 = float(TABLE_BETA0 + 0.05 * rng.standard_normal())
    b1 = float(TABLE_BETA1 + 0.03 * rng.standard_normal())
    k = [float(kk * math.exp(0.15 * rng.standard_normal())) for kk in TABLE_K]
    h = [float(10.0**b0 * kk**b1 * math.exp(0.06 * rng.standard_normal())) for kk in k]
    return dict(m_h=m_h, k=k, h=h, beta0=b0, beta1=b1, source=f"random(seed={seed})")


def load_params(path):
    """JSON {"m_h": x, "k": [9 values], "h": [9 values]} (k/h may also be
    {"1": v, ...} maps over the experiments given)."""
    with open(path) as f:
        p = json.load(f)
    base = table_subject()
    out = dict(m_h=float(p.get("m_h", base["m_h"])), k=list(base["k"]), h=list(base["h"]),
               beta0=p.get("beta0"), beta1=p.get("beta1"), source=os.path.basename(path))
    for key in ("k", "h"):
        v = p.get(key)
        if isinstance(v, list):
            if len(v) != 9:
                raise SystemExit(f"{path}: '{key}' must list 9 values (experiments 1-9)")
            out[key] = [float(x) for x in v]
        elif isinstance(v, dict):
            for e, x in v.items():
                out[key][int(e) - 1] = float(x)
    return out


# ---------------------------------------------------------------- period specs
def human_realisation(k, h, m_h, alpha, load_kg, w, damping):
    """The time-domain human whose S_h(j w) is exactly K - M_h w^2 + j H:
    S_h(s) = M_h s^2 + b0 s + k0 + km tau s / (1 + tau s) (a Maxwell element
    km, km tau). viscous: b0 = H / w, k0 = K, km = 0. two-point: besides,
    the loss is H also at the arm's natural frequency w_n = sqrt(K / (M_h +
    M_e / alpha)) (as a hysteretic human's would be), via a Maxwell element
    with tau = 1 / w_n, when w > w_n (below, b0 = H / w already gives more)."""
    w_n = math.sqrt(k / (m_h + m_e(load_kg) / alpha))
    x = w / w_n
    if damping == "viscous" or x <= 1.0:
        return dict(k0=k, b0=h / w, km=0.0, tau_m=1.0 / w_n)
    km = 2.0 * h * (1.0 + x * x) / (x * (1.0 + x))  # Im Z_m = H - b0 w at w_n and w
    return dict(k0=k - km * x * x / (1.0 + x * x), b0=(h - 0.5 * km) / w_n, km=km, tau_m=1.0 / w_n)


def closed_loop_mode(sp, rig=NOMINAL):
    """(w, zeta) of the slowest oscillatory pole of the linearised closed loop
    (human realisation, exoskeleton, SEA, amplification; continuous time,
    rigid cuff, gravity, sampling and the sensors' delays left out;
    sampled_loop() takes them in)."""
    w_s = 2.0 * math.pi * rig.sea_hz
    d = np.array([1.0, 2.0 * rig.sea_zeta * w_s, w_s * w_s])
    kms, taus = np.atleast_1d(sp["km"]), np.atleast_1d(sp["tau_m"])
    lag = np.array([1.0])
    for tau in taus:
        lag = np.polymul(lag, [tau, 1.0])
    n_h = np.polymul([sp["m_h"], sp["b0"], sp["k0"]], lag)
    for i, (km, tau) in enumerate(zip(kms, taus)):
        rest = np.array([1.0])
        for j, t in enumerate(taus):
            if j != i:
                rest = np.polymul(rest, [t, 1.0])
        n_h = np.polyadd(n_h, np.polymul([km * tau, 0.0], rest))
    me = m_e(sp["load_kg"])
    char = np.polyadd(np.polymul(np.polymul([me, 0.0, 0.0], d), lag),
                      np.polymul(np.polyadd(d, [0.0, 0.0, (sp["alpha"] - 1.0) * w_s * w_s]), n_h))
    r = np.roots(char)
    r = r[np.abs(r.imag) > 1e-9 * np.abs(r)]
    if len(r) == 0:
        return 0.0, 1.0
    x = r[np.argmin(np.abs(r))]
    return float(abs(x)), float(-x.real / abs(x))


def expm(a):
    """exp(a) of a small square matrix: scaling and squaring of its Taylor series."""
    nrm = float(np.abs(a).sum(axis=1).max())
    sq = max(0, int(math.ceil(math.log2(nrm / 0.25)))) if nrm > 0.25 else 0
    x = a / 2.0**sq
    e = np.eye(len(a))
    term = np.eye(len(a))
    for i in range(1, 18):
        term = term @ x / i
        e = e + term
    for _ in range(sq):
        e = e @ e
    return e


def delay_taps(delay_s, dt):
    """A pure delay of delay_s seconds at sample period dt as (m, f): the
    reading at tick n is (1 - f) x[n - m] + f x[n - m - 1], the true value
    at t_n - delay_s linearly interpolated between the two ticks around it."""
    x = delay_s / dt
    m = int(math.floor(x + 1e-9))
    f = x - m
    return m, (0.0 if f < 1e-9 else f)


def tustin_sea(rig):
    """The SEA's continuous low pass w^2 / (s^2 + 2 zeta w s + w^2) by the
    bilinear transform s = c (z - 1) / (z + 1), pre-warped at w
    (c = w / tan(w dt / 2)): exact at w. Returns (b0, b1, b2), (a1, a2) of
    y[n] = b0 x[n] + b1 x[n-1] + b2 x[n-2] - a1 y[n-1] - a2 y[n-2]."""
    w = 2.0 * math.pi * rig.sea_hz
    c = w / math.tan(0.5 * w * rig.tm.dt)
    a0 = c * c + 2.0 * rig.sea_zeta * w * c + w * w
    b = w * w / a0
    return (b, 2.0 * b, b), ((2.0 * w * w - 2.0 * c * c) / a0, (c * c - 2.0 * rig.sea_zeta * w * c + w * w) / a0)


def sampled_loop(sp, rig=NOMINAL, k_exo_spring=0.0, horizontal=False):
    """(growth 1/s, w rad/s) of the least stable eigenvalue z of the
    linearised closed loop as it is sampled: growth = ln|z| / dt (> 0:
    unstable), w = |arg z| / dt. The plant about the posture goal (the
    human realisation, the cuff as a spring-damper or rigid, the exoskeleton
    with the gravity's stiffness and the exo spring, the SEA) is discretised
    exactly over a tick with its input held; the controller's gravity
    compensation and amplification act on the delayed measured angle and
    cuff torque (delay_taps); the SEA is the continuous low pass or the
    Tustin filter as simulated (its output reached by a ramp over the next
    tick). Noise, quantisation, saturation, the lash, the stiffness drift
    and the nonlinear human terms are left out."""
    tm = rig.tm
    dt = tm.dt
    me, mh = m_e(sp["load_kg"]), sp["m_h"]
    b0, k0 = sp["b0"], sp["k0"]
    kms, taus = np.atleast_1d(sp["km"]), np.atleast_1d(sp["tau_m"])
    nq = len(kms)  # the Maxwell elements' damper nodes
    c_th = 0.0 if horizontal else math.cos(sp["theta_goal"])
    gt = G * (ARM_MASS * ARM_COM + sp["load_kg"] * LEVER) * c_th
    gc = G * (COMP_ARM_MASS_FACTOR * ARM_MASS * ARM_COM + COMP_LOAD_MASS_FACTOR * sp["load_kg"] * LEVER) * c_th
    kc, bc = rig.cuff_k, rig.cuff_b
    tustin = rig.sea_model == "tustin"
    # Plant states: rigid th, om, q...; compliant th_e, om_e, th_h, om_h,
    # q...; then ts, and dts with the low pass. Input: tau_d (low pass) or
    # the rate of the tustin torque's ramp over the tick.
    nm = (4 if kc else 2) + nq
    n = nm + (1 if tustin else 2)
    A, B = np.zeros((n, n)), np.zeros(n)
    c_th_row = np.zeros(n)
    ex = np.zeros(n)  # the exoskeleton-side drive: tau_s
    ex[nm] = 1.0
    if tustin:
        B[nm] = 1.0
    else:
        A[nm, nm + 1] = 1.0
        w = 2.0 * math.pi * rig.sea_hz
        A[nm + 1, nm], A[nm + 1, nm + 1], B[nm + 1] = -w * w, -2.0 * rig.sea_zeta * w, w * w
    if kc:
        fh = np.zeros(n)  # the human's passive torque on th_h, om_h, q
        fh[2], fh[3] = k0 + kms.sum(), b0
        fh[4:4 + nq] = -kms
        tc = np.zeros(n)
        tc[0], tc[1], tc[2], tc[3] = kc, bc, -kc, -bc
        A[0, 1], A[2, 3] = 1.0, 1.0
        A[1] = (ex - tc) / me
        A[1, 0] -= (gt + k_exo_spring) / me
        A[3] = (tc - fh) / mh
        for i, tau in enumerate(taus):
            A[4 + i, 2], A[4 + i, 4 + i] = 1.0 / tau, -1.0 / tau
        c_tc_row = tc
    else:
        fh = np.zeros(n)
        fh[0], fh[1] = k0 + kms.sum(), b0
        fh[2:2 + nq] = -kms
        mt = me + mh
        A[0, 1] = 1.0
        A[1] = (ex - fh) / mt
        A[1, 0] -= (gt + k_exo_spring) / mt
        for i, tau in enumerate(taus):
            A[2 + i, 0], A[2 + i, 2 + i] = 1.0 / tau, -1.0 / tau
        c_tc_row = mh * A[1] + fh  # tau_c = M_h acc + the human's passive torque
    c_th_row[0] = 1.0
    aug = np.zeros((n + 1, n + 1))
    aug[:n, :n], aug[:n, n] = A * dt, B * dt
    e = expm(aug)
    phi, gam = e[:n, :n], e[:n, n]

    m_e_, f_e = delay_taps(rig.encoder_delay_s, dt)
    m_c, f_c = delay_taps(rig.cuff_delay_s, dt)
    l_e, l_c = m_e_ + (1 if f_e else 0), m_c + (1 if f_c else 0)  # past samples kept
    i_he, i_hc = n, n + l_e
    i_tu = n + l_e + l_c
    N = i_tu + (4 if tustin else 0)  # tustin: tau_d[n-1], tau_d[n-2], tau_s[n-1], tau_s[n-2]

    def unit(i):
        r = np.zeros(N)
        r[i] = 1.0
        return r

    cur_th = np.zeros(N)
    cur_th[:n] = c_th_row
    cur_tc = np.zeros(N)
    cur_tc[:n] = c_tc_row

    def measured(cur, i_h, m, f):
        tap = lambda j: cur if j == 0 else unit(i_h + j - 1)
        return (1.0 - f) * tap(m) + (f * tap(m + 1) if f else 0.0)

    tau_d = gc * measured(cur_th, i_he, m_e_, f_e) - (sp["alpha"] - 1.0) * measured(cur_tc, i_hc, m_c, f_c)
    M = np.zeros((N, N))
    if tustin:
        (bb0, bb1, bb2), (a1, a2) = tustin_sea(rig)
        y = bb0 * tau_d + bb1 * unit(i_tu) + bb2 * unit(i_tu + 1) - a1 * unit(i_tu + 2) - a2 * unit(i_tu + 3)
        M[i_tu], M[i_tu + 1], M[i_tu + 2], M[i_tu + 3] = tau_d, unit(i_tu), y, unit(i_tu + 2)
        u = (y - unit(nm)) / dt  # tau_s ramps from its value to the filter's output over the tick
    else:
        u = tau_d
    M[:n, :n] = phi
    M[:n] += np.outer(gam, u)
    for i_h, l, cur in ((i_he, l_e, cur_th), (i_hc, l_c, cur_tc)):
        for j in range(l):
            M[i_h + j] = cur if j == 0 else unit(i_h + j - 1)
    z = np.linalg.eigvals(M)
    zz = z[np.argmax(np.abs(z))]
    return float(math.log(abs(zz)) / dt), float(abs(np.angle(zz)) / dt)


def period_specs(seed, subject, experiments, n_periods, noise_scale, twitch_sigma, damping="viscous", rig=NOMINAL,
                 posture_shift=None):
    """Everything random about each period, drawn from its own stream
    default_rng([seed, 1, e, k]) so an experiment's data do not depend on
    which other experiments are written. posture_shift: {experiment: rad},
    the offset of the subject's posture reference th_p in that experiment."""
    tm = rig.tm
    specs = []
    ms = rig.multisine
    for e in experiments:
        st = experiment_settings(e)
        for k in range(1 if ms else n_periods):
            rng = np.random.default_rng([seed, 1, e, k])
            # A multisine is one broadband protocol period (omega 0 on the wire).
            w = 0.0 if ms else period_omega(e, k)
            spec = dict(
                experiment=e, period=k + 1, omega=w, amplitude=ms["peak_nm"] if ms else period_amplitude(k),
                alpha=st["alpha"], load_kg=st["load_kg"], grip_kg=st["grip_kg"],
                bias_nm=st["bias_nm"], m_h=subject["m_h"], k=subject["k"][e - 1],
                h=subject["h"][e - 1],
                theta_rest=0.3 + 0.02 * rng.standard_normal(),
                theta_goal=math.radians(45.0) + math.radians(2.0) * rng.standard_normal(),
                twitch_tick=tm.t_analysis + int(rng.integers(0, tm.rate_hz - tm.twitch_ticks)),
                twitch_nm=twitch_sigma * rng.standard_normal() / (tm.twitch_ticks * tm.dt),
                posture_shift=float((posture_shift or {}).get(e, 0.0)),
            )
            if damping == "prony":
                spec.update(prony_realisation(spec["k"], spec["h"], rig.prony_band))
            else:
                spec.update(human_realisation(spec["k"], spec["h"], spec["m_h"], spec["alpha"],
                                              spec["load_kg"], w, damping))
            spec["mode_omega"], spec["mode_zeta"] = closed_loop_mode(spec, rig)
            spec["noise_enc"] = SIGMA_ENC * noise_scale * rng.standard_normal(tm.n_sim)
            spec["noise_tc"] = SIGMA_TAU_C * noise_scale * rng.standard_normal(tm.n_sim)
            spec["noise_ts"] = SIGMA_TAU_S * noise_scale * rng.standard_normal(tm.n_sim)
            specs.append(spec)
    return specs


def annotate_loop(specs, rig=NOMINAL, k_exo_spring=0.0, horizontal=False):
    """Adds each period's sampled_loop() growth and frequency to its spec."""
    for sp in specs:
        sp["loop_growth"], sp["loop_omega"] = sampled_loop(sp, rig, k_exo_spring, horizontal)


# ---------------------------------------------------------------- simulation
def smooth_ramp(x):  # 0 -> 1 over x in [0, 1], zero slope at both ends
    x = np.clip(x, 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(np.pi * x)


def min_jerk(x):
    x = np.clip(x, 0.0, 1.0)
    return x**3 * (10.0 - 15.0 * x + 6.0 * x**2)


def mesh(lead, lead_rate, lash):
    """Torque of the gear mesh on the arm for the motor side leading the arm
    by `lead` (rad) at rate `lead_rate`: nothing while the lead is inside the
    lost motion (+-lash/2), a stiff damped contact beyond it."""
    past = np.maximum(np.abs(lead) - 0.5 * lash, 0.0)
    return np.where(past > 0.0, np.sign(lead) * MESH_STIFFNESS * past + MESH_DAMPING * lead_rate, 0.0)


class DelayLine:
    """A sensor's pure delay (delay_taps): called once a tick with the true
    value, it returns the value delay_s earlier, linearly interpolated
    between the two ticks around that time. Before tick 0 the rig was at
    rest: the true value then is the one at tick 0."""

    def __init__(self, delay_s, dt):
        self.m, self.f = delay_taps(delay_s, dt)
        self.buf = None

    def __call__(self, x):
        if self.buf is None:
            self.buf = collections.deque([x] * (self.m + 2), maxlen=self.m + 2)
        else:
            self.buf.append(x)
        a = self.buf[-1 - self.m]
        return (1.0 - self.f) * a + self.f * self.buf[-2 - self.m] if self.f else a


def rk4(f, y, h, steps):
    """`steps` classical Runge-Kutta steps of size h of y' = f(*y) (y a tuple of arrays)."""
    c = h / 6.0
    for _ in range(steps):
        k1 = f(*y)
        k2 = f(*(x + 0.5 * h * d for x, d in zip(y, k1)))
        k3 = f(*(x + 0.5 * h * d for x, d in zip(y, k2)))
        k4 = f(*(x + h * d for x, d in zip(y, k3)))
        y = tuple(x + c * (d1 + 2.0 * d2 + 2.0 * d3 + d4) for x, d1, d2, d3, d4 in zip(y, k1, k2, k3, k4))
    return y


def cuff_substeps(specs, rig, lash=0.0):
    """RK4 steps a tick with a compliant cuff: the two-body mode's eigenvalues
    are at most B/m_r + sqrt(K/m_r) (m_r = M_h M_e / (M_h + M_e), the
    reduced inertia), kept <= CUFF_STEP_BOUND / h."""
    if not rig.cuff_k:
        return 1
    mh = np.array([s["m_h"] for s in specs])
    me = np.array([m_e(s["load_kg"]) for s in specs]) - (MOTOR_SIDE_INERTIA if lash else 0.0)
    m_r = mh * me / (mh + me)
    rate = float(np.max(rig.cuff_b / m_r + np.sqrt(rig.cuff_k / m_r)))
    return max(1, int(math.ceil(rate * rig.tm.dt / CUFF_STEP_BOUND)))


def simulate(specs, pre_window_s=PRE_WINDOW_S, k_cubic=0.0, k_exo_spring=0.0, k_drift=0.0, lash=0.0,
             b_cubic=0.0, k_quad=0.0, horizontal=False, rig=NOMINAL, substeps=None):
    """Simulates the periods side by side (vectorised over periods), RK4 with
    the controller's torque held over each tick (2 ms at 500 Hz), from rest
    at the start of the ramp-in to the end of the analysis window. Returns
    the recorded ticks (pre_window_s before the analysis window to its end,
    inclusive) of every period as (P, n) arrays. k_cubic (Nm/rad^3): a stiffening spring of the
    human joint, K3 (theta - theta_p)^3 added to the human's linear spring
    K (theta - theta_p) (theta_p: the subject's reference posture).
    b_cubic (Nm s^3/rad^3): a cubic damper of the human joint, B3 omega^3
    added to the human's viscous damping b omega.
    k_quad (Nm/rad^2): a stiffness that depends on posture, K2/2 (theta -
    plan)^2 added to the human's spring (its slope dK/dtheta = K2 about the
    planned arm angle: the rest posture, the ramp, then the goal).
    horizontal: the joint's axis vertical, so no gravity acts on the arm and
    the controller compensates none (the SEA's torque then reverses with
    the sine where no bias holds it: backlash shows).
    k_exo_spring (Nm/rad): a spring in the exoskeleton joint centred at the
    period's posture goal, -k (theta - theta_goal) on the arm (a cable or
    harness; no term of exo's catalogue): it stiffens S_h-e by k without
    changing the static balance at the goal posture.
    k_drift (1/min): the human's stiffness drifting within each experiment,
    K(t) = K (1 + k_drift t / 60), t (s) from the start of the experiment's
    first analysis window (period k's window starts k tm.t_period ticks after it);
    the static spring k0 carries the change, so the loss H stays.
    lash (rad): lost motion in the exoskeleton joint's drive. The SEA's
    torque then acts on the motor side (inertia MOTOR_SIDE_INERTIA, taken
    out of the arm's) which drives the arm through a gear mesh with this
    total play (see mesh()); integrated with RK4 steps of MESH_STEP_S.
    rig (Rig): the rate, the encoder's bits, the SEA (sea_hz, sea_zeta;
    lowpass: integrated with the plant; tustin: the discrete filter
    tustin_sea() at the control rate, the SEA's torque ramping linearly over
    each tick from its value to the filter's output of that tick, so it is
    continuous and the sensor at tick n reads the output of tick n - 1:
    half a tick more lag than the low pass driven by the held tau_d), the drive's current
    limit (the SEA follows clip(tau_d, -sat, sat); tau_d is recorded
    unclipped), the sensors' delays (DelayLine: the cuff torque and the
    angle the controller uses are the delayed readings; the angle is
    delayed before its noise and quantisation, so omega_e is too), and
    the cuff: with cuff_k > 0 the forearm is a body of its own (angle
    th_h, inertia M_h; the human's springs, dampers and Maxwell element act
    on it) joined to the arm (th, inertia M_e) by tau_c = cuff_k (th - th_h)
    + cuff_b (om - om_h), which pushes the forearm and holds the arm back;
    integrated with cuff_substeps() RK4 steps a tick. Each spec's
    posture_shift (rad) is added to the subject's posture reference theta_p
    (the controller and its plan do not change); the period then starts at
    rest at the angle where that reference holds it. substeps: RK4 steps a
    tick (default: as the lash and the cuff need), for convergence checks."""
    tm = rig.tm
    dt, t_analysis, n_sim, t_sine, t_ramp_out = tm.dt, tm.t_analysis, tm.n_sim, tm.t_sine, tm.t_ramp_out
    rec0 = t_analysis - tm.ticks(pre_window_s)
    n_rec = n_sim - rec0
    col = lambda key: np.array([s[key] for s in specs], dtype=float)
    alpha, load, m_h = col("alpha"), col("load_kg"), col("m_h")
    k, b, km, inv_tau = col("k0"), col("b0"), col("km"), 1.0 / col("tau_m")
    bank = km.ndim == 2  # --damping prony: (P, elements)

    def maxwell(x, q_):  # the Maxwell elements' torque on a body at angle x
        return np.sum(km * (x[:, None] - q_), axis=1) if bank else km * (x - q_)

    def relax(x, q_):  # their damper nodes' rates
        return (x[:, None] - q_) * inv_tau if bank else (x - q_) * inv_tau
    # The static stiffness at every tick: k0 + k_drift K t / 60.
    t_exp = ((col("period") - 1.0) * tm.t_period)[:, None] * dt + (np.arange(n_sim) - t_analysis)[None, :] * dt
    k_t = k[:, None] + (k_drift / 60.0) * col("k")[:, None] * t_exp
    omega, amp, bias = col("omega"), col("amplitude"), col("bias_nm")
    th_rest, th_goal = col("theta_rest"), col("theta_goal")
    shift = col("posture_shift") if specs and "posture_shift" in specs[0] else np.zeros(len(specs))
    shifted = bool(np.any(shift != 0.0))
    kc, bc = rig.cuff_k, rig.cuff_b
    P = len(specs)
    m_tot = m_e(load) + m_h - (MOTOR_SIDE_INERTIA if lash else 0.0)
    inv_m = 1.0 / m_tot
    inv_me = 1.0 / (m_e(load) - (MOTOR_SIDE_INERTIA if lash else 0.0))  # the arm alone (compliant cuff)
    inv_mh = 1.0 / m_h
    g_true = G * (ARM_MASS * ARM_COM + load * LEVER)
    g_comp = G * (COMP_ARM_MASS_FACTOR * ARM_MASS * ARM_COM + COMP_LOAD_MASS_FACTOR * load * LEVER)
    if horizontal:
        g_true, g_comp = 0.0 * g_true, 0.0 * g_comp
    w_s = 2.0 * math.pi * rig.sea_hz
    w2, z2 = w_s * w_s, 2.0 * rig.sea_zeta * w_s
    tustin = rig.sea_model == "tustin"
    if tustin:  # the SEA's torque ramps to the filter's output: ts' = dts, held over the tick
        w2, z2 = 0.0, 0.0
        (sb0, sb1, sb2), (sa1, sa2) = tustin_sea(rig)
    sat = rig.saturation_nm
    enc_q = rig.enc_q
    ms_wave = rig.multisine["wave"] if rig.multisine else None

    # The subject's input u = K th_p + tau_tw, held over each tick at its
    # mid-tick value. th_p: the planned arm angle, minus the offset the
    # muscles need against bias and residual gravity to hold it there.
    t_mid = (np.arange(n_sim) + 0.5) * dt
    plan = th_rest[:, None] + (th_goal - th_rest)[:, None] * min_jerk(t_mid / RAMP_IN_S)[None, :]
    bias_mid = bias[:, None] * smooth_ramp(t_mid / RAMP_IN_S)[None, :]
    dg = (g_comp - g_true)[:, None] * np.sin(plan)
    th_p = plan - (bias_mid + dg) / (alpha[:, None] * k_t)  # k_t: the static stiffness k0
    if shifted:
        th_p = th_p + shift[:, None]
    u = k_t * th_p
    for i, s in enumerate(specs):
        u[i, s["twitch_tick"]:s["twitch_tick"] + tm.twitch_ticks] += s["twitch_nm"]
    n_enc = np.stack([s["noise_enc"] for s in specs])
    n_tc = np.stack([s["noise_tc"] for s in specs])
    n_ts = np.stack([s["noise_ts"] for s in specs])

    # Initial rest equilibrium (th_p(0) is consistent with it by construction).
    th = th_rest.copy()
    if shifted or kc:
        # At rest the cuff carries tc0 = (g_comp - g_true) sin th / alpha
        # (the controller's balance); the forearm's spring holds it at
        # th_h = th_p + tc0 / k, the cuff's at th = th_h + tc0 / K_c.
        for _ in range(4):
            tc_r = (g_comp - g_true) * np.sin(th) / alpha
            th = th_p[:, 0] + tc_r * (1.0 / k_t[:, 0] + (1.0 / kc if kc else 0.0))
    om = np.zeros(P)
    tc0 = (g_comp - g_true) * np.sin(th if (shifted or kc) else th_rest) / alpha
    th_h = th - tc0 / kc if kc else th  # the forearm (compliant cuff)
    om_h = np.zeros(P)
    q = np.repeat(th_h[:, None], km.shape[1], axis=1) if bank else th_h.copy()  # damper nodes, relaxed
    ts = g_true * np.sin(th if (shifted or kc) else th_rest) + tc0
    dts = np.zeros(P)
    # The motor side at rest, in contact on the side its torque pushes.
    mot = th + np.sign(ts) * 0.5 * lash + ts / MESH_STIFFNESS
    om_mot = np.zeros(P)
    if tustin:
        sx1 = sx2 = sy1 = sy2 = ts
    th_m_prev = None
    om_e = np.zeros(P)
    a_om = 1.0 - math.exp(-2.0 * math.pi * OMEGA_FILTER_HZ * dt)
    d_enc = DelayLine(rig.encoder_delay_s, dt) if rig.encoder_delay_s else None
    d_tc = DelayLine(rig.cuff_delay_s, dt) if rig.cuff_delay_s else None
    d_ts = DelayLine(rig.sea_delay_s, dt) if rig.sea_delay_s else None

    out = {key: np.empty((P, n_rec)) for key in
           ("theta", "omega_e", "tau_c", "tau_s", "tau_d", "tau_gravity", "tau_amplification",
            "tau_bias", "tau_excitation")}

    h = dt
    if substeps is None:
        substeps = max(tm.mesh_substeps if lash else 1, cuff_substeps(specs, rig, lash))
    for n in range(n_sim):
        t = n * dt
        un = u[:, n]
        kn = k_t[:, n]
        # --- sensors at tick n
        if kc:
            tau_c = kc * (th - th_h) + bc * (om - om_h)
        else:
            f_h = b * om + kn * th + maxwell(th, q) - un  # the human's passive torque less the voluntary
            if k_cubic:
                f_h = f_h + k_cubic * (th - th_p[:, n]) ** 3
            if b_cubic:
                f_h = f_h + b_cubic * om ** 3
            if k_quad:
                f_h = f_h + 0.5 * k_quad * (th - plan[:, n]) ** 2
            drive = mesh(mot - th, om_mot - om, lash) if lash else ts
            acc = (drive - g_true * np.sin(th) - k_exo_spring * (th - th_goal) - f_h) * inv_m
            tau_c = m_h * acc + f_h
        th_m = np.round(((d_enc(th) if d_enc else th) + n_enc[:, n]) / enc_q) * enc_q
        tc_m = (d_tc(tau_c) if d_tc else tau_c) + n_tc[:, n]
        ts_m = (d_ts(ts) if d_ts else ts) + n_ts[:, n]
        if th_m_prev is not None:
            om_e += a_om * ((th_m - th_m_prev) / dt - om_e)
        th_m_prev = th_m
        # --- controller
        t_gc = g_comp * np.sin(th_m)
        t_amp = (1.0 - alpha) * tc_m + 0.0  # + 0.0: no -0.0 at alpha = 1
        t_bias = bias * float(smooth_ramp(t / RAMP_IN_S))
        if t_sine <= n < t_ramp_out and ms_wave is not None:
            t_x = amp * ms_wave[(n - t_sine) % len(ms_wave)]  # the multisine from its period's sample 0
        elif t_sine <= n < t_ramp_out:
            t_x = amp * np.sin(omega * ((n - t_sine) * dt))
        else:
            t_x = np.zeros(P)
        tau_d = t_gc + t_amp + t_bias + t_x
        if n >= rec0:
            j = n - rec0
            for key, v in (("theta", th_m), ("omega_e", om_e), ("tau_c", tc_m), ("tau_s", ts_m),
                           ("tau_d", tau_d), ("tau_gravity", t_gc), ("tau_amplification", t_amp),
                           ("tau_bias", t_bias), ("tau_excitation", t_x)):
                out[key][:, j] = v
        if n == n_sim - 1:
            break
        # --- the drive: its current limit, then the SEA
        tau_in = np.clip(tau_d, -sat, sat) if sat else tau_d
        if tustin:
            y_s = sb0 * tau_in + sb1 * sx1 + sb2 * sx2 - sa1 * sy1 - sa2 * sy2
            sx2, sx1, sy2, sy1 = sx1, tau_in, sy1, y_s
            dts = (y_s - ts) / h
        # --- plant: RK4 over [t, t + h] with tau_d and u held
        thp = th_p[:, n]
        pln = plan[:, n]

        if kc:
            def f(th_, om_, ts_, dts_, q_, thh_, omh_, *motor):
                nonlin = ((k_cubic * (thh_ - thp) ** 3 if k_cubic else 0.0)
                          + (b_cubic * omh_ ** 3 if b_cubic else 0.0)
                          + (0.5 * k_quad * (thh_ - pln) ** 2 if k_quad else 0.0))
                tc = kc * (th_ - thh_) + bc * (om_ - omh_)
                drive_ = mesh(motor[0] - th_, motor[1] - om_, lash) if lash else ts_
                d = (om_, (drive_ - g_true * np.sin(th_) - k_exo_spring * (th_ - th_goal) - tc) * inv_me,
                     dts_, w2 * (tau_in - ts_) - z2 * dts_, relax(thh_, q_),
                     omh_, (tc - b * omh_ - kn * thh_ - maxwell(thh_, q_) - nonlin + un) * inv_mh)
                return d + (motor[1], (ts_ - drive_) / MOTOR_SIDE_INERTIA) if lash else d
            y = rk4(f, (th, om, ts, dts, q, th_h, om_h) + ((mot, om_mot) if lash else ()), h / substeps, substeps)
            th, om, ts, dts, q, th_h, om_h = y[:7]
            if lash:
                mot, om_mot = y[7:]
            continue

        def f(th_, om_, ts_, dts_, q_):
            nonlin = ((k_cubic * (th_ - thp) ** 3 if k_cubic else 0.0) + (b_cubic * om_ ** 3 if b_cubic else 0.0)
                      + (0.5 * k_quad * (th_ - pln) ** 2 if k_quad else 0.0))
            spring = k_exo_spring * (th_ - th_goal)
            return (om_, (ts_ - g_true * np.sin(th_) - spring - b * om_ - kn * th_ - maxwell(th_, q_) - nonlin + un)
                    * inv_m,
                    dts_, w2 * (tau_in - ts_) - z2 * dts_, relax(th_, q_))
        if lash:
            def f(th_, om_, ts_, dts_, q_, mot_, om_mot_):
                nonlin = ((k_cubic * (th_ - thp) ** 3 if k_cubic else 0.0)
                         + (b_cubic * om_ ** 3 if b_cubic else 0.0)
                         + (0.5 * k_quad * (th_ - pln) ** 2 if k_quad else 0.0))
                spring = k_exo_spring * (th_ - th_goal)
                tm_ = mesh(mot_ - th_, om_mot_ - om_, lash)
                return (om_, (tm_ - g_true * np.sin(th_) - spring - b * om_ - kn * th_ - maxwell(th_, q_) - nonlin
                              + un) * inv_m,
                        dts_, w2 * (tau_in - ts_) - z2 * dts_, relax(th_, q_),
                        om_mot_, (ts_ - tm_) / MOTOR_SIDE_INERTIA)
            th, om, ts, dts, q, mot, om_mot = rk4(f, (th, om, ts, dts, q, mot, om_mot), h / substeps, substeps)
            continue
        th, om, ts, dts, q = rk4(f, (th, om, ts, dts, q), h / substeps, substeps)
    if not all(np.isfinite(v).all() for v in out.values()):
        raise RuntimeError("simulation diverged")
    return out


# ---------------------------------------------------------------- contract schemas
SENSOR_SCHEMA = ("exo_msgs/msg/SensorSample", "exo/sensor",
                 "uint64 seq\nuint64 stamp_ns\nfloat64 theta_e\nfloat64 omega_e\n"
                 "float64 tau_c\nfloat64 tau_s\nuint32 status\n")
COMMAND_SCHEMA = ("exo_msgs/msg/ActuatorCommand", "exo/command",
                  "uint64 seq\nuint64 stamp_ns\nuint64 sensor_seq\nfloat64 tau_d\n"
                  "float64 tau_gravity\nfloat64 tau_amplification\nfloat64 tau_bias\n"
                  "float64 tau_excitation\nuint32 mode\n")
PROTOCOL_SCHEMA = ("exo_msgs/msg/ProtocolState", "exo/protocol",
                   "uint32 experiment\nuint32 period\nuint32 phase\nfloat64 omega\n"
                   "float64 amplitude\nfloat64 alpha\nfloat64 load_kg\nfloat64 grip_kg\n"
                   "float64 bias_nm\nuint64 stamp_ns\n")
CH_PROTOCOL, CH_SENSOR, CH_COMMAND = 1, 2, 3

# MCAP message record (opcode, length, channel, sequence, log, publish) then
# the CDR encapsulation header 00 01 00 00 and the payload. CDR alignment is
# relative to the byte after the encapsulation header: with these field
# orders every field already sits on its own size (the sensor and command
# payloads end with a uint32, so no padding anywhere; the protocol's needs
# 4 bytes after `phase`).
_MSG_HDR = [("op", "u1"), ("rlen", "<u8"), ("chan", "<u2"), ("mseq", "<u4"),
            ("log", "<u8"), ("pub", "<u8"), ("encap", "<u4")]
SENSOR_DT = np.dtype(_MSG_HDR + [("seq", "<u8"), ("stamp", "<u8"), ("theta_e", "<f8"),
                                 ("omega_e", "<f8"), ("tau_c", "<f8"), ("tau_s", "<f8"),
                                 ("status", "<u4")])
COMMAND_DT = np.dtype(_MSG_HDR + [("seq", "<u8"), ("stamp", "<u8"), ("sensor_seq", "<u8"),
                                  ("tau_d", "<f8"), ("tau_gravity", "<f8"),
                                  ("tau_amplification", "<f8"), ("tau_bias", "<f8"),
                                  ("tau_excitation", "<f8"), ("mode", "<u4")])
PAIR_DT = np.dtype([("s", SENSOR_DT), ("c", COMMAND_DT)])
ENCAP = int.from_bytes(b"\x00\x01\x00\x00", "little")
_PROTO_STRUCT = struct.Struct("<BQHIQQ" + "4sIII4xddddddQ")


def protocol_record(mseq, stamp, experiment, period, phase, omega, amplitude, alpha, load, grip, bias):
    return _PROTO_STRUCT.pack(0x05, _PROTO_STRUCT.size - 9, CH_PROTOCOL, mseq & 0xFFFFFFFF, stamp, stamp,
                              b"\x00\x01\x00\x00", experiment, period, phase,
                              omega, amplitude, alpha, load, grip, bias, stamp)


# ---------------------------------------------------------------- MCAP container
def _s(x):
    b = x.encode()
    return struct.pack("<I", len(b)) + b


def _map(d):
    body = b"".join(_s(k) + _s(v) for k, v in d.items())
    return struct.pack("<I", len(body)) + body


def _rec(op, body):
    return struct.pack("<BQ", op, len(body)) + body


MAGIC = b"\x89MCAP0\r\n"


class OwnMcapWriter:
    """A small chunked MCAP writer (profile ros2) for pre-built message
    records: one chunk per call of add_chunk, zstd, with message indexes,
    chunk/metadata indexes, statistics and summary offsets."""

    def __init__(self, path, compression="zstd"):
        try:
            import zstandard  # installed with mcap
        except ImportError:
            zstandard = None
        self.f = open(path, "wb")
        self.zc = zstandard.ZstdCompressor(level=3) if compression == "zstd" and zstandard else None
        self.compression = compression if self.zc else ""
        self.schemas, self.channels = [], []
        self.chunk_index, self.meta_index = [], []
        self.counts = {}
        self.n_msgs, self.t0, self.t1 = 0, None, 0
        self.f.write(MAGIC)
        self.f.write(_rec(0x01, _s("ros2") + _s(SOFTWARE)))

    def register(self, sid, name, topic, text):
        body = text.encode()
        s = _rec(0x03, struct.pack("<H", sid) + _s(name) + _s("ros2msg") + struct.pack("<I", len(body)) + body)
        c = _rec(0x04, struct.pack("<HH", sid, sid) + _s(topic) + _s("cdr") + _map({}))
        self.schemas.append(s)
        self.channels.append(c)
        self.f.write(s)
        self.f.write(c)
        self.counts[sid] = 0

    def add_metadata(self, name, d):
        off = self.f.tell()
        r = _rec(0x0C, _s(name) + _map(d))
        self.f.write(r)
        self.meta_index.append(_rec(0x0D, struct.pack("<QQ", off, len(r)) + _s(name)))

    def add_chunk(self, records, index, t_start, t_end):
        """records: the chunk's message records (bytes); index: {channel:
        (log_times, offsets)} numpy arrays, offsets into records."""
        raw = records
        data = self.zc.compress(raw) if self.zc else raw
        start = self.f.tell()
        body = (struct.pack("<QQQI", t_start, t_end, len(raw), zlib.crc32(raw)) + _s(self.compression)
                + struct.pack("<Q", len(data)))
        self.f.write(struct.pack("<BQ", 0x06, len(body) + len(data)) + body)
        self.f.write(data)
        chunk_len = self.f.tell() - start
        mi_offsets = {}
        mi_start = self.f.tell()
        for ch in sorted(index):
            logs, offs = index[ch]
            arr = np.empty((len(logs), 2), dtype="<u8")
            arr[:, 0], arr[:, 1] = logs, offs
            mi_offsets[ch] = self.f.tell()
            self.f.write(_rec(0x07, struct.pack("<HI", ch, arr.nbytes) + arr.tobytes()))
            self.counts[ch] += len(logs)
            self.n_msgs += len(logs)
        mi_len = self.f.tell() - mi_start
        mo = b"".join(struct.pack("<HQ", ch, o) for ch, o in mi_offsets.items())
        self.chunk_index.append(_rec(0x08, struct.pack("<QQQQ", t_start, t_end, start, chunk_len)
                                     + struct.pack("<I", len(mo)) + mo + struct.pack("<Q", mi_len)
                                     + _s(self.compression) + struct.pack("<QQ", len(data), len(raw))))
        self.t0 = t_start if self.t0 is None else min(self.t0, t_start)
        self.t1 = max(self.t1, t_end)

    def finish(self):
        self.f.write(_rec(0x0F, struct.pack("<I", 0)))
        summary_start = self.f.tell()
        groups = [(0x03, self.schemas), (0x04, self.channels)]
        cm = b"".join(struct.pack("<HQ", ch, n) for ch, n in self.counts.items())
        stats = _rec(0x0B, struct.pack("<QHIIIIQQ", self.n_msgs, len(self.schemas), len(self.channels), 0,
                                       len(self.meta_index), len(self.chunk_index), self.t0 or 0, self.t1)
                     + struct.pack("<I", len(cm)) + cm)
        groups += [(0x0B, [stats]), (0x08, self.chunk_index), (0x0D, self.meta_index)]
        summary = bytearray()
        offsets = []
        for op, recs in groups:
            g0 = len(summary)
            for r in recs:
                summary += r
            offsets.append(_rec(0x0E, struct.pack("<BQQ", op, summary_start + g0, len(summary) - g0)))
        summary_offset_start = summary_start + len(summary)
        for r in offsets:
            summary += r
        crc = zlib.crc32(bytes(summary))
        crc = zlib.crc32(struct.pack("<BQQQ", 0x02, 20, summary_start, summary_offset_start), crc)
        self.f.write(summary)
        self.f.write(_rec(0x02, struct.pack("<QQI", summary_start, summary_offset_start, crc)))
        self.f.write(MAGIC)
        self.f.close()


class LibMcapWriter:
    """The same chunks written message by message through the mcap library's
    Writer (slow; to cross-check OwnMcapWriter)."""

    def __init__(self, path):
        from mcap.writer import Writer
        self.f = open(path, "wb")
        self.w = Writer(self.f)
        self.w.start("ros2", SOFTWARE)
        self.ch = {}

    def register(self, sid, name, topic, text):
        s = self.w.register_schema(name, "ros2msg", text.encode())
        self.ch[sid] = self.w.register_channel(topic, "cdr", s)

    def add_metadata(self, name, d):
        self.w.add_metadata(name, d)

    def add_chunk(self, records, index, t_start, t_end):
        mv = memoryview(records)
        pos = 0
        while pos < len(mv):
            op, ln = struct.unpack_from("<BQ", mv, pos)
            assert op == 0x05
            ch, mseq, log, pub = struct.unpack_from("<HIQQ", mv, pos + 9)
            self.w.add_message(self.ch[ch], log, bytes(mv[pos + 31:pos + 9 + ln]), pub, mseq)
            pos += 9 + ln

    def finish(self):
        self.w.finish()
        self.f.close()


# ---------------------------------------------------------------- recording
def phase_at(lt, tm):
    if lt < tm.t_sine:
        return 1
    if lt < tm.t_analysis:
        return 2
    if lt < tm.t_ramp_out:
        return 3
    if lt < tm.t_rest:
        return 4
    return 5


def multisine_meta(ms):
    """The exo metadata keys that name a multisine's lines
    (docs/recording-format.md), written by this script's own hand."""
    floats = lambda v: ",".join(repr(float(x)) for x in v)
    return {"protocol_mode": "multisine", "excitation": "multisine",
            "multisine_period_samples": str(ms["n"]), "multisine_bins": ",".join(str(b) for b in ms["bins"]),
            "multisine_amplitudes": floats(ms["amplitudes"]), "multisine_phases_rad": floats(ms["phases"])}


def write_recording(path, subject_name, seed, specs, sim, noise_scale, writer="own", extra_meta=None, tm=NOMINAL.tm,
                    ms=None):
    """Writes one recording: the periods of specs (in order) with their
    simulated samples sim (rows in the order of specs) at tm's rate; ms (a
    multisine_design) names the lines in the metadata."""
    n_rec = sim["theta"].shape[1]  # recorded ticks per period: the last n_rec simulated ones
    rec0 = tm.n_sim - n_rec
    TICK_NS = tm.tick_ns
    w = OwnMcapWriter(path) if writer == "own" else LibMcapWriter(path)
    w.register(CH_PROTOCOL, PROTOCOL_SCHEMA[0], PROTOCOL_SCHEMA[1], PROTOCOL_SCHEMA[2])
    w.register(CH_SENSOR, SENSOR_SCHEMA[0], SENSOR_SCHEMA[1], SENSOR_SCHEMA[2])
    w.register(CH_COMMAND, COMMAND_SCHEMA[0], COMMAND_SCHEMA[1], COMMAND_SCHEMA[2])
    meta = {
        "subject": subject_name,
        "software_version": SOFTWARE,
        "rate_hz": str(tm.rate_hz),
        "arm_inertia_kg_m2": repr(ARM_INERTIA),
        "load_lever_arm_m": repr(LEVER),
        "seed": str(seed),
        "noise_scale": repr(float(noise_scale)),
        "recorded_samples": f"from {(tm.t_analysis - rec0) / tm.rate_hz:g} s before each analysis window "
                            "to its end (inclusive); seq counts the written samples",
    }
    meta.update(multisine_meta(ms) if ms else {})
    meta.update(extra_meta or {})
    w.add_metadata("exo", meta)

    pair_size = PAIR_DT.itemsize
    s_size = SENSOR_DT.itemsize
    seq0 = 0
    n_proto = 0

    def proto(tick, e, k, ph, sp):
        nonlocal n_proto
        r = protocol_record(n_proto, tick * TICK_NS, e, k, ph, sp["omega"] if sp else 0.0,
                            sp["amplitude"] if sp else 0.0, sp["alpha"] if sp else 1.0,
                            sp["load_kg"] if sp else 0.0, sp["grip_kg"] if sp else 0.0,
                            sp["bias_nm"] if sp else 0.0)
        n_proto += 1
        return r

    # Idle before the protocol.
    t_idle = [i * tm.rate_hz for i in range(tm.lead_ticks // tm.rate_hz)]
    recs = [proto(t, 0, 0, 0, None) for t in t_idle]
    w.add_chunk(b"".join(recs), {CH_PROTOCOL: (np.array(t_idle, dtype=np.uint64) * TICK_NS,
                                               np.arange(len(recs), dtype=np.uint64) * _PROTO_STRUCT.size)},
                t_idle[0] * TICK_NS, t_idle[-1] * TICK_NS)

    keys_s = ("theta_e", "omega_e", "tau_c", "tau_s")
    src_s = ("theta", "omega_e", "tau_c", "tau_s")
    keys_c = ("tau_d", "tau_gravity", "tau_amplification", "tau_bias", "tau_excitation")
    for j, sp in enumerate(specs):
        base = tm.lead_ticks + j * tm.t_period
        e, k = sp["experiment"], sp["period"]
        # Sensor + command pairs of the recorded ticks.
        pairs = np.zeros(n_rec, dtype=PAIR_DT)
        gt = base + rec0 + np.arange(n_rec, dtype=np.uint64)
        stamps = gt * np.uint64(TICK_NS)
        seqs = seq0 + np.arange(n_rec, dtype=np.uint64)
        for part, dt_, ch in (("s", SENSOR_DT, CH_SENSOR), ("c", COMMAND_DT, CH_COMMAND)):
            p = pairs[part]
            p["op"] = 0x05
            p["rlen"] = dt_.itemsize - 9
            p["chan"] = ch
            p["mseq"] = seqs & np.uint64(0xFFFFFFFF)
            p["log"] = stamps
            p["pub"] = stamps
            p["encap"] = ENCAP
            p["seq"] = seqs
            p["stamp"] = stamps
        for key, src in zip(keys_s, src_s):
            pairs["s"][key] = sim[src][j]
        pairs["s"]["status"] = 0
        pairs["c"]["sensor_seq"] = seqs
        for key in keys_c:
            pairs["c"][key] = sim[key][j]
        pairs["c"]["mode"] = 1
        seq0 += n_rec
        pair_bytes = pairs.tobytes()

        # Merge protocol states (every change, and once a second) with the pairs.
        proto_ticks = sorted(set(range(0, tm.t_period, tm.rate_hz))
                             | {0, tm.t_sine, tm.t_analysis, tm.t_ramp_out, tm.t_rest})
        segs, p_logs, p_offs = [], [], []
        s_offs = np.empty(n_rec, dtype=np.uint64)
        pos, next_pair = 0, 0

        def flush_pairs(upto):  # pairs with local index < upto
            nonlocal pos, next_pair
            if upto > next_pair:
                segs.append(pair_bytes[next_pair * pair_size:upto * pair_size])
                s_offs[next_pair:upto] = pos + pair_size * np.arange(upto - next_pair, dtype=np.uint64)
                pos += (upto - next_pair) * pair_size
                next_pair = upto

        for lt in proto_ticks:
            flush_pairs(min(max(lt - rec0, 0), n_rec))
            r = proto(base + lt, e, k, phase_at(lt, tm), sp)
            p_logs.append((base + lt) * TICK_NS)
            p_offs.append(pos)
            segs.append(r)
            pos += len(r)
        flush_pairs(n_rec)
        index = {
            CH_PROTOCOL: (np.array(p_logs, dtype=np.uint64), np.array(p_offs, dtype=np.uint64)),
            CH_SENSOR: (stamps, s_offs),
            CH_COMMAND: (stamps, s_offs + np.uint64(s_size)),
        }
        w.add_chunk(b"".join(segs), index, base * TICK_NS, (base + proto_ticks[-1]) * TICK_NS)

    end = tm.lead_ticks + len(specs) * tm.t_period
    r = proto(end, 0, 0, 0, None)
    w.add_chunk(r, {CH_PROTOCOL: (np.array([end * TICK_NS], dtype=np.uint64), np.zeros(1, dtype=np.uint64))},
                end * TICK_NS, end * TICK_NS)
    w.add_metadata("exo.drops", {"exo/sensor": "0", "exo/command": "0", "exo/protocol": "0"})
    w.finish()


# ---------------------------------------------------------------- truth
def subject_truth(name, seed, subject, specs, tm=NOMINAL.tm, ms=None):
    """The truth of one subject's recording: per experiment its settings,
    each period's realisation and S_h at the period's omega (s_h_re, s_h_im;
    exact), and with a multisine ms S_h at every excited line (lines) with
    the M2 that fits those values (m2_of_lines)."""
    exps = {}
    for sp in specs:
        e = exps.setdefault(str(sp["experiment"]), dict(
            alpha=sp["alpha"], load_kg=sp["load_kg"], grip_kg=sp["grip_kg"], bias_nm=sp["bias_nm"],
            m_e=m_e(sp["load_kg"]), k=sp["k"], h=sp["h"], c=sp["h"] / sp["k"],
            omega=[], amplitude=[], theta_goal=[], twitch_impulse_nms=[],
            realisation=dict(k0=[], b0=[], km=[], tau_m=[]), mode_omega=[], mode_zeta=[],
            loop_growth_per_s=[], loop_omega=[]))
        e["omega"].append(sp["omega"])
        e["amplitude"].append(sp["amplitude"])
        if not ms:
            z = human_response(sp, sp["omega"])
            e.setdefault("s_h_re", []).append(z.real)
            e.setdefault("s_h_im", []).append(z.imag)
        elif "lines" not in e:
            zs = [human_response(sp, w) for w in ms["omega"]]
            e["lines"] = dict(omega=list(ms["omega"]), bins=list(ms["bins"]), s_h_re=[z.real for z in zs],
                              s_h_im=[z.imag for z in zs])
            kk, hh, mm = m2_of(ms["omega"], zs)
            e["m2_of_lines"] = dict(K=kk, H=hh, M=mm)
        for key in ("k0", "b0", "km", "tau_m"):
            e["realisation"][key].append(sp[key])
        e["mode_omega"].append(sp["mode_omega"])
        e["mode_zeta"].append(sp["mode_zeta"])
        e["loop_growth_per_s"].append(sp.get("loop_growth"))
        e["loop_omega"].append(sp.get("loop_omega"))
        e["theta_goal"].append(sp["theta_goal"])
        e["twitch_impulse_nms"].append(sp["twitch_nm"] * tm.twitch_ticks * tm.dt)
    return dict(subject=name, seed=seed, m_h=subject["m_h"], beta0=subject.get("beta0"),
                beta1=subject.get("beta1"), params_source=subject.get("source"),
                subject_table=dict(m_h=subject["m_h"], k=subject["k"], h=subject["h"]),
                experiments=exps)


def rig_truth(rig=NOMINAL):
    tm = rig.tm
    return dict(generator=SOFTWARE, rate_hz=tm.rate_hz, arm_inertia_kg_m2=ARM_INERTIA, load_lever_arm_m=LEVER,
                arm_mass_kg=ARM_MASS, arm_com_m=ARM_COM,
                gravity_comp_mass_factors=dict(arm=COMP_ARM_MASS_FACTOR, load=COMP_LOAD_MASS_FACTOR),
                sea=dict(hz=rig.sea_hz, zeta=rig.sea_zeta), encoder_bits=rig.encoder_bits,
                sigma=dict(tau_c=SIGMA_TAU_C, tau_s=SIGMA_TAU_S, encoder=SIGMA_ENC),
                omega_filter_hz=OMEGA_FILTER_HZ,
                hysteresis="S_h(s) = M_h s^2 + b0 s + k0 + km tau_m s / (1 + tau_m s) per period, exact "
                           "K - M_h w^2 + j H at the period's omega (viscous: b0 = H / omega, k0 = K, km = 0)",
                mode="mode_omega/mode_zeta: slowest oscillatory pole of the linearised closed loop",
                loop="loop_growth_per_s/loop_omega: least stable eigenvalue of the linearised closed loop as "
                     "sampled, ln|z|/dt and |arg z|/dt (> 0: unstable; see sampled_loop)",
                twitch=f"{tm.twitch_ticks * tm.dt * 1e3:g} ms voluntary pulse at a random time in the first second "
                       "of each analysis window")


def options_truth(rig, posture_shift, experiments, mass_scale):
    """The off-nominal rig and subject options, under the truth file's keys."""
    return dict(cuff_delay_s=rig.cuff_delay_s, sea_delay_s=rig.sea_delay_s, encoder_delay_s=rig.encoder_delay_s,
                cuff_compliance_nm_per_rad=rig.cuff_k,
                cuff_damping_nm_s_per_rad=rig.cuff_b if rig.cuff_k else None,
                posture_shift_rad={str(e): float(posture_shift.get(e, 0.0)) for e in experiments},
                rate_hz=rig.tm.rate_hz, encoder_bits=rig.encoder_bits, sea_hz=rig.sea_hz, sea_zeta=rig.sea_zeta,
                sea_model=rig.sea_model, saturation_nm=rig.saturation_nm, mass_scale=mass_scale)


# ---------------------------------------------------------------- command line
def warn_unstable(name_specs):
    """Names the periods whose linearised closed loop has an unstable natural
    mode (its oscillation grows through the window: no steady state there)."""
    for name, specs in name_specs:
        bad = [f"{sp['experiment']}/{sp['period']} (zeta {sp['mode_zeta']:.3f} at {sp['mode_omega']:.1f} rad/s)"
               for sp in specs if sp["mode_zeta"] < 0.0]
        if bad:
            print(f"{SOFTWARE}: {name}: WARNING: unstable closed-loop natural mode in experiment/period "
                  + ", ".join(bad) + "; --damping two-point damps it", file=sys.stderr)
        bad = [f"{sp['experiment']}/{sp['period']} (growth {sp['loop_growth']:.2f} 1/s at {sp['loop_omega']:.1f} rad/s)"
               for sp in specs if sp.get("loop_growth", -1.0) > 0.0 and sp["mode_zeta"] >= 0.0]
        if bad:
            print(f"{SOFTWARE}: {name}: WARNING: the sampled closed loop (delays, cuff, gravity, SEA) is unstable "
                  "in experiment/period " + ", ".join(bad), file=sys.stderr)


def parse_experiments(s):
    ex = [int(x) for x in s.split(",") if x.strip()]
    if not ex or any(e < 1 or e > 9 for e in ex) or len(set(ex)) != len(ex):
        raise SystemExit(f"--experiments: distinct numbers 1-9 expected, got {s!r}")
    return ex


def parse_posture_shift(s, experiments):
    """--posture-shift E:RAD,E:RAD,...: {experiment: rad}."""
    out = {}
    for item in (s or "").split(","):
        if not item.strip():
            continue
        try:
            e_s, r_s = item.split(":")
            e, r = int(e_s), float(r_s)
        except ValueError:
            raise SystemExit(f"--posture-shift: E:RAD pairs expected (e.g. 1:0.03,4:-0.05), got {item!r}")
        if e not in experiments:
            raise SystemExit(f"--posture-shift: experiment {e} is not one of --experiments {experiments}")
        if e in out:
            raise SystemExit(f"--posture-shift: experiment {e} given twice")
        if not (math.isfinite(r) and abs(r) <= 0.3):
            raise SystemExit(f"--posture-shift: {item!r}: the shift must be finite, within +-0.3 rad")
        out[e] = r
    return out


def in_range(name, v, lo, hi, unit):
    """Refuses v unless finite and in [lo, hi]."""
    if not (math.isfinite(v) and lo <= v <= hi):
        raise SystemExit(f"{name} must be finite, in [{lo:g}, {hi:g}]{' ' + unit if unit else ''}, got {v!r}")
    return v


def rig_from_args(a):
    """The Rig of the command line's options, each checked."""
    for name, v in (("--cuff-delay", a.cuff_delay), ("--sea-delay", a.sea_delay),
                    ("--encoder-delay", a.encoder_delay)):
        in_range(name, v, 0.0, MAX_SENSOR_DELAY_S, "s")
    in_range("--cuff-compliance", a.cuff_compliance, 0.0, 1e5, "Nm/rad")
    if 0.0 < a.cuff_compliance < 10.0:
        raise SystemExit("--cuff-compliance must be 0 (rigid) or in [10, 100000] Nm/rad")
    if a.cuff_damping is not None:
        if not a.cuff_compliance:
            raise SystemExit("--cuff-damping needs --cuff-compliance K > 0 (a rigid cuff has no damper)")
        in_range("--cuff-damping", a.cuff_damping, 0.0, 50.0, "Nm s/rad")
    if a.rate_hz not in RATES_HZ:
        raise SystemExit(f"--rate-hz must be one of {', '.join(map(str, RATES_HZ))}, got {a.rate_hz}")
    if not 12 <= a.encoder_bits <= 24:
        raise SystemExit(f"--encoder-bits must be in [12, 24], got {a.encoder_bits}")
    in_range("--sea-hz", a.sea_hz, 1.0, 50.0, "Hz")
    in_range("--sea-zeta", a.sea_zeta, 0.2, 2.0, "")
    if not (math.isfinite(a.saturation) and a.saturation >= 0.0):
        raise SystemExit(f"--saturation must be finite and >= 0 Nm (0 = no limit), got {a.saturation!r}")
    in_range("--mass-scale", a.mass_scale, 0.5, 2.0, "")
    ms, band = None, MS_BAND
    if a.damping is None:
        a.damping = "prony" if a.protocol == "multisine" else "two-point"
    if a.protocol == "multisine":
        if a.damping != "prony":
            raise SystemExit(f"--protocol multisine needs --damping prony (got {a.damping}: an equivalent viscous "
                             "human is exact at one sine only)")
        band = parse_band(a.ms_band, a.rate_hz)
        if not 2 <= a.ms_lines <= 64:
            raise SystemExit(f"--ms-lines must be in [2, 64], got {a.ms_lines}")
        in_range("--ms-period", a.ms_period, 1.0, 120.0, "s")
        if not 0 <= a.ms_settle_periods <= 10:
            raise SystemExit(f"--ms-settle-periods must be in [0, 10], got {a.ms_settle_periods}")
        if not 2 <= a.ms_periods <= 20:
            raise SystemExit(f"--ms-periods must be in [2, 20] (the noise is their spread), got {a.ms_periods}")
        ms = multisine_design(a.rate_hz, band, a.ms_lines, a.ms_period, a.ms_settle_periods, a.ms_periods,
                              period_amplitude(N_PERIODS - 1))
    elif a.damping == "prony":
        band = parse_band(a.ms_band, a.rate_hz)
    return Rig(rate_hz=a.rate_hz, encoder_bits=a.encoder_bits, sea_hz=a.sea_hz, sea_zeta=a.sea_zeta,
               sea_model=a.sea_model, saturation_nm=a.saturation, cuff_delay_s=a.cuff_delay,
               sea_delay_s=a.sea_delay, encoder_delay_s=a.encoder_delay, cuff_k=a.cuff_compliance,
               cuff_b=CUFF_DAMPING if a.cuff_damping is None else a.cuff_damping, multisine=ms,
               prony_band=band)


def parse_band(s, rate_hz):
    """--ms-band LO,HI (rad/s): 0 < LO < HI below Nyquist."""
    try:
        lo, hi = (float(x) for x in s.split(","))
    except ValueError:
        raise SystemExit(f"--ms-band must be LO,HI in rad/s, got {s!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo < hi < math.pi * rate_hz):
        raise SystemExit(f"--ms-band {s}: needs 0 < LO < HI < Nyquist ({math.pi * rate_hz:g} rad/s)")
    return lo, hi


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", nargs="?", help="output .mcap (single-recording mode)")
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--subject", default=None, help="subject name (default indep<seed>)")
    ap.add_argument("--experiments", default="1,2,3,4,5,6,7,8,9")
    ap.add_argument("--periods", type=int, default=N_PERIODS)
    ap.add_argument("--truth", help="write the true parameters to this JSON file")
    ap.add_argument("--noise-scale", type=float, default=1.0,
                    help="multiplies the sensor noise (tau_c, tau_s, encoder); quantisation stays")
    ap.add_argument("--twitch", type=float, default=TWITCH_IMPULSE_SIGMA,
                    help="standard deviation of the analysis-window twitch impulse, N m s (0 = none)")
    ap.add_argument("--damping", choices=("viscous", "two-point", "prony"), default=None,
                    help="realisation of the hysteretic damping H: viscous B = H / omega_k; two-point: loss H "
                         "at omega_k and at the arm's natural frequency (see human_realisation; the default of "
                         "the sine steps); prony: a causal bank of Maxwell elements, loss about H across the "
                         "band (see prony_realisation; the default and only human of --protocol multisine)")
    ap.add_argument("--protocol", choices=("sines", "multisine"), default="sines",
                    help="sines: the paper's sine steps (--periods of them); multisine: one period per "
                         "experiment of a designed multisine (see multisine_design)")
    ap.add_argument("--ms-band", default=f"{MS_BAND[0]:g},{MS_BAND[1]:g}", metavar="LO,HI",
                    help="multisine: the band of its lines, rad/s (also the band of --damping prony's loss)")
    ap.add_argument("--ms-lines", type=int, default=MS_LINES, metavar="L", help="multisine: lines (2-64)")
    ap.add_argument("--ms-period", type=float, default=MS_PERIOD_S, metavar="S",
                    help="multisine: one period, s (1-120; a whole number of samples)")
    ap.add_argument("--ms-settle-periods", type=int, default=MS_SETTLE_PERIODS, metavar="N",
                    help="multisine: periods of settling before the analysis (0-10)")
    ap.add_argument("--ms-periods", type=int, default=MS_PERIODS, metavar="N",
                    help="multisine: periods analysed (2-20: the noise is their spread)")
    ap.add_argument("--random-subject", action="store_true",
                    help="draw the subject's parameters from the seed (default: the built-in table)")
    ap.add_argument("--params", help="JSON with m_h, k[9], h[9] overriding the table")
    ap.add_argument("--writer", choices=("own", "mcap"), default="own",
                    help="own: fast numpy chunk writer; mcap: the mcap library's Writer (slow)")
    ap.add_argument("--monte-carlo", type=int, metavar="N")
    ap.add_argument("--out-dir")
    ap.add_argument("--table-subject", action="store_true",
                    help="Monte Carlo: every subject uses the table (default: drawn from its seed)")
    ap.add_argument("--pre-window", type=float, default=PRE_WINDOW_S, metavar="S",
                    help="seconds of samples written before each analysis window (0-5)")
    ap.add_argument("--k3", type=float, default=0.0, metavar="K3",
                    help="stiffening spring of the human joint: K3 (theta - theta_p)^3, Nm/rad^3 (0 = linear)")
    ap.add_argument("--k2", type=float, default=0.0, metavar="K2",
                    help="a stiffness that depends on posture: K2/2 (theta - planned angle)^2 in the human's spring, Nm/rad^2 "
                         "(0 = none)")
    ap.add_argument("--horizontal", action="store_true",
                    help="a horizontal rig: no gravity on the arm and none compensated")
    ap.add_argument("--b3", type=float, default=0.0, metavar="B3",
                    help="cubic damper of the human joint: B3 omega^3, Nm s^3/rad^3 (0 = none)")
    ap.add_argument("--exo-spring", type=float, default=0.0, metavar="K",
                    help="spring in the exoskeleton joint centred at the posture goal, Nm/rad (0 = none)")
    ap.add_argument("--k-drift", type=float, default=0.0, metavar="RHO",
                    help="the human's stiffness drifting within each experiment, K (1 + RHO t/60), "
                         "RHO per minute, t from the experiment's first analysis window (0 = none)")
    ap.add_argument("--lash", type=float, default=0.0, metavar="RAD",
                    help="backlash (total lost motion, rad) in the exoskeleton joint's gear mesh between the "
                         "SEA's output and the arm (0 = none)")
    ap.add_argument("--cuff-delay", type=float, default=0.0, metavar="S",
                    help="pure delay of the cuff torque sensor's reading tau_c, s (0-0.05; the controller uses "
                         "the delayed reading)")
    ap.add_argument("--sea-delay", type=float, default=0.0, metavar="S",
                    help="pure delay of the SEA torque sensor's reading tau_s, s (0-0.05)")
    ap.add_argument("--encoder-delay", type=float, default=0.0, metavar="S",
                    help="pure delay of the encoder's angle before its quantisation, s (0-0.05; theta_e, omega_e "
                         "and the gravity compensation are delayed)")
    ap.add_argument("--cuff-compliance", type=float, default=0.0, metavar="K",
                    help="stiffness of the cuff between the arm and the forearm, Nm/rad (0 = rigid; else "
                         "10-100000): the forearm becomes a body of its own")
    ap.add_argument("--cuff-damping", type=float, default=None, metavar="B",
                    help=f"damping of the compliant cuff, Nm s/rad (0-50; default {CUFF_DAMPING:g})")
    ap.add_argument("--posture-shift", default="", metavar="E:RAD,...",
                    help="the subject's posture reference offset by RAD (|RAD| <= 0.3) in experiment E, the "
                         "controller unchanged (re-seated between experiments; others 0)")
    ap.add_argument("--rate-hz", type=int, default=RATE_HZ, metavar="HZ",
                    help="control and sample rate, 500 or 1000 Hz (the noise per sample stays)")
    ap.add_argument("--encoder-bits", type=int, default=ENC_BITS, metavar="N",
                    help=f"encoder quantisation, bits a turn (12-24; default {ENC_BITS})")
    ap.add_argument("--sea-hz", type=float, default=SEA_HZ, metavar="F",
                    help=f"natural frequency of the SEA's second-order low pass, Hz (1-50; default {SEA_HZ:g})")
    ap.add_argument("--sea-zeta", type=float, default=SEA_ZETA, metavar="Z",
                    help=f"damping ratio of the SEA's low pass (0.2-2; default {SEA_ZETA:g})")
    ap.add_argument("--sea-model", choices=("lowpass", "tustin"), default="lowpass",
                    help="lowpass: the continuous low pass integrated with the plant; tustin: the same low pass "
                         "discretised (pre-warped bilinear) at the control rate, its output held over each tick")
    ap.add_argument("--saturation", type=float, default=0.0, metavar="NM",
                    help="the drive's current limit: the SEA follows clip(tau_d, -NM, NM), Nm (0 = none); "
                         "tau_d is recorded unclipped")
    ap.add_argument("--mass-scale", type=float, default=1.0, metavar="X",
                    help="the subject's M_h times X (0.5-2; off-nominal inertia)")
    ap.add_argument("--batch-periods", type=int, default=400, help="periods simulated side by side")
    a = ap.parse_args(argv)
    experiments = parse_experiments(a.experiments)
    if a.seed < 0:
        raise SystemExit("--seed must be >= 0")
    if not 1 <= a.periods <= N_PERIODS:
        raise SystemExit(f"--periods must be 1-{N_PERIODS}")
    if not (a.noise_scale >= 0 and a.twitch >= 0 and 0 <= a.pre_window <= SETTLE_S):
        raise SystemExit("--noise-scale and --twitch must be >= 0, --pre-window in [0, 5] s")
    rig = rig_from_args(a)
    shift = parse_posture_shift(a.posture_shift, experiments)
    scaled = lambda subj: dict(subj, m_h=subj["m_h"] * a.mass_scale)  # --mass-scale
    t_begin = time.perf_counter()

    if a.monte_carlo is not None:
        if not a.out_dir or a.out:
            raise SystemExit("--monte-carlo N needs --out-dir DIR and no OUT")
        os.makedirs(a.out_dir, exist_ok=True)
        per = len(experiments) * (1 if rig.multisine else a.periods)
        per_batch = max(1, a.batch_periods // per)
        truth = dict(rig=rig_truth(rig), seed0=a.seed, experiments=experiments, periods=a.periods,
                     noise_scale=a.noise_scale, twitch_sigma_nms=a.twitch, damping=a.damping,
                     **options_truth(rig, shift, experiments, a.mass_scale), subjects={})
        t_sim = t_write = 0.0
        for b0 in range(0, a.monte_carlo, per_batch):
            t0 = time.perf_counter()
            batch = []  # drawn batch by batch: the noise of all subjects at once would not fit well
            for i in range(b0, min(b0 + per_batch, a.monte_carlo)):
                seed = a.seed + i
                if a.params:
                    subj = load_params(a.params)
                else:
                    subj = table_subject() if a.table_subject else random_subject(seed)
                subj = scaled(subj)
                specs = period_specs(seed, subj, experiments, a.periods, a.noise_scale, a.twitch, a.damping, rig,
                                     shift)
                annotate_loop(specs, rig)
                batch.append((f"mc{i:03d}", seed, subj, specs))
            warn_unstable([(b[0], b[3]) for b in batch])
            sim = simulate([sp for _, _, _, specs in batch for sp in specs], a.pre_window, rig=rig)
            t1 = time.perf_counter()
            for i, (name, seed, subj, specs) in enumerate(batch):
                part = {key: v[i * per:(i + 1) * per] for key, v in sim.items()}
                write_recording(os.path.join(a.out_dir, f"{name}.mcap"), name, seed, specs, part,
                                a.noise_scale, a.writer, tm=rig.tm, ms=rig.multisine)
                truth["subjects"][name] = subject_truth(name, seed, subj, specs, rig.tm, rig.multisine)
            t_write += time.perf_counter() - t1
            t_sim += t1 - t0
        with open(os.path.join(a.out_dir, "truth.json"), "w") as f:
            json.dump(truth, f, indent=1)
        print(f"{a.monte_carlo} recordings x {len(experiments)} experiments in {a.out_dir}: "
              f"{time.perf_counter() - t_begin:.1f} s (simulation {t_sim:.1f} s, writing {t_write:.1f} s)",
              file=sys.stderr)
        return 0

    if not a.out:
        raise SystemExit("OUT.mcap is required (or --monte-carlo N --out-dir DIR)")
    if a.params:
        subj = load_params(a.params)
    elif a.random_subject:
        subj = random_subject(a.seed)
    else:
        subj = table_subject()
    subj = scaled(subj)
    name = a.subject or f"indep{a.seed}"
    specs = period_specs(a.seed, subj, experiments, a.periods, a.noise_scale, a.twitch, a.damping, rig, shift)
    annotate_loop(specs, rig, a.exo_spring, a.horizontal)
    warn_unstable([(name, specs)])
    if not 0.0 <= a.lash <= 0.2:
        raise SystemExit("--lash must be in [0, 0.2] rad")
    if not 0.0 <= a.b3 <= 1e3:
        raise SystemExit("--b3 must be in [0, 1000] Nm s^3/rad^3")
    if not (math.isfinite(a.k2) and abs(a.k2) <= 1e3):
        raise SystemExit("--k2 must be finite, in [-1000, 1000] Nm/rad^2")
    sim = simulate(specs, a.pre_window, a.k3, a.exo_spring, a.k_drift, a.lash, a.b3, a.k2, a.horizontal, rig)
    write_recording(a.out, name, a.seed, specs, sim, a.noise_scale, a.writer, tm=rig.tm, ms=rig.multisine)
    if a.truth:
        t = subject_truth(name, a.seed, subj, specs, rig.tm, rig.multisine)
        t.update(**options_truth(rig, shift, experiments, a.mass_scale))
        t.update(rig=rig_truth(rig), k3_nm_per_rad3=a.k3, k2_nm_per_rad2=a.k2, horizontal=a.horizontal, b3_nm_s3_per_rad3=a.b3, exo_spring_nm_per_rad=a.exo_spring,
                 k_drift_per_min=a.k_drift, lash_rad=a.lash, noise_scale=a.noise_scale, twitch_sigma_nms=a.twitch, damping=a.damping,
                 experiments_written=experiments,
                 periods=a.periods)
        with open(a.truth, "w") as f:
            json.dump(t, f, indent=1)
    print(f"{a.out}: {len(experiments)} experiments x {a.periods} periods in "
          f"{time.perf_counter() - t_begin:.2f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
