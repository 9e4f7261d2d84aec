//! The MCAP reading steps the reader, the index and recovery share: bounded reads at an
//! offset, the records of one chunk with its CRC checked first, and the sanity limits that
//! keep a damaged file from making the decoder allocate absurd amounts.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

use mcap::records::Record;
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};

use super::BagError;

/// Largest chunk, compressed or not, the reader loads (a guard against absurd sizes in a
/// damaged index; the writer's chunks are about 1 MiB plus at most one message).
pub(super) const MAX_CHUNK_BYTES: u64 = 4 << 30;

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

/// Decodes the chunk record `record` (opcode and length included) and calls `on_record` with
/// each record in it, in file order. The chunk's CRC is checked before any record inside is
/// parsed, and no record may claim more than `limit` bytes, so damaged data can neither reach
/// `on_record` nor make the decoder allocate absurd amounts.
pub(super) fn for_each_record(
    record: &[u8],
    limit: usize,
    mut on_record: impl FnMut(Record<'_>),
) -> mcap::McapResult<()> {
    let options = LinearReaderOptions::default()
        .with_skip_start_magic(true)
        .with_skip_end_magic(true)
        .with_prevalidate_chunk_crcs(true)
        .with_record_length_limit(limit);
    let mut reader = LinearReader::new_with_options(options);
    let mut input = record;
    while let Some(event) = reader.next_event() {
        match event? {
            LinearReadEvent::ReadRequest(need) => {
                let n = need.min(input.len());
                reader.insert(n).copy_from_slice(&input[..n]);
                reader.notify_read(n);
                input = &input[n..];
            }
            LinearReadEvent::Record { opcode, data } => {
                on_record(mcap::parse_record(opcode, data)?);
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
