//! A background subscriber that keeps every sample of one channel: what the
//! `exo` tool (progress, `exo tune`) and the integration tests use to watch a
//! run from outside, like any other subscriber. Off the real-time path: it
//! allocates, and it never blocks a publisher (a subscriber that falls more
//! than the channel's `max_buffer` samples behind loses the
//! oldest ones, which [`Collector::finish`] callers can see as `seq` gaps).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

use exo_messages::channels::Topic;
use exo_messages::Message;

use crate::ipc::{Ipc, IpcError, DEEPEST};

/// Collects every sample of one channel on a background thread.
pub struct Collector<T: Copy + Send + 'static> {
    samples: Arc<Mutex<Vec<T>>>,
    stop: Arc<AtomicBool>,
    handle: Option<JoinHandle<Result<(), IpcError>>>,
}

impl<T: Message> Collector<T> {
    /// Subscribes to `topic` of `instance` (node `node_name`) and returns once
    /// the subscription exists, so nothing published afterwards is missed.
    pub fn start(node_name: &str, instance: &str, topic: Topic<T>) -> Result<Self, IpcError> {
        Self::start_filtered(node_name, instance, topic, |_| true)
    }

    /// [`Collector::start`], keeping only the samples `keep` accepts (a
    /// watch for rare events on a busy channel, e.g. a latched safe state
    /// in the commands, without holding every sample).
    pub fn start_filtered(
        node_name: &str,
        instance: &str,
        topic: Topic<T>,
        keep_if: impl Fn(&T) -> bool + Send + 'static,
    ) -> Result<Self, IpcError> {
        let samples = Arc::new(Mutex::new(Vec::new()));
        let stop = Arc::new(AtomicBool::new(false));
        let (ready_tx, ready_rx) = mpsc::channel::<Result<(), IpcError>>();
        let (keep, halt, inst, node) = (
            Arc::clone(&samples),
            Arc::clone(&stop),
            instance.to_string(),
            node_name.to_string(),
        );
        let handle = std::thread::spawn(move || -> Result<(), IpcError> {
            let opened = Ipc::open(&node, &inst, None)
                .and_then(|ipc| ipc.inbox(topic, DEEPEST).map(|inbox| (ipc, inbox)));
            let (_ipc, inbox) = match opened {
                Ok(x) => {
                    let _ = ready_tx.send(Ok(()));
                    x
                }
                Err(e) => {
                    let _ = ready_tx.send(Err(e));
                    return Ok(());
                }
            };
            let push = |v: T| {
                if keep_if(&v) {
                    keep.lock().unwrap_or_else(PoisonError::into_inner).push(v);
                }
            };
            while !halt.load(Ordering::Relaxed) {
                let mut got = false;
                while let Some(v) = inbox.try_recv()? {
                    push(v);
                    got = true;
                }
                if !got {
                    inbox.wait(Duration::from_millis(5))?;
                }
            }
            while let Some(v) = inbox.try_recv()? {
                push(v);
            }
            Ok(())
        });
        match ready_rx.recv() {
            Ok(Ok(())) => Ok(Collector {
                samples,
                stop,
                handle: Some(handle),
            }),
            Ok(Err(e)) => {
                let _ = handle.join();
                Err(e)
            }
            Err(_) => Err(IpcError::Node {
                name: node_name.to_string(),
                message: "the collector thread ended before subscribing".into(),
            }),
        }
    }

    /// A copy of what has arrived so far.
    pub fn snapshot(&self) -> Vec<T> {
        self.samples
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    /// The latest sample so far, if any.
    pub fn latest(&self) -> Option<T> {
        self.samples
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .last()
            .copied()
    }

    /// Number of samples so far.
    pub fn len(&self) -> usize {
        self.samples
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .len()
    }

    /// Whether nothing has arrived yet.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Stops collecting and returns everything (or the subscriber's error).
    pub fn finish(mut self) -> Result<Vec<T>, IpcError> {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(h) = self.handle.take() {
            match h.join() {
                Ok(r) => r?,
                Err(_) => {
                    return Err(IpcError::Node {
                        name: "collector".into(),
                        message: "the collector thread panicked".into(),
                    })
                }
            }
        }
        Ok(std::mem::take(
            &mut *self.samples.lock().unwrap_or_else(PoisonError::into_inner),
        ))
    }
}

impl<T: Copy + Send + 'static> Drop for Collector<T> {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}
