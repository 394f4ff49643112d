#!/usr/bin/env python3
"""Checks the physics of independent_rig.py's off-nominal options against
closed forms, and prints the measured numbers.

    check_rig_options.py [--quick]

Every check simulates the table subject (seed 7, --damping two-point) with
no sensor noise and no twitch (the encoder's quantisation stays), and takes
each period's fundamental at its excitation frequency w by least squares
(constant, cos, sin) over the 5 s analysis window. A ratio's phase is that
of the complex amplitudes. Checks:

* --cuff-delay, --sea-delay, --encoder-delay (S = 13 ms, 6.5 ticks at
  500 Hz: the interpolated case): the delayed reading's phase lags by w S.
  tau_s and, at alpha = 1, tau_c: directly against a run without the delay
  (the controller does not use them there, so the physics is the same);
  tau_c at alpha = 4 and theta_e: the ratio tau_c / theta_e, which the
  delay turns by -w S (cuff) or +w S (encoder) whatever the loop does.
* --cuff-compliance (K_c, default damping B_c): tau_c / theta_e against the
  series formula S_h Z_c / (S_h + Z_c), S_h = K - M_h w^2 + j H,
  Z_c = K_c + j w B_c; the rigid cuff against S_h; the RK4 substeps against
  four times as many.
* the sampled loop's growth rate (sampled_loop) against the simulation in
  a case it calls unstable (K_c 300, B_c 0.5, alpha 4), and against the
  continuous closed_loop_mode where both model the same loop.
* --saturation: tau_s's peaks stay at the limit while tau_d's pass it.
* --rate-hz 1000: twice the samples a window, the same fundamental as at
  500 Hz; one recording read back (metadata rate_hz, stamps 1 ms apart,
  seq and sensor_seq contiguous).
* --posture-shift: the window's mean angle moves by the shift (times the
  static balance's gain) in the shifted experiments only (the others bit
  for bit unchanged).
* --encoder-bits 12: theta_e on the 2 pi / 4096 grid.
* --sea-hz/--sea-zeta/--sea-model: tau_s / tau_d against the low pass
  w_s^2 / (w_s^2 - w^2 + 2 j zeta w_s w) with the held command's half tick
  (lowpass) or a whole tick (tustin: the torque ramps to the filter's output
  over the next tick).
* --mass-scale 2: tau_c / theta_e against K - 2 M_h w^2 + j H.
"""

import math
import os
import struct
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import independent_rig as R  # noqa: E402

QUICK = "--quick" in sys.argv
PERIODS = 4 if QUICK else 10


def run(experiments, rig=R.NOMINAL, shift=None, mass_scale=1.0, substeps=None, periods=None):
    subj = R.table_subject()
    subj["m_h"] *= mass_scale
    specs = R.period_specs(7, subj, experiments, periods or PERIODS, 0.0, 0.0, "two-point", rig, shift)
    R.annotate_loop(specs, rig)
    return specs, R.simulate(specs, R.PRE_WINDOW_S, rig=rig, substeps=substeps)


def window(x, rig):
    """The analysis window's samples (the last 5 s and a tick) of recorded rows x."""
    return x[:, -(rig.tm.ticks(R.ANALYSIS_S) + 1):]


def fit_fundamental(x, specs, rig):
    """(c, X) of each period's window at its w: x ~ c + Re X e^{j w t}."""
    tm = rig.tm
    x = window(x, rig)
    t = (tm.t_analysis - tm.t_sine + np.arange(x.shape[1])) * tm.dt
    const, amp = [], []
    for row, sp in zip(x, specs):
        a = np.stack([np.ones_like(t), np.cos(sp["omega"] * t), np.sin(sp["omega"] * t)], axis=1)
        c = np.linalg.lstsq(a, row, rcond=None)[0]
        const.append(c[0])
        amp.append(c[1] - 1j * c[2])
    return np.array(const), np.array(amp)


def fundamental(x, specs, rig):
    """Complex amplitude X (x ~ c + Re X e^{j w t}) of each period's window at its w."""
    return fit_fundamental(x, specs, rig)[1]


def fundamental_const(x, specs, rig):
    """The constant c of the fit of fundamental()."""
    return fit_fundamental(x, specs, rig)[0]


def wrap(p):
    return (p + np.pi) % (2.0 * np.pi) - np.pi


