//! The recording contract in one place: for every topic its ros2msg schema
//! name, the Rust message it carries, and its field list (from which the
//! schema text and the CDR encoding are both generated, so they cannot
//! disagree). `docs/recording-format.md` gives every field's unit and
//! meaning.
//!
//! Fixed part: the first [`Recordable::REQUIRED_FIELDS`] fields of each
//! topic never change name, type or order; new fields may only be appended
//! (as `ProtocolState.stamp_ns` was), and readers default them to 0 when a
//! writer leaves them out.

use exo_messages::channels;
use exo_messages::{
    ActuatorCommand, BusMotorCommand, BusSensorFrame, FrfPoint, ImpedanceEstimate, OperatorCommand,
    ProtocolState, SensorSample,
};

use crate::cdr::{recordable, Recordable};
use crate::ros2msg::{parse_ros2msg, schema_text};

/// The MCAP profile of a recording.
pub const PROFILE: &str = "ros2";
/// The schema encoding of every contract channel.
pub const SCHEMA_ENCODING: &str = "ros2msg";
/// The message encoding of every contract channel.
pub const MESSAGE_ENCODING: &str = "cdr";

recordable!(
    SensorSample,
    channels::SENSOR,
    required = 7,
    [seq, stamp_ns, theta_e, omega_e, tau_c, tau_s, status]
);
recordable!(
    ActuatorCommand,
    channels::COMMAND,
    required = 9,
    [
        seq,
        stamp_ns,
        sensor_seq,
        tau_d,
        tau_gravity,
        tau_amplification,
        tau_bias,
        tau_excitation,
        mode
    ]
);
recordable!(
    ProtocolState,
    channels::PROTOCOL,
    required = 9,
    [experiment, period, phase, omega, amplitude, alpha, load_kg, grip_kg, bias_nm, stamp_ns]
);
recordable!(
    FrfPoint,
    channels::IDENTIFIER_FRF,
    required = 13,
    [
        seq,
        stamp_ns,
        experiment,
        period,
        omega,
        s_h_re,
        s_h_im,
        s_hea_re,
        s_hea_im,
        sea_re,
        sea_im,
        coherence,
        noise_rel,
        s_he_re,
        s_he_im,
        s_he_noise_rel
    ]
);
recordable!(
    ImpedanceEstimate,
    channels::IDENTIFIER_ESTIMATE,
    required = 24,
    [
        seq,
        stamp_ns,
        experiment,
        period,
        n_points,
        model,
        k_h,
        k_h_se,
        h_h,
        h_h_se,
        b_h,
        b_h_se,
        m_h,
        m_h_se,
        c_h,
        c_h_se,
        r2,
        f_m1_m3,
        f_m2_m3,
        f_critical,
        beta0,
        beta1,
        power_law_r2,
        recommended_f
    ]
);
recordable!(
    OperatorCommand,
    channels::OPERATOR,
    required = 4,
    [seq, stamp_ns, kind, value]
);
recordable!(
    BusSensorFrame,
    channels::BUS_SENSOR,
    required = 6,
    [
        seq,
        stamp_ns,
        encoder_counts,
        cuff_wrench,
        sea_deflection_counts,
        status
    ]
);
recordable!(
    BusMotorCommand,
    channels::BUS_MOTOR,
    required = 5,
    [seq, stamp_ns, frame_seq, tau_motor_nm, enable]
);

/// One row of the contract table.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicSchema {
    /// The topic, e.g. `exo/sensor`.
    pub topic: &'static str,
    /// The ros2msg schema name, e.g. `exo_msgs/msg/SensorSample`.
    pub schema_name: &'static str,
    /// The Rust message type (in `exo-messages`), e.g. `SensorSample`.
    pub rust_type: &'static str,
    /// How many leading fields every writer must write.
    pub required_fields: usize,
    /// `(name, ros2msg type)` of every field, in order.
    pub fields: Vec<(&'static str, &'static str)>,
}

impl TopicSchema {
    fn of<T: Recordable>() -> Self {
        TopicSchema {
            topic: T::TOPIC,
            schema_name: T::SCHEMA_NAME,
            rust_type: <T as exo_messages::Message>::NAME,
            required_fields: T::REQUIRED_FIELDS,
            fields: T::fields(),
        }
    }

    /// The ros2msg schema text.
    pub fn text(&self) -> String {
        schema_text(&self.fields)
    }
}

/// Every contract topic, in the order of the format document.
pub fn contract() -> Vec<TopicSchema> {
    vec![
        TopicSchema::of::<SensorSample>(),
        TopicSchema::of::<ActuatorCommand>(),
        TopicSchema::of::<ProtocolState>(),
        TopicSchema::of::<FrfPoint>(),
        TopicSchema::of::<ImpedanceEstimate>(),
        TopicSchema::of::<OperatorCommand>(),
        TopicSchema::of::<BusSensorFrame>(),
        TopicSchema::of::<BusMotorCommand>(),
    ]
}

