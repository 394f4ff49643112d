//! A raw Ethernet socket for EtherCAT frames (AF_PACKET, EtherType 0x88A4),
//! with a bounded receive. Our own, because the backend runs its own TX/RX
//! loop over ethercrab's `PduTx`/`PduRx` (ethercrab's `tx_rx_task` ends for
//! good at the first failed send, i.e. on a lost link).

use std::ffi::CString;
use std::io;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};
use std::time::Duration;

/// EtherType of EtherCAT frames.
const ETHERTYPE_ETHERCAT: u16 = 0x88A4;

/// An open raw socket bound to one interface.
#[derive(Debug)]
pub struct RawSocket {
    fd: OwnedFd,
}

/// Why an interface could not be opened.
#[derive(Debug, thiserror::Error)]
pub enum OpenError {
    /// No interface of that name.
    #[error("no network interface {0:?} on this machine")]
    NoSuchInterface(String),
    /// The name cannot be an interface name.
    #[error("{0:?} is not a network interface name")]
    BadName(String),
    /// The socket could not be created or bound (permissions: CAP_NET_RAW).
    #[error("cannot open a raw socket on {iface:?}: {source} (raw sockets need CAP_NET_RAW)")]
    Socket {
        /// The interface.
        iface: String,
        /// The OS error.
        source: io::Error,
    },
}

impl RawSocket {
    /// Opens `iface` for EtherCAT frames.
    pub fn open(iface: &str) -> Result<Self, OpenError> {
        let name = CString::new(iface).map_err(|_| OpenError::BadName(iface.into()))?;
        if iface.is_empty() || iface.len() >= libc::IF_NAMESIZE {
            return Err(OpenError::BadName(iface.into()));
        }
        // SAFETY: a valid NUL-terminated string.
        let index = unsafe { libc::if_nametoindex(name.as_ptr()) };
        if index == 0 {
            return Err(OpenError::NoSuchInterface(iface.into()));
        }
        let socket_error = |source| OpenError::Socket {
            iface: iface.into(),
            source,
        };
        let proto = ETHERTYPE_ETHERCAT.to_be();
        // SAFETY: plain socket(2) call; the result is checked.
        let fd = unsafe {
            libc::socket(
                libc::AF_PACKET,
                libc::SOCK_RAW | libc::SOCK_NONBLOCK | libc::SOCK_CLOEXEC,
                i32::from(proto),
            )
        };
        if fd < 0 {
            return Err(socket_error(io::Error::last_os_error()));
        }
        // SAFETY: fd is a fresh descriptor we own.
        let fd = unsafe { OwnedFd::from_raw_fd(fd) };
        // SAFETY: sockaddr_ll is plain data; zero is a valid start.
        let mut addr: libc::sockaddr_ll = unsafe { std::mem::zeroed() };
        addr.sll_family = libc::AF_PACKET as u16;
        addr.sll_protocol = proto;
        addr.sll_ifindex = index as i32;
        // SAFETY: addr is a valid sockaddr_ll of the given size.
        let rc = unsafe {
            libc::bind(
                fd.as_raw_fd(),
                (&addr as *const libc::sockaddr_ll).cast(),
                std::mem::size_of::<libc::sockaddr_ll>() as u32,
            )
        };
        if rc < 0 {
            return Err(socket_error(io::Error::last_os_error()));
        }
        Ok(RawSocket { fd })
    }

    /// Sends one frame; the bytes sent.
    pub fn send(&self, frame: &[u8]) -> io::Result<usize> {
        // SAFETY: frame is a valid buffer of its length.
        let n = unsafe { libc::send(self.fd.as_raw_fd(), frame.as_ptr().cast(), frame.len(), 0) };
        if n < 0 {
            Err(io::Error::last_os_error())
        } else {
            Ok(n as usize)
        }
    }

    /// Receives one incoming frame into `buf`, waiting at most `timeout`;
    /// `Ok(None)` when none came. Frames this host sent are skipped.
    pub fn recv(&self, buf: &mut [u8], timeout: Duration) -> io::Result<Option<usize>> {
        let mut pfd = libc::pollfd {
            fd: self.fd.as_raw_fd(),
            events: libc::POLLIN,
            revents: 0,
        };
        let ts = libc::timespec {
            tv_sec: timeout.as_secs() as libc::time_t,
            tv_nsec: libc::c_long::from(timeout.subsec_nanos() as i32),
        };
        // SAFETY: one valid pollfd; a valid timespec; no signal mask.
        let rc = unsafe { libc::ppoll(&mut pfd, 1, &ts, std::ptr::null()) };
        if rc < 0 {
            let e = io::Error::last_os_error();
            return if e.kind() == io::ErrorKind::Interrupted {
                Ok(None)
            } else {
                Err(e)
            };
        }
        if rc == 0 {
            return Ok(None);
        }
        loop {
            // SAFETY: sockaddr_ll is plain data.
            let mut from: libc::sockaddr_ll = unsafe { std::mem::zeroed() };
            let mut from_len = std::mem::size_of::<libc::sockaddr_ll>() as u32;
            // SAFETY: buf and from are valid for their lengths.
            let n = unsafe {
                libc::recvfrom(
                    self.fd.as_raw_fd(),
                    buf.as_mut_ptr().cast(),
                    buf.len(),
                    libc::MSG_DONTWAIT,
                    (&mut from as *mut libc::sockaddr_ll).cast(),
                    &mut from_len,
                )
            };
            if n < 0 {
                let e = io::Error::last_os_error();
                return if e.kind() == io::ErrorKind::WouldBlock {
                    Ok(None)
                } else {
                    Err(e)
                };
            }
            if from.sll_pkttype == libc::PACKET_OUTGOING {
                continue; // our own frame, seen on the way out
            }
            return Ok(Some(n as usize));
        }
    }
}
