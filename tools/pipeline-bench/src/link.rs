//! The two transports the bare loops run over, behind one small interface:
//! iceoryx2 through exo-service-kit's `Outbox`/`Inbox` (the very ports and
//! wake-ups the services use) and Unix-domain stream sockets carrying the
//! same `#[repr(C)]` payloads byte for byte.

use std::fmt::Debug;
use std::io::{ErrorKind, Read, Write};
use std::os::unix::net::UnixStream;
use std::time::Duration;

use anyhow::{bail, Context, Result};
use exo_messages::{ActuatorCommand, BusMotorCommand, BusSensorFrame, SensorSample};
use exo_service_kit::ipc::{Inbox, Outbox};
use iceoryx2::prelude::ZeroCopySend;

/// What a receive brought.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Got<T> {
    /// A message.
    Msg(T),
    /// Nothing within the timeout.
    Timeout,
    /// The peer closed the connection (sockets only).
    Closed,
}

/// The sending half of a link.
pub trait Tx<T> {
    /// Sends one message; never waits for the receiver.
    fn send(&mut self, v: &T) -> Result<()>;
}

/// The receiving half of a link.
pub trait Rx<T> {
    /// Waits at most about `timeout` for one message.
    fn recv(&mut self, timeout: Duration) -> Result<Got<T>>;
}

impl<T: Debug + ZeroCopySend + Copy + 'static> Tx<T> for Outbox<T> {
    fn send(&mut self, v: &T) -> Result<()> {
        Outbox::send(self, *v).map_err(Into::into)
    }
}

impl<T: Debug + ZeroCopySend + Copy + 'static> Rx<T> for Inbox<T> {
    fn recv(&mut self, timeout: Duration) -> Result<Got<T>> {
        Ok(match self.recv_timeout(timeout)? {
            Some(v) => Got::Msg(v),
            None => Got::Timeout,
        })
    }
}

/// A payload that can cross a socket as its in-memory bytes.
///
/// # Safety
///
/// Implementors are `#[repr(C)]`, have no implicit padding (every byte
/// belongs to a field), and every bit pattern of their bytes is a valid
/// value (integer and floating-point fields only). The exo messages below
/// are declared that way and their layouts are pinned by exo-messages'
/// tests.
pub unsafe trait Wire: Copy + Default {}

// SAFETY: repr(C), u64/f64/u32 fields with explicit `_pad` (see exo-messages).
unsafe impl Wire for SensorSample {}
// SAFETY: as above.
unsafe impl Wire for ActuatorCommand {}
// SAFETY: as above (i64, [f64; 6] and u32 fields with explicit `_pad`).
unsafe impl Wire for BusSensorFrame {}
// SAFETY: as above.
unsafe impl Wire for BusMotorCommand {}

/// The largest payload a socket link carries (bytes).
const MAX_WIRE: usize = 128;

/// The bytes of `v`.
pub fn to_bytes<T: Wire>(v: &T) -> &[u8] {
    // SAFETY: `T: Wire` has no padding, so all `size_of::<T>()` bytes are
    // initialised; the slice borrows `v`.
    unsafe { std::slice::from_raw_parts((v as *const T).cast::<u8>(), std::mem::size_of::<T>()) }
}

/// The value whose bytes are `b` (`b.len()` must be `size_of::<T>()`).
pub fn from_bytes<T: Wire>(b: &[u8]) -> Result<T> {
    let n = std::mem::size_of::<T>();
    if b.len() != n {
        bail!("payload of {} bytes where {n} were expected", b.len());
    }
    let mut v = T::default();
    // SAFETY: `n` bytes into a `T` of exactly `n` bytes; every bit pattern
    // is a valid `T` (`Wire`).
    unsafe { std::ptr::copy_nonoverlapping(b.as_ptr(), (&mut v as *mut T).cast::<u8>(), n) };
    Ok(v)
}

/// One end of a Unix-domain stream socket carrying fixed-size payloads.
pub struct UdsLink {
    stream: UnixStream,
    timeout: Option<Duration>,
    buf: [u8; MAX_WIRE],
    peer: String,
}

impl UdsLink {
    /// Wraps a connected stream (set to blocking); `peer` names it in errors.
    pub fn new(stream: UnixStream, peer: &str) -> Result<Self> {
        stream
            .set_nonblocking(false)
            .with_context(|| format!("socket to {peer}: set blocking"))?;
        Ok(UdsLink {
            stream,
            timeout: None,
            buf: [0; MAX_WIRE],
            peer: peer.to_string(),
        })
    }

    /// A second handle on the same socket (for a separate sending half).
    pub fn try_clone(&self) -> Result<Self> {
        let s = self
            .stream
            .try_clone()
            .with_context(|| format!("socket to {}: duplicate", self.peer))?;
        UdsLink::new(s, &self.peer)
    }

    fn set_timeout(&mut self, timeout: Duration) -> Result<()> {
        let t = timeout.max(Duration::from_millis(1));
        if self.timeout != Some(t) {
            self.stream
                .set_read_timeout(Some(t))
                .with_context(|| format!("socket to {}: set read timeout", self.peer))?;
            self.timeout = Some(t);
        }
        Ok(())
    }
}

