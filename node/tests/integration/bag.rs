//! Record and replay through MCAP: bit-exact round trips, the reference Python reader's view
//! of the same file, damaged files, an empty bag, and replay pacing.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Arc;
use std::time::{Duration, Instant};

use node::bag::{BagError, BagReader, BagWriter, ChannelInfo, Message, Pacer, Rate};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sha2::{Digest, Sha256};

const HEADER_MSG: &str = "builtin_interfaces/Time stamp\nstring frame_id\n";

/// The three channels of the test drive: two images and a pose.
fn channels() -> Vec<Arc<ChannelInfo>> {
    let image = format!(
        "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n\
         uint8 is_bigendian\nuint32 step\nuint8[] data\n\
         ================================================================================\n\
         MSG: std_msgs/Header\n{HEADER_MSG}"
    );
    let pose = format!(
        "std_msgs/Header header\ngeometry_msgs/Pose pose\n\
         ================================================================================\n\
         MSG: std_msgs/Header\n{HEADER_MSG}"
    );
    let channel = |topic: &str, name: &str, text: &str| {
        Arc::new(ChannelInfo {
            topic: topic.into(),
            schema_name: name.into(),
            schema_text: text.into(),
            message_encoding: "cdr".into(),
            offered_qos: String::new(),
        })
    };
    vec![
        channel("/stereo/left/image_raw", "sensor_msgs/msg/Image", &image),
        channel("/stereo/right/image_raw", "sensor_msgs/msg/Image", &image),
        channel("/pose", "geometry_msgs/msg/PoseStamped", &pose),
    ]
}

/// `count` messages on the three channels, in write order. Log times advance about 10 ms per
/// message with jitter, so some are written out of log-time order and some tie. Payload sizes
/// run from 0 bytes to 1 MiB (both ends included), half random bytes, half compressible.
fn drive(seed: u64, count: usize, max_size: usize) -> Vec<Message> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let channels = channels();
    (0..count)
        .map(|i| {
            let size = match i {
                0 => 0,
                1 => max_size,
                _ if rng.random_bool(0.1) => rng.random_range(0..=max_size),
                _ => rng.random_range(0..=max_size / 16),
            };
            let payload: Vec<u8> = if rng.random_bool(0.5) {
                (0..size).map(|_| rng.random()).collect()
            } else {
                (0..size).map(|k| (k / 7 % 5) as u8).collect()
            };
            let log_time_ns = 1_700_000_000_000_000_000 + i as u64 * 10_000_000
                - rng.random_range(0..3u64) * 10_000_000;
            Message {
                channel: Arc::clone(&channels[rng.random_range(0..3)]),
                log_time_ns,
                publish_time_ns: log_time_ns - rng.random_range(0..1_000_000),
                sequence: i as u32,
                payload,
            }
        })
        .collect()
}

/// Writes `messages` to `path`.
fn write_bag(path: &Path, messages: &[Message]) {
    let mut writer = BagWriter::create(path).unwrap();
    for m in messages {
        writer
            .write(
                &m.channel,
                m.log_time_ns,
                m.publish_time_ns,
                m.sequence,
                &m.payload,
            )
            .unwrap();
    }
    writer.finish().unwrap();
}

/// A fresh path in the test scratch directory.
fn scratch(name: &str) -> PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("bag-test-{name}.mcap"))
}

/// `messages` stably sorted by log time: the order a reader must give them back.
fn in_log_time_order(messages: &[Message]) -> Vec<Message> {
    let mut sorted = messages.to_vec();
    sorted.sort_by_key(|m| m.log_time_ns);
    sorted
}

/// Opens `path` and reads every message, or the first error.
fn read_all(path: &Path) -> Result<Vec<Message>, BagError> {
    BagReader::open(path)?.messages().collect()
}

