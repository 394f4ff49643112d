//! Fuzzes the lenient recording reader: any bytes, starting with the MCAP
//! magic or not, must give a `Recording` (with warnings) or an error, never
//! a panic, an abort or an unbounded allocation.
//!
//! Run: `cargo +nightly fuzz run read_recording` from the repository root
//! (seed the corpus with a few recordings, e.g. `out/runs/*.mcap`).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut bytes = Vec::with_capacity(data.len() + 8);
    // Half of the inputs get the magic, so the fuzzer reaches the records.
    if data.first().is_some_and(|b| b & 1 == 1) {
        bytes.extend_from_slice(b"\x89MCAP0\r\n");
    }
    bytes.extend_from_slice(data);
    let _ = exo_recording::read_recording_bytes("fuzz.mcap", &bytes);
});