def s_h(sp):
    return sp["k"] - sp["m_h"] * sp["omega"] ** 2 + 1j * sp["h"]


def report(name, specs, measured, expected, unit="rad"):
    err = measured - expected
    i = int(np.argmax(np.abs(err)))
    print(f"  {name}: worst |error| {abs(err[i]):.2e} {unit} (experiment/period {specs[i]['experiment']}/"
          f"{specs[i]['period']}, w {specs[i]['omega']:.2f} rad/s: measured {measured[i]:+.5f}, expected "
          f"{expected[i]:+.5f})")
    return float(np.max(np.abs(err)))


def sample_exact(clean, delayed, delay_s, rig):
    """The delayed recording against the clean one interpolated by hand."""
    m, f = R.delay_taps(delay_s, rig.tm.dt)
    ref = (1.0 - f) * clean[:, 1:-m] + f * clean[:, :-m - 1]
    return (f"sample by sample (m = {m} ticks, f = {f:g}): max |delayed - ((1 - f) x[n - m] + f x[n - m - 1])| "
            f"{np.max(np.abs(delayed[:, m + 1:] - ref)):.1e}")


def check_delays():
    print("sensor delays, S = 0.013 s (6.5 ticks at 500 Hz, 13 at 1 kHz)")
    for rate in (500, 1000):
        nom = R.Rig(rate_hz=rate)
        S = 0.013
        sp0, c0 = run([1, 4, 7], nom)
        w = np.array([s["omega"] for s in sp0])
        sp_, c = run([1, 4, 7], R.Rig(rate_hz=rate, sea_delay_s=S))
        x0, x1 = fundamental(c0["tau_s"], sp0, nom), fundamental(c["tau_s"], sp_, nom)
        report(f"{rate} Hz --sea-delay: phase(tau_s) - phase(clean tau_s)", sp0, wrap(np.angle(x1 / x0)), -w * S)
        print(f"    amplitude ratio {np.min(np.abs(x1 / x0)):.6f} .. {np.max(np.abs(x1 / x0)):.6f}; "
              f"{sample_exact(c0['tau_s'], c['tau_s'], S, nom)}")
        _, c = run([1, 4, 7], R.Rig(rate_hz=rate, cuff_delay_s=S))
        x0, x1 = fundamental(c0["tau_c"], sp0, nom), fundamental(c["tau_c"], sp_, nom)
        report(f"{rate} Hz --cuff-delay, alpha 1: phase(tau_c) - phase(clean tau_c)", sp0,
               wrap(np.angle(x1 / x0)), -w * S)
        print(f"    amplitude ratio {np.min(np.abs(x1 / x0)):.6f} .. {np.max(np.abs(x1 / x0)):.6f}; "
              f"{sample_exact(c0['tau_c'], c['tau_c'], S, nom)}")
        spa, ca = run([3, 6, 9], nom)
        wa = np.array([s["omega"] for s in spa])
        ra = fundamental(ca["tau_c"], spa, nom) / fundamental(ca["theta"], spa, nom)
        spd, cd = run([3, 6, 9], R.Rig(rate_hz=rate, cuff_delay_s=S))
        rd = fundamental(cd["tau_c"], spd, nom) / fundamental(cd["theta"], spd, nom)
        report(f"{rate} Hz --cuff-delay, alpha 4: phase of tau_c/theta_e, delayed - clean", spa,
               wrap(np.angle(rd / ra)), -wa * S)
        spd, cd = run([1, 4, 7], R.Rig(rate_hz=rate, encoder_delay_s=S))
        r0 = fundamental(c0["tau_c"], sp0, nom) / fundamental(c0["theta"], sp0, nom)
        rd = fundamental(cd["tau_c"], spd, nom) / fundamental(cd["theta"], spd, nom)
        report(f"{rate} Hz --encoder-delay: phase of tau_c/theta_e, delayed - clean", sp0,
               wrap(np.angle(rd / r0)), w * S)