#[test]
fn round_trip_is_bit_exact_in_log_time_order() {
    let path = scratch("round-trip");
    let written = drive(1, 300, 1 << 20);
    write_bag(&path, &written);

    let bag = BagReader::open(&path).unwrap();
    let read: Vec<Message> = bag.messages().collect::<Result<_, _>>().unwrap();
    let expected = in_log_time_order(&written);
    assert_ne!(expected, written, "the drive must have out-of-order writes");
    assert_eq!(read.len(), 300);
    let chunks = chunk_indexes(&std::fs::read(&path).unwrap());
    let overlapping = chunks
        .windows(2)
        .filter(|w| w[1].message_start_time <= w[0].message_end_time)
        .count();
    assert!(
        overlapping > 0,
        "some chunks must overlap in time to test the merge"
    );
    for (i, (r, e)) in read.iter().zip(&expected).enumerate() {
        assert_eq!(r, e, "message {i} differs");
    }
    assert_eq!(read.iter().map(|m| m.payload.len()).min(), Some(0));
    assert_eq!(read.iter().map(|m| m.payload.len()).max(), Some(1 << 20));

    assert_eq!(bag.message_count(), 300);
    let first = expected.first().unwrap().log_time_ns;
    let last = expected.last().unwrap().log_time_ns;
    assert_eq!(bag.time_range(), Some((first, last)));
    let summary: Vec<(ChannelInfo, u64)> = bag
        .channels()
        .iter()
        .map(|c| ((*c.info).clone(), c.message_count))
        .collect();
    let mut expected_channels: Vec<(ChannelInfo, u64)> = channels()
        .iter()
        .map(|c| {
            let n = written.iter().filter(|m| m.channel == *c).count() as u64;
            ((**c).clone(), n)
        })
        .filter(|(_, n)| *n > 0)
        .collect();
    let mut summary_sorted = summary.clone();
    summary_sorted.sort_by(|a, b| a.0.topic.cmp(&b.0.topic));
    expected_channels.sort_by(|a, b| a.0.topic.cmp(&b.0.topic));
    assert_eq!(summary_sorted, expected_channels);
    assert_eq!(summary.len(), 3);
    std::fs::remove_file(&path).unwrap();
}

#[test]
fn equal_log_times_keep_write_order_across_chunks() {
    // Forty 100 kB messages at one log time fill several chunks; the last chunk also holds
    // earlier messages, so it starts earliest and is read first.
    let path = scratch("ties");
    let channel = Arc::clone(&channels()[0]);
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let written: Vec<Message> = (0..44u32)
        .map(|i| Message {
            channel: Arc::clone(&channel),
            log_time_ns: if i < 40 { 1_000 } else { 500 },
            publish_time_ns: 0,
            sequence: i,
            payload: (0..100_000).map(|_| rng.random()).collect(),
        })
        .collect();
    write_bag(&path, &written);
    let chunks = chunk_indexes(&std::fs::read(&path).unwrap());
    assert!(chunks.len() >= 3);
    assert_eq!(chunks.last().unwrap().message_start_time, 500);
    let order: Vec<u32> = read_all(&path)
        .unwrap()
        .iter()
        .map(|m| m.sequence)
        .collect();
    let expected: Vec<u32> = (40..44).chain(0..40).collect();
    assert_eq!(order, expected);
    std::fs::remove_file(&path).unwrap();
}

/// One message as the Python check reports it: topic, times, sequence, payload SHA-256.
type Row = (String, u64, u64, u32, String);

fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// Runs `scripts/mcap_check.py` on `path` and parses its JSON.
fn python_check(path: &Path) -> serde_json::Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/mcap_check.py");
    let output = Command::new("python3")
        .arg(&script)
        .arg(path)
        .output()
        .expect("python3 must be installed to run scripts/mcap_check.py");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        output.status.success(),
        "scripts/mcap_check.py failed (if the Python `mcap` package is missing: \
         pip install -r scripts/requirements.txt):\n{stderr}"
    );
    serde_json::from_slice(&output.stdout).expect("mcap_check.py prints JSON")
}

