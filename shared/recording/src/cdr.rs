//! CDR (OMG XCDR1, little endian, as ROS 2 serialises) of the exo messages,
//! and their ros2msg schemas, generated from one field list per message so
//! the two cannot disagree.
//!
//! Layout: a 4-byte encapsulation header `00 01 00 00` (CDR_LE), then the
//! fields in order, each aligned to its own size (1, 2, 4 or 8 bytes)
//! relative to the first byte after the header; fixed arrays have no length
//! prefix. So `ProtocolState`'s three `uint32`s are followed by 4 bytes of
//! padding before its first `float64`. The `_pad` fields of the Rust structs
//! are not part of the schemas.

use exo_messages::{
    ActuatorCommand, BusMotorCommand, BusSensorFrame, FrfPoint, ImpedanceEstimate, OperatorCommand,
    ProtocolState, SensorSample,
};

/// The CDR encapsulation header: little-endian plain CDR, no options.
pub const ENCAPSULATION_LE: [u8; 4] = [0x00, 0x01, 0x00, 0x00];
const ENCAPSULATION_BE: [u8; 4] = [0x00, 0x00, 0x00, 0x00];

/// Why a CDR payload could not be decoded.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CdrError {
    /// Shorter than its fields.
    #[error("payload ends at byte {len} inside field `{field}` (needs bytes up to {needed})")]
    Truncated {
        /// The field being read.
        field: &'static str,
        /// Payload length (bytes).
        len: usize,
        /// Bytes needed.
        needed: usize,
    },
    /// Not a little-endian CDR encapsulation.
    #[error("encapsulation header {0:02x?} is not little-endian CDR (00 01 00 00)")]
    Encapsulation([u8; 4]),
}

/// A scalar or fixed array that CDR can carry.
pub trait CdrField: Sized + Copy {
    /// The ros2msg type, e.g. `float64` or `float64[6]`.
    const ROS_TYPE: &'static str;
    /// Appends the value, aligned.
    fn put(&self, w: &mut CdrWriter);
    /// Reads the value, aligned.
    fn get(r: &mut CdrReader<'_>, field: &'static str) -> Result<Self, CdrError>;
}

/// Builds a CDR payload (header included) into a reusable buffer.
#[derive(Debug, Default)]
pub struct CdrWriter {
    buf: Vec<u8>,
}

impl CdrWriter {
    /// Starts a payload in `buf` (cleared; its capacity is reused).
    pub fn start(mut buf: Vec<u8>) -> Self {
        buf.clear();
        buf.extend_from_slice(&ENCAPSULATION_LE);
        CdrWriter { buf }
    }

    fn align(&mut self, n: usize) {
        let body = self.buf.len() - 4;
        let pad = (n - body % n) % n;
        self.buf.extend(std::iter::repeat_n(0u8, pad));
    }

    fn bytes<const N: usize>(&mut self, b: [u8; N]) {
        self.align(N);
        self.buf.extend_from_slice(&b);
    }

    /// The payload.
    pub fn finish(self) -> Vec<u8> {
        self.buf
    }
}

/// Reads a CDR payload.
#[derive(Debug)]
pub struct CdrReader<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> CdrReader<'a> {
    /// Checks the encapsulation header.
    pub fn new(data: &'a [u8]) -> Result<Self, CdrError> {
        if data.len() < 4 {
            return Err(CdrError::Truncated {
                field: "encapsulation header",
                len: data.len(),
                needed: 4,
            });
        }
        let head = [data[0], data[1], data[2], data[3]];
        if head[..2] != ENCAPSULATION_LE[..2] {
            // Big-endian CDR is legal but no ROS 2 tool on a PC writes it.
            let _ = ENCAPSULATION_BE;
            return Err(CdrError::Encapsulation(head));
        }
        Ok(CdrReader { data, pos: 4 })
    }

    /// Whether every byte has been read.
    pub fn at_end(&self) -> bool {
        self.pos >= self.data.len()
    }

    fn bytes<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N], CdrError> {
        let body = self.pos - 4;
        let start = self.pos + (N - body % N) % N;
        let end = start + N;
        let slice = self.data.get(start..end).ok_or(CdrError::Truncated {
            field,
            len: self.data.len(),
            needed: end,
        })?;
        let mut out = [0u8; N];
        out.copy_from_slice(slice);
        self.pos = end;
        Ok(out)
    }
}

macro_rules! scalar {
    ($t:ty, $ros:literal, $n:literal) => {
        impl CdrField for $t {
            const ROS_TYPE: &'static str = $ros;
            fn put(&self, w: &mut CdrWriter) {
                w.bytes::<$n>(self.to_le_bytes());
            }
            fn get(r: &mut CdrReader<'_>, field: &'static str) -> Result<Self, CdrError> {
                Ok(<$t>::from_le_bytes(r.bytes::<$n>(field)?))
            }
        }
    };
}
scalar!(u32, "uint32", 4);
scalar!(u64, "uint64", 8);
scalar!(i64, "int64", 8);
scalar!(f64, "float64", 8);