def check_compliance():
    print("cuff compliance (damping default %g Nm s/rad), alpha 1 (experiments 1, 4, 7)" % R.CUFF_DAMPING)
    nom = R.NOMINAL
    sp0, c0 = run([1, 4, 7], nom)
    r0 = fundamental(c0["tau_c"], sp0, nom) / fundamental(c0["theta"], sp0, nom)
    sh = np.array([s_h(s) for s in sp0])
    report("rigid: |tau_c/theta_e - S_h| / |S_h|", sp0, np.abs(r0 - sh) / np.abs(sh), 0.0 * sh.real, "")
    for kc in (150.0, 1500.0):
        rig = R.Rig(cuff_k=kc)
        sp, c = run([1, 4, 7], rig)
        r = fundamental(c["tau_c"], sp, rig) / fundamental(c["theta"], sp, rig)
        zc = np.array([kc + 1j * s["omega"] * rig.cuff_b for s in sp])
        pred = sh * zc / (sh + zc)
        print(f"  K_c {kc:g} Nm/rad ({R.cuff_substeps(sp, rig)} RK4 steps a tick): tau_c/theta_e moves from S_h by "
              f"{np.min(np.abs(pred / sh - 1)) * 100:.2f}..{np.max(np.abs(pred / sh - 1)) * 100:.2f} % (formula)")
        report(f"K_c {kc:g}: |tau_c/theta_e - S_h Z_c/(S_h + Z_c)| / |S_h Z_c/(S_h + Z_c)|", sp,
               np.abs(r - pred) / np.abs(pred), 0.0 * pred.real, "")
        for s, rr, pp in list(zip(sp, r, pred))[::max(1, len(sp) // 4)]:
            print(f"    {s['experiment']}/{s['period']} w {s['omega']:6.2f}: measured {rr.real:8.3f}{rr.imag:+8.3f}j, "
                  f"formula {pp.real:8.3f}{pp.imag:+8.3f}j, rigid S_h {s_h(s).real:8.3f}{s_h(s).imag:+8.3f}j")
    for kc, ms in ((1500.0, 1.0), (1e5, 0.5)):
        rig = R.Rig(cuff_k=kc)
        sp, c1 = run([1, 9], rig, mass_scale=ms, periods=2)
        n = R.cuff_substeps(sp, rig)
        _, c4 = run([1, 9], rig, mass_scale=ms, periods=2, substeps=4 * n)
        d = np.max(np.abs(window(c1["tau_c"], rig) - window(c4["tau_c"], rig)))
        print(f"  substeps: K_c {kc:g}, M_h x {ms:g}: {n} vs {4 * n} RK4 steps a tick: max |tau_c difference| "
              f"{d:.2e} Nm (tau_c spans {np.ptp(window(c4['tau_c'], rig)):.2f} Nm)")
    rig = R.Rig(cuff_k=300.0, cuff_b=0.5)
    sp, c = run([3], rig, periods=10)
    sp = sp[6]
    d = np.diff(c["theta"][6], 2)[-5 * 500:]
    g = [np.sqrt(np.mean(d[j * 500:(j + 1) * 500] ** 2)) for j in range(5)]
    meas = float(np.mean(np.diff(np.log(g))))
    print(f"  K_c 300, B_c 0.5, experiment 3 period 7: sampled_loop growth {sp['loop_growth']:.3f} 1/s at "
          f"{sp['loop_omega']:.1f} rad/s; simulated growth (second difference of theta_e, 1 s rms) "
          f"{meas:.3f} 1/s")


def check_loop():
    print("sampled_loop against the continuous closed_loop_mode (alpha 4, no gravity, no delays, rigid cuff)")
    for rate in (500, 1000):
        rig = R.Rig(rate_hz=rate)
        for damping in ("viscous", "two-point"):
            specs = R.period_specs(7, R.table_subject(), [3, 6, 9], 10, 0.0, 0.0, damping, rig)
            g = np.array([R.sampled_loop(sp, rig, horizontal=True)[0] for sp in specs])
            c = np.array([-sp["mode_zeta"] * sp["mode_omega"] for sp in specs])
            i = int(np.argmax(np.abs(g - c)))
            print(f"  {rate} Hz, {damping}: growth differs from -zeta w by at most {abs(g[i] - c[i]):.3f} 1/s "
                  f"(experiment/period {specs[i]['experiment']}/{specs[i]['period']}: {g[i]:.3f} vs {c[i]:.3f})")


def check_saturation():
    print("saturation (experiment 7: bias 8 Nm)")
    nom = R.NOMINAL
    sp0, c0 = run([7], nom, periods=10)
    top = float(np.max(window(c0["tau_d"], nom)))
    nm = round(top - 1.0, 1)
    rig = R.Rig(saturation_nm=nm)
    sp, c = run([7], rig, periods=10)
    td, ts = window(c["tau_d"], rig), window(c["tau_s"], rig)
    print(f"  without a limit: max tau_d {top:.3f}, max tau_s {np.max(window(c0['tau_s'], nom)):.3f} Nm")
    print(f"  --saturation {nm:g}: max tau_d {np.max(td):.3f} Nm, above the limit in {np.mean(td > nm) * 100:.1f} % "
          f"of the samples; max tau_s {np.max(ts):.3f} Nm; mean tau_d - tau_s where tau_d > limit "
          f"{np.mean((td - ts)[td > nm]):.3f} Nm")


def check_rate():
    print("rate 1000 Hz")
    r5, r10 = R.Rig(rate_hz=500), R.Rig(rate_hz=1000)
    sp5, c5 = run([1, 4, 7], r5)
    sp10, c10 = run([1, 4, 7], r10)
    print(f"  samples a period (1 s before the window to its end): {c5['theta'].shape[1]} at 500 Hz, "
          f"{c10['theta'].shape[1]} at 1000 Hz; window {window(c5['theta'], r5).shape[1]}, "
          f"{window(c10['theta'], r10).shape[1]}")
    a = fundamental(c5["tau_c"], sp5, r5) / fundamental(c5["theta"], sp5, r5)
    b = fundamental(c10["tau_c"], sp10, r10) / fundamental(c10["theta"], sp10, r10)
    report("|tau_c/theta_e at 1000 Hz - at 500 Hz| / |at 500 Hz|", sp5, np.abs(b - a) / np.abs(a), 0.0 * a.real, "")
    from mcap.reader import make_reader
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "r.mcap")
        R.main([path, "--seed", "7", "--experiments", "1,4", "--periods", "2", "--rate-hz", "1000"])
        with open(path, "rb") as f:
            rd = make_reader(f)
            meta = {m.name: m.metadata for m in rd.iter_metadata()}
            f.seek(0)
            rd = make_reader(f)
            sens, cmd, proto = [], [], []
            for _, ch, msg in rd.iter_messages():
                if ch.topic == "exo/sensor":
                    sens.append((msg.log_time,) + struct.unpack_from("<QQ", msg.data, 4))
                elif ch.topic == "exo/command":
                    cmd.append(struct.unpack_from("<QQQ", msg.data, 4))
                else:
                    proto.append(msg.log_time)
        s = np.array(sens, dtype=np.int64)
        cm = np.array(cmd, dtype=np.int64)
        steps = np.diff(s[:, 2])
        print(f"  recording: metadata rate_hz {meta['exo']['rate_hz']!r}; {len(s)} sensor samples "
              f"({len(s) // 4} a period); stamp steps {sorted(set(steps.tolist()))[:3]} ns (the larger ones between "
              f"periods); seq contiguous {bool(np.all(np.diff(s[:, 1]) == 1))}; log_time == stamp_ns "
              f"{bool(np.all(s[:, 0] == s[:, 2]))}; command seq == sensor_seq == sensor seq "
              f"{bool(np.all(cm[:, 0] == s[:, 1]) and np.all(cm[:, 2] == s[:, 1]))}; protocol stamps on whole ms "
              f"{all(t % 1_000_000 == 0 for t in proto)}; {meta['exo']['recorded_samples']!r}")


def check_posture():
    print("posture shift 1:0.03, 4:0.075, 7:-0.045 (experiment 2 not shifted)")
    nom = R.NOMINAL
    shift = {1: 0.03, 4: 0.075, 7: -0.045}
    sp0, c0 = run([1, 2, 4, 7], nom)
    sp, c = run([1, 2, 4, 7], nom, shift=shift)
    m0, m1 = window(c0["theta"], nom).mean(axis=1), window(c["theta"], nom).mean(axis=1)
    # The constant of the fundamental's fit: the mean without the sine's
    # share over a window of a non-integer number of periods.
    l0, l1 = (fundamental_const(x["theta"], specs, nom) for x, specs in ((c0, sp0), (c, sp)))
    # Static balance: k0 (th - th_p) = (bias + dg sin th) / alpha, dg the
    # gravity model's excess and k0 the realisation's static stiffness (the
    # Maxwell element holds no static torque), so
    # d th / d th_p = 1 / (1 - dg cos th / (alpha k0)).
    for e in (1, 2, 4, 7):
        rows = [i for i, s in enumerate(sp) if s["experiment"] == e]
        d, dl = m1[rows] - m0[rows], l1[rows] - l0[rows]
        dg = R.G * ((R.COMP_ARM_MASS_FACTOR - 1.0) * R.ARM_MASS * R.ARM_COM
                    + (R.COMP_LOAD_MASS_FACTOR - 1.0) * sp[rows[0]]["load_kg"] * R.LEVER)
        pred = np.array([shift.get(e, 0.0) / (1.0 - dg * math.cos(l0[i]) / (sp[i]["alpha"] * sp[i]["k0"]))
                         for i in rows])
        same = bool(np.array_equal(c["theta"][rows], c0["theta"][rows]))
        print(f"  experiment {e}: shift {shift.get(e, 0.0):+.3f} rad; window mean angle moved {d.min():+.5f}.."
              f"{d.max():+.5f} rad; the fit's constant {dl.min():+.5f}..{dl.max():+.5f}, static balance "
              f"{pred.min():+.5f}..{pred.max():+.5f}, worst difference {np.max(np.abs(dl - pred)):.1e}"
              + (f"; samples bit for bit unchanged: {same}" if e not in shift else ""))


def check_encoder_bits():
    rig = R.Rig(encoder_bits=12)
    sp, c = run([4], rig, periods=2)
    th = window(c["theta"], rig)
    q = 2.0 * math.pi / 4096
    k = th / q
    print(f"encoder 12 bits: theta_e / (2 pi / 4096) off an integer by at most {np.max(np.abs(k - np.round(k))):.1e}; "
          f"{len(np.unique(np.round(k[0])))} levels in period 1's window (17 bits: "
          f"{len(np.unique(window(run([4], R.NOMINAL, periods=2)[1]['theta'], R.NOMINAL)[0]))})")


def check_sea():
    print("SEA low pass: tau_s / tau_d against w_s^2 / (w_s^2 - w^2 + 2 j zeta w_s w), experiments 1, 4, 7")
    for hz, zeta, model in ((10.0, 0.7, "lowpass"), (6.0, 0.5, "lowpass"), (10.0, 0.7, "tustin"),
                            (6.0, 0.5, "tustin")):
        rig = R.Rig(sea_hz=hz, sea_zeta=zeta, sea_model=model)
        sp, c = run([1, 4, 7], rig)
        r = fundamental(c["tau_s"], sp, rig) / fundamental(c["tau_d"], sp, rig)
        w = np.array([s["omega"] for s in sp])
        ws = 2.0 * math.pi * hz
        lp = ws * ws / (ws * ws - w * w + 2j * zeta * ws * w)
        lag = (0.5 if model == "lowpass" else 1.0) * rig.tm.dt
        pred = lp * np.exp(-1j * w * lag)
        report(f"{model} {hz:g} Hz zeta {zeta:g}: |tau_s/tau_d - L e^(-j w {lag * 1e3:g} ms)| / |L|", sp,
               np.abs(r - pred) / np.abs(lp), 0.0 * w, "")
        print(f"    |L| spans {np.min(np.abs(lp)):.3f}..{np.max(np.abs(lp)):.3f}, phase "
              f"{np.min(np.angle(lp)):.3f}..{np.max(np.angle(lp)):.3f} rad")


def check_mass_scale():
    rig = R.NOMINAL
    sp, c = run([1, 4, 7], rig, mass_scale=2.0)
    r = fundamental(c["tau_c"], sp, rig) / fundamental(c["theta"], sp, rig)
    pred = np.array([s_h(s) for s in sp])
    print(f"--mass-scale 2: M_h {sp[0]['m_h']:.3f} kg m^2")
    report("|tau_c/theta_e - (K - M_h w^2 + j H)| / |S_h|", sp, np.abs(r - pred) / np.abs(pred), 0.0 * pred.real, "")


def main():
    t0 = time.perf_counter()
    for f in (check_delays, check_compliance, check_loop, check_saturation, check_rate, check_posture, check_encoder_bits,
              check_sea, check_mass_scale):
        f()
    print(f"{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