#[test]
fn python_mcap_reads_the_same_channels_counts_and_payloads() {
    let path = scratch("python");
    let written = drive(2, 200, 1 << 20);
    write_bag(&path, &written);
    let report = python_check(&path);

    assert_eq!(report["profile"], "ros2");
    assert_eq!(report["statistics_message_count"], 200);
    let mut seen_channels = 0;
    for c in report["channels"].as_array().unwrap() {
        let topic = c["topic"].as_str().unwrap();
        let info = channels().into_iter().find(|i| i.topic == topic).unwrap();
        let mine: Vec<&Message> = written.iter().filter(|m| m.channel == info).collect();
        assert_eq!(c["message_encoding"], "cdr");
        assert_eq!(
            c["metadata"],
            serde_json::json!({"offered_qos_profiles": ""})
        );
        assert_eq!(c["schema_name"], info.schema_name.as_str());
        assert_eq!(c["schema_encoding"], "ros2msg");
        assert_eq!(c["schema_text"], info.schema_text.as_str());
        assert_eq!(c["message_count"], mine.len() as u64);
        let first = mine.iter().map(|m| m.log_time_ns).min().unwrap();
        let last = mine.iter().map(|m| m.log_time_ns).max().unwrap();
        assert_eq!(c["first_log_time"], first);
        assert_eq!(c["last_log_time"], last);
        seen_channels += 1;
    }
    assert_eq!(seen_channels, 3);

    let mut theirs: Vec<Row> = report["messages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| {
            (
                m["topic"].as_str().unwrap().to_string(),
                m["log_time"].as_u64().unwrap(),
                m["publish_time"].as_u64().unwrap(),
                m["sequence"].as_u64().unwrap() as u32,
                m["sha256"].as_str().unwrap().to_string(),
            )
        })
        .collect();
    let mut mine: Vec<Row> = written
        .iter()
        .map(|m| {
            (
                m.channel.topic.clone(),
                m.log_time_ns,
                m.publish_time_ns,
                m.sequence,
                sha256_hex(&m.payload),
            )
        })
        .collect();
    let log_times: Vec<u64> = theirs.iter().map(|r| r.1).collect();
    assert!(log_times.windows(2).all(|w| w[0] <= w[1]), "log-time order");
    theirs.sort();
    mine.sort();
    assert_eq!(theirs, mine);
    std::fs::remove_file(&path).unwrap();
}

#[test]
fn empty_bag_is_valid() {
    let path = scratch("empty");
    BagWriter::create(&path).unwrap().finish().unwrap();
    let bag = BagReader::open(&path).unwrap();
    assert_eq!(bag.message_count(), 0);
    assert_eq!(bag.time_range(), None);
    assert!(bag.channels().is_empty());
    assert_eq!(bag.messages().count(), 0);
    let report = python_check(&path);
    assert_eq!(report["channels"].as_array().unwrap().len(), 0);
    assert_eq!(report["messages"].as_array().unwrap().len(), 0);
    std::fs::remove_file(&path).unwrap();
}

/// A small bag of several chunks, its bytes and its messages.
fn small_bag(name: &str) -> (PathBuf, Vec<u8>, Vec<Message>) {
    let path = scratch(name);
    let written = drive(3, 320, 128 << 10);
    write_bag(&path, &written);
    let bytes = std::fs::read(&path).unwrap();
    (path, bytes, in_log_time_order(&written))
}

#[test]
fn truncated_files_give_errors() {
    let (path, bytes, _) = small_bag("truncated-source");
    let cut_path = scratch("truncated");
    let n = bytes.len();
    let cuts = [
        0,
        1,
        7,
        8,
        9,
        100,
        n / 3,
        n / 2,
        n - 100,
        n - 38,
        n - 37,
        n - 9,
        n - 1,
    ];
    for cut in cuts {
        std::fs::write(&cut_path, &bytes[..cut]).unwrap();
        let result = read_all(&cut_path);
        assert!(result.is_err(), "cut at {cut} of {n} bytes was accepted");
        let message = result.unwrap_err().to_string();
        assert!(message.contains("bag-test-truncated"), "{message}");
    }
    std::fs::remove_file(&path).unwrap();
    std::fs::remove_file(&cut_path).unwrap();
}

