//! `exo design`: runs [`exo_impedance::design::design`] and prints it.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use exo_impedance::design::{design, DesignInputs};
use exo_impedance::{PowerLaw, ScienceError, SeaModel, StiffnessRange};

use crate::args;

/// Arguments of `exo design`. Defaults are the paper's setup (section
/// "Experimental Protocol for Loop Shaping"); a flag left out takes its
/// default, and errors name the flags given (a default that conflicts with
/// them is named as the default).
#[derive(Debug, Args)]
pub struct DesignArgs {
    /// Exoskeleton inertia M_e (kg·m²), load included [default: 1.01].
    #[arg(long, value_name = "KG_M2", allow_negative_numbers = true, value_parser = args::positive)]
    pub me: Option<f64>,
    /// Human inertia M_h (kg·m²) [default: 0.11].
    #[arg(long, value_name = "KG_M2", allow_negative_numbers = true, value_parser = args::positive)]
    pub mh: Option<f64>,
    /// Lowest human stiffness the controller must be stable for (Nm/rad) [default: 10.03].
    #[arg(long, value_name = "NM_PER_RAD", allow_negative_numbers = true, value_parser = args::positive)]
    pub k_min: Option<f64>,
    /// Highest human stiffness the controller must be stable for (Nm/rad) [default: 108.33].
    #[arg(long, value_name = "NM_PER_RAD", allow_negative_numbers = true, value_parser = args::positive)]
    pub k_max: Option<f64>,
    /// The stiffness range in one flag, as MIN,MAX (Nm/rad; also `MIN MAX`),
    /// e.g. `--k-range 10.03,108.33`, the run file's
    /// `controller.k_range_nm_per_rad`; instead of --k-min/--k-max.
    #[arg(long, value_name = "MIN,MAX", num_args = 1..=2, allow_negative_numbers = true, conflicts_with_all = ["k_min", "k_max"])]
    pub k_range: Option<Vec<String>>,
    /// Intercept β0 of the subject's power law log10 H = β0 + β1 log10 K.
    #[arg(long, value_name = "BETA0", allow_hyphen_values = true, requires = "beta1", value_parser = args::finite)]
    pub beta0: Option<f64>,
    /// Slope β1 of the subject's power law.
    #[arg(long, value_name = "BETA1", allow_hyphen_values = true, requires = "beta0", value_parser = args::finite)]
    pub beta1: Option<f64>,
    /// A constant loss factor c = H/K for the margins, when no power law is known.
    #[arg(long, value_name = "C", conflicts_with = "beta0", value_parser = args::positive)]
    pub loss_factor: Option<f64>,
    /// Guaranteed phase margin φ (degrees) for eq. f.
    #[arg(long, value_name = "DEG", allow_negative_numbers = true, value_parser = args::positive)]
    pub phase_margin_deg: Option<f64>,
    /// Explicit fractional order f in (0, 1) (overrides eq. f).
    #[arg(long, value_name = "F", allow_negative_numbers = true, value_parser = args::fractional_order)]
    pub f: Option<f64>,
    /// Explicit proportional gain kp (overrides eq. kp).
    #[arg(long, value_name = "KP", allow_negative_numbers = true, value_parser = args::positive)]
    pub kp: Option<f64>,
    /// Number of lag filters n (1 to 16) [default: 5].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u8).range(1..=16))]
    pub filters: Option<u8>,
    /// First pole p1 of the lag-filter cascade (rad/s) [default: 1].
    #[arg(long, value_name = "RAD_S", allow_negative_numbers = true, value_parser = args::positive)]
    pub p1: Option<f64>,
    /// Pole-to-pole ratio r_pp (> 1); the paper uses 10^0.5 [default: 3.1622776601683795].
    #[arg(long, value_name = "RATIO", allow_negative_numbers = true, value_parser = args::positive)]
    pub rpp: Option<f64>,
    /// Controller sample rate (Hz) for the discrete coefficients [default: 1000].
    #[arg(long, value_name = "HZ", allow_negative_numbers = true, value_parser = args::positive)]
    pub rate_hz: Option<f64>,
    /// SEA torque-loop natural frequency (Hz) [default: 10].
    #[arg(long, value_name = "HZ", allow_negative_numbers = true, value_parser = args::positive)]
    pub sea_hz: Option<f64>,
    /// SEA torque-loop damping ratio [default: 0.7].
    #[arg(long, value_name = "ZETA", allow_negative_numbers = true, value_parser = args::positive)]
    pub sea_zeta: Option<f64>,
    /// Frequencies (rad/s) at which to predict the amplification.
    #[arg(long, value_name = "RAD_S", value_delimiter = ',', default_value = "1,10", value_parser = args::positive)]
    pub omega: Vec<f64>,
    /// Print one JSON object instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Write the Bode plot of L(jω) at both stiffness bounds to this SVG file.
    #[arg(long, value_name = "FILE.svg")]
    pub plot: Option<PathBuf>,
}

