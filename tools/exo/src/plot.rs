//! Bode plot of the loop `L(jω) = kp·F(jω)·P(jω)` at both stiffness bounds,
//! with crossovers and phase margins marked (`exo design --plot`).

use std::path::Path;

use anyhow::{anyhow, Result};
use exo_impedance::design::{Design, DesignInputs};
use exo_impedance::{AmplificationLoop, AmplificationPlant};
use plotters::prelude::*;

/// Draws the Bode plot to an SVG file.
pub fn bode_svg(inputs: &DesignInputs, d: &Design, path: &Path) -> Result<()> {
    let cases = d.margins.as_ref().ok_or_else(|| {
        anyhow!(
            "the Bode plot needs the human's loss factor: give --beta0/--beta1 or --loss-factor"
        )
    })?;
    let loops: Vec<(f64, AmplificationLoop)> = cases
        .iter()
        .map(|c| {
            let plant = AmplificationPlant::new(
                inputs.m_e_kg_m2,
                inputs.m_h_kg_m2,
                c.k_nm_per_rad,
                c.loss_factor,
                inputs.sea,
            )?;
            Ok((
                c.k_nm_per_rad,
                AmplificationLoop {
                    kp: d.kp,
                    filter: d.filter,
                    plant,
                },
            ))
        })
        .collect::<Result<_, exo_impedance::ScienceError>>()?;
    let (w_lo, w_hi) = (0.1 * d.filter.p1_rad_s(), 3.0 * inputs.sea.omega_n_rad_s());
    let omegas: Vec<f64> = (0..=800)
        .map(|i| w_lo * (w_hi / w_lo).powf(i as f64 / 800.0))
        .collect();
    // (K, [(ω, |L| dB, ∠L deg)]) per stiffness bound.
    type Curve = (f64, Vec<(f64, f64, f64)>);
    let curves: Vec<Curve> = loops
        .iter()
        .map(|(k, l)| {
            (
                *k,
                omegas
                    .iter()
                    .map(|&w| (w, 20.0 * l.response(w).norm().log10(), l.phase_deg(w)))
                    .collect(),
            )
        })
        .collect();
    let (mut db_lo, mut db_hi, mut ph_lo, mut ph_hi) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for (_, c) in &curves {
        for &(_, db, ph) in c {
            db_lo = db_lo.min(db);
            db_hi = db_hi.max(db);
            ph_lo = ph_lo.min(ph);
            ph_hi = ph_hi.max(ph);
        }
    }
    let ph_lo = ph_lo.min(-190.0);
    let ph_hi = ph_hi.max(10.0);

    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)?;
    }
    let root = SVGBackend::new(path, (900, 760)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let (top, bottom) = root.split_vertically(380);
    let colors = [RGBColor(0, 104, 179), RGBColor(148, 44, 44)];

    let mut mag = ChartBuilder::on(&top)
        .caption(
            format!(
                "Loop L = kp·F·P   (kp = {:.3}, f = {:.3}, {} lag filters)",
                d.kp,
                d.f,
                d.filter.n_filters()
            ),
            ("sans-serif", 18),
        )
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(60)
        .build_cartesian_2d((w_lo..w_hi).log_scale(), (db_lo - 5.0)..(db_hi + 5.0))
        .map_err(plot_err)?;
    mag.configure_mesh()
        .y_desc("|L| (dB)")
        .x_desc("ω (rad/s)")
        .draw()
        .map_err(plot_err)?;
    mag.draw_series(LineSeries::new([(w_lo, 0.0), (w_hi, 0.0)], BLACK.mix(0.5)))
        .map_err(plot_err)?;
    for ((k, c), color) in curves.iter().zip(colors) {
        mag.draw_series(LineSeries::new(
            c.iter().map(|&(w, db, _)| (w, db)),
            color.stroke_width(2),
        ))
        .map_err(plot_err)?
        .label(format!("K = {k} Nm/rad"))
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
    }
    mag.configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(plot_err)?;

    let mut phase = ChartBuilder::on(&bottom)
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(60)
        .build_cartesian_2d((w_lo..w_hi).log_scale(), (ph_lo - 10.0)..(ph_hi + 10.0))
        .map_err(plot_err)?;
    phase
        .configure_mesh()
        .y_desc("∠L (deg)")
        .x_desc("ω (rad/s)")
        .draw()
        .map_err(plot_err)?;
    phase
        .draw_series(LineSeries::new(
            [(w_lo, -180.0), (w_hi, -180.0)],
            BLACK.mix(0.5),
        ))
        .map_err(plot_err)?;
    for ((_, c), color) in curves.iter().zip(colors) {
        phase
            .draw_series(LineSeries::new(
                c.iter().map(|&(w, _, ph)| (w, ph)),
                color.stroke_width(2),
            ))
            .map_err(plot_err)?;
    }
    for (case, color) in cases.iter().zip(colors) {
        for x in &case.analysis.crossovers {
            let w = x.omega_rad_s;
            mag.draw_series(std::iter::once(Circle::new((w, 0.0), 5, color.filled())))
                .map_err(plot_err)?;
            phase
                .draw_series([PathElement::new(
                    vec![(w, -180.0), (w, x.phase_deg)],
                    color.stroke_width(3),
                )])
                .map_err(plot_err)?;
            phase
                .draw_series(std::iter::once(Text::new(
                    format!("PM {:.1}° @ {:.2} rad/s", x.phase_margin_deg, w),
                    (w * 1.1, x.phase_deg + 8.0),
                    ("sans-serif", 14).into_font().color(&color),
                )))
                .map_err(plot_err)?;
        }
    }
    root.present().map_err(plot_err)?;
    Ok(())
}

fn plot_err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow!("plotting failed: {e:?}")
}