/// A recording cut off at any byte (a recorder killed with -9) gives back exactly the
/// messages of its complete chunks, and says how many bytes it kept and ignored; a damaged
/// chunk ends the recovered part there.
#[test]
fn cut_off_recordings_give_back_their_complete_chunks() {
    // Twelve chunks of 25 messages, closed by `flush` as the recorder does every second.
    let path = scratch("recover-source");
    let written = drive(9, 300, 4096);
    let mut writer = BagWriter::create(&path).unwrap();
    for (i, m) in written.iter().enumerate() {
        let (ch, t, p, q) = (&m.channel, m.log_time_ns, m.publish_time_ns, m.sequence);
        writer.write(ch, t, p, q, &m.payload).unwrap();
        if i % 25 == 24 {
            writer.flush().unwrap();
        }
    }
    writer.finish().unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let mut chunk_ends: Vec<u64> = chunk_indexes(&bytes)
        .iter()
        .map(|c| c.chunk_start_offset + c.chunk_length)
        .collect();
    chunk_ends.sort_unstable();
    assert_eq!(chunk_ends.len(), 12);
    let mut cuts: Vec<u64> = chunk_ends
        .iter()
        .flat_map(|&e| [e - 1, e, e + 1])
        .chain([8, 9, 100, bytes.len() as u64 - 1])
        .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    cuts.extend((0..60).map(|_| rng.random_range(8..bytes.len() as u64)));
    let cut_path = scratch("recover-cut");
    for cut in cuts {
        std::fs::write(&cut_path, &bytes[..cut as usize]).unwrap();
        assert!(
            BagReader::open(&cut_path).is_err(),
            "cut at {cut} is not finished"
        );
        let (bag, recovery) = BagReader::open_or_recover(&cut_path).unwrap();
        let recovery = recovery.expect("a cut-off file is recovered");
        let complete = chunk_ends.iter().filter(|&&e| e <= cut).count();
        let expected = in_log_time_order(&written[..complete * 25]);
        assert_eq!(recovery.messages, expected.len() as u64, "cut at {cut}");
        assert_eq!(recovery.chunks, complete as u64, "cut at {cut}");
        assert_eq!(recovery.readable_bytes + recovery.ignored_bytes, cut);
        let last_end = chunk_ends
            .get(complete.wrapping_sub(1))
            .copied()
            .unwrap_or(8);
        assert!(
            recovery.readable_bytes >= last_end,
            "cut at {cut}: {recovery}"
        );
        assert_eq!(bag.message_count(), expected.len() as u64);
        let read: Vec<Message> = bag.messages().map(Result::unwrap).collect();
        assert_eq!(read, expected, "cut at {cut}");
    }
    // A damaged sixth chunk: the five before it are recovered, the rest ignored.
    let mut chunks = chunk_indexes(&bytes);
    chunks.sort_by_key(|c| c.chunk_start_offset);
    let sixth = chunks[5].chunk_start_offset;
    let mut damaged = bytes[..chunk_ends[9] as usize].to_vec();
    damaged[(sixth + chunks[5].chunk_length / 2) as usize] ^= 0x55;
    std::fs::write(&cut_path, &damaged).unwrap();
    let (bag, recovery) = BagReader::recover(&cut_path).unwrap();
    assert_eq!(recovery.messages, 125, "{recovery}");
    assert_eq!(recovery.readable_bytes, sixth, "{recovery}");
    assert!(
        recovery
            .stopped
            .starts_with(&format!("chunk at byte {sixth}: ")),
        "{recovery}"
    );
    assert_eq!(bag.messages().count(), 125);
    // Not MCAP at all: still an error naming the file.
    std::fs::write(&cut_path, b"not an mcap file").unwrap();
    let err = BagReader::open_or_recover(&cut_path)
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("bag-test-recover-cut"), "{err}");
    std::fs::remove_file(&path).unwrap();
    std::fs::remove_file(&cut_path).unwrap();
}

/// The chunk indexes of the MCAP file `bytes`, as the `mcap` crate reads them.
fn chunk_indexes(bytes: &[u8]) -> Vec<mcap::records::ChunkIndex> {
    mcap::Summary::read(bytes).unwrap().unwrap().chunk_indexes
}

/// Byte ranges `[start, end)` that CRCs or checks cover: the start magic, the chunk records
/// and everything from the summary to the end.
fn checked_ranges(bytes: &[u8]) -> Vec<(usize, usize)> {
    let footer = &bytes[bytes.len() - 37..];
    let summary_start = u64::from_le_bytes(footer[9..17].try_into().unwrap()) as usize;
    let chunks = chunk_indexes(bytes);
    assert!(chunks.len() >= 3, "the small bag must have several chunks");
    let mut ranges: Vec<(usize, usize)> = chunks
        .iter()
        .map(|c| {
            let start = c.chunk_start_offset as usize;
            (start, start + c.chunk_length as usize)
        })
        .collect();
    ranges.push((0, 8));
    ranges.push((summary_start, bytes.len()));
    ranges
}

#[test]
fn byte_flips_give_errors_where_checked_and_never_panic() {
    let (path, bytes, expected) = small_bag("flip-source");
    let checked = checked_ranges(&bytes);
    let flip_path = scratch("flipped");
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let (mut errors, mut same, mut different) = (0, 0, 0);
    for _ in 0..250 {
        let at = rng.random_range(0..bytes.len());
        let mut damaged = bytes.clone();
        damaged[at] ^= rng.random_range(1..=255u8);
        std::fs::write(&flip_path, &damaged).unwrap();
        let is_checked = checked.iter().any(|&(s, e)| (s..e).contains(&at));
        match read_all(&flip_path) {
            Err(_) => errors += 1,
            Ok(read) => {
                assert!(
                    !is_checked,
                    "flip at byte {at} (checked region) went unnoticed"
                );
                if read == expected {
                    same += 1;
                } else {
                    different += 1;
                }
            }
        }
    }
    eprintln!("250 flips: {errors} errors, {same} unchanged reads, {different} altered reads");
    assert!(errors >= 200, "{errors} errors");
    assert_eq!(different, 0, "CRCs cover every byte that reaches a message");
    std::fs::remove_file(&path).unwrap();
    std::fs::remove_file(&flip_path).unwrap();
}

