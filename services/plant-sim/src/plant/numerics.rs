//! The plant's numerical parts, each tested against the plain form: the
//! delay lines, the state update `[Φ Γ] [x; u]` column by column, and the
//! carried sine of the gravity term.

use super::N_INPUTS;

/// A fixed-size ring buffer of delayed values (one slot per integration step).
#[derive(Debug, Clone)]
pub(super) struct Delay {
    pub(super) buf: Vec<f64>,
    head: usize,
}

impl Delay {
    pub(super) fn new(steps: usize, initial: f64) -> Self {
        Delay {
            buf: vec![initial; steps + 1],
            head: 0,
        }
    }
    /// Pushes the newest value, returns the one `steps` steps old.
    pub(super) fn push(&mut self, v: f64) -> f64 {
        self.buf[self.head] = v;
        // A compare, not `%`: an integer division per push is most of a
        // delay line's cost at 10 kHz.
        self.head += 1;
        if self.head == self.buf.len() {
            self.head = 0;
        }
        self.buf[self.head]
    }
    /// The value pushed `steps` pushes ago (the one `push` returned last).
    pub(super) fn oldest(&self) -> f64 {
        self.buf[self.head]
    }
}

/// `next = [Φ Γ] [x; u]` with `[Φ Γ]` column by column (`cols`), for `N`
/// states: the sum over the columns in order, as a dot product per row
/// would take it, but a vector operation per column.
#[inline(always)]
pub(super) fn apply_cols<const N: usize>(cols: &[f64], x: &[f64], u: &[f64], next: &mut [f64]) {
    if x.len() != N || u.len() != N_INPUTS || next.len() != N || cols.len() != N * (N + N_INPUTS) {
        return apply_cols_any(cols, x, u, next);
    }
    let mut acc = [0.0; N];
    for (col, v) in cols.chunks_exact(N).zip(x.iter().chain(u)) {
        for (a, c) in acc.iter_mut().zip(col) {
            *a += c * v;
        }
    }
    next.copy_from_slice(&acc);
}

/// [`apply_cols`] for any number of states.
pub(super) fn apply_cols_any(cols: &[f64], x: &[f64], u: &[f64], next: &mut [f64]) {
    let n = next.len();
    next.fill(0.0);
    for (col, v) in cols.chunks_exact(n).zip(x.iter().chain(u)) {
        for (a, c) in next.iter_mut().zip(col) {
            *a += c * v;
        }
    }
}

/// `sin θ` for a θ that moves little from one call to the next: the sine
/// and cosine of an anchor θ₀ are kept, and `sin θ = sin θ₀ cos δ +
/// cos θ₀ sin δ` with `δ = θ − θ₀` and the series of `cos δ`, `sin δ` to
/// the 5th order; the anchor moves to θ when |δ| exceeds [`SineNear::REACH`].
/// Within the reach the series' truncation error is below δ⁶/720 ≈ 1e-21,
/// so the result is `sin θ` to rounding (tested against `f64::sin`), at a
/// fraction of a `sin` call: the integration's gravity term needs one every
/// 0.1 ms, where θ moves by 1e-3 rad at the most.
#[derive(Debug, Clone, Copy)]
pub(super) struct SineNear {
    theta0: f64,
    sin0: f64,
    cos0: f64,
}

impl SineNear {
    /// The widest step from the anchor (rad) the series covers.
    const REACH: f64 = 2e-3;

    pub(super) fn new(theta: f64) -> Self {
        let (sin0, cos0) = theta.sin_cos();
        SineNear {
            theta0: theta,
            sin0,
            cos0,
        }
    }

    pub(super) fn sin(&mut self, theta: f64) -> f64 {
        let d = theta - self.theta0;
        if d.abs() > Self::REACH || !d.is_finite() {
            *self = SineNear::new(theta);
            return self.sin0;
        }
        const INV_24: f64 = 1.0 / 24.0;
        const INV_6: f64 = 1.0 / 6.0;
        const INV_120: f64 = 1.0 / 120.0;
        let d2 = d * d;
        let cos_d = 1.0 - d2 * (0.5 - d2 * INV_24);
        let sin_d = d * (1.0 - d2 * (INV_6 - d2 * INV_120));
        self.sin0 * cos_d + self.cos0 * sin_d
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_carried_sine_is_the_sine_to_rounding() {
        // A walk of small steps (as the integration takes), then jumps.
        let mut s = SineNear::new(0.3);
        let mut theta: f64 = 0.3;
        let mut worst: f64 = 0.0;
        for i in 0..200_000 {
            theta += 1.1e-3 * ((i as f64) * 0.0137).sin();
            worst = worst.max((s.sin(theta) - theta.sin()).abs());
        }
        for theta in [-3.0, 2.5, 1e-9, -0.7, 100.0, 0.0] {
            worst = worst.max((s.sin(theta) - theta.sin()).abs());
        }
        assert!(worst <= 4.0 * f64::EPSILON, "worst error {worst:e}");
        // The anchor stays within the reach (no `sin` call) and moves
        // beyond it, or on a non-finite angle.
        let mut s = SineNear::new(0.0);
        s.sin(SineNear::REACH);
        s.sin(-SineNear::REACH);
        assert_eq!(s.theta0, 0.0);
        s.sin(1.5 * SineNear::REACH);
        assert_eq!(s.theta0, 1.5 * SineNear::REACH);
        s.sin(f64::NAN);
        assert!(s.theta0.is_nan());
        s.sin(0.25);
        assert_eq!(s.theta0, 0.25);
        s.sin(0.25 + 0.5 * SineNear::REACH);
        assert_eq!(s.theta0, 0.25);
        // Just inside and just outside the reach from the anchor.
        let mut s = SineNear::new(1.0);
        for d in [SineNear::REACH, -SineNear::REACH, 1.5 * SineNear::REACH] {
            assert!((s.sin(1.0 + d) - (1.0 + d).sin()).abs() <= 4.0 * f64::EPSILON);
        }
    }

    #[test]
    fn the_unrolled_product_is_the_general_one() {
        for n in [4usize, 6, 5, 11] {
            let width = n + N_INPUTS;
            let cols: Vec<f64> = (0..n * width)
                .map(|i| ((i * 37 % 11) as f64) - 5.0)
                .collect();
            let x: Vec<f64> = (0..n).map(|i| 0.5 + i as f64).collect();
            let u: Vec<f64> = (0..N_INPUTS).map(|i| 1.5 - i as f64).collect();
            let mut general = vec![0.0; n];
            apply_cols_any(&cols, &x, &u, &mut general);
            // By hand: entry (i, j) of the column-major matrix is cols[j n + i].
            for (i, g) in general.iter().enumerate() {
                let by_hand: f64 = (0..n).map(|j| cols[j * n + i] * x[j]).sum::<f64>()
                    + (0..N_INPUTS)
                        .map(|j| cols[(n + j) * n + i] * u[j])
                        .sum::<f64>();
                assert_eq!(*g, by_hand);
            }
            // Right size unrolled, or the wrong one (falls back to the loop).
            let (mut four, mut six, mut eleven) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
            apply_cols::<4>(&cols, &x, &u, &mut four);
            apply_cols::<6>(&cols, &x, &u, &mut six);
            apply_cols::<11>(&cols, &x, &u, &mut eleven);
            assert_eq!(four, general, "n = {n}");
            assert_eq!(six, general, "n = {n}");
            assert_eq!(eleven, general, "n = {n}");
        }
    }
}
