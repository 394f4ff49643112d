//! Time-domain signatures of what remains (issue 15, item 2): harmonics of
//! the excitation and non-harmonic content, each measured against the
//! noise of its own window, with the arm's transient ringing separated
//! from that noise.
//!
//! Per single-sine window and torque channel (`τ_c` for `S_h`, `τ_s −
//! τ_gravity` for `S_h-e`), over the window's whole cycles of ω:
//!
//! 1. least squares of the samples on a mean, a linear trend and the
//!    fundamental, 2nd and 3rd harmonics (cosine and sine each);
//! 2. the residual's Hann-windowed spectrum at the block's DFT frequencies
//!    `2πk/T` (`X_k = (2/Σw) Σ w r e^{−jω_k t}`), leaving out the first
//!    five harmonics' bins and the two lowest bins (the trend); the window keeps a strong transient from leaking over the
//!    band, and its equivalent noise bandwidth converts a bin's power to
//!    that of a harmonic's estimate;
//! 3. the strongest non-harmonic bin, when above ten times that floor, is
//!    **fitted** as a decaying sinusoid at its frequency (decay rate from its
//!    amplitude in the window's two halves) together with step 1's terms,
//!    and the floor and the harmonics are measured again without it: the
//!    arm's ringing separated from the noise;
//! 4. the noise power per bin is the **median** of `|X_k|²` over those bins
//!    divided by `ln 2` (white noise makes `|X_k|²` exponential, whose
//!    median is `ln 2` times its mean). A ringing occupies a few bins, so
//!    the median is not lifted by it as a mean would be (the test this
//!    replaces took the level at 2.5 ω as the floor, where the ringing of
//!    the arm at its natural frequency often is);
//! 5. a harmonic's `|A_h|²` over that noise power is `Exp(1)` under noise
//!    alone (its sine and cosine are orthogonal to the others over whole
//!    cycles, so their estimates have the bins' variance); summed over an
//!    experiment's `n` windows, twice the sum is `χ²(2n)`: the p-value;
//! 6. the strongest bin that is no harmonic is the window's non-harmonic
//!    content; beyond `−ln(α/bins)` times the noise power it is reported
//!    with its frequency and its amplitude in the first and in the second
//!    half of the window: a ratio below 0.8 is a transient that decays (the
//!    arm's ringing after the protocol's steps), near 1 a persistent
//!    oscillation that is no harmonic of the excitation.
//!
//! Assumptions: the noise is white over the bins used (up to six times ω,
//! at least 40 bins); a ringing that falls on a harmonic's bin is counted
//! as that harmonic.

use std::collections::BTreeMap;

use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;
use serde::Serialize;
use statrs::distribution::{ChiSquared, ContinuousCDF};

use crate::data::{Dataset, Tf};

/// The harmonics of one window's channel, against its noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindowSpectrum {
    /// Amplitude of the fundamental (signal units).
    pub fundamental: f64,
    /// Amplitudes of the 2nd and 3rd harmonics.
    pub harmonics: [f64; 2],
    /// Noise power per DFT bin, `E|X_k|²` (signal units²), from the median.
    pub noise_power: f64,
    /// DFT bins the noise power was taken over.
    pub bins: usize,
    /// The strongest non-harmonic bin: (ω in rad/s, amplitude, power over
    /// the noise power, amplitude in the second half over the first).
    pub peak: Option<(f64, f64, f64, f64)>,
}

/// `(2/n) Σ r e^{−jωt}` over `t`, `r`.
fn project(t: &[f64], r: &[f64], w: f64) -> Complex64 {
    let n = r.len().max(1) as f64;
    let mut acc = Complex64::new(0.0, 0.0);
    for (ti, ri) in t.iter().zip(r) {
        acc += ri * Complex64::from_polar(1.0, -w * ti);
    }
    acc * (2.0 / n)
}

/// The spectrum of one window's channel `y` at `t` (s, from the window
/// start) for an excitation at `w` (rad/s); `None` with less than one whole
/// cycle or too few samples.
pub fn window_spectrum(t: &[f64], y: &[f64], w: f64) -> Option<WindowSpectrum> {
    window_harmonics(t, y, w).map(|x| x.0)
}