impl<T: Wire> Tx<T> for UdsLink {
    fn send(&mut self, v: &T) -> Result<()> {
        self.stream
            .write_all(to_bytes(v))
            .with_context(|| format!("socket to {}: write", self.peer))
    }
}

impl<T: Wire> Rx<T> for UdsLink {
    /// Reads one whole payload. A timeout before its first byte is
    /// `Timeout`; once a payload has begun, the rest is waited for, so the
    /// stream never loses its framing.
    fn recv(&mut self, timeout: Duration) -> Result<Got<T>> {
        let n = std::mem::size_of::<T>();
        if n > MAX_WIRE {
            bail!("payload of {n} bytes exceeds the socket link's {MAX_WIRE}");
        }
        self.set_timeout(timeout)?;
        let mut got = 0;
        while got < n {
            match self.stream.read(&mut self.buf[got..n]) {
                Ok(0) if got == 0 => return Ok(Got::Closed),
                Ok(0) => bail!("socket to {}: closed in the middle of a payload", self.peer),
                Ok(k) => got += k,
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                    if got == 0 {
                        return Ok(Got::Timeout);
                    }
                }
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(e) => return Err(e).with_context(|| format!("socket to {}: read", self.peer)),
            }
        }
        from_bytes(&self.buf[..n]).map(Got::Msg)
    }
}

/// A message the bench sends out to start one round trip.
pub trait Probe: Copy {
    /// The probe with sequence number `seq` stamped `stamp_ns`.
    fn probe(seq: u64, stamp_ns: u64) -> Self;
}

/// A message that answers a probe.
pub trait Answer: Copy {
    /// The `seq` of the probe it answers.
    fn answers(&self) -> u64;
    /// The probe's stamp, carried through (ns, monotonic clock).
    fn stamp_ns(&self) -> u64;
}

impl Probe for SensorSample {
    fn probe(seq: u64, stamp_ns: u64) -> Self {
        let x = seq as f64 * 1e-3;
        SensorSample {
            seq,
            stamp_ns,
            theta_e: 0.5 + 0.1 * x.sin(),
            omega_e: 0.1 * x.cos(),
            tau_c: 0.2 * x.sin(),
            tau_s: 1.0,
            status: 0,
            _pad: 0,
        }
    }
}

impl Probe for BusSensorFrame {
    fn probe(seq: u64, stamp_ns: u64) -> Self {
        let x = seq as f64 * 1e-3;
        BusSensorFrame {
            seq,
            stamp_ns,
            encoder_counts: 41_722 + (4000.0 * x.sin()) as i64,
            cuff_wrench: [0.1, 0.8 * x.sin(), 0.0, 0.0, 0.0, 0.01],
            sea_deflection_counts: 250,
            status: 0,
            _pad: 0,
        }
    }
}

impl Answer for ActuatorCommand {
    fn answers(&self) -> u64 {
        self.sensor_seq
    }
    fn stamp_ns(&self) -> u64 {
        self.stamp_ns
    }
}

impl Answer for BusMotorCommand {
    fn answers(&self) -> u64 {
        self.frame_seq
    }
    fn stamp_ns(&self) -> u64 {
        self.stamp_ns
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn payloads_cross_as_bytes_unchanged() {
        let s = SensorSample::probe(7, 123_456_789);
        let b = to_bytes(&s);
        assert_eq!(
            b.len(),
            56,
            "SensorSample is 56 bytes (exo-messages layout test)"
        );
        assert_eq!(from_bytes::<SensorSample>(b).unwrap(), s);
        let f = BusSensorFrame::probe(9, 42);
        assert_eq!(from_bytes::<BusSensorFrame>(to_bytes(&f)).unwrap(), f);
        assert!(from_bytes::<BusSensorFrame>(&to_bytes(&f)[1..]).is_err());
    }

    #[test]
    fn a_socket_pair_carries_payloads_and_reports_timeout_and_close() {
        let (a, b) = UnixStream::pair().unwrap();
        let mut a = UdsLink::new(a, "a").unwrap();
        let mut b = UdsLink::new(b, "b").unwrap();
        let c = ActuatorCommand {
            seq: 3,
            stamp_ns: 99,
            sensor_seq: 2,
            tau_d: -1.5,
            ..Default::default()
        };
        Tx::<ActuatorCommand>::send(&mut a, &c).unwrap();
        assert_eq!(
            Rx::<ActuatorCommand>::recv(&mut b, Duration::from_millis(100)).unwrap(),
            Got::Msg(c)
        );
        assert_eq!(
            Rx::<ActuatorCommand>::recv(&mut b, Duration::from_millis(5)).unwrap(),
            Got::Timeout
        );
        drop(a);
        assert_eq!(
            Rx::<ActuatorCommand>::recv(&mut b, Duration::from_millis(100)).unwrap(),
            Got::Closed
        );
    }
}
