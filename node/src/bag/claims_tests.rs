//! Lengths a damaged MCAP file claims are checked before anything is allocated for them:
//! hand-made files of a few dozen bytes whose strings or chunk sizes claim gigabytes are
//! refused, and the largest single allocation each thread asks for
//! ([`crate::alloc_probe`]) stays small.

use std::path::PathBuf;

use mcap::records::op;

use super::*;
use crate::alloc_probe::largest_allocation;
use crate::bag::BagReader;

/// Allocations these tests allow: the files are tiny, and the claims are gigabytes.
const SMALL: usize = 1 << 20;

fn record(opcode: u8, body: &[u8]) -> Vec<u8> {
    let mut r = vec![opcode];
    r.extend_from_slice(&(body.len() as u64).to_le_bytes());
    r.extend_from_slice(body);
    r
}

/// An MCAP string whose length field claims `claimed` bytes and which holds `text`.
fn string(claimed: u32, text: &str) -> Vec<u8> {
    let mut s = claimed.to_le_bytes().to_vec();
    s.extend_from_slice(text.as_bytes());
    s
}

/// A schema record whose name claims `claimed` bytes.
fn schema(claimed: u32) -> Vec<u8> {
    let body = [
        &7u16.to_le_bytes()[..],
        &string(claimed, "sensor_msgs/msg/Image"),
        &string(7, "ros2msg"),
        &0u32.to_le_bytes(),
    ]
    .concat();
    record(op::SCHEMA, &body)
}

/// A chunk record holding `data` as it is, claiming `uncompressed` bytes and `compression`.
fn chunk(data: &[u8], uncompressed: u64, crc: u32, compression: &str) -> Vec<u8> {
    let body = [
        &0u64.to_le_bytes()[..],
        &0u64.to_le_bytes(),
        &uncompressed.to_le_bytes(),
        &crc.to_le_bytes(),
        &string(compression.len() as u32, compression),
        &(data.len() as u64).to_le_bytes(),
        data,
    ]
    .concat();
    record(op::CHUNK, &body)
}

/// An attachment record body with empty strings, no data and no room for its CRC.
fn attachment_without_crc() -> Vec<u8> {
    [
        &[0u8; 16][..],
        &string(0, ""),
        &string(0, ""),
        &0u64.to_le_bytes(),
    ]
    .concat()
}

fn file(name: &str, bytes: &[u8]) -> PathBuf {
    let path = std::env::temp_dir().join(format!("bag-claims-{name}-{}", std::process::id()));
    std::fs::write(&path, bytes).unwrap();
    path
}

/// A cut-off recording: the magic, then records, and no footer.
fn cut_off(records: &[Vec<u8>]) -> Vec<u8> {
    [mcap::MAGIC, records.concat().as_slice()].concat()
}

#[test]
fn a_schema_name_claiming_4_gib_in_a_tiny_cut_off_file_is_refused_unallocated() {
    // What is guarded against: the `mcap` crate alone reserves what a string claims before
    // it reads the string (shown with a claim of 256 MiB, which any machine reserves).
    let claim = 256 << 20;
    let body = schema(claim)[9..].to_vec();
    let (largest, parsed) =
        largest_allocation(|| mcap::parse_record(op::SCHEMA, &body).map(|_| ()));
    assert!(parsed.is_err());
    assert!(
        largest >= claim as usize,
        "{largest} bytes allocated at once"
    );
    let bytes = cut_off(&[schema(0xffff_fff0)]);
    assert!(bytes.len() < 64);
    let path = file("schema", &bytes);
    let (largest, recovered) = largest_allocation(|| BagReader::recover(&path));
    let (bag, recovery) = recovered.expect("a file starting as MCAP is recovered");
    assert!(
        recovery
            .stopped
            .contains("schema name claims 4294967280 bytes"),
        "{recovery}"
    );
    assert_eq!((recovery.readable_bytes, bag.message_count()), (8, 0));
    assert!(largest < SMALL, "{largest} bytes allocated at once");
    std::fs::remove_file(&path).unwrap();
}

#[test]
fn a_zstd_chunk_claiming_4_gib_from_4_bytes_is_refused_unallocated() {
    let bytes = cut_off(&[chunk(&[0x28, 0xb5, 0x2f, 0xfd], (4 << 30) - 1, 1, "zstd")]);
    let path = file("zstd", &bytes);
    let (largest, recovered) = largest_allocation(|| BagReader::recover(&path));
    let (_, recovery) = recovered.unwrap();
    assert!(
        recovery
            .stopped
            .contains("more than 4 compressed bytes can hold"),
        "{recovery}"
    );
    assert_eq!(recovery.chunks, 0);
    assert!(largest < SMALL, "{largest} bytes allocated at once");
    std::fs::remove_file(&path).unwrap();
}