/// [`window_spectrum`] and the phasors `X_h` of the fundamental, 2nd and
/// 3rd harmonics (`y ≈ Re Σ X_h e^{j h ω t}`, `t` from the window start).
pub fn window_harmonics(t: &[f64], y: &[f64], w: f64) -> Option<(WindowSpectrum, [Complex64; 3])> {
    let n = exo_impedance::frf::whole_cycles(t, w)?;
    if n < 32 || y.len() < n {
        return None;
    }
    let t0 = t[0];
    let tau: Vec<f64> = t[..n].iter().map(|x| x - t0).collect();
    let dt = tau[n - 1] / (n - 1) as f64;
    let span = n as f64 * dt;
    let cycles = (span * w / std::f64::consts::TAU).round().max(1.0) as usize;
    let yv = DVector::from_column_slice(&y[..n]);
    // Mean, trend, cos/sin of the first three harmonics: one `sin_cos` a
    // sample, the harmonics by the phasor's powers.
    let mut fixed = DMatrix::from_fn(n, 8, |i, j| match j {
        0 => 1.0,
        1 => tau[i] / span - 0.5,
        _ => 0.0,
    });
    for i in 0..n {
        let (sn, cs) = (w * tau[i]).sin_cos();
        let e1 = Complex64::new(cs, sn);
        let mut e = e1;
        for h in 0..3 {
            fixed[(i, 2 + 2 * h)] = e.re;
            fixed[(i, 3 + 2 * h)] = e.im;
            e *= e1;
        }
    }
    let gram = fixed.tr_mul(&fixed);
    let fixed_y = fixed.tr_mul(&yv);
    // Least squares on those terms and (second pass) a decaying sinusoid
    // `e^{−λt}` at the ringing's frequency, given as its cosine and sine
    // columns: the normal equations from the fixed terms' Gram matrix, built
    // once.
    let yy = yv.dot(&yv);
    let fit0 = || {
        let beta = gram.clone().try_inverse()? * &fixed_y;
        let r: Vec<f64> = (&yv - &fixed * &beta).iter().copied().collect();
        Some((beta, r))
    };
    // With the ringing's cosine and sine columns `c`, `sn`: the
    // coefficients and the residual sum of squares `y'y − β'X'y` (the
    // residual itself is formed only for the best of the grid).
    let fit_ringing = |c: &[f64], sn: &[f64]| {
        let mut g = DMatrix::<f64>::zeros(10, 10);
        g.view_mut((0, 0), (8, 8)).copy_from(&gram);
        let mut xy = DVector::<f64>::zeros(10);
        xy.rows_mut(0, 8).copy_from(&fixed_y);
        for (k, col) in [c, sn].into_iter().enumerate() {
            let v = DVector::from_column_slice(col);
            let cross = fixed.tr_mul(&v);
            for j in 0..8 {
                g[(j, 8 + k)] = cross[j];
                g[(8 + k, j)] = cross[j];
            }
            xy[8 + k] = v.dot(&yv);
        }
        let cc: f64 = c.iter().map(|v| v * v).sum();
        let ss: f64 = sn.iter().map(|v| v * v).sum();
        let cs: f64 = c.iter().zip(sn).map(|(a, b)| a * b).sum();
        g[(8, 8)] = cc;
        g[(9, 9)] = ss;
        g[(8, 9)] = cs;
        g[(9, 8)] = cs;
        let beta = g.try_inverse()? * &xy;
        let rss = yy - beta.dot(&xy);
        Some((beta, rss))
    };
    let residual = |beta: &DVector<f64>, c: &[f64], sn: &[f64]| -> Vec<f64> {
        let base = &fixed * beta.rows(0, 8);
        (0..n)
            .map(|i| y[i] - base[i] - beta[8] * c[i] - beta[9] * sn[i])
            .collect()
    };
    // The residual's Hann-windowed spectrum (sidelobes falling as 1/Δω³,
    // so a strong transient does not leak over the band): bins 2 … up to
    // 6 ω, without the first five harmonics' bins and `skip`.
    let hann: Vec<f64> = (0..n)
        .map(|i| {
            (std::f64::consts::PI * (i as f64 + 0.5) / n as f64)
                .sin()
                .powi(2)
        })
        .collect();
    let sum_w: f64 = hann.iter().sum();
    // Equivalent noise bandwidth in bins: a bin's noise power over that
    // of an unwindowed projection (whose variance the harmonics share).
    let enbw = n as f64 * hann.iter().map(|v| v * v).sum::<f64>() / (sum_w * sum_w);
    let kmax = (n / 2).saturating_sub(1).min((6 * cycles).max(40));
    // Only the harmonics' own bins: with few cycles in the window the
    // harmonics are a few bins apart, and the least squares removed the
    // first three anyway.
    let harmonic_bin = |k: usize| (1..=5).any(|h| k == h * cycles);
    // Each sample's `e^{−j 2π t/T}`, whose k-th power is bin k's phasor.
    let bin_step: Vec<Complex64> = tau
        .iter()
        .map(|&s| Complex64::from_polar(1.0, -std::f64::consts::TAU * s / span))
        .collect();
    let spectrum = |r: &[f64], skip: Option<usize>| -> Vec<(usize, f64)> {
        let mut acc = vec![Complex64::new(0.0, 0.0); kmax + 1];
        for i in 0..n {
            let a = hann[i] * r[i];
            let step = bin_step[i];
            let mut z = step * step;
            for bin in acc.iter_mut().skip(2) {
                *bin += a * z;
                z *= step;
            }
        }
        (2..=kmax)
            .filter(|&k| !harmonic_bin(k) && skip.is_none_or(|q| (k as i64 - q as i64).abs() > 2))
            .map(|k| (k, (acc[k] * (2.0 / sum_w)).norm_sqr()))
            .collect()
    };
    let floor = |pw: &[(usize, f64)]| {
        let mut v: Vec<f64> = pw.iter().map(|p| p.1).collect();
        v.sort_by(f64::total_cmp);
        median(v) / std::f64::consts::LN_2 / enbw
    };
    let (beta0, r0) = fit0()?;
    let mut power = spectrum(&r0, None);
    if power.len() < 8 {
        return None;
    }
    let floor0 = floor(&power);
    power.sort_by(|a, b| b.1.total_cmp(&a.1));
    // The strongest non-harmonic bin, its decay from the first half of the
    // window to the second (unwindowed projections of the residual).
    let peak0 = power.first().map(|&(k, pw)| {
        let wk = std::f64::consts::TAU * k as f64 / span;
        let half = n / 2;
        let a1 = project(&tau[..half], &r0[..half], wk).norm();
        let a2 = project(&tau[half..], &r0[half..], wk).norm();
        (k, wk, pw, a2 / a1.max(1e-300))
    });
    // A peak well above the floor is fitted as a decaying sinusoid (its
    // rate from the halves' ratio) and taken out before the floor and the
    // harmonics are measured: the ringing separated from the noise.
    let ringing = peak0.filter(|p| p.2 / enbw > 10.0 * floor0);
    let (beta, noise_power, bins) = match ringing.and_then(|(k, wk, _, ratio)| {
        // Its frequency and decay rate refined on a small grid about the
        // bin and the halves' estimate (least residual).
        let lambda0 = (-ratio.clamp(1e-3, 1.0).ln() / (0.5 * span)).max(0.2 / span);
        let dw = std::f64::consts::TAU / span;
        let decays: Vec<Vec<f64>> = [0.0f64, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0]
            .iter()
            .map(|l| tau.iter().map(|s| (-l * lambda0 * s).exp()).collect())
            .collect();
        // The grid's frequencies `wk + i δ`, i = −4 … 4, δ = dw/8: each
        // sample's phasor at `wk − 4δ` and its step `e^{jδt}`.
        let delta = 0.125 * dw;
        let mut phasor: Vec<(Complex64, Complex64)> = tau
            .iter()
            .map(|&s| {
                let (a, b) = ((wk - 4.0 * delta) * s).sin_cos();
                let (da, db) = (delta * s).sin_cos();
                (Complex64::new(b, a), Complex64::new(db, da))
            })
            .collect();
        let (mut c, mut sn) = (vec![0.0; n], vec![0.0; n]);
        // The best grid point: its RSS, coefficients and (cosine, sine)
        // columns.
        type Best = (f64, DVector<f64>, Vec<f64>, Vec<f64>);
        let mut best: Option<Best> = None;
        for _ in 0..9 {
            for decay in &decays {
                for (j, e) in decay.iter().enumerate() {
                    c[j] = e * phasor[j].0.re;
                    sn[j] = e * phasor[j].0.im;
                }
                let Some((b, rss)) = fit_ringing(&c, &sn) else {
                    continue;
                };
                if best.as_ref().is_none_or(|x| rss < x.0) {
                    best = Some((rss, b, c.clone(), sn.clone()));
                }
            }
            for p in phasor.iter_mut() {
                p.0 *= p.1;
            }
        }
        let (_, b, c, sn) = best?;
        let r = residual(&b, &c, &sn);
        let pw = spectrum(&r, Some(k));
        (pw.len() >= 8).then(|| (b, floor(&pw), pw.len()))
    }) {
        Some(x) => x,
        None => (beta0, floor0, power.len()),
    };
    if !(noise_power.is_finite() && noise_power > 0.0) {
        return None;
    }
    let amp = |h: usize| beta[2 + 2 * h].hypot(beta[3 + 2 * h]);
    // a cos + b sin = Re((a − j b) e^{jωt}).
    let phasor = |h: usize| Complex64::new(beta[2 + 2 * h], -beta[3 + 2 * h]);
    let phasors = [phasor(0), phasor(1), phasor(2)];
    let peak = peak0.map(|(_, wk, pw, ratio)| {
        // Amplitude of a steady sinusoid at the bin (the window's gain
        // taken out), power over the floor in the same units.
        (wk, pw.sqrt(), pw / (noise_power * enbw), ratio)
    });
    Some((
        WindowSpectrum {
            fundamental: amp(0),
            harmonics: [amp(1), amp(2)],
            noise_power,
            bins,
            peak,
        },
        phasors,
    ))
}

