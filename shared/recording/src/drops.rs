//! What a recorder missed, as its `exo.drops` metadata record says
//! ([`DROPS_METADATA`], `docs/recording-format.md`): per topic the samples
//! missed (sequence gaps in what it wrote) and, where any were, the first
//! missing `seq` (`<topic>.first_missing`). `exo run` reads it from each
//! segment after the run and names every topic with a miss as a fault.

use std::collections::BTreeMap;
use std::path::Path;

use crate::writer::DROPS_METADATA;
use crate::RecordingError;

/// The key suffix of a topic's first missing `seq` in `exo.drops`
/// (`exo/sensor.first_missing`).
pub const FIRST_MISSING: &str = ".first_missing";

/// The samples a recorder missed on one topic.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Missed {
    /// The topic, e.g. `exo/sensor`.
    pub topic: String,
    /// Samples missed (the sum of the gaps).
    pub count: u64,
    /// The first missing `seq`, when the record names it (exo's recorder
    /// does since issue 32; older files and other writers may not).
    pub first_seq: Option<u64>,
}

/// The topics of a recording contract with samples missed, from the
/// `exo.drops` record `drops` of `file`, in topic order. A count or a seq
/// that is not a whole number is an error naming the file and the key.
/// Keys that are not contract topics (`writer_queue_discarded`,
/// `exo/sensor.skipped_by_driver`, which are not misses of the file, or
/// are already in the gaps) are left out.
pub fn missed(
    file: &Path,
    drops: &BTreeMap<String, String>,
) -> Result<Vec<Missed>, RecordingError> {
    let number = |key: &str, value: &str| {
        value
            .trim()
            .parse::<u64>()
            .map_err(|_| RecordingError::Invalid {
                file: file.display().to_string(),
                message: format!("{DROPS_METADATA}: {key}: `{value}` is not a count"),
            })
    };
    let mut out = Vec::new();
    for t in crate::schema::contract() {
        let Some(value) = drops.get(t.topic) else {
            continue;
        };
        let count = number(t.topic, value)?;
        if count == 0 {
            continue;
        }
        let key = format!("{}{FIRST_MISSING}", t.topic);
        let first_seq = drops.get(&key).map(|v| number(&key, v)).transpose()?;
        out.push(Missed {
            topic: t.topic.to_string(),
            count,
            first_seq,
        });
    }
    out.sort_by(|a, b| a.topic.cmp(&b.topic));
    Ok(out)
}

/// The `exo.drops` record of one file (one segment, not its later ones),
/// or `None` when it has none (its recorder did not finish it). Read
/// through the file's summary (the metadata index) when it has one, so a
/// long recording is not decoded for it; a file without a summary is read
/// whole.
pub fn read_drops(file: &Path) -> Result<Option<BTreeMap<String, String>>, RecordingError> {
    let bytes = std::fs::read(file).map_err(|e| RecordingError::io(file, e))?;
    if let Ok(Some(summary)) = mcap::Summary::read(&bytes) {
        if let Some(index) = summary
            .metadata_indexes
            .iter()
            .find(|i| i.name == DROPS_METADATA)
        {
            let record =
                mcap::read::metadata(&bytes, index).map_err(|e| RecordingError::mcap(file, e))?;
            return Ok(Some(record.metadata));
        }
        return Ok(None);
    }
    let rec = crate::read_recording_bytes(&file.display().to_string(), &bytes)?;
    Ok(rec.metadata.get(DROPS_METADATA).cloned())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(pairs: &[(&str, &str)]) -> BTreeMap<String, String> {
        pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect()
    }

    #[test]
    fn topics_with_misses_are_named_with_their_first_seq() {
        let drops = map(&[
            ("exo/sensor", "1800"),
            ("exo/sensor.first_missing", "2301"),
            ("exo/command", "0"),
            ("exo/bus/motor", "7"),
            ("exo/sensor.skipped_by_driver", "3"),
            ("writer_queue_discarded", "12"),
        ]);
        let m = missed(Path::new("run.mcap"), &drops).unwrap();
        assert_eq!(
            m,
            vec![
                Missed {
                    topic: "exo/bus/motor".into(),
                    count: 7,
                    first_seq: None
                },
                Missed {
                    topic: "exo/sensor".into(),
                    count: 1800,
                    first_seq: Some(2301)
                },
            ]
        );
        assert!(missed(Path::new("run.mcap"), &map(&[("exo/sensor", "0")]))
            .unwrap()
            .is_empty());
    }

    #[test]
    fn a_count_that_is_not_a_number_names_the_file_and_the_key() {
        let e = missed(
            Path::new("run.mcap"),
            &map(&[("exo/sensor", "5"), ("exo/sensor.first_missing", "x")]),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("run.mcap") && e.contains("exo.drops: exo/sensor.first_missing: `x`"),
            "{e}"
        );
    }
}
