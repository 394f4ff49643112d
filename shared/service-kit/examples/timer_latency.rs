//! The platform's own wake-up lateness at a control rate, with nothing of
//! exo's loop around it: a thread asks for the real-time settings the
//! driver asks for (`SCHED_FIFO` 80, locked memory, one CPU), sleeps to
//! absolute deadlines with the driver's own `sleep_until_ns`, and reports
//! how late it woke. A driver that latches a cycle started more than a
//! period late cannot hold a row longer than this platform's gaps between
//! such wake-ups (BENCHMARKS.md, "EtherCAT").
//!
//! With `SPIN_US` > 0 the same thread also waits with
//! `sleep_then_spin_until_ns` (asleep until `SPIN_US` before the deadline,
//! then polling the clock), in alternating blocks of one second, so that
//! both waits meet the same load; each is reported on its own line
//! (`bus.ethercat.wake_spin_us`, docs/hardware.md, "Less lateness").
//!
//! `cargo run --release -p exo-service-kit --example timer_latency -- [SECONDS=10] [RATE_HZ=1000] [CPU=1] [SPIN_US=0]`

use exo_service_kit::{monotonic_ns, request_realtime, sleep_then_spin_until_ns, RealtimeRequest};

fn main() {
    let arg = |i: usize, default: f64| {
        std::env::args()
            .nth(i)
            .map_or(Ok(default), |s| s.parse::<f64>())
            .unwrap_or_else(|e| {
                eprintln!("timer_latency: argument {i}: {e}");
                std::process::exit(2)
            })
    };
    let (secs, rate, cpu, spin_us) = (arg(1, 10.0), arg(2, 1000.0), arg(3, 1.0), arg(4, 0.0));
    if !(secs > 0.0 && rate > 0.0 && cpu >= 0.0 && spin_us >= 0.0 && spin_us * rate < 1e6) {
        eprintln!(
            "timer_latency: SECONDS and RATE_HZ must be positive, CPU and SPIN_US at least 0, SPIN_US less than a period"
        );
        std::process::exit(2);
    }
    let grant = request_realtime(
        "timer_latency",
        RealtimeRequest {
            sched_fifo_priority: Some(80),
            lock_memory: true,
            cpu: Some(cpu as usize),
        },
    );
    let period_ns = (1e9 / rate) as u64;
    let spin_ns = (spin_us * 1e3) as u64;
    let n = (secs * rate) as usize;
    let block = (rate as usize).max(1);
    // Lateness per wait: [plain sleep, sleep then spin].
    let mut late = [Vec::with_capacity(n), Vec::with_capacity(n)];
    let mut next = monotonic_ns() + period_ns;
    for i in 0..n {
        let mode = usize::from(spin_ns > 0 && (i / block) % 2 == 1);
        sleep_then_spin_until_ns(next, if mode == 1 { spin_ns } else { 0 });
        late[mode].push(monotonic_ns().saturating_sub(next));
        next += period_ns;
    }
    for (mode, mut late) in late.into_iter().enumerate() {
        if late.is_empty() {
            continue;
        }
        let over = late.iter().filter(|&&l| l > period_ns).count();
        late.sort_unstable();
        let q = |p: f64| late[((late.len() - 1) as f64 * p) as usize] as f64 / 1e3;
        let wait = if mode == 1 {
            format!("asleep until {spin_us} µs before, then spinning")
        } else {
            "asleep until the deadline".to_string()
        };
        println!(
            "wake-up lateness over {} cycles at {rate} Hz, {wait} (SCHED_FIFO {}, memory locked {}, pinned {}): p50 {:.1} µs, p99 {:.1} µs, p99.9 {:.1} µs, max {:.1} µs; {over} more than a period late",
            late.len(),
            grant.sched_fifo,
            grant.memory_locked,
            grant.pinned,
            q(0.5),
            q(0.99),
            q(0.999),
            q(1.0)
        );
    }
}