/// What a cubic spring or damper predicts beyond the fundamental, checked
/// where it predicts it: the cubic terms `K₃ θ³ + B₃ θ̇³` of the human's
/// impedance put `¼ Θ₁³ (K₃ + B₃ (jω)³)` into the 3rd harmonic of `τ_c`
/// (`Θ₁` the angle's fundamental phasor; `cos³ x = ¾ cos x + ¼ cos 3x`), on
/// top of the linear response `S_h(3ω) Θ₃` to the angle's own 3rd harmonic.
/// With `y = T₃ − S_h(3ω) Θ₃ − ¼ Θ₁³ (K₃⁰ + B₃⁰ (jω)³)` the current model's
/// 3rd-harmonic residual and `m = ¼ Θ₁³ (ΔK₃ + ΔB₃ (jω)³)` the change the
/// candidate makes, both whitened by the noise of `τ_c`'s spectrum in the
/// window, `β = Re Σ m̄ y/|m|²` is the fraction of the predicted harmonic the
/// data show, its standard error `1/|m|` scaled by the scatter. Returns
/// `(|m|², β, se, windows)`, `None` when the candidate changes neither `K₃`
/// nor `B₃` or no window has the harmonics.
pub fn cubic_harmonic_check(
    d: &Dataset,
    before: &crate::model::Physics,
    after: &crate::model::Physics,
) -> Option<(f64, f64, f64, usize)> {
    let (dk3, db3) = (after.k3 - before.k3, after.b3 - before.b3);
    if (dk3 == 0.0 && db3 == 0.0) || !d.supported.contains(&Tf::Sh) {
        return None;
    }
    let harmonics = sh_harmonics(d);
    let (mut ym, mut mm, mut rows) = (0.0, 0.0, Vec::new());
    for (i, (s, h)) in d.signals.iter().zip(harmonics).enumerate() {
        let w = s.omega_rad_s;
        let Some((noise_power, th, tc)) = *h else {
            continue;
        };
        let c = &d.conditions[i];
        let sd = component_sd(noise_power);
        let zero = Complex64::new(0.0, 0.0);
        let cube = th[0] * th[0] * th[0] * 0.25;
        let jw3 = Complex64::new(0.0, -w * w * w); // (jω)³
        let y = tc[2]
            - before.predict_tf(Tf::Sh, 3.0 * w, c, zero) * th[2]
            - (before.k3 + before.b3 * jw3) * cube;
        let m = (dk3 + db3 * jw3) * cube;
        let (y, m) = (y / sd, m / sd);
        ym += (m.conj() * y).re;
        mm += m.norm_sqr();
        rows.push((y, m));
    }
    beta_of(ym, mm, &rows)
}