/// The paper's setup, for the flags left out.
const DEFAULT_ME: f64 = 1.01;
const DEFAULT_MH: f64 = 0.11;
const DEFAULT_K_MIN: f64 = 10.03;
const DEFAULT_K_MAX: f64 = 108.33;
const DEFAULT_FILTERS: u8 = 5;
const DEFAULT_P1: f64 = 1.0;
const DEFAULT_RPP: f64 = 3.1622776601683795;
const DEFAULT_RATE_HZ: f64 = 1000.0;
const DEFAULT_SEA_HZ: f64 = 10.0;
const DEFAULT_SEA_ZETA: f64 = 0.7;

/// `--k-range` as given: `MIN,MAX` in one value or `MIN MAX` in two (a
/// `:` or `..` between them is taken too).
fn parse_k_range(tokens: &[String]) -> Result<[f64; 2]> {
    let given = tokens.join(" ");
    let usage = || {
        anyhow::anyhow!(
            "--k-range {given}: expects MIN,MAX in Nm/rad with 0 < MIN ≤ MAX, e.g. --k-range 10.03,108.33"
        )
    };
    let text = given.replace("..", ",").replace(':', ",");
    let parts: Vec<&str> = text
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|p| !p.is_empty())
        .collect();
    let [lo, hi] = parts.as_slice() else {
        return Err(usage());
    };
    let lo: f64 = lo.parse().map_err(|_| usage())?;
    let hi: f64 = hi.parse().map_err(|_| usage())?;
    if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && hi > 0.0) {
        return Err(usage());
    }
    if lo > hi {
        anyhow::bail!(
            "--k-range {given}: the stiffness range is reversed (MIN {lo} is above MAX {hi})"
        );
    }
    Ok([lo, hi])
}

impl DesignArgs {
    /// The stiffness range, and the flags it came from.
    fn stiffness_range(&self) -> Result<[f64; 2]> {
        if let Some(tokens) = &self.k_range {
            return parse_k_range(tokens);
        }
        let (lo, hi) = (
            self.k_min.unwrap_or(DEFAULT_K_MIN),
            self.k_max.unwrap_or(DEFAULT_K_MAX),
        );
        if lo > hi {
            let name = |v: Option<f64>, flag: &str, x: f64| match v {
                Some(_) => format!("{flag} {x}"),
                None => format!("the default {flag} {x}"),
            };
            anyhow::bail!(
                "{} is above {}: the stiffness range is reversed{}",
                name(self.k_min, "--k-min", lo),
                name(self.k_max, "--k-max", hi),
                match (self.k_min, self.k_max) {
                    (Some(_), None) => " (give --k-max too, or --k-range MIN,MAX)",
                    (None, Some(_)) => " (give --k-min too, or --k-range MIN,MAX)",
                    _ => "",
                }
            );
        }
        Ok([lo, hi])
    }

