//! Our TX/RX loop: ethercrab's futures driven by hand on the driver's
//! thread, their frames moved over the raw socket.

use std::future::Future;
use std::pin::pin;
use std::task::{Context, Poll, Waker};
use std::time::{Duration, Instant};

use ethercrab::{PduRx, PduTx};

use super::socket::RawSocket;

/// Our TX/RX loop: ethercrab's frames over the raw socket.
pub(super) struct Pump {
    pub(super) socket: RawSocket,
    pub(super) tx: PduTx<'static>,
    pub(super) rx: PduRx<'static>,
    pub(super) buf: Box<[u8; 2048]>,
    /// Frames received that ethercrab did not accept (a reply to a frame
    /// already given up on, mostly).
    pub(super) late_replies: u64,
}

/// A frame that did not come back: the OS error of a failed send, if any.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Lost {
    pub(super) os_error: i32,
}

impl Pump {
    /// Sends every frame ethercrab has queued, then receives what comes
    /// back within `wait`. `Err` when a send failed (link down).
    pub(super) fn pump(&mut self, wait: Duration) -> Result<(), Lost> {
        while let Some(frame) = self.tx.next_sendable_frame() {
            let socket = &self.socket;
            let mut os_error = 0;
            let sent = frame.send_blocking(|data| {
                socket.send(data).map_err(|e| {
                    os_error = e.raw_os_error().unwrap_or(-1);
                    ethercrab::error::Error::SendFrame
                })
            });
            if sent.is_err() {
                return Err(Lost { os_error });
            }
        }
        let mut wait = wait;
        while let Ok(Some(n)) = self.socket.recv(&mut self.buf[..], wait) {
            // A frame that answers a frame given up on is counted and
            // ignored (one that is not ours is ignored by ethercrab).
            if self.rx.receive_frame(&self.buf[..n]).is_err() {
                self.late_replies += 1;
            }
            wait = Duration::ZERO;
        }
        Ok(())
    }

    /// Drives `fut` to completion by hand, moving its frames, until
    /// `deadline`; `Err` when it is not done by then or a send failed.
    /// Dropping an unfinished ethercrab future releases its frame.
    pub(super) fn drive<F: Future>(
        &mut self,
        fut: F,
        deadline: Instant,
    ) -> Result<F::Output, Lost> {
        let mut fut = pin!(fut);
        let mut cx = Context::from_waker(Waker::noop());
        loop {
            if let Poll::Ready(v) = fut.as_mut().poll(&mut cx) {
                return Ok(v);
            }
            let now = Instant::now();
            if now >= deadline {
                return Err(Lost { os_error: 0 });
            }
            self.pump((deadline - now).min(Duration::from_micros(500)))?;
        }
    }
}