/// `(|m|², β, se, rows)` of a signature check from its whitened rows
/// `(y, m)`: `β = Σ Re(m̄ y)/|m|²`, its standard error `1/|m|` scaled by the
/// scatter about `β m` (never below the noise's); `None` when nothing is
/// predicted.
fn beta_of(ym: f64, mm: f64, rows: &[(Complex64, Complex64)]) -> Option<(f64, f64, f64, usize)> {
    if mm.is_nan() || mm <= 1e-12 {
        return None;
    }
    let beta = ym / mm;
    let dof = (2.0 * rows.len() as f64 - 1.0).max(1.0);
    let scatter = rows
        .iter()
        .map(|(y, m)| (y - beta * m).norm_sqr())
        .sum::<f64>()
        / dof;
    Some((mm, beta, (scatter.max(1.0) / mm).sqrt(), rows.len()))
}

/// The noise's standard deviation of each real component of a harmonic's
/// phasor, from the noise power per bin (`E|X|² = 2σ²`): what the harmonic
/// checks whiten by.
pub(crate) fn component_sd(noise_power: f64) -> f64 {
    (0.5 * noise_power).sqrt()
}

/// Every window's `θ_e` and `τ_c` harmonics with `τ_c`'s noise power per
/// bin ([`window_harmonics`]; `None` for a broadband window or one too
/// short), computed once per dataset.
pub(crate) fn sh_harmonics(d: &Dataset) -> &[Option<crate::data::ShHarmonics>] {
    d.sh_harmonics
        .get_or_init(|| output_harmonics(d, |s| &s.tau_c_nm))
}