impl CdrField for [f64; 6] {
    const ROS_TYPE: &'static str = "float64[6]";
    fn put(&self, w: &mut CdrWriter) {
        for v in self {
            v.put(w);
        }
    }
    fn get(r: &mut CdrReader<'_>, field: &'static str) -> Result<Self, CdrError> {
        let mut out = [0.0; 6];
        for v in &mut out {
            *v = f64::get(r, field)?;
        }
        Ok(out)
    }
}

/// A message of the recording contract.
pub trait Recordable: exo_messages::Message {
    /// Its topic, e.g. `exo/sensor`.
    const TOPIC: &'static str;
    /// Its ros2msg schema name, e.g. `exo_msgs/msg/SensorSample`.
    const SCHEMA_NAME: &'static str;
    /// How many leading fields a recording must carry; later ones were added
    /// to the contract and default when a writer leaves them out.
    const REQUIRED_FIELDS: usize;
    /// `(name, ros2msg type)` of every field, in order.
    fn fields() -> Vec<(&'static str, &'static str)>;
    /// The ros2msg schema text.
    fn schema() -> String {
        let mut s = String::new();
        for (name, ty) in Self::fields() {
            s.push_str(ty);
            s.push(' ');
            s.push_str(name);
            s.push('\n');
        }
        s
    }
    /// The message's time stamp (ns): the log time of the recording.
    fn stamp_ns(&self) -> u64;
    /// Appends the CDR payload (header included) to a cleared `buf`.
    fn encode_into(&self, buf: Vec<u8>) -> Vec<u8>;
    /// Decodes a CDR payload; fields beyond [`REQUIRED_FIELDS`](Self::REQUIRED_FIELDS)
    /// that the payload lacks are zero, and a zero `stamp_ns` is replaced by `log_time_ns`.
    fn decode(data: &[u8], log_time_ns: u64) -> Result<Self, CdrError>;
}

macro_rules! recordable {
    ($ty:ident, $topic:literal, $schema:literal, required = $req:literal, [$($field:ident),+ $(,)?]) => {
        impl Recordable for $ty {
            const TOPIC: &'static str = $topic;
            const SCHEMA_NAME: &'static str = $schema;
            const REQUIRED_FIELDS: usize = $req;
            fn fields() -> Vec<(&'static str, &'static str)> {
                fn ty_of<T: CdrField>(_: impl Fn(&$ty) -> T) -> &'static str {
                    T::ROS_TYPE
                }
                vec![$((stringify!($field), ty_of(|m: &$ty| m.$field))),+]
            }
            fn stamp_ns(&self) -> u64 {
                self.stamp_ns
            }
            fn encode_into(&self, buf: Vec<u8>) -> Vec<u8> {
                let mut w = CdrWriter::start(buf);
                $(self.$field.put(&mut w);)+
                w.finish()
            }
            fn decode(data: &[u8], log_time_ns: u64) -> Result<Self, CdrError> {
                let mut r = CdrReader::new(data)?;
                let mut m = $ty::default();
                let mut index = 0usize;
                $(
                    if !(index >= $req && r.at_end()) {
                        m.$field = CdrField::get(&mut r, stringify!($field))?;
                    }
                    index += 1;
                )+
                let _ = index;
                if m.stamp_ns == 0 {
                    m.stamp_ns = log_time_ns;
                }
                Ok(m)
            }
        }
    };
}

recordable!(
    SensorSample,
    "exo/sensor",
    "exo_msgs/msg/SensorSample",
    required = 7,
    [seq, stamp_ns, theta_e, omega_e, tau_c, tau_s, status]
);
recordable!(
    ActuatorCommand,
    "exo/command",
    "exo_msgs/msg/ActuatorCommand",
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
    "exo/protocol",
    "exo_msgs/msg/ProtocolState",
    required = 9,
    [experiment, period, phase, omega, amplitude, alpha, load_kg, grip_kg, bias_nm, stamp_ns]
);
recordable!(
    FrfPoint,
    "exo/identifier/frf",
    "exo_msgs/msg/FrfPoint",
    required = 13,
    [
        seq, stamp_ns, experiment, period, omega, s_h_re, s_h_im, s_hea_re, s_hea_im, sea_re,
        sea_im, coherence, noise_rel
    ]
);
recordable!(
    ImpedanceEstimate,
    "exo/identifier/estimate",
    "exo_msgs/msg/ImpedanceEstimate",
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
    "exo/operator",
    "exo_msgs/msg/OperatorCommand",
    required = 4,
    [seq, stamp_ns, kind, value]
);
recordable!(
    BusSensorFrame,
    "exo/bus/sensor",
    "exo_msgs/msg/BusSensorFrame",
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
    "exo/bus/motor",
    "exo_msgs/msg/BusMotorCommand",
    required = 5,
    [seq, stamp_ns, frame_seq, tau_motor_nm, enable]
);

/// `(topic, schema name, schema text)` of every contract topic.
pub fn contract() -> Vec<(&'static str, &'static str, String)> {
    fn row<T: Recordable>() -> (&'static str, &'static str, String) {
        (T::TOPIC, T::SCHEMA_NAME, T::schema())
    }
    vec![
        row::<SensorSample>(),
        row::<ActuatorCommand>(),
        row::<ProtocolState>(),
        row::<FrfPoint>(),
        row::<ImpedanceEstimate>(),
        row::<OperatorCommand>(),
        row::<BusSensorFrame>(),
        row::<BusMotorCommand>(),
    ]
}
