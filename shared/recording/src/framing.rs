//! Splitting MCAP bytes into records without trusting them: the framing
//! (opcode, length, body) of a record never read past the bytes there are,
//! the lengths inside a record's body checked before `mcap`'s parser sees
//! it, a chunk's records decompressed and checked against its header. Used
//! by exo's lenient reader ([`crate::reader`]) and by completing a dead
//! writer's file in place ([`crate::segments::complete_in_place`]).

use std::borrow::Cow;

use mcap::records::{op, ChunkHeader};

/// Largest uncompressed chunk accepted (bytes).
const MAX_CHUNK_BYTES: u64 = 1 << 30;
/// Largest compression ratio a chunk may claim (zstd and lz4 stay far below).
const MAX_COMPRESSION_RATIO: u64 = 4096;

/// Splits bytes into MCAP records (opcode, 8-byte length, body) without
/// parsing them.
pub(crate) struct Framing<'a> {
    buf: &'a [u8],
    pos: usize,
}

pub(crate) enum Frame<'a> {
    Record(u8, &'a [u8]),
    End,
    Cut(String),
}

impl<'a> Framing<'a> {
    pub(crate) fn new(buf: &'a [u8], pos: usize) -> Self {
        Framing { buf, pos }
    }

    /// Where the next record starts (bytes from the start of the buffer).
    pub(crate) fn position(&self) -> usize {
        self.pos
    }

    pub(crate) fn next(&mut self) -> Frame<'a> {
        let rest = self.buf.get(self.pos..).unwrap_or_default();
        let Some((&opcode, after)) = rest.split_first() else {
            return Frame::End;
        };
        let Some(len) = after.get(..8).map(|l| {
            let mut a = [0u8; 8];
            a.copy_from_slice(l);
            u64::from_le_bytes(a)
        }) else {
            return Frame::Cut(format!(
                "a record header cut off after {} of 9 bytes at byte {}",
                rest.len(),
                self.pos
            ));
        };
        let available = rest.len() - 9;
        match usize::try_from(len).ok().filter(|l| *l <= available) {
            Some(l) => {
                let body = &rest[9..9 + l];
                self.pos += 9 + l;
                Frame::Record(opcode, body)
            }
            None => Frame::Cut(format!(
                "a record (opcode {opcode:#04x}) at byte {} claims {len} bytes, {available} follow",
                self.pos
            )),
        }
    }
}

/// Walks a record body checking that every length stays inside it.
struct Walk<'a> {
    b: &'a [u8],
    pos: usize,
}

impl Walk<'_> {
    fn skip(&mut self, n: u64) -> bool {
        match usize::try_from(n) {
            Ok(n) if self.b.len() - self.pos >= n => {
                self.pos += n;
                true
            }
            _ => false,
        }
    }

    fn int<const N: usize>(&mut self) -> Option<u64> {
        let s = self.b.get(self.pos..self.pos + N)?;
        self.pos += N;
        let mut a = [0u8; 8];
        a[..N].copy_from_slice(s);
        Some(u64::from_le_bytes(a))
    }

    /// A `u32`-length-prefixed string or byte array.
    fn string(&mut self) -> bool {
        self.int::<4>().is_some_and(|n| self.skip(n))
    }

    /// A `u64`-length-prefixed byte array.
    fn bytes64(&mut self) -> bool {
        self.int::<8>().is_some_and(|n| self.skip(n))
    }

    /// A string map: `u32` byte length, then key and value strings filling it.
    fn map(&mut self) -> bool {
        let Some(n) = self.int::<4>() else {
            return false;
        };
        let end = self.pos as u64 + n;
        if end > self.b.len() as u64 {
            return false;
        }
        while (self.pos as u64) < end {
            if !(self.string() && self.string()) {
                return false;
            }
        }
        self.pos as u64 == end
    }
}

/// Whether every length inside a record's body stays inside it (for the
/// records exo reads): mcap's parser would otherwise reserve what a damaged
/// string length claims, up to 4 GiB, or slice out of bounds (found by
/// fuzzing).
pub(crate) fn lengths_fit(opcode: u8, body: &[u8]) -> bool {
    let mut w = Walk { b: body, pos: 0 };
    match opcode {
        op::HEADER => w.string() && w.string(),
        op::SCHEMA => w.skip(2) && w.string() && w.string() && w.string(),
        op::CHANNEL => w.skip(4) && w.string() && w.string() && w.map(),
        op::MESSAGE => w.skip(22),
        op::CHUNK => w.skip(28) && w.string() && w.bytes64(),
        op::METADATA => w.string() && w.map(),
        op::ATTACHMENT => w.skip(16) && w.string() && w.string() && w.bytes64() && w.skip(4),
        op::FOOTER => w.skip(20),
        _ => false,
    }
}

/// The decompressed records of a chunk, checked against its header's
/// size and CRC.
pub(crate) fn chunk_body<'d>(
    header: &ChunkHeader,
    data: &Cow<'d, [u8]>,
) -> Result<Cow<'d, [u8]>, String> {
    // A damaged header can claim any size: refuse before allocating it.
    let plausible = (data.len() as u64)
        .saturating_mul(MAX_COMPRESSION_RATIO)
        .saturating_add(1 << 20)
        .min(MAX_CHUNK_BYTES);
    if header.uncompressed_size > plausible {
        return Err(format!(
            "it claims {} uncompressed bytes from {} compressed",
            header.uncompressed_size,
            data.len()
        ));
    }
    let size = usize::try_from(header.uncompressed_size).map_err(|e| e.to_string())?;
    let body: Cow<'d, [u8]> = match header.compression.as_str() {
        "" => data.clone(),
        "zstd" => Cow::Owned(zstd::bulk::decompress(data, size).map_err(|e| format!("zstd: {e}"))?),
        "lz4" => {
            let mut out = Vec::with_capacity(size);
            let mut dec = lz4::Decoder::new(&data[..]).map_err(|e| format!("lz4: {e}"))?;
            std::io::Read::read_to_end(
                &mut std::io::Read::take(&mut dec, header.uncompressed_size),
                &mut out,
            )
            .map_err(|e| format!("lz4: {e}"))?;
            Cow::Owned(out)
        }
        other => return Err(format!("compression `{other}` is not supported")),
    };
    if body.len() != size {
        return Err(format!(
            "it decompresses to {} bytes, its header says {size}",
            body.len()
        ));
    }
    if header.uncompressed_crc != 0 {
        let crc = crc32(&body);
        if crc != header.uncompressed_crc {
            return Err(format!(
                "CRC {crc:08x} of its records, its header says {:08x}",
                header.uncompressed_crc
            ));
        }
    }
    Ok(body)
}

/// CRC-32 (IEEE 802.3, as zlib and MCAP use). `crc32fast` uses the CPU's
/// carry-less multiply where it has one: the bytewise table this replaced
/// took 46 % of `exo fit`'s time.
fn crc32(data: &[u8]) -> u32 {
    crc32fast::hash(data)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32_is_the_ieee_one() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
        assert_eq!(crc32(b""), 0);
    }
}
