//! CDR encoding of every contract message: exact bytes, round trips, and
//! errors (never panics) on short or malformed payloads.

use crate::common::*;
use exo_messages::*;
use exo_recording::cdr::{CdrError, FieldValue, ENCAPSULATION_LE};
use exo_recording::schema::{contract, find};
use exo_recording::Recordable;

#[test]
fn protocol_state_cdr_bytes_are_exact_with_the_padding_after_the_three_uint32() {
    let p = protocol(3);
    let b = p.encode_into(Vec::new());
    let mut expected = vec![0x00, 0x01, 0x00, 0x00];
    expected.extend_from_slice(&p.experiment.to_le_bytes());
    expected.extend_from_slice(&p.period.to_le_bytes());
    expected.extend_from_slice(&p.phase.to_le_bytes());
    expected.extend_from_slice(&[0, 0, 0, 0]);
    for v in [
        p.omega,
        p.amplitude,
        p.alpha,
        p.load_kg,
        p.grip_kg,
        p.bias_nm,
    ] {
        expected.extend_from_slice(&v.to_le_bytes());
    }
    expected.extend_from_slice(&p.stamp_ns.to_le_bytes());
    assert_eq!(b, expected);
    // Byte by byte at the places that matter: header, uint32s, padding, first float64.
    assert_eq!(&b[..4], &[0x00, 0x01, 0x00, 0x00], "CDR_LE encapsulation");
    assert_eq!(&b[4..8], &4u32.to_le_bytes(), "experiment");
    assert_eq!(&b[8..12], &4u32.to_le_bytes(), "period");
    assert_eq!(&b[12..16], &4u32.to_le_bytes(), "phase");
    for (i, byte) in b[16..20].iter().enumerate() {
        assert_eq!(*byte, 0, "padding byte {i} before omega");
    }
    assert_eq!(
        &b[20..28],
        &p.omega.to_le_bytes(),
        "omega at payload offset 16"
    );
    assert_eq!(b.len(), 4 + 12 + 4 + 6 * 8 + 8);
}

#[test]
fn a_known_protocol_state_has_these_bytes() {
    // Written out by hand from the contract, independent of the encoder.
    let p = ProtocolState {
        experiment: 1,
        period: 2,
        phase: 3,
        omega: 1.0,
        amplitude: 2.0,
        alpha: -1.0,
        load_kg: 0.5,
        grip_kg: 0.0,
        bias_nm: 8.0,
        stamp_ns: 0x0102_0304_0506_0708,
        ..Default::default()
    };
    #[rustfmt::skip]
    let bytes: [u8; 76] = [
        0x00, 0x01, 0x00, 0x00,
        0x01, 0, 0, 0,  0x02, 0, 0, 0,  0x03, 0, 0, 0,  0, 0, 0, 0,
        0, 0, 0, 0, 0, 0, 0xf0, 0x3f,  // 1.0
        0, 0, 0, 0, 0, 0, 0x00, 0x40,  // 2.0
        0, 0, 0, 0, 0, 0, 0xf0, 0xbf,  // -1.0
        0, 0, 0, 0, 0, 0, 0xe0, 0x3f,  // 0.5
        0, 0, 0, 0, 0, 0, 0x00, 0x00,  // 0.0
        0, 0, 0, 0, 0, 0, 0x20, 0x40,  // 8.0
        0x08, 0x07, 0x06, 0x05, 0x04, 0x03, 0x02, 0x01,
    ];
    assert_eq!(p.encode_into(Vec::new()), bytes);
    assert_eq!(ProtocolState::decode(&bytes, 0).unwrap(), p);
}

#[test]
fn the_schemas_are_the_contract_text() {
    assert_eq!(
        SensorSample::schema(),
        "uint64 seq\nuint64 stamp_ns\nfloat64 theta_e\nfloat64 omega_e\nfloat64 tau_c\nfloat64 tau_s\nuint32 status\n"
    );
    assert_eq!(
        ActuatorCommand::schema(),
        "uint64 seq\nuint64 stamp_ns\nuint64 sensor_seq\nfloat64 tau_d\nfloat64 tau_gravity\nfloat64 tau_amplification\nfloat64 tau_bias\nfloat64 tau_excitation\nuint32 mode\n"
    );
    assert_eq!(
        ProtocolState::schema(),
        "uint32 experiment\nuint32 period\nuint32 phase\nfloat64 omega\nfloat64 amplitude\nfloat64 alpha\nfloat64 load_kg\nfloat64 grip_kg\nfloat64 bias_nm\nuint64 stamp_ns\n"
    );
    assert!(BusSensorFrame::schema().contains("float64[6] cuff_wrench\n"));
    assert!(contract().iter().all(|t| !t.text().contains("_pad")));
    let names: Vec<_> = contract()
        .iter()
        .map(|t| (t.topic, t.schema_name))
        .collect();
    assert_eq!(
        names,
        [
            ("exo/sensor", "exo_msgs/msg/SensorSample"),
            ("exo/command", "exo_msgs/msg/ActuatorCommand"),
            ("exo/protocol", "exo_msgs/msg/ProtocolState"),
            ("exo/identifier/frf", "exo_msgs/msg/FrfPoint"),
            ("exo/identifier/estimate", "exo_msgs/msg/ImpedanceEstimate"),
            ("exo/operator", "exo_msgs/msg/OperatorCommand"),
            ("exo/bus/sensor", "exo_msgs/msg/BusSensorFrame"),
            ("exo/bus/motor", "exo_msgs/msg/BusMotorCommand"),
        ]
    );
    assert_eq!(find("exo/protocol").unwrap().required_fields, 9);
}