/// The same as [`sh_harmonics`] for `τ_s − τ_gravity`, `S_h-e`'s output.
pub(crate) fn she_harmonics(d: &Dataset) -> &[Option<crate::data::ShHarmonics>] {
    d.she_harmonics
        .get_or_init(|| output_harmonics(d, |s| &s.tau_s_net_nm))
}

/// Every window's `τ_s` and `τ_d` harmonics with each one's noise power
/// per bin ([`window_harmonics`]; `None` for a broadband window or one too
/// short), computed once per dataset.
fn sea_harmonics(d: &Dataset) -> &[Option<crate::data::SeaHarmonics>] {
    d.sea_harmonics.get_or_init(|| {
        d.signals
            .iter()
            .map(|s| {
                let w = s.omega_rad_s;
                if w <= 0.0
                    || s.tau_d_nm.len() != s.t_s.len()
                    || s.tau_d_nm.iter().any(|x| !x.is_finite())
                {
                    return None;
                }
                let (spec_s, ts) = window_harmonics(&s.t_s, &s.tau_s_nm, w)?;
                let (spec_d, td) = window_harmonics(&s.t_s, &s.tau_d_nm, w)?;
                Some(((spec_s.noise_power, ts), (spec_d.noise_power, td)))
            })
            .collect()
    })
}

fn output_harmonics(
    d: &Dataset,
    output: impl Fn(&crate::data::WindowSignals) -> &[f64],
) -> Vec<Option<crate::data::ShHarmonics>> {
    d.signals
        .iter()
        .map(|s| {
            let w = s.omega_rad_s;
            if w <= 0.0 {
                return None;
            }
            let (_, th) = window_harmonics(&s.t_s, &s.theta_rad, w)?;
            let (spec, y) = window_harmonics(&s.t_s, output(s), w)?;
            Some((spec.noise_power, th, y))
        })
        .collect()
}

/// Backlash's signature outside the transfer functions it is fitted to:
/// the 2nd and 3rd harmonics of the SEA's torque (`τ_s − τ_gravity`) beyond
/// what the joint's linear impedance makes of the angle's own harmonics.
/// Exactly `τ_s = Z_arm θ + J_m θ̈_m`, `θ_m = θ + Δ`, so at harmonic `h` the
/// SEA carries `S_h-e(hω) Θ_h − g_s J_m (hω)² Δ_h` with `Δ_h` the lost
/// motion's harmonic ([`crate::model::Mesh::lost_motion_harmonic`]: a pulse wave's
/// `(4δ/hπ) sin(hφ₀)`, even harmonics where a preload makes its duty
/// unequal). The check is [`cubic_harmonic_check`]'s: `y_h = T_h −
/// S_h-e(hω) Θ_h` less what `before` predicts, `m_h` the change `after`
/// predicts, both whitened by the window's noise per bin; `(|m|², β, se,
/// windows)`, `None` when the lost motion does not change or `S_h-e` is not
/// measured.
pub fn backlash_harmonic_check(
    d: &Dataset,
    before: &crate::model::Physics,
    after: &crate::model::Physics,
) -> Option<(f64, f64, f64, usize)> {
    if after.lash_half_rad == before.lash_half_rad || !d.supported.contains(&Tf::She) {
        return None;
    }
    // The linear joint: the model without the lost motion.
    let mut linear = before.clone();
    linear.lash_half_rad = 0.0;
    let mut gravity_comp = vec![None; d.signals.len()];
    for o in d.of(Tf::She) {
        gravity_comp[o.window] = Some(o.gravity_comp);
    }
    let harmonics = she_harmonics(d);
    let (mut ym, mut mm, mut rows) = (0.0, 0.0, Vec::new());
    for (i, (s, h)) in d.signals.iter().zip(harmonics).enumerate() {
        let w = s.omega_rad_s;
        let (Some((noise_power, th, ts)), Some(gc)) = (*h, gravity_comp[i]) else {
            continue;
        };
        let c = &d.conditions[i];
        let sd = component_sd(noise_power);
        // The SEA's torque at harmonic h from the lost motion `Δ_h` of `p`,
        // placed at the angle's measured phase (less the encoder's delay).
        let theta_phase = th[0].arg() + w * linear.delay_s[0];
        let s_exo = linear.s_exo_linear(w, c);
        let lost = |p: &crate::model::Physics, h: u32| {
            let hw = f64::from(h) * w;
            let delta = p.mesh(p.lash_half_rad, s_exo, w, c).lost_motion_harmonic(h)
                * Complex64::from_polar(1.0, f64::from(h) * theta_phase);
            -linear.gain[2]
                * p.motor_inertia
                * hw
                * hw
                * delta
                * Complex64::from_polar(1.0, -hw * linear.delay_s[2])
        };
        for h in [2u32, 3] {
            let k = h as usize - 1;
            let hw = f64::from(h) * w;
            let y = ts[k] - linear.predict_tf(Tf::She, hw, c, gc) * th[k] - lost(before, h);
            let m = lost(after, h) - lost(before, h);
            let (y, m) = (y / sd, m / sd);
            ym += (m.conj() * y).re;
            mm += m.norm_sqr();
            rows.push((y, m));
        }
    }
    beta_of(ym, mm, &rows)
}

