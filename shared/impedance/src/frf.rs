//! Frequency-response estimation from sampled signals: what turns a
//! recorded period into the FRF points the models are fitted to.
//!
//! # Single frequency (the paper's sine periods)
//!
//! [`SineCorrelator`] is a lock-in: a least-squares fit, at the known
//! excitation frequency ω, of every channel of a block of samples (input
//! `x(t) = θ_e`, outputs `τ_c`, `τ_s`, …) to
//!
//! ```text
//! y(t) ≈ c0 + c1·τ + a·cos ωτ + b·sin ωτ = c0 + c1·τ + Re(Â e^{jωτ}),  Â = a − j b,
//! ```
//!
//! with `τ = t − origin`. The mean `c0` is the bias (gravity, bias torque,
//! posture) and the trend `c1` a slow drift; the trend column is optional
//! (`detrend`). The mean and trend are fitted jointly with the sinusoid
//! rather than removed first: `τ·sin ωτ` does not average out over whole
//! cycles, so a trend removed on its own would take part of the sinusoid
//! with it. Over whole cycles the sinusoid is orthogonal to the mean and
//! to every other harmonic of ω, and the fit reduces to the single-bin DFT
//! `Â = (2/N) Σ y e^{−jωτ}`.
//!
//! **Whole cycles.** The window is trimmed to the largest whole number of
//! cycles counted from `origin`, `[origin, origin + c·2π/ω)`; the remainder
//! (less than one cycle, at the end) is dropped, not used: keeping it would
//! let harmonics and nonlinear distortion of the response leak into the
//! estimate, and the paper's analysis is over whole cycles. Streaming, this
//! costs nothing: the running sums are copied at each cycle boundary, so
//! [`SineCorrelator::finish`] uses the last boundary (or the window's end,
//! when it completes a cycle). Samples need not be evenly spaced (the fit
//! uses their time stamps), and a dropped sample only costs its weight.
//!
//! **Noise.** The residual of the fit gives the noise variance `σ²` of each
//! channel (`RSS/(N − p)`, `p` = 3 or 4 columns), and the covariance of
//! `(a, b)` is `σ² (AᵀA)⁻¹` restricted to the two sinusoid columns — exact
//! for white residuals, including the loss of precision when few cycles
//! make the trend column correlate with the sinusoid (one cycle with
//! `detrend`: the variance of `b` grows 2.6×; a plain `2σ²/N` per component
//! would hide this). The covariance of a ratio `R = Y/X` follows to first
//! order, `δR = δY/X − R δX/X`, input and output noise taken as
//! independent; `noise_rel = √(E|δR|²)/|R|`. The error `R̂ − R` lies inside
//! the 95 % ellipse of [`SinePoint::cov`] (`eᵀ cov⁻¹ e < 5.99`, χ² with two
//! degrees of freedom) in 95 % of windows, and within `2·noise_rel·|R|` in
//! 95–98 % (98 % when the error is circular, as over many cycles).
//! Coloured residual noise (drift beyond a line, tremor) breaks the white
//! assumption: the estimate is then right only as far as the residual's
//! spectrum near ω equals its average over the band.
//!
//! **Coherence.** For each channel, the fraction of its variance (about
//! mean and trend) that the sinusoid explains; a ratio reports the smaller
//! of input and output. Like the magnitude-squared coherence of a
//! broadband estimate, it is 1 for a noise-free linear response and falls
//! as noise (or response at other frequencies) grows: with output
//! signal-to-noise power ratio `q`, it is `q/(1 + q)`.
//!
//! Pushing a sample is O(1) and allocation-free (the sums are `4 × 4` on
//! the stack); [`sine_amplitude`] and [`sine_ratio`] are the block forms.
//!
//! # Broadband (chirp, multisine, random)
//!
//! [`welch_h1`]: the H1 estimator `H = S_xy/S_xx` with Welch averaging
//! (Hann window, 50 % overlap) and magnitude-squared coherence
//! `γ² = |S_xy|²/(S_xx S_yy)`; [`select_band`] keeps the bins where the input
//! carries power and the coherence is high, averaged into log-spaced
//! points. H1 is unbiased by output noise (it only lowers `γ²`); input
//! noise biases it low. Welch allocates its spectra once per call.
//!
//! # Periodic (multisine) excitation
//!
//! [`periodic_frf`]: each excited line's `Ȳ/X̄` over whole periods, its
//! noise from the spread between the periods (module `periodic`).

mod lpm;
mod periodic;
mod sine;
mod welch;

pub use lpm::{
    hann_mean, local_polynomial_ratio, mean_standard_error, mean_standard_error_beside,
    LocalPolynomialPoint, BESIDE_BINS, HANN_MEAN_NOISE_GAIN,
};
pub use periodic::{
    periodic_frf, periodic_frf_each, remove_slow_trend, LineEstimate, PeriodicLine,
};
pub use sine::{
    sine_amplitude, sine_ratio, whole_cycles, SineAmplitude, SineCorrelator, SinePoint,
};
pub use welch::{average_bins, band_groups, fft_in_place, select_band, welch_h1, Fft, H1Bin};