/// Size of the CDR body of a field list, with alignment.
fn cdr_len(fields: &[(&str, &str)]) -> usize {
    let mut pos = 0usize;
    for (_, ty) in fields {
        let (n, count) = match *ty {
            "uint32" => (4, 1),
            "float64[6]" => (8, 6),
            _ => (8, 1),
        };
        pos = pos.div_ceil(n) * n + n * count;
    }
    4 + pos
}

fn round_trip<T: Recordable>(m: T) {
    let b = m.encode_into(vec![0xAA; 3]);
    assert_eq!(&b[..4], &ENCAPSULATION_LE);
    assert_eq!(b.len(), cdr_len(&T::fields()), "{}", T::TOPIC);
    assert_eq!(T::decode(&b, 0).unwrap(), m, "{}", T::TOPIC);
    assert_eq!(
        T::decode_fields(&b, T::fields().len(), 0).unwrap(),
        m,
        "{}",
        T::TOPIC
    );
    // Every field is set in the fixture, so a lost field would show.
    for (name, v) in m.field_values() {
        let zero = match v {
            FieldValue::Uint(u) => u == 0,
            FieldValue::Int(i) => i == 0,
            FieldValue::Float(x) => x == 0.0,
            FieldValue::Floats(x) => x.contains(&0.0),
        };
        assert!(!zero, "fixture {}.{name} is 0", T::TOPIC);
    }
    // Every shorter payload is an error naming a field, never a panic.
    for len in 0..b.len() {
        let e = T::decode_fields(&b[..len], T::fields().len(), 0).unwrap_err();
        match e {
            CdrError::Truncated {
                field,
                offset,
                len: l,
                needed,
            } => {
                assert_eq!(l, len);
                assert!(needed > len && offset < needed, "{e}");
                assert!(
                    field == "encapsulation header" || T::fields().iter().any(|(n, _)| *n == field)
                );
            }
            other => panic!("{other}"),
        }
    }
    // Bytes a newer writer appended are ignored.
    let mut longer = b.clone();
    longer.extend_from_slice(&[1, 2, 3, 4, 5, 6, 7, 8]);
    assert_eq!(T::decode(&longer, 0).unwrap(), m);
}

#[test]
fn every_message_round_trips_through_cdr() {
    for k in [1, 2, 7] {
        round_trip(sample(k));
        round_trip(command(k));
        round_trip(protocol(k));
        round_trip(frf(k));
        round_trip(estimate(k));
        round_trip(operator(k));
        round_trip(bus_sensor(k));
        round_trip(bus_motor(k));
    }
}

#[test]
fn decoding_errors_name_field_and_offset() {
    let b = protocol(3).encode_into(Vec::new());
    // Cut inside amplitude (payload bytes 28..36).
    let e = ProtocolState::decode(&b[..30], 0).unwrap_err();
    assert_eq!(
        e,
        CdrError::Truncated {
            field: "amplitude",
            offset: 28,
            len: 30,
            needed: 36
        }
    );
    assert!(
        e.to_string().contains("amplitude") && e.to_string().contains("28"),
        "{e}"
    );
    // A writer that stops after bias_nm (the fixed part) is accepted, the
    // stamp taken from the log time; half a stamp is an error.
    let q = ProtocolState::decode(&b[..68], 42).unwrap();
    assert_eq!(q.stamp_ns, 42);
    assert_eq!(q.bias_nm, protocol(3).bias_nm);
    assert!(ProtocolState::decode(&b[..72], 42).is_err());
    // With the writer's schema known (9 fields) the rest is not read.
    assert_eq!(
        ProtocolState::decode_fields(&b, 9, 42).unwrap().stamp_ns,
        42
    );
    // Big-endian CDR and garbage headers are refused.
    let mut be = b.clone();
    be[1] = 0x00;
    assert_eq!(
        ProtocolState::decode(&be, 0).unwrap_err(),
        CdrError::Encapsulation([0, 0, 0, 0])
    );
    assert!(ProtocolState::decode(&[], 0).is_err());
    assert!(SensorSample::decode(&[0x00, 0x01], 0).is_err());
}

#[test]
fn nan_is_encoded_and_decoded_as_is_and_the_caller_validates() {
    let mut s = sample(2);
    s.tau_c = f64::NAN;
    s.omega_e = f64::NEG_INFINITY;
    let d = SensorSample::decode(&s.encode_into(Vec::new()), 0).unwrap();
    assert!(d.tau_c.is_nan() && d.omega_e == f64::NEG_INFINITY);
    assert_eq!(d.first_non_finite().unwrap().0, "omega_e");
}