/// A torque limit's signature outside `τ_s/τ_d`'s fundamental, to which it
/// is fitted: the 2nd and 3rd harmonics of the measured SEA torque beyond
/// what the SEA makes of the command's own harmonics. The drive applies
/// `clip(τ_d, −τ_max, τ_max)`, so at harmonic `h` the SEA carries
/// `G(hω) (D_h + C_h)`, `G` the SEA's response with its delays (the model's
/// `τ_s/τ_d` without the limit), `D_h` the recorded command's harmonic and
/// `C_h` that of the part the limit cuts off the recorded command's own
/// samples, `clip(τ_d) − τ_d` (so the check needs no assumption on the
/// command's shape: its peaks are what they were). The check is
/// [`cubic_harmonic_check`]'s: `y_h = T_h − G(hω) D_h` less what `before`
/// predicts, `m_h` the change `after` predicts, whitened by the noise of
/// `T_h − G D_h` per bin; `(|m|², β, se, windows)`, `None` when the limit
/// does not change or `τ_s/τ_d` is not measured.
pub fn saturation_harmonic_check(
    d: &Dataset,
    before: &crate::model::Physics,
    after: &crate::model::Physics,
) -> Option<(f64, f64, f64, usize)> {
    if after.saturation_per_nm == before.saturation_per_nm || !d.supported.contains(&Tf::Sea) {
        return None;
    }
    // The SEA without the limit.
    let mut linear = before.clone();
    linear.saturation_per_nm = 0.0;
    let zero = Complex64::new(0.0, 0.0);
    let (mut ym, mut mm, mut rows) = (0.0, 0.0, Vec::new());
    for (i, s) in d.signals.iter().enumerate() {
        let w = s.omega_rad_s;
        if w <= 0.0 || s.tau_d_nm.len() != s.t_s.len() || s.tau_d_nm.iter().any(|x| !x.is_finite())
        {
            continue;
        }
        let Some(n) = exo_impedance::frf::whole_cycles(&s.t_s, w) else {
            continue;
        };
        let Some(((noise_s, ts), (noise_d, td))) = sea_harmonics(d)[i] else {
            continue;
        };
        let c = &d.conditions[i];
        let t: Vec<f64> = s.t_s[..n].iter().map(|x| x - s.t_s[0]).collect();
        // The harmonic of what the limit of `p` cuts off the command.
        let cut = |p: &crate::model::Physics, hw: f64| {
            let l = p.torque_limit_nm();
            if !l.is_finite() {
                return zero;
            }
            let r: Vec<f64> = s.tau_d_nm[..n].iter().map(|x| x.clamp(-l, l) - x).collect();
            project(&t, &r, hw)
        };
        for h in [2u32, 3] {
            let k = h as usize - 1;
            let hw = f64::from(h) * w;
            let g = linear.predict_tf(Tf::Sea, hw, c, zero);
            let sd = component_sd(noise_s).hypot(g.norm() * component_sd(noise_d));
            if sd.is_nan() || sd <= 0.0 {
                continue;
            }
            let before_h = g * cut(before, hw);
            let y = ts[k] - g * td[k] - before_h;
            let m = g * cut(after, hw) - before_h;
            let (y, m) = (y / sd, m / sd);
            ym += (m.conj() * y).re;
            mm += m.norm_sqr();
            rows.push((y, m));
        }
    }
    beta_of(ym, mm, &rows)
}

