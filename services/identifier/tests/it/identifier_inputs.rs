//! What the identifier discards, warns about or refuses, on the synthetic
//! stream of `identifier.rs`: a faulted or safe-state sample or command
//! (only its window), missing commands, protocol states sent on change
//! only and late, bad settings.

use exo_identifier::{FitSource, Identifier, IdentifierSettings};
use exo_impedance::Complex64;
use exo_messages::{status, ControlMode, ProtocolPhase};

use crate::identifier::{
    brief_human, paper_omega, Delivery, Faults, Stream, GRAVITY_NM, M_E, POSTURE_RAD,
};

#[test]
fn a_faulted_or_safe_state_sample_or_command_discards_only_its_window() {
    let human = brief_human();
    let mut st = Stream::new().with(IdentifierSettings::default(), Delivery::EveryTick, true);
    let fault = |phase, k, bits| Faults {
        status: Some((phase, k, bits)),
        ..Default::default()
    };
    let mode = |phase, k, m| Faults {
        mode: Some((phase, k, m)),
        ..Default::default()
    };
    let plan = [
        Faults::default(),
        fault(ProtocolPhase::Analysis, 1234, status::FT_FAULT),
        // A fault while settling is outside the analysis window.
        fault(ProtocolPhase::Settling, 100, status::ENCODER_FAULT),
        fault(ProtocolPhase::Analysis, 0, status::SAFE_STATE),
        // STALE and SATURATED are not rejections.
        fault(ProtocolPhase::Analysis, 10, status::STALE),
        Faults {
            nan_at: Some(2500),
            ..Default::default()
        },
        // The controller's latched safe state, seen only in its command.
        mode(ProtocolPhase::Analysis, 700, ControlMode::SafeGravityOnly),
        // Outside the window, or in normal operation: no rejection.
        mode(ProtocolPhase::Settling, 700, ControlMode::FaultLatched),
        mode(ProtocolPhase::Analysis, 700, ControlMode::Run),
    ];
    for (i, f) in plan.into_iter().enumerate() {
        let n = i as u32 + 1;
        let omega = paper_omega(n);
        st.period(1, n, omega, human.response(omega), 1.0, 0.0, f);
    }
    let sink = &st.sinks[0];
    let periods: Vec<u32> = sink.frf().iter().map(|p| p.period).collect();
    assert_eq!(periods, vec![1, 3, 5, 8, 9]);
    let w = sink.warnings();
    assert!(
        w.iter()
            .any(|w| w.contains("period 2") && w.contains("0x2") && w.contains("discarded")),
        "{w:?}"
    );
    assert!(
        w.iter()
            .any(|w| w.contains("period 4") && w.contains("0x10") && w.contains("discarded")),
        "{w:?}"
    );
    assert!(
        w.iter()
            .any(|w| w.contains("period 6") && w.contains("tau_c") && w.contains("no FRF point")),
        "{w:?}"
    );
    assert!(
        w.iter().any(|w| w.contains("period 7")
            && w.contains("latched safe state")
            && w.contains("discarded")),
        "{w:?}"
    );
    // Points keep consecutive sequence numbers.
    let seqs: Vec<u64> = sink.frf().iter().map(|p| p.seq).collect();
    assert_eq!(seqs, vec![0, 1, 2, 3, 4]);
}

