//! CDR (OMG XCDR1, little endian, as ROS 2 serialises) of the exo messages.
//!
//! Layout: a 4-byte encapsulation header `00 01 00 00` (CDR_LE), then the
//! fields in order, each aligned to its own size (1, 2, 4 or 8 bytes)
//! relative to the first byte after the header; fixed arrays have no length
//! prefix. So `ProtocolState`'s three `uint32`s are followed by 4 bytes of
//! padding before its first `float64`. The `_pad` fields of the Rust structs
//! are not part of the schemas.
//!
//! The field list of every message (and so its schema text and its
//! encoding) is declared once, in [`crate::schema`], through
//! [`Recordable`]. Decoding never panics: short or malformed payloads give a
//! [`CdrError`] naming the field and byte offsets. Decoding does **not**
//! reject NaN or ±∞: the reader ([`crate::reader`]) drops such messages with
//! a warning naming file, topic and field (`Message::first_non_finite` is
//! the validate step), and the writer records what it is given.

/// The CDR encapsulation header: little-endian plain CDR, no options.
pub const ENCAPSULATION_LE: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// Why a CDR payload could not be decoded.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CdrError {
    /// Shorter than its fields.
    #[error(
        "payload of {len} bytes ends inside field `{field}` (bytes {offset}..{needed} of the payload)"
    )]
    Truncated {
        /// The field being read.
        field: &'static str,
        /// Byte offset (in the payload, header included) where the field starts, after alignment.
        offset: usize,
        /// Payload length (bytes).
        len: usize,
        /// Bytes the field needs the payload to have.
        needed: usize,
    },
    /// Not a little-endian CDR encapsulation.
    #[error("encapsulation header {0:02x?} is not little-endian CDR (00 01 00 00)")]
    Encapsulation([u8; 4]),
}

/// A decoded field value, for generic use (comparisons, exports).
#[derive(Debug, Clone, PartialEq)]
pub enum FieldValue {
    /// `uint32` or `uint64`.
    Uint(u64),
    /// `int64`.
    Int(i64),
    /// `float64`.
    Float(f64),
    /// A fixed `float64` array.
    Floats(Vec<f64>),
}

/// A scalar or fixed array that CDR can carry.
pub trait CdrField: Sized + Copy {
    /// The ros2msg type, e.g. `float64` or `float64[6]`.
    const ROS_TYPE: &'static str;
    /// Appends the value, aligned.
    fn put(&self, w: &mut CdrWriter);
    /// Reads the value, aligned.
    fn get(r: &mut CdrReader<'_>, field: &'static str) -> Result<Self, CdrError>;
    /// The value, for generic use.
    fn value(&self) -> FieldValue;
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
        let body = self.buf.len() - ENCAPSULATION_LE.len();
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
    /// Checks the encapsulation header (`00 01`, options ignored).
    pub fn new(data: &'a [u8]) -> Result<Self, CdrError> {
        let Some(head) = data.get(..4) else {
            return Err(CdrError::Truncated {
                field: "encapsulation header",
                offset: 0,
                len: data.len(),
                needed: 4,
            });
        };
        let head = [head[0], head[1], head[2], head[3]];
        // Big-endian CDR (00 00) is legal, but no ROS 2 tool on a PC writes it.
        if head[..2] != ENCAPSULATION_LE[..2] {
            return Err(CdrError::Encapsulation(head));
        }
        Ok(CdrReader { data, pos: 4 })
    }

    /// Whether every byte has been read.
    pub fn at_end(&self) -> bool {
        self.pos >= self.data.len()
    }

