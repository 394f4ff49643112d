//! Fuzzes the lenient recording reader: any bytes, starting with the MCAP
//! magic or not, must give a `Recording` (whose warnings all name the file)
//! or an error naming the file; never a panic, an abort or an unbounded
//! allocation.
//!
//! Run: `cargo +nightly fuzz run read_recording` from `fuzz/` (or the
//! repository root); seed the corpus (`fuzz/corpus/read_recording/`) with a
//! few small recordings, e.g. ones `RecordingWriter` writes with 1 KiB
//! chunks. `cargo check --manifest-path fuzz/Cargo.toml` builds it on stable.
#![no_main]

use std::borrow::Cow;

use libfuzzer_sys::fuzz_target;

const MAGIC: &[u8] = b"\x89MCAP0\r\n";

fuzz_target!(|data: &[u8]| {
    // Real recordings in the corpus are used as they are; other inputs get
    // the magic half of the time (first byte odd, then dropped), so the
    // fuzzer reaches the record parser from any start.
    let bytes: Cow<'_, [u8]> = match data.first() {
        Some(b) if b & 1 == 1 && !data.starts_with(MAGIC) => {
            let mut v = MAGIC.to_vec();
            v.extend_from_slice(&data[1..]);
            Cow::Owned(v)
        }
        _ => Cow::Borrowed(data),
    };
    match exo_recording::read_recording_bytes("fuzz.mcap", &bytes) {
        Ok(r) => {
            assert!(r.warnings.iter().all(|w| w.starts_with("fuzz.mcap: ")));
            if r.truncated {
                let said = format!("truncated after {} messages", r.message_count());
                assert!(r.warnings.iter().any(|w| w.contains(&said)));
            }
        }
        Err(e) => assert!(e.to_string().starts_with("fuzz.mcap: ")),
    }
});