    /// The flags given on the command line, for error messages.
    fn given(&self) -> Vec<&'static str> {
        let mut out = Vec::new();
        for (on, flag) in [
            (self.me.is_some(), "--me"),
            (self.mh.is_some(), "--mh"),
            (self.k_min.is_some(), "--k-min"),
            (self.k_max.is_some(), "--k-max"),
            (self.k_range.is_some(), "--k-range"),
            (self.beta0.is_some(), "--beta0"),
            (self.beta1.is_some(), "--beta1"),
            (self.loss_factor.is_some(), "--loss-factor"),
            (self.phase_margin_deg.is_some(), "--phase-margin-deg"),
            (self.f.is_some(), "--f"),
            (self.kp.is_some(), "--kp"),
            (self.filters.is_some(), "--filters"),
            (self.p1.is_some(), "--p1"),
            (self.rpp.is_some(), "--rpp"),
            (self.rate_hz.is_some(), "--rate-hz"),
            (self.sea_hz.is_some(), "--sea-hz"),
            (self.sea_zeta.is_some(), "--sea-zeta"),
        ] {
            if on {
                out.push(flag);
            }
        }
        out
    }

    fn inputs(&self) -> Result<DesignInputs> {
        let [k_min, k_max] = self.stiffness_range()?;
        let rpp = self.rpp.unwrap_or(DEFAULT_RPP);
        if rpp <= 1.0 {
            anyhow::bail!("--rpp must be greater than 1, got {rpp}");
        }
        let flag_error = |e| flag_error(e, &self.given());
        let power_law = match (self.beta0, self.beta1) {
            (Some(b0), Some(b1)) => Some(PowerLaw::new(b0, b1).map_err(flag_error)?),
            _ => None,
        };
        Ok(DesignInputs {
            m_e_kg_m2: self.me.unwrap_or(DEFAULT_ME),
            m_h_kg_m2: self.mh.unwrap_or(DEFAULT_MH),
            range: StiffnessRange::new(k_min, k_max).map_err(flag_error)?,
            power_law,
            loss_factor: self.loss_factor,
            phase_margin_deg: self.phase_margin_deg,
            f: self.f,
            kp: self.kp,
            n_filters: usize::from(self.filters.unwrap_or(DEFAULT_FILTERS)),
            p1_rad_s: self.p1.unwrap_or(DEFAULT_P1),
            r_pp: rpp,
            rate_hz: self.rate_hz.unwrap_or(DEFAULT_RATE_HZ),
            sea: SeaModel::new(
                self.sea_hz.unwrap_or(DEFAULT_SEA_HZ),
                self.sea_zeta.unwrap_or(DEFAULT_SEA_ZETA),
            )
            .map_err(flag_error)?,
            prediction_omegas_rad_s: self.omega.clone(),
        })
    }
}

/// Rewrites a science-core error so it names the command-line flag that
/// set the quantity: the flag itself when it was given (`given`), else
/// that its default was used. A stiffness bound given by `--k-range` is
/// named as `--k-range`.
fn flag_error(err: ScienceError, given: &[&str]) -> anyhow::Error {
    const FLAGS: [(&str, &str); 16] = [
        ("m_e_kg_m2", "--me"),
        ("m_h_kg_m2", "--mh"),
        ("k_min", "--k-min"),
        ("k_max", "--k-max"),
        ("beta0", "--beta0"),
        ("beta1", "--beta1"),
        ("loss_factor", "--loss-factor"),
        ("phase_margin_deg", "--phase-margin-deg"),
        ("kp", "--kp"),
        ("f", "--f"),
        ("n_filters", "--filters"),
        ("p1_rad_s", "--p1"),
        ("r_pp", "--rpp"),
        ("sample_rate_hz", "--rate-hz"),
        ("sea natural_frequency_hz", "--sea-hz"),
        ("sea damping_ratio", "--sea-zeta"),
    ];
    let name = match &err {
        ScienceError::NotFinite { name, .. }
        | ScienceError::NotPositive { name, .. }
        | ScienceError::OutOfRange { name, .. } => Some(*name),
        ScienceError::ReversedRange { .. } => Some("k_min"),
        _ => None,
    };
    let flag = name
        .and_then(|n| FLAGS.iter().find(|(k, _)| *k == n))
        .map(|(_, flag)| *flag)
        .map(|flag| match flag {
            "--k-min" | "--k-max" if given.contains(&"--k-range") => "--k-range",
            f => f,
        });
    match flag {
        Some(flag) if given.contains(&flag) => anyhow::anyhow!("{flag}: {err}"),
        Some(flag) => anyhow::anyhow!(
            "{err} (from the default {flag}, not given; the flags given: {})",
            if given.is_empty() {
                "none".to_string()
            } else {
                given.join(" ")
            }
        ),
        None => anyhow::anyhow!("{err}"),
    }
}

/// Runs `exo design`.
pub fn run(args: &DesignArgs) -> Result<()> {
    let inputs = args.inputs()?;
    let d = design(&inputs).map_err(|e| flag_error(e, &args.given()))?;
    if let Some(path) = &args.plot {
        exo_report::design::bode_svg(&inputs, &d, path)
            .with_context(|| format!("writing the Bode plot to {}", path.display()))?;
    }
    if args.json {
        let out = exo_report::design::json(&inputs, &d)?;
        println!("{out}");
    } else {
        print!(
            "{}",
            exo_report::design::human(&inputs, &d, args.plot.as_deref())
        );
    }
    Ok(())
}
