//! Operator commands: operator console (the `exo` tool) → controller, sensor driver.

#[cfg(feature = "ipc")]
use iceoryx2::prelude::ZeroCopySend;

use crate::error::{check_finite, check_range, MessageError};

/// What an [`OperatorCommand`] asks for; [`OperatorCommand::kind`] as a `u32`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u32)]
pub enum OperatorCommandKind {
    /// Clear a latched fault (controller and sensor driver); `value` unused (0).
    ResetFault = 1,
    /// Adopt the fractional order f given in `value` (dimensionless, in [0, 1),
    /// further clamped to the run's configured bounds), e.g. the identifier's
    /// `recommended_f`.
    AdoptFractionalOrder = 2,
    /// Start (or resume) the protocol; `value` is the experiment number to
    /// start at (1–9), or 0 for the next one. The controller restarts the
    /// protocol at the first period of that experiment (one of the run's
    /// `protocol.experiments`), ramping the running period out first if
    /// one is under way; 0 continues a stopped protocol (the interrupted
    /// period again if it stopped before the end of its analysis window,
    /// else the next). Refused while a fault is latched.
    StartProtocol = 3,
    /// Stop the protocol: ramp out and hold gravity compensation, without a fault; `value` unused (0).
    /// The controller stays in mode `Run`, holding gravity compensation
    /// alone, until a `StartProtocol` or the end of the run.
    StopProtocol = 4,
}

impl OperatorCommandKind {
    /// Every kind, in code order.
    pub const ALL: [OperatorCommandKind; 4] = [
        OperatorCommandKind::ResetFault,
        OperatorCommandKind::AdoptFractionalOrder,
        OperatorCommandKind::StartProtocol,
        OperatorCommandKind::StopProtocol,
    ];

    /// The kind of a raw code (1–4), or `None`.
    pub fn from_u32(code: u32) -> Option<Self> {
        match code {
            1 => Some(OperatorCommandKind::ResetFault),
            2 => Some(OperatorCommandKind::AdoptFractionalOrder),
            3 => Some(OperatorCommandKind::StartProtocol),
            4 => Some(OperatorCommandKind::StopProtocol),
            _ => None,
        }
    }

    /// The raw code sent in [`OperatorCommand::kind`].
    pub fn as_u32(self) -> u32 {
        self as u32
    }

    /// The kind's name, e.g. `"ResetFault"`.
    pub fn name(self) -> &'static str {
        match self {
            OperatorCommandKind::ResetFault => "ResetFault",
            OperatorCommandKind::AdoptFractionalOrder => "AdoptFractionalOrder",
            OperatorCommandKind::StartProtocol => "StartProtocol",
            OperatorCommandKind::StopProtocol => "StopProtocol",
        }
    }
}

/// `ResetFault (1)`.
impl core::fmt::Display for OperatorCommandKind {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "{} ({})", self.name(), self.as_u32())
    }
}

/// Every kind with its code, for a message about an unknown one:
/// `1 ResetFault, 2 AdoptFractionalOrder, 3 StartProtocol, 4 StopProtocol`.
#[derive(Debug, Clone, Copy)]
pub struct KnownKinds;

impl core::fmt::Display for KnownKinds {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        for (i, k) in OperatorCommandKind::ALL.iter().enumerate() {
            let sep = if i == 0 { "" } else { ", " };
            write!(f, "{sep}{} {}", k.as_u32(), k.name())?;
        }
        Ok(())
    }
}

/// The `seq`s a receiver has handled lately, so that it acts on each once
/// (a command delivered twice, e.g. from a publisher's history to a
/// subscriber that connects late, or sent twice by mistake, is not acted
/// on again). Fixed storage: the last [`SeenSeqs::CAPACITY`] distinct
/// `seq`s, which makes no assumption about their order (the `exo` tool
/// uses the wall clock, a test may count from 1). Allocation-free.
#[derive(Debug, Clone, Copy)]
pub struct SeenSeqs {
    seqs: [u64; SeenSeqs::CAPACITY],
    len: usize,
    next: usize,
}

impl Default for SeenSeqs {
    fn default() -> Self {
        SeenSeqs {
            seqs: [0; SeenSeqs::CAPACITY],
            len: 0,
            next: 0,
        }
    }
}

impl SeenSeqs {
    /// How many `seq`s are remembered.
    pub const CAPACITY: usize = 64;