#[test]
fn records_inside_a_chunk_are_checked_before_they_are_parsed() {
    // A schema claiming 4 GiB inside an uncompressed chunk without a CRC (so nothing is
    // validated first): the chunk is refused, nothing large allocated.
    let inner = schema(0xffff_0000);
    let bytes = cut_off(&[chunk(&inner, inner.len() as u64, 0, "")]);
    let path = file("inner-schema", &bytes);
    let (largest, recovered) = largest_allocation(|| BagReader::recover(&path));
    let (_, recovery) = recovered.unwrap();
    assert!(
        recovery.stopped.contains("schema name claims"),
        "{recovery}"
    );
    assert!(largest < SMALL, "{largest} bytes allocated at once");
    // The `mcap` crate panics on an attachment record without room for its CRC; inside a
    // chunk such a record is skipped unparsed (a chunk holds messages, schemas, channels).
    let body = attachment_without_crc();
    assert!(std::panic::catch_unwind(|| mcap::parse_record(op::ATTACHMENT, &body)).is_err());
    assert!(claims_fit(op::ATTACHMENT, &body).is_err());
    let inner = record(op::ATTACHMENT, &body);
    std::fs::write(&path, cut_off(&[chunk(&inner, inner.len() as u64, 0, "")])).unwrap();
    let (_, recovery) = BagReader::recover(&path).unwrap();
    assert_eq!((recovery.chunks, recovery.messages), (1, 0), "{recovery}");
    std::fs::remove_file(&path).unwrap();
}

#[test]
fn a_summary_is_checked_before_the_library_reads_it() {
    // A finished file whose summary holds one record: magic, the summary, the footer
    // (summary start, no summary offsets, no CRC), magic.
    let finished = |summary: &[u8]| {
        let footer = [
            &8u64.to_le_bytes()[..],
            &0u64.to_le_bytes(),
            &0u32.to_le_bytes(),
        ]
        .concat();
        [
            mcap::MAGIC,
            summary,
            &record(op::FOOTER, &footer),
            mcap::MAGIC,
        ]
        .concat()
    };
    let path = file("summary", &finished(&schema(0xffff_fff0)));
    let (largest, opened) = largest_allocation(|| BagReader::open(&path));
    let message = opened.err().expect("refused").to_string();
    assert!(
        message.contains("damaged at byte 8: schema name claims"),
        "{message}"
    );
    assert!(largest < SMALL, "{largest} bytes allocated at once");
    // Records that do not belong in a summary are refused before the library parses them
    // (an attachment there would make it panic).
    std::fs::write(
        &path,
        finished(&record(op::ATTACHMENT, &attachment_without_crc())),
    )
    .unwrap();
    let message = BagReader::open(&path).err().expect("refused").to_string();
    assert!(
        message.contains("record of opcode 0x09 in the summary"),
        "{message}"
    );
    std::fs::remove_file(&path).unwrap();
}

#[test]
fn claims_of_every_record_kind_are_walked_as_the_parser_reads_them() {
    let channel = |topic_claim: u32, map: &[u8]| {
        [
            &[1, 0, 7, 0][..],
            &string(topic_claim, "/pose"),
            &string(3, "cdr"),
            map,
        ]
        .concat()
    };
    let map = [
        &16u32.to_le_bytes()[..],
        &string(2, "qo"),
        &string(6, "s: [1]"),
    ]
    .concat();
    assert_eq!(claims_fit(op::CHANNEL, &channel(5, &map)), Ok(()));
    assert!(mcap::parse_record(op::CHANNEL, &channel(5, &map)).is_ok());
    assert!(claims_fit(op::CHANNEL, &channel(6, &map)).is_err());
    let long_value = [
        &16u32.to_le_bytes()[..],
        &string(2, "qo"),
        &string(600, "s"),
    ]
    .concat();
    assert!(claims_fit(op::CHANNEL, &channel(5, &long_value)).is_err());
    // A header, metadata and indexes: their strings are found where the parser reads them.
    let header = [&string(4, "ros2")[..], &string(4, "test")].concat();
    assert_eq!(claims_fit(op::HEADER, &header), Ok(()));
    assert!(claims_fit(op::HEADER, &header[..10]).is_err());
    let index = [&[0u8; 16][..], &string(1 << 30, "name")].concat();
    assert!(claims_fit(op::METADATA_INDEX, &index).is_err());
    assert!(claims_fit(op::ATTACHMENT_INDEX, &[0u8; 40]).is_err());
    let chunk_index = [
        &[0u8; 32][..],
        &10u32.to_le_bytes(),
        &[0u8; 10],
        &[0u8; 8],
        &string(9, "zstd"),
    ]
    .concat();
    assert!(claims_fit(op::CHUNK_INDEX, &chunk_index).is_err());
    assert!(
        claims_fit(op::MESSAGE, &[]).is_ok(),
        "no strings, nothing to check"
    );
}
