//! The MCAP reading steps the reader, the index and recovery share: bounded reads at an
//! offset, the records of one chunk with its CRC checked first, and the sanity limits that
//! keep a damaged file from making the decoder allocate absurd amounts.
//!
//! The `mcap` crate reserves a string's claimed length before it reads the string (binrw's
//! `reserve_exact`), so a record must never reach `mcap::parse_record` before every length
//! it claims is known to lie inside it ([`claims_fit`]); and it decompresses a chunk into a
//! buffer of the size the chunk claims, so that size is bounded by what its compressed bytes
//! can hold ([`chunk_sizes_fit`]).

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

use mcap::records::{op, ChunkHeader, Record};
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};

use super::BagError;

/// Largest chunk, compressed or not, the reader loads (a guard against absurd sizes in a
/// damaged index; the writer's chunks are about 1 MiB plus at most one message).
pub(super) const MAX_CHUNK_BYTES: u64 = 4 << 30;

/// The most bytes zstd makes of one compressed byte: a block regenerates at most 128 KiB
/// and takes at least 4 bytes (an RLE block: a 3-byte header and the byte repeated).
pub(super) const MAX_ZSTD_RATIO: u64 = (128 << 10) / 4;

/// Whether the chunk record `record`'s compression name (a length-prefixed string after the
/// opcode, the record length, two times, the uncompressed size and CRC) lies inside it. The
/// `mcap` crate reserves a string's claimed length before reading it, so a damaged length
/// must be refused first (found by the `mcap` fuzz target: 2.4 GB asked for by a 2.7 kB file).
pub(super) fn compression_name_fits(record: &[u8]) -> bool {
    const NAME_LEN_AT: usize = 1 + 8 + 8 + 8 + 8 + 4;
    let len = record
        .get(NAME_LEN_AT..NAME_LEN_AT + 4)
        .and_then(|b| <[u8; 4]>::try_from(b).ok())
        .map(u32::from_le_bytes);
    len.is_some_and(|len| len as usize <= record.len() - NAME_LEN_AT - 4)
}

/// Whether a chunk's claimed sizes are ones its data can have: at most [`MAX_CHUNK_BYTES`]
/// uncompressed, and for a zstd chunk at most [`MAX_ZSTD_RATIO`] times its compressed size
/// (the reader decompresses into a buffer of the claimed size, so a chunk of a few bytes
/// claiming 4 GiB would otherwise have that much allocated and zeroed).
pub(super) fn chunk_sizes_fit(header: &ChunkHeader) -> Result<(), String> {
    if header.uncompressed_size > MAX_CHUNK_BYTES {
        return Err("uncompressed size larger than 4 GiB".into());
    }
    let most = header.compressed_size.saturating_mul(MAX_ZSTD_RATIO);
    if !header.compression.is_empty() && header.uncompressed_size > most {
        return Err(format!(
            "uncompressed size {} is more than {} compressed bytes can hold",
            header.uncompressed_size, header.compressed_size
        ));
    }
    Ok(())
}

/// Whether every length the body of a record of `opcode` claims (its strings, its maps'
/// strings, an attachment's checksum) lies inside the body, walking the fields as
/// `mcap::parse_record` reads them: what it says no to, the parser would have refused too,
/// but only after reserving the claimed bytes (or, for an attachment without room for its
/// checksum, by panicking). Records without strings always fit.
pub(super) fn claims_fit(opcode: u8, body: &[u8]) -> Result<(), String> {
    let mut w = Walk { body, at: 0 };
    match opcode {
        op::HEADER => {
            w.string("profile")?;
            w.string("library")
        }
        op::SCHEMA => {
            w.skip(2)?;
            w.string("schema name")?;
            w.string("schema encoding")
        }
        op::CHANNEL => {
            w.skip(4)?;
            w.string("topic")?;
            w.string("message encoding")?;
            w.string_map("channel metadata")
        }
        op::CHUNK => {
            w.skip(8 + 8 + 8 + 4)?;
            w.string("chunk compression")
        }
        op::CHUNK_INDEX => {
            w.skip(8 * 4)?;
            // Message index offsets: (u16, u64) pairs until the map's byte length is read.
            let len = w.u32()? as usize;
            let start = w.at;
            while w.at - start < len {
                w.skip(2 + 8)?;
            }
            w.skip(8)?;
            w.string("chunk index compression")
        }
        op::ATTACHMENT => {
            w.skip(8 + 8)?;
            w.string("attachment name")?;
            w.string("attachment media type")?;
            w.skip(8)?;
            match w.left() >= 4 {
                true => Ok(()),
                false => Err("attachment without room for its CRC".into()),
            }
        }
        op::ATTACHMENT_INDEX => {
            w.skip(8 * 5)?;
            w.string("attachment index name")?;
            w.string("attachment index media type")
        }
        op::METADATA => {
            w.string("metadata name")?;
            w.string_map("metadata")
        }
        op::METADATA_INDEX => {
            w.skip(8 + 8)?;
            w.string("metadata index name")
        }
        _ => Ok(()),
    }
}

/// A walk over a record body's fields, only checking their lengths.
struct Walk<'a> {
    body: &'a [u8],
    at: usize,
}