    /// Whether `seq` is new (and remembers it); `false` for a repeat.
    pub fn first_time(&mut self, seq: u64) -> bool {
        if self.seqs[..self.len].contains(&seq) {
            return false;
        }
        self.seqs[self.next] = seq;
        self.next = (self.next + 1) % Self::CAPACITY;
        self.len = (self.len + 1).min(Self::CAPACITY);
        true
    }
}

/// A command from the operator.
///
/// 32 bytes, 8-aligned, no implicit padding.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[cfg_attr(
    feature = "ipc",
    derive(ZeroCopySend),
    type_name("exo.OperatorCommand.v1")
)]
#[repr(C)]
pub struct OperatorCommand {
    /// Sequence number (count); receivers act on each `seq` once.
    pub seq: u64,
    /// Time stamp (ns) on the monotonic clock when the operator issued the command.
    pub stamp_ns: u64,
    /// [`OperatorCommandKind`] code.
    pub kind: u32,
    /// Explicit padding before `value` (always 0), so the struct has no implicit padding.
    pub _pad: u32,
    /// Argument of the command; its meaning and unit depend on `kind` (see [`OperatorCommandKind`]).
    pub value: f64,
}

crate::impl_message!(OperatorCommand, "exo.OperatorCommand.v1", |c| [
    "value" => c.value,
]);

impl OperatorCommand {
    /// A command of `kind` with argument `value`.
    pub fn new(seq: u64, stamp_ns: u64, kind: OperatorCommandKind, value: f64) -> Self {
        OperatorCommand {
            seq,
            stamp_ns,
            kind: kind.as_u32(),
            _pad: 0,
            value,
        }
    }

    /// The kind, or `None` if `kind` holds an unknown code.
    pub fn command_kind(&self) -> Option<OperatorCommandKind> {
        OperatorCommandKind::from_u32(self.kind)
    }

    /// Checks the kind code and that `value` is finite and valid for it
    /// (f in [0, 1) for `AdoptFractionalOrder`, experiment 0–9 for `StartProtocol`).
    pub fn validate(&self) -> Result<(), MessageError> {
        const M: &str = "OperatorCommand";
        check_finite(M, self.first_non_finite())?;
        match self.command_kind() {
            None => Err(MessageError::UnknownCode {
                message: M,
                field: "kind",
                value: self.kind,
            }),
            Some(OperatorCommandKind::AdoptFractionalOrder) => {
                check_range(M, "value", self.value, 0.0, 1.0 - f64::EPSILON)
            }
            Some(OperatorCommandKind::StartProtocol) => check_range(
                M,
                "value",
                self.value,
                0.0,
                crate::protocol::MAX_EXPERIMENT as f64,
            ),
            Some(_) => Ok(()),
        }
    }
}

/// What the controller did with an operator command
/// ([`OperatorReply::verdict`] as a `u32`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u32)]
pub enum OperatorVerdict {
    /// Acted on (or nothing was left to do, e.g. a stop of a stopped
    /// protocol); the reply's text says what.
    Accepted = 1,
    /// Refused: an unknown kind, an invalid value, or not in the present
    /// state; nothing changed, the reply's text says why.
    Refused = 2,
    /// The `seq` was handled before; nothing done again.
    Repeated = 3,
}

impl OperatorVerdict {
    /// The verdict of a raw code (1–3), or `None`.
    pub fn from_u32(code: u32) -> Option<Self> {
        match code {
            1 => Some(OperatorVerdict::Accepted),
            2 => Some(OperatorVerdict::Refused),
            3 => Some(OperatorVerdict::Repeated),
            _ => None,
        }
    }

    /// The raw code sent in [`OperatorReply::verdict`].
    pub fn as_u32(self) -> u32 {
        self as u32
    }
}

/// The bytes of an [`OperatorReply`]'s text.
pub const REPLY_TEXT_BYTES: usize = 240;