/// Found by the `mcap` fuzz target: a chunk whose compression name claims 2.4 GB made the
/// `mcap` crate reserve that much for a 2.7 kB file. The reader refuses it before parsing.
#[test]
fn a_chunk_string_longer_than_its_chunk_is_refused_unread() {
    let (path, mut bytes, _) = small_bag("long-name-source");
    let start = chunk_indexes(&bytes)[0].chunk_start_offset as usize;
    // Opcode, record length, start and end times, uncompressed size and CRC: then the name.
    let name_len_at = start + 1 + 8 + 8 + 8 + 8 + 4;
    bytes[name_len_at..name_len_at + 4].copy_from_slice(&0x9000_0000u32.to_le_bytes());
    let damaged = scratch("long-name");
    std::fs::write(&damaged, &bytes).unwrap();
    let message = read_all(&damaged).unwrap_err().to_string();
    assert!(
        message.contains("compression name is longer than the chunk"),
        "{message}"
    );
    std::fs::remove_file(&path).unwrap();
    std::fs::remove_file(&damaged).unwrap();
}

#[test]
fn huge_lengths_and_junk_give_errors_not_aborts() {
    let (path, bytes, _) = small_bag("junk-source");
    let junk_path = scratch("junk");
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    // Eight 0xff bytes, read as a length field, ask for 2^64 - 1 bytes: never allocated.
    let checked = checked_ranges(&bytes);
    for _ in 0..150 {
        let (start, end) = checked[rng.random_range(0..checked.len())];
        let at = rng.random_range(start..=end - 8);
        let mut damaged = bytes.clone();
        damaged[at..at + 8].fill(0xff);
        std::fs::write(&junk_path, &damaged).unwrap();
        assert!(read_all(&junk_path).is_err(), "0xff x 8 at byte {at}");
    }
    // Random bytes, bare or between a real start and a real end of an MCAP file.
    let junk: Vec<u8> = (0..20_000).map(|_| rng.random()).collect();
    let framed = [&bytes[..200], &junk[..], &bytes[bytes.len() - 37..]].concat();
    for file in [junk, framed] {
        std::fs::write(&junk_path, &file).unwrap();
        assert!(read_all(&junk_path).is_err());
    }
    std::fs::remove_file(&path).unwrap();
    std::fs::remove_file(&junk_path).unwrap();
}

#[test]
fn pacing_keeps_scales_or_drops_recorded_gaps() {
    let start = Instant::now();
    let first = 5_000_000_000;
    let log_times = [first, first + 10_000_000, first + 35_000_000];
    let ms = Duration::from_millis;
    let delays = |rate, now| {
        let pacer = Pacer::new(rate, start, first).unwrap();
        log_times.map(|t| pacer.delay(t, now))
    };
    assert_eq!(delays(Rate::Recorded, start), [ms(0), ms(10), ms(35)]);
    assert_eq!(
        delays(Rate::Factor(2.0), start),
        [ms(0), ms(5), Duration::from_micros(17_500)]
    );
    assert_eq!(delays(Rate::Factor(0.5), start), [ms(0), ms(20), ms(70)]);
    assert_eq!(delays(Rate::AsFastAsPossible, start), [Duration::ZERO; 3]);
    // Time already spent counts against the wait; late messages go out at once.
    assert_eq!(
        delays(Rate::Recorded, start + ms(12)),
        [ms(0), ms(0), ms(23)]
    );
    // A message logged before the first one is due immediately.
    let pacer = Pacer::new(Rate::Recorded, start, first).unwrap();
    assert_eq!(pacer.delay(first - 1_000, start), Duration::ZERO);
    // As fast as possible never sleeps, even for a message logged an hour later.
    Pacer::new(Rate::AsFastAsPossible, Instant::now(), first)
        .unwrap()
        .wait(first + 3_600_000_000_000);
    // Extreme factors neither panic nor overflow.
    assert_eq!(Rate::Factor(1e-300).due_after(1), Duration::MAX);
    assert_eq!(Rate::Factor(1e300).due_after(u64::MAX), Duration::ZERO);
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            Pacer::new(Rate::Factor(bad), start, first),
            Err(BagError::BadRate(_))
        ));
    }
}