    fn bytes<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N], CdrError> {
        let body = self.pos - ENCAPSULATION_LE.len();
        let start = self.pos + (N - body % N) % N;
        let end = start + N;
        let slice = self.data.get(start..end).ok_or(CdrError::Truncated {
            field,
            offset: start,
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
    ($t:ty, $ros:literal, $n:literal, $variant:ident, $as:ty) => {
        impl CdrField for $t {
            const ROS_TYPE: &'static str = $ros;
            fn put(&self, w: &mut CdrWriter) {
                w.bytes::<$n>(self.to_le_bytes());
            }
            fn get(r: &mut CdrReader<'_>, field: &'static str) -> Result<Self, CdrError> {
                Ok(<$t>::from_le_bytes(r.bytes::<$n>(field)?))
            }
            fn value(&self) -> FieldValue {
                FieldValue::$variant(<$as>::from(*self))
            }
        }
    };
}
scalar!(u32, "uint32", 4, Uint, u64);
scalar!(u64, "uint64", 8, Uint, u64);
scalar!(i64, "int64", 8, Int, i64);
scalar!(f64, "float64", 8, Float, f64);

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
    fn value(&self) -> FieldValue {
        FieldValue::Floats(self.to_vec())
    }
}

/// A message of the recording contract (implemented for every exo message
/// in [`crate::schema`], the one table of the contract).
pub trait Recordable: exo_messages::Message {
    /// Its topic, e.g. `exo/sensor`.
    const TOPIC: &'static str;
    /// Its ros2msg schema name, e.g. `exo_msgs/msg/SensorSample`.
    const SCHEMA_NAME: &'static str;
    /// How many leading fields a recording must carry (the contract's fixed
    /// part); later ones were added to the contract and are 0 when a writer
    /// leaves them out.
    const REQUIRED_FIELDS: usize;
    /// `(name, ros2msg type)` of every field, in order.
    fn fields() -> Vec<(&'static str, &'static str)>;
    /// The ros2msg schema text: one `type name` line per field.
    fn schema() -> String {
        crate::ros2msg::schema_text(&Self::fields())
    }
    /// `(name, value)` of every field, in schema order.
    fn field_values(&self) -> Vec<(&'static str, FieldValue)>;
    /// The message's time stamp (ns): the log time of the recording.
    fn stamp_ns(&self) -> u64;
    /// Appends the CDR payload (header included) to `buf` after clearing it
    /// (its capacity is reused) and returns it.
    fn encode_into(&self, buf: Vec<u8>) -> Vec<u8>;
    /// Decodes the first `n_fields` fields of a CDR payload (clamped to
    /// between [`REQUIRED_FIELDS`](Self::REQUIRED_FIELDS) and all of them);
    /// the others are 0, and a zero `stamp_ns` is replaced by `log_time_ns`.
    /// Bytes after the last decoded field are ignored (fields a newer
    /// writer added).
    fn decode_fields(data: &[u8], n_fields: usize, log_time_ns: u64) -> Result<Self, CdrError>;
    /// Decodes a CDR payload without knowing the writer's schema: fields
    /// beyond [`REQUIRED_FIELDS`](Self::REQUIRED_FIELDS) are read while the
    /// payload has bytes left.
    fn decode(data: &[u8], log_time_ns: u64) -> Result<Self, CdrError>;
}

/// Implements [`Recordable`] from the topic, schema name, number of
/// required fields and the field list (in CDR order, `_pad` left out).
macro_rules! recordable {
    ($ty:ident, $topic:expr, required = $req:literal, [$($field:ident),+ $(,)?]) => {
        impl $crate::cdr::Recordable for $ty {
            const TOPIC: &'static str = $topic.info().topic;
            const SCHEMA_NAME: &'static str = $topic.info().schema;
            const REQUIRED_FIELDS: usize = $req;
            fn fields() -> Vec<(&'static str, &'static str)> {
                fn ty_of<T: $crate::cdr::CdrField>(_: impl Fn(&$ty) -> T) -> &'static str {
                    T::ROS_TYPE
                }
                vec![$((stringify!($field), ty_of(|m: &$ty| m.$field))),+]
            }
            fn field_values(&self) -> Vec<(&'static str, $crate::cdr::FieldValue)> {
                vec![$((stringify!($field), $crate::cdr::CdrField::value(&self.$field))),+]
            }
            fn stamp_ns(&self) -> u64 {
                self.stamp_ns
            }
            fn encode_into(&self, buf: Vec<u8>) -> Vec<u8> {
                let mut w = $crate::cdr::CdrWriter::start(buf);
                $($crate::cdr::CdrField::put(&self.$field, &mut w);)+
                w.finish()
            }
            fn decode_fields(
                data: &[u8],
                n_fields: usize,
                log_time_ns: u64,
            ) -> Result<Self, $crate::cdr::CdrError> {
                let n = n_fields.max($req);
                let mut r = $crate::cdr::CdrReader::new(data)?;
                let mut m = $ty::default();
                let mut index = 0usize;
                $(
                    if index < n {
                        m.$field = $crate::cdr::CdrField::get(&mut r, stringify!($field))?;
                    }
                    index += 1;
                )+
                let _ = index;
                if m.stamp_ns == 0 {
                    m.stamp_ns = log_time_ns;
                }
                Ok(m)
            }
            fn decode(data: &[u8], log_time_ns: u64) -> Result<Self, $crate::cdr::CdrError> {
                let mut r = $crate::cdr::CdrReader::new(data)?;
                let mut m = $ty::default();
                let mut index = 0usize;
                $(
                    if !(index >= $req && r.at_end()) {
                        m.$field = $crate::cdr::CdrField::get(&mut r, stringify!($field))?;
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
pub(crate) use recordable;