/// The controller's answer to one [`OperatorCommand`], on
/// `exo/operator/reply`: the command's `seq` and kind, the verdict, and the
/// sentence the controller logs (UTF-8, cut at a character boundary to
/// [`REPLY_TEXT_BYTES`]).
///
/// 280 bytes, 8-aligned, no implicit padding.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "ipc",
    derive(ZeroCopySend),
    type_name("exo.OperatorReply.v1")
)]
#[repr(C)]
pub struct OperatorReply {
    /// The answered command's `seq`.
    pub seq: u64,
    /// Time stamp (ns) on the monotonic clock when the controller handled it.
    pub stamp_ns: u64,
    /// The answered command's [`OperatorCommandKind`] code (as received).
    pub kind: u32,
    /// [`OperatorVerdict`] code.
    pub verdict: u32,
    /// The answered command's `value`.
    pub value: f64,
    /// Bytes of `text` used.
    pub text_len: u32,
    /// Explicit padding (always 0), so the struct has no implicit padding.
    pub _pad: u32,
    /// What the controller did or why it refused (UTF-8, `text_len` bytes).
    pub text: [u8; REPLY_TEXT_BYTES],
}

impl Default for OperatorReply {
    fn default() -> Self {
        OperatorReply {
            seq: 0,
            stamp_ns: 0,
            kind: 0,
            verdict: 0,
            value: 0.0,
            text_len: 0,
            _pad: 0,
            text: [0; REPLY_TEXT_BYTES],
        }
    }
}

crate::impl_message!(OperatorReply, "exo.OperatorReply.v1", |r| [
    "value" => r.value,
]);

/// Writes into a reply's fixed text, dropping what does not fit (at a
/// character boundary). Allocation-free.
struct TextWriter<'a> {
    buf: &'a mut [u8; REPLY_TEXT_BYTES],
    len: usize,
}

impl core::fmt::Write for TextWriter<'_> {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        for ch in s.chars() {
            let n = ch.len_utf8();
            if self.len + n > REPLY_TEXT_BYTES {
                return Ok(());
            }
            ch.encode_utf8(&mut self.buf[self.len..self.len + n]);
            self.len += n;
        }
        Ok(())
    }
}

impl OperatorReply {
    /// The reply to `cmd` with `verdict` and the text `what` (formatted
    /// into the fixed buffer, cut to fit; allocation-free).
    pub fn new(
        cmd: &OperatorCommand,
        stamp_ns: u64,
        verdict: OperatorVerdict,
        what: core::fmt::Arguments<'_>,
    ) -> Self {
        let mut r = OperatorReply {
            seq: cmd.seq,
            stamp_ns,
            kind: cmd.kind,
            verdict: verdict.as_u32(),
            value: cmd.value,
            ..OperatorReply::default()
        };
        let mut w = TextWriter {
            buf: &mut r.text,
            len: 0,
        };
        let _ = core::fmt::Write::write_fmt(&mut w, what);
        r.text_len = w.len as u32;
        r
    }

    /// The verdict, or `None` if `verdict` holds an unknown code.
    pub fn verdict(&self) -> Option<OperatorVerdict> {
        OperatorVerdict::from_u32(self.verdict)
    }

    /// The text, or `None` if `text_len` is out of range or the bytes are
    /// not UTF-8.
    pub fn text(&self) -> Option<&str> {
        let n = usize::try_from(self.text_len).ok()?;
        core::str::from_utf8(self.text.get(..n)?).ok()
    }