/// The contract row of `topic`, if it is a contract topic.
pub fn find(topic: &str) -> Option<TopicSchema> {
    contract().into_iter().find(|t| t.topic == topic)
}

/// How a file's schema text fits the contract's field list.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SchemaMatch {
    /// Leading fields the file's messages carry in the contract's names and
    /// types: how many to decode.
    pub n_fields: usize,
    /// The file's fields after those (not part of the contract, or in
    /// another place), which are ignored.
    pub ignored: Vec<String>,
}

/// Compares a file's schema text with the contract row: the file must
/// carry at least the required fields, with the contract's names and types
/// in the contract's order. Later fields that differ are ignored (named in
/// [`SchemaMatch::ignored`]). `Err` says which field does not match.
pub fn match_fields(row: &TopicSchema, text: &str) -> Result<SchemaMatch, String> {
    let theirs = parse_ros2msg(text);
    let mut n = 0;
    for ((ty, name), (our_name, our_ty)) in theirs.iter().zip(&row.fields) {
        if ty != our_ty || name != our_name {
            break;
        }
        n += 1;
    }
    if n < row.required_fields {
        let (our_name, our_ty) = row.fields[n];
        let found = theirs
            .get(n)
            .map_or("nothing".to_string(), |(t, f)| format!("`{t} {f}`"));
        return Err(format!(
            "field {} must be `{our_ty} {our_name}`, the file's schema has {found} there",
            n + 1
        ));
    }
    Ok(SchemaMatch {
        n_fields: n,
        ignored: theirs[n..]
            .iter()
            .map(|(t, f)| format!("{t} {f}"))
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parsing_skips_comments_constants_defaults_and_nested_types() {
        let text = "# header\nuint64 seq  # count\nuint32 FLAG=4\nuint32 X = 5\n\nfloat64 theta_e 0.5\nfloat64[6] w\n====\nMSG: a/b\nuint8 z\n";
        assert_eq!(
            parse_ros2msg(text),
            vec![
                ("uint64".to_string(), "seq".to_string()),
                ("float64".to_string(), "theta_e".to_string()),
                ("float64[6]".to_string(), "w".to_string()),
            ]
        );
    }

    #[test]
    fn a_schema_must_carry_the_required_fields_in_order() {
        let row = find("exo/protocol").unwrap();
        let full = match_fields(&row, &row.text()).unwrap();
        assert_eq!(full.n_fields, 10);
        assert!(full.ignored.is_empty());
        let fixed: String = row
            .text()
            .lines()
            .take(9)
            .map(|l| format!("{l}\n"))
            .collect();
        assert_eq!(match_fields(&row, &fixed).unwrap().n_fields, 9);
        let extra = format!("{fixed}float32 temperature\n");
        let m = match_fields(&row, &extra).unwrap();
        assert_eq!(
            (m.n_fields, m.ignored),
            (9, vec!["float32 temperature".to_string()])
        );
        let swapped = row.text().replace(
            "float64 omega\nfloat64 amplitude",
            "float64 amplitude\nfloat64 omega",
        );
        let e = match_fields(&row, &swapped).unwrap_err();
        assert!(
            e.contains("field 4 must be `float64 omega`") && e.contains("`float64 amplitude`"),
            "{e}"
        );
        let e = match_fields(&row, "uint32 experiment\n").unwrap_err();
        assert!(e.contains("field 2") && e.contains("nothing"), "{e}");
    }

    #[test]
    fn the_table_has_every_topic_once() {
        let c = contract();
        assert_eq!(c.len(), 8);
        for (i, t) in c.iter().enumerate() {
            assert!(c[i + 1..].iter().all(|u| u.topic != t.topic));
            assert!(t.required_fields <= t.fields.len());
            assert_eq!(find(t.topic).as_ref(), Some(t));
        }
        assert_eq!(find("exo/other"), None);
    }

    #[test]
    fn the_contract_is_every_recorded_channel_with_its_payload() {
        let mut recorded: Vec<_> = channels::CHANNELS
            .iter()
            .filter(|c| c.recorded)
            .map(|c| c.topic)
            .collect();
        let mut topics: Vec<_> = contract().iter().map(|t| t.topic).collect();
        recorded.sort_unstable();
        topics.sort_unstable();
        assert_eq!(topics, recorded);
        for t in contract() {
            let ch = channels::Channel::of_topic(t.topic).unwrap().info();
            assert_eq!(ch.schema, t.schema_name);
            assert!(
                ch.payload.contains(&format!(".{}.", t.rust_type)),
                "{}",
                t.topic
            );
        }
    }
}