#[test]
fn without_commands_gravity_stays_in_tau_s_and_a_warning_says_so() {
    let human = brief_human();
    let settings = IdentifierSettings {
        fit_source: FitSource::ActuatorTorque,
        ..IdentifierSettings::default()
    };
    let mut st = Stream::new()
        .with(settings, Delivery::EveryTick, false)
        .with(IdentifierSettings::default(), Delivery::EveryTick, false);
    let omega = 5.0;
    st.period(
        1,
        1,
        omega,
        human.response(omega),
        1.0,
        0.0,
        Faults::default(),
    );
    let sink = &st.sinks[0];
    let p = sink.frf()[0];
    assert!(sink.warnings().iter().any(|w| w.contains("no command")));
    // No command answers a sample: τ_s/τ_d is left unestimated (0), not
    // tried on commands that answer nothing, and not warned about twice.
    assert!(
        sink.warnings().iter().all(|w| !w.contains("τ_s/τ_d")),
        "{:?}",
        sink.warnings()
    );
    // Fitting the cuff's S_h needs no command: nothing to warn about.
    let w = st.sinks[1].warnings();
    assert!(
        w.iter()
            .all(|w| !w.contains("command") && !w.contains("gravity")),
        "{w:?}"
    );
    assert_eq!((p.sea_re, p.sea_im), (0.0, 0.0));
    // τ_s keeps 20 sin θ: S_h-e/α gains its slope about the posture,
    // 20 cos(0.85) (posture + the ramped 0.05 rad), to first order in the
    // 0.02 rad excitation (the cubic term of sin changes it by A²/8 = 5e-5).
    let truth_hea = human.response(omega) - M_E * omega * omega;
    let gain = Complex64::new(p.s_he_re, p.s_he_im) - truth_hea;
    let slope = GRAVITY_NM * (POSTURE_RAD + 0.05).cos();
    assert!((gain - slope).norm() < 1e-3 * slope, "{gain} vs {slope}");
}

#[test]
fn protocol_states_on_change_only_and_late_give_the_same_points() {
    let human = brief_human();
    let mut st = Stream::new()
        .with(IdentifierSettings::default(), Delivery::EveryTick, true)
        .with(
            IdentifierSettings::default(),
            Delivery::OnChange { delay: 0 },
            true,
        )
        .with(
            IdentifierSettings::default(),
            Delivery::OnChange { delay: 7 },
            true,
        );
    for n in 1..=3 {
        let omega = paper_omega(n);
        st.period(
            2,
            n,
            omega,
            human.response(omega),
            1.0,
            0.01,
            Faults::default(),
        );
    }
    let reference = st.sinks[0].frf();
    assert_eq!(reference.len(), 3);
    for sink in &st.sinks[1..] {
        assert_eq!(sink.frf(), reference);
        assert_eq!(sink.estimates(), st.sinks[0].estimates());
    }
}

#[test]
fn bad_settings_are_refused_naming_the_field() {
    let bad = [
        (
            "rate_hz",
            IdentifierSettings {
                rate_hz: f64::NAN,
                ..Default::default()
            },
        ),
        (
            "f_bounds[1]",
            IdentifierSettings {
                f_bounds: [0.0, 1.0],
                ..Default::default()
            },
        ),
        (
            "k_range_nm_per_rad[1]",
            IdentifierSettings {
                k_range_nm_per_rad: [50.0, 10.0],
                ..Default::default()
            },
        ),
        (
            "welch_segment",
            IdentifierSettings {
                welch_segment: 15,
                ..Default::default()
            },
        ),
        (
            "phase_margin_deg",
            IdentifierSettings {
                phase_margin_deg: 95.0,
                ..Default::default()
            },
        ),
        (
            "max_window_s",
            IdentifierSettings {
                max_window_s: 1e9,
                ..Default::default()
            },
        ),
        // The product rate · window (2e8 samples) is what is bounded, not
        // either alone.
        (
            "max_window_s",
            IdentifierSettings {
                rate_hz: 2e4,
                max_window_s: 1e4,
                ..Default::default()
            },
        ),
    ];
    for (field, s) in bad {
        let e = Identifier::try_new(s).unwrap_err();
        assert_eq!(e.field, field, "{e}");
        assert!(e.to_string().contains(field));
    }
    assert!(Identifier::try_new(IdentifierSettings::default()).is_ok());
    assert!(Identifier::try_new(IdentifierSettings {
        rate_hz: 1e3,
        max_window_s: 9e4,
        ..Default::default()
    })
    .is_ok());
    // A Welch segment need not be a power of two (rustfft, issue 34); 16 is
    // the shortest.
    for welch_segment in [16, 1000] {
        assert!(Identifier::try_new(IdentifierSettings {
            welch_segment,
            ..Default::default()
        })
        .is_ok());
    }
}