    /// Checks the verdict code, the text and that `value` is finite (a
    /// reply that does not decode is never taken for an acceptance).
    pub fn validate(&self) -> Result<(), MessageError> {
        const M: &str = "OperatorReply";
        check_finite(M, self.first_non_finite())?;
        if self.verdict().is_none() {
            return Err(MessageError::UnknownCode {
                message: M,
                field: "verdict",
                value: self.verdict,
            });
        }
        if self.text().is_none() {
            return Err(MessageError::UnknownCode {
                message: M,
                field: "text",
                value: self.text_len,
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::mem::{align_of, offset_of, size_of};

    #[test]
    fn reply_layout_text_and_verdicts() {
        assert_eq!(size_of::<OperatorReply>(), 280);
        assert_eq!(align_of::<OperatorReply>(), 8);
        assert_eq!(offset_of!(OperatorReply, seq), 0);
        assert_eq!(offset_of!(OperatorReply, stamp_ns), 8);
        assert_eq!(offset_of!(OperatorReply, kind), 16);
        assert_eq!(offset_of!(OperatorReply, verdict), 20);
        assert_eq!(offset_of!(OperatorReply, value), 24);
        assert_eq!(offset_of!(OperatorReply, text_len), 32);
        assert_eq!(offset_of!(OperatorReply, _pad), 36);
        assert_eq!(offset_of!(OperatorReply, text), 40);
        let cmd = OperatorCommand::new(7, 1, OperatorCommandKind::StartProtocol, 3.0);
        let r = OperatorReply::new(
            &cmd,
            2,
            OperatorVerdict::Refused,
            format_args!("experiment {} is not in this run", 3),
        );
        assert_eq!((r.seq, r.kind, r.value), (7, 3, 3.0));
        assert_eq!(r.verdict(), Some(OperatorVerdict::Refused));
        assert_eq!(r.text(), Some("experiment 3 is not in this run"));
        assert_eq!(r.validate(), Ok(()));
        // Cut at a character boundary: 200 three-byte characters are 600
        // bytes; 80 of them fit.
        let long = "€".repeat(200);
        let r = OperatorReply::new(&cmd, 2, OperatorVerdict::Accepted, format_args!("{long}"));
        assert_eq!(r.text_len, 240);
        assert_eq!(r.text().map(|t| t.chars().count()), Some(80));
        for v in [
            OperatorVerdict::Accepted,
            OperatorVerdict::Refused,
            OperatorVerdict::Repeated,
        ] {
            assert_eq!(OperatorVerdict::from_u32(v.as_u32()), Some(v));
        }
        assert_eq!(OperatorVerdict::from_u32(0), None);
        let bad = OperatorReply { verdict: 9, ..r };
        assert_eq!(bad.validate().unwrap_err().field(), "verdict");
        let bad = OperatorReply { text_len: 241, ..r };
        assert_eq!(bad.validate().unwrap_err().field(), "text");
        let mut bad = r;
        bad.text[0] = 0xff;
        assert_eq!(bad.validate().unwrap_err().field(), "text");
    }

    #[test]
    fn layout() {
        assert_eq!(size_of::<OperatorCommand>(), 32);
        assert_eq!(align_of::<OperatorCommand>(), 8);
        assert_eq!(offset_of!(OperatorCommand, seq), 0);
        assert_eq!(offset_of!(OperatorCommand, stamp_ns), 8);
        assert_eq!(offset_of!(OperatorCommand, kind), 16);
        assert_eq!(offset_of!(OperatorCommand, _pad), 20);
        assert_eq!(offset_of!(OperatorCommand, value), 24);
    }

    #[test]
    fn kinds_round_trip_and_validate() {
        for k in OperatorCommandKind::ALL {
            assert_eq!(OperatorCommandKind::from_u32(k.as_u32()), Some(k));
        }
        assert_eq!(OperatorCommandKind::from_u32(0), None);
        let adopt = OperatorCommand::new(1, 2, OperatorCommandKind::AdoptFractionalOrder, 0.35);
        assert_eq!(adopt.validate(), Ok(()));
        assert_eq!(
            OperatorCommand {
                value: 1.0,
                ..adopt
            }
            .validate()
            .unwrap_err()
            .field(),
            "value"
        );
        assert_eq!(
            OperatorCommand {
                value: f64::NAN,
                ..adopt
            }
            .validate()
            .unwrap_err()
            .field(),
            "value"
        );
        assert_eq!(
            OperatorCommand { kind: 99, ..adopt }
                .validate()
                .unwrap_err()
                .field(),
            "kind"
        );
        let start = OperatorCommand::new(3, 4, OperatorCommandKind::StartProtocol, 10.0);
        assert_eq!(start.validate().unwrap_err().field(), "value");
    }

    #[test]
    fn kinds_are_named_with_their_codes() {
        assert_eq!(
            OperatorCommandKind::StopProtocol.to_string(),
            "StopProtocol (4)"
        );
        assert_eq!(
            KnownKinds.to_string(),
            "1 ResetFault, 2 AdoptFractionalOrder, 3 StartProtocol, 4 StopProtocol"
        );
    }

    #[test]
    fn each_seq_is_seen_once() {
        let mut seen = SeenSeqs::default();
        assert!(seen.first_time(7));
        assert!(!seen.first_time(7));
        assert!(seen.first_time(3), "order does not matter");
        for s in 100..100 + SeenSeqs::CAPACITY as u64 {
            assert!(seen.first_time(s));
        }
        // Only the last CAPACITY are remembered.
        assert!(seen.first_time(7));
        assert!(!seen.first_time(100 + SeenSeqs::CAPACITY as u64 - 1));
    }
}