/// Non-harmonic content of an experiment's windows beyond their noise.
#[derive(Debug, Clone, Serialize)]
pub struct NonHarmonic {
    /// Windows whose strongest non-harmonic bin is beyond the noise.
    pub windows: usize,
    /// Windows examined.
    pub of: usize,
    /// Median frequency of those peaks (rad/s).
    pub omega_rad_s: f64,
    /// Median peak amplitude (% of the fundamental).
    pub size_pct: f64,
    /// Median peak power over the noise power.
    pub power_ratio: f64,
    /// Median amplitude in the window's second half over its first.
    pub decay: f64,
    /// Decays within the window (median ratio below 0.8): a transient.
    pub transient: bool,
}

/// The harmonics of one experiment's channel, against the noise.
#[derive(Debug, Clone, Serialize)]
pub struct HarmonicContent {
    /// Experiment.
    pub experiment: u32,
    /// Channel (`tau_c`, `tau_s_net`).
    pub channel: &'static str,
    /// The transfer function the channel is the output of.
    pub tf: Tf,
    /// Windows analysed.
    pub windows: usize,
    /// RMS over the windows of the 2nd and 3rd harmonic (% of the fundamental).
    pub harmonic_pct: [f64; 2],
    /// The noise level of one bin (% of the fundamental, RMS over windows).
    pub noise_pct: f64,
    /// Mean power of the 2nd and 3rd harmonic over the noise power (1 = noise).
    pub power_ratio: [f64; 2],
    /// p-values of the 2nd and 3rd harmonic (χ²(2n) of the summed ratios).
    pub p_value: [f64; 2],
    /// Beyond the noise at the level divided over every test.
    pub significant: [bool; 2],
    /// Non-harmonic content beyond the noise, if any window has it.
    pub non_harmonic: Option<NonHarmonic>,
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The harmonic and non-harmonic content of every experiment's torque
/// channels; `level` is the family-wise level (divided over experiments,
/// channels and the two harmonics; per window over its bins for the
/// non-harmonic peak).
pub fn harmonics(d: &Dataset, level: f64) -> Vec<HarmonicContent> {
    let mut acc: BTreeMap<(u32, &'static str, Tf), Vec<WindowSpectrum>> = BTreeMap::new();
    for (i, s) in d.signals.iter().enumerate() {
        let w = s.omega_rad_s;
        if w <= 0.0 {
            continue;
        }
        let e = d.conditions[i].experiment;
        for (name, y, tf) in [
            ("tau_c", &s.tau_c_nm, Tf::Sh),
            ("tau_s_net", &s.tau_s_net_nm, Tf::She),
        ] {
            if !d.supported.contains(&tf) {
                continue;
            }
            if let Some(ws) = window_spectrum(&s.t_s, y, w) {
                acc.entry((e, name, tf)).or_default().push(ws);
            }
        }
    }
    let alpha = level / (2 * acc.len()).max(1) as f64;
    acc.into_iter()
        .map(|((experiment, channel, tf), ws)| {
            let nw = ws.len();
            let mut harmonic_pct = [0.0; 2];
            let mut power_ratio = [0.0; 2];
            let mut p_value = [f64::NAN; 2];
            for h in 0..2 {
                let ratios: Vec<f64> = ws
                    .iter()
                    .map(|x| x.harmonics[h].powi(2) / x.noise_power)
                    .collect();
                let sum: f64 = ratios.iter().sum();
                power_ratio[h] = sum / nw as f64;
                harmonic_pct[h] = 100.0
                    * (ws
                        .iter()
                        .map(|x| (x.harmonics[h] / x.fundamental).powi(2))
                        .sum::<f64>()
                        / nw as f64)
                        .sqrt();
                p_value[h] = ChiSquared::new(2.0 * nw as f64).map_or(f64::NAN, |c| c.sf(2.0 * sum));
            }
            let noise_pct = 100.0
                * (ws
                    .iter()
                    .map(|x| x.noise_power / x.fundamental.powi(2))
                    .sum::<f64>()
                    / nw as f64)
                    .sqrt();
            let peaks: Vec<(f64, f64, f64, f64)> = ws
                .iter()
                .filter_map(|x| {
                    let (wk, a, ratio, decay) = x.peak?;
                    let critical = -(level / x.bins as f64).ln();
                    (ratio > critical).then_some((wk, 100.0 * a / x.fundamental, ratio, decay))
                })
                .collect();
            let non_harmonic = (!peaks.is_empty()).then(|| {
                let decay = median(peaks.iter().map(|p| p.3).collect());
                NonHarmonic {
                    windows: peaks.len(),
                    of: nw,
                    omega_rad_s: median(peaks.iter().map(|p| p.0).collect()),
                    size_pct: median(peaks.iter().map(|p| p.1).collect()),
                    power_ratio: median(peaks.iter().map(|p| p.2).collect()),
                    decay,
                    transient: decay < 0.8,
                }
            });
            HarmonicContent {
                experiment,
                channel,
                tf,
                windows: nw,
                harmonic_pct,
                noise_pct,
                power_ratio,
                significant: [p_value[0] < alpha, p_value[1] < alpha],
                p_value,
                non_harmonic,
            }
        })
        .collect()
}

/// The lines about one transfer function's channel: (words, finding).
/// Harmonics beyond the noise and persistent non-harmonic content are
/// findings; a decaying transient is said but is no finding (the arm rings
/// after every step of the protocol).
pub fn words(tf: Tf, rows: &[&HarmonicContent]) -> Vec<(String, bool)> {
    let Some(first) = rows.first() else {
        return Vec::new();
    };
    let channel = first.channel;
    let mut out = Vec::new();
    for (h, name) in [(1usize, "3rd"), (0, "2nd")] {
        let sig: Vec<String> = rows
            .iter()
            .filter(|r| r.significant[h])
            .map(|r| {
                format!(
                    "exp {} {:.2} % of the fundamental against a noise level of {:.2} % (power {:.0}× the noise, p = {:.1e})",
                    r.experiment, r.harmonic_pct[h], r.noise_pct, r.power_ratio[h], r.p_value[h]
                )
            })
            .collect();
        if !sig.is_empty() {
            let kind = if h == 1 {
                "odd harmonics come from a symmetric nonlinearity: a stiffening or softening spring, friction, backlash"
            } else {
                "even harmonics come from an asymmetric one: gravity's sin θ about the posture at large angle amplitudes, a spring stiffer on one side, a nonlinearity about an offset posture"
            };
            out.push((
                format!(
                    "{} ({channel}): {name} harmonic of the excitation beyond the noise in {} ({kind})",
                    tf.name(),
                    sig.join("; ")
                ),
                true,
            ));
        }
    }
    if !rows.iter().any(|r| r.significant[0] || r.significant[1]) {
        let worst = rows
            .iter()
            .map(|r| r.harmonic_pct[1].max(r.harmonic_pct[0]))
            .fold(0.0, f64::max);
        out.push((
            format!(
                "{} ({channel}): no harmonic of the excitation beyond the noise (largest 2nd or 3rd {:.2} % of the fundamental; noise {:.2}–{:.2} %)",
                tf.name(),
                worst,
                rows.iter().map(|r| r.noise_pct).fold(f64::INFINITY, f64::min),
                rows.iter().map(|r| r.noise_pct).fold(0.0, f64::max)
            ),
            false,
        ));
    }
    for r in rows {
        if let Some(nh) = &r.non_harmonic {
            let what = if nh.transient {
                format!(
                    "a transient that decays (second half of the window {:.2}× the first): the arm's ringing after the protocol's steps, kept out of the noise floor",
                    nh.decay
                )
            } else {
                format!(
                    "persistent (second half {:.2}× the first): an oscillation that is no harmonic of the excitation — an instability, a limit cycle or a second source",
                    nh.decay
                )
            };
            out.push((
                format!(
                    "{} ({channel}) exp {}: non-harmonic content at ≈ {:.1} rad/s in {} of {} windows, {:.1} % of the fundamental ({:.0}× the noise power), {what}",
                    tf.name(),
                    r.experiment,
                    nh.omega_rad_s,
                    nh.windows,
                    nh.of,
                    nh.size_pct,
                    nh.power_ratio
                ),
                !nh.transient && 2 * nh.windows > nh.of,
            ));
        }
    }
    out
}