impl Walk<'_> {
    fn left(&self) -> usize {
        self.body.len() - self.at
    }

    fn skip(&mut self, n: usize) -> Result<(), String> {
        if n > self.left() {
            return Err(format!(
                "record cut off at byte {} of {}",
                self.at,
                self.body.len()
            ));
        }
        self.at += n;
        Ok(())
    }

    fn u32(&mut self) -> Result<u32, String> {
        let at = self.at;
        self.skip(4)?;
        let b = &self.body[at..at + 4];
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    fn string(&mut self, what: &str) -> Result<(), String> {
        let len = self.u32()? as usize;
        if len > self.left() {
            return Err(format!(
                "{what} claims {len} bytes, {} are left in its record",
                self.left()
            ));
        }
        self.at += len;
        Ok(())
    }

    /// A string-to-string map: its byte length, then keys and values until it is read.
    fn string_map(&mut self, what: &str) -> Result<(), String> {
        let len = self.u32()? as usize;
        let start = self.at;
        while self.at - start < len {
            self.string(what)?;
            self.string(what)?;
        }
        Ok(())
    }
}

/// Whether the summary section `summary` (from the footer's summary start up to the footer)
/// is whole records of the kinds a summary holds, each claiming only lengths inside it
/// ([`claims_fit`]). The `mcap` crate's summary reader parses every record it meets (and
/// decompresses a chunk), so this is checked before it runs. The error names the offset
/// within `summary`.
pub(super) fn summary_records_fit(summary: &[u8]) -> Result<(), (usize, String)> {
    let mut at = 0;
    while at < summary.len() {
        let left = summary.len() - at;
        if left < 9 {
            return Err((at, "summary record cut off in its header".into()));
        }
        let opcode = summary[at];
        let len = le_u64(&summary[at + 1..at + 9]);
        if len > (left - 9) as u64 {
            return Err((
                at,
                format!("summary record claims {len} bytes, {} are left", left - 9),
            ));
        }
        let summary_kind = matches!(
            opcode,
            op::SCHEMA
                | op::CHANNEL
                | op::CHUNK_INDEX
                | op::ATTACHMENT_INDEX
                | op::METADATA_INDEX
                | op::STATISTICS
                | op::SUMMARY_OFFSET
        );
        // Opcodes 0x80 and up are private records, which readers skip.
        if !summary_kind && opcode < 0x80 {
            return Err((at, format!("record of opcode {opcode:#04x} in the summary")));
        }
        let body = &summary[at + 9..at + 9 + len as usize];
        claims_fit(opcode, body).map_err(|reason| (at, reason))?;
        at += 9 + len as usize;
    }
    Ok(())
}

/// Why a chunk's records could not be read.
#[derive(Debug)]
pub(super) enum ChunkError {
    /// The `mcap` crate refused the chunk or a record in it.
    Format(mcap::McapError),
    /// A record in it claims more than it holds ([`claims_fit`]).
    Claims(String),
}

impl std::fmt::Display for ChunkError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ChunkError::Format(e) => e.fmt(f),
            ChunkError::Claims(reason) => f.write_str(reason),
        }
    }
}

/// Decodes the chunk record `record` (opcode and length included) and calls `on_record` with
/// each message, schema and channel record in it, in file order (other records are skipped
/// unparsed). The chunk's CRC is checked before any record inside is parsed, no record may
/// claim more than `limit` bytes, and a record's inner lengths are checked before it is
/// parsed ([`claims_fit`]), so damaged data can neither reach `on_record` nor make the
/// decoder allocate absurd amounts. The caller checks the chunk's header first
/// ([`compression_name_fits`], [`chunk_sizes_fit`]).
pub(super) fn for_each_record(
    record: &[u8],
    limit: usize,
    mut on_record: impl FnMut(Record<'_>),
) -> Result<(), ChunkError> {
    let options = LinearReaderOptions::default()
        .with_skip_start_magic(true)
        .with_skip_end_magic(true)
        .with_prevalidate_chunk_crcs(true)
        .with_record_length_limit(limit);
    let mut reader = LinearReader::new_with_options(options);
    let mut input = record;
    while let Some(event) = reader.next_event() {
        match event.map_err(ChunkError::Format)? {
            LinearReadEvent::ReadRequest(need) => {
                let n = need.min(input.len());
                reader.insert(n).copy_from_slice(&input[..n]);
                reader.notify_read(n);
                input = &input[n..];
            }
            LinearReadEvent::Record { opcode, data } => {
                if !matches!(opcode, op::MESSAGE | op::SCHEMA | op::CHANNEL) {
                    continue;
                }
                claims_fit(opcode, data).map_err(ChunkError::Claims)?;
                on_record(mcap::parse_record(opcode, data).map_err(ChunkError::Format)?);
            }
        }
    }
    Ok(())
}

/// Reads `len` bytes at `offset` of `file`.
pub(super) fn read_at(
    path: &Path,
    mut file: &File,
    offset: u64,
    len: usize,
) -> Result<Vec<u8>, BagError> {
    let mut buf = vec![0; len];
    file.seek(SeekFrom::Start(offset))
        .and_then(|_| file.read_exact(&mut buf))
        .map_err(|source| BagError::Io {
            path: path.to_path_buf(),
            action: format!("read {len} bytes at byte {offset}"),
            source,
        })?;
    Ok(buf)
}

/// A little-endian u64 from the first 8 bytes of `bytes`.
pub(super) fn le_u64(bytes: &[u8]) -> u64 {
    let mut le = [0; 8];
    le.copy_from_slice(&bytes[..8]);
    u64::from_le_bytes(le)
}

#[cfg(test)]
#[path = "claims_tests.rs"]
mod tests;
