//! Latency and throughput of the Zenoh tunnel beside the local path, at
//! 1 kHz and 10 kHz (BENCHMARKS.md, "Channels to another host").
//!
//! One run: this process publishes `SensorSample`s on instance A's sample
//! channel at the rate, each stamped with the monotonic clock; the real
//! `exo-tunnel` exports A over Zenoh (TCP on loopback) and a second real
//! `exo-tunnel` imports it onto instance B. Two subscribers in this process
//! take the stamp from the clock on arrival: one on A (the local path,
//! iceoryx2 only) and one on B (iceoryx2 → export → Zenoh → import →
//! iceoryx2), side by side in the same run. Percentiles from HDR
//! histograms (µs); lost = published − received.
//!
//! `cargo build -p exo-tunnel --bins --examples && cargo run -p exo-tunnel
//! --example tunnel_latency` (the binaries of the same profile; dev profile: Zenoh, iceoryx2 and every other
//! dependency at opt-level 3, exo's crates at 1; EXO_BENCH_SECONDS sets
//! each rate's duration, default 10).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use exo_messages::channels::SENSOR;
use exo_messages::SensorSample;
use exo_service_kit::ipc::Ipc;
use exo_service_kit::{monotonic_ns, sleep_until_ns};
use exo_tests::{start_tunnel, terminate, Scenario};
use hdrhistogram::Histogram;

/// Receives on `instance`'s sample channel until `done`, recording latency.
fn receiver(
    instance: String,
    tag: &'static str,
    from_seq: u64,
    done: Arc<AtomicBool>,
) -> std::thread::JoinHandle<(Histogram<u64>, u64)> {
    std::thread::spawn(move || {
        let ipc = Ipc::open(
            &format!("bench_{tag}_{}", std::process::id()),
            &instance,
            None,
        )
        .unwrap();
        let inbox = ipc.inbox(SENSOR, 8192).unwrap();
        let mut h = Histogram::<u64>::new_with_bounds(1, 60_000_000, 3).unwrap();
        let mut n = 0;
        let mut idle_since: Option<Instant> = None;
        loop {
            let _ = inbox.wait(Duration::from_millis(10));
            let mut got = false;
            while let Some(s) = inbox.try_recv().unwrap() {
                let now = monotonic_ns();
                // Only this rate's samples (not the last one before, which
                // a new subscriber receives on connecting).
                if s.seq > from_seq {
                    h.record(((now.saturating_sub(s.stamp_ns)) / 1000).max(1))
                        .unwrap();
                    n += 1;
                }
                got = true;
            }
            if got {
                idle_since = None;
            } else if done.load(Ordering::Relaxed) {
                let t = *idle_since.get_or_insert_with(Instant::now);
                if t.elapsed() > Duration::from_secs(2) {
                    return (h, n);
                }
            }
        }
    })
}

fn row(path: &str, rate: f64, h: &Histogram<u64>, n: u64, sent: u64, secs: f64) {
    println!(
        "| {path} | {rate:.0} | {} | {} | {} | {} | {} | {} | {:.0} | {} |",
        h.value_at_quantile(0.5),
        h.value_at_quantile(0.9),
        h.value_at_quantile(0.99),
        h.value_at_quantile(0.999),
        h.max(),
        n,
        n as f64 / secs,
        sent.saturating_sub(n)
    );
}

fn main() {
    let secs: f64 = std::env::var("EXO_BENCH_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(10.0);
    let exo = Scenario::new("benchA", &[]);
    let other = Scenario::new("benchB", &[]);
    let (mut export, mut import, _) = start_tunnel(&exo, &other);
    let (a, b) = (exo.instance.clone(), other.instance.clone());
    let ipc = Ipc::open(&format!("bench_pub_{}", std::process::id()), &a, None).unwrap();
    let out = ipc.outbox(SENSOR).unwrap();
    println!(
        "| path | rate (Hz) | p50 (µs) | p90 | p99 | p99.9 | max | received | throughput (msg/s) | lost |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let mut seq = 0u64;
    for rate in [1000.0, 10_000.0] {
        let done = Arc::new(AtomicBool::new(false));
        let local = receiver(a.clone(), "local", seq, Arc::clone(&done));
        let remote = receiver(b.clone(), "remote", seq, Arc::clone(&done));
        std::thread::sleep(Duration::from_millis(500));
        let n = (rate * secs) as u64;
        let period_ns = (1e9 / rate) as u64;
        let start = monotonic_ns() + 10_000_000;
        for i in 0..n {
            sleep_until_ns(start + i * period_ns);
            seq += 1;
            out.send(SensorSample {
                seq,
                stamp_ns: monotonic_ns(),
                ..Default::default()
            })
            .unwrap();
        }
        done.store(true, Ordering::Relaxed);
        let (hl, nl) = local.join().unwrap();
        let (hr, nr) = remote.join().unwrap();
        row("local (iceoryx2)", rate, &hl, nl, n, secs);
        row(
            "tunnel (iceoryx2 → Zenoh TCP loopback → iceoryx2)",
            rate,
            &hr,
            nr,
            n,
            secs,
        );
    }
    terminate(&mut export);
    terminate(&mut import);
}
