//! The fuzz seeds of the `mcap` target (`fuzz/seeds/mcap/`), and the CI equivalent of that
//! target: recordings with bytes overwritten or cut, and recordings whose messages carry extreme
//! numbers (every JSON number in turn replaced by an `i64`/`u64` bound, a huge float, a negative),
//! are refused or read, and what replay does with a recording read (the replay bridge, the cloud
//! frames, the device trajectory, `describe`) never panics.
//!
//! `MMT_WRITE_FUZZ_SEEDS=1 cargo test -p record --test fuzz_seeds -- every_seed` rewrites the seeds (written by
//! the recorder itself, so their creation time differs run to run); without it the test checks
//! that every checked-in seed reads.
#![allow(clippy::unwrap_used)]

mod common;

use std::borrow::Cow;
use std::io::Cursor;
use std::path::{Path, PathBuf};
use std::time::Duration;

use common::batches;
use node::RobotBridge;
use proptest::prelude::*;
use proptest::sample::Index;
use record::replay::{ReplayBridge, device_trajectory, telerobot_clouds};
use record::{Kind, Recorder, RecorderConfig, Recording, read_bytes};

fn seed_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fuzz/seeds/mcap")
}

/// A recording of `ticks` ticks of everything, by the recorder (zstd chunks).
fn recorded(ticks: u64) -> Vec<u8> {
    let dir = std::env::temp_dir().join(format!("record-fuzz-seeds-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{ticks}.mcap"));
    let recorder = Recorder::start(RecorderConfig {
        mcap: Some(path.clone()),
        live: None,
        kind: Kind::Demo,
        clock_origin_ns: 0,
    })
    .unwrap();
    let sink = recorder.sink();
    for batch in batches(ticks) {
        while !sink.send(batch.clone()) {
            std::thread::sleep(Duration::from_millis(1));
        }
    }
    recorder.finish().unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    bytes
}

/// `bytes` rewritten without compression or chunks (the metadata first, as the recorder writes
/// it), each message's payload passed through `edit(index, topic, payload)`.
fn rewritten(bytes: &[u8], mut edit: impl FnMut(usize, &str, &[u8]) -> Vec<u8>) -> Vec<u8> {
    let options = mcap::WriteOptions::new()
        .compression(None)
        .use_chunks(false)
        .library("mmt fuzz seeds");
    let mut w = options.create(Cursor::new(Vec::new())).unwrap();
    for record in mcap::read::LinearReader::new(bytes).unwrap() {
        if let mcap::records::Record::Metadata(m) = record.unwrap() {
            w.write_metadata(&m).unwrap();
        }
    }
    for (i, m) in mcap::MessageStream::new(bytes).unwrap().enumerate() {
        let m = m.unwrap();
        let data = edit(i, &m.channel.topic, &m.data);
        w.write(&mcap::Message {
            data: Cow::Owned(data),
            ..m
        })
        .unwrap();
    }
    w.finish().unwrap();
    w.into_inner().into_inner()
}

fn seeds() -> Vec<(&'static str, Vec<u8>)> {
    let zstd = recorded(3);
    let plain = rewritten(&zstd, |_, _, d| d.to_vec());
    // A killed run: the file ends inside a message record.
    let cut = plain[..plain.len() / 2].to_vec();
    vec![
        ("demo_zstd.mcap", zstd),
        ("demo_plain.mcap", plain),
        ("demo_cut.mcap", cut),
        ("empty.mcap", recorded(0)),
    ]
}

#[test]
fn every_seed_reads_and_is_checked_in() {
    let dir = seed_dir();
    if std::env::var_os("MMT_WRITE_FUZZ_SEEDS").is_some() {
        std::fs::create_dir_all(&dir).unwrap();
        for (name, bytes) in seeds() {
            std::fs::write(dir.join(name), bytes).unwrap();
        }
    }
    for (name, _) in seeds() {
        let bytes = std::fs::read(dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        let rec = read_bytes(&bytes, name, &[]).unwrap_or_else(|e| panic!("{e}"));
        replay(&rec);
        assert_eq!(rec.truncated.is_some(), name == "demo_cut.mcap", "{name}");
        if name.starts_with("demo") {
            assert!(!rec.telerobot_ticks.is_empty(), "{name}");
        }
        if name == "demo_zstd.mcap" || name == "demo_plain.mcap" {
            assert!(!rec.clouds.is_empty() && !rec.events.is_empty(), "{name}");
        }
    }
}

/// What replay does with a recording; checks the counts the fuzz target checks.
fn replay(rec: &Recording) {
    assert!(rec.header.is_some());
    assert!(rec.skipped <= rec.messages);
    let _ = rec.describe();
    assert!(telerobot_clouds(rec).len() <= rec.clouds.len());
    assert_eq!(device_trajectory(rec).len(), rec.operator_ticks.len());
    let mut bridge = ReplayBridge::new(rec.telerobot_ticks.clone());
    let _ = bridge.tool_m();
    for k in 0..=rec.telerobot_ticks.len() {
        let _ = bridge.step(k as i64, None);
    }
    assert!(bridge.finished());
}

fn read_and_replay(bytes: &[u8]) {
    if let Ok(rec) = read_bytes(bytes, "mutant.mcap", &[]) {
        replay(&rec);
    }
}

/// Numbers a mutation writes in place of a JSON number.
const EXTREMES: [&str; 10] = [
    "9223372036854775807",
    "-9223372036854775808",
    "18446744073709551615",
    "-1",
    "0",
    "1e308",
    "-1e308",
    "5e-324",
    "4294967296",
    "-0.0",
];

/// The `which`-th number token of a JSON text replaced by `value`.
fn replace_number(json: &[u8], which: &Index, value: &str) -> Vec<u8> {
    let mut spans = Vec::new();
    let mut i = 0;
    while i < json.len() {
        let starts = json[i].is_ascii_digit()
            || (json[i] == b'-' && json.get(i + 1).is_some_and(u8::is_ascii_digit));
        if starts && (i == 0 || !json[i - 1].is_ascii_alphanumeric()) {
            let start = i;
            i += 1;
            while i < json.len()
                && matches!(json[i], b'0'..=b'9' | b'.' | b'e' | b'E' | b'+' | b'-')
            {
                i += 1;
            }
            spans.push(start..i);
        } else {
            i += 1;
        }
    }
    if spans.is_empty() {
        return json.to_vec();
    }
    let span = spans[which.index(spans.len())].clone();
    let mut out = json[..span.start].to_vec();
    out.extend_from_slice(value.as_bytes());
    out.extend_from_slice(&json[span.end..]);
    out
}

fn plain_seed() -> Vec<u8> {
    let path = seed_dir().join("demo_plain.mcap");
    std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", Path::display(&path)))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Bytes of a seed overwritten, and the file cut.
    #[test]
    fn corrupted_seeds_never_panic(
        which in 0usize..4,
        edits in prop::collection::vec((any::<Index>(), any::<u8>()), 1..6),
        cut in prop::option::of(any::<Index>()),
    ) {
        let name = ["demo_zstd.mcap", "demo_plain.mcap", "demo_cut.mcap", "empty.mcap"][which];
        let mut bytes = std::fs::read(seed_dir().join(name)).unwrap();
        for (at, value) in edits {
            let i = at.index(bytes.len());
            bytes[i] = value;
        }
        if let Some(c) = cut {
            bytes.truncate(c.index(bytes.len() + 1));
        }
        read_and_replay(&bytes);
    }

    /// A message whose JSON carries an extreme number (times, counts, positions).
    #[test]
    fn extreme_numbers_in_messages_never_panic(
        topic in any::<prop::sample::Selector>(),
        message in any::<Index>(),
        number in any::<Index>(),
        value in 0..EXTREMES.len(),
    ) {
        let seed = plain_seed();
        // A topic first, then one of its messages: the one `/run` message is as likely a
        // target as the many ticks.
        let mut topics: Vec<(String, usize)> = Vec::new();
        for (i, m) in mcap::MessageStream::new(&seed).unwrap().enumerate() {
            let m = m.unwrap();
            if !topics.iter().any(|(t, _)| *t == m.channel.topic) {
                topics.push((m.channel.topic.clone(), i));
            }
        }
        let (topic, _) = topic.select(&topics).clone();
        let mut in_topic = 0usize;
        let wanted = message.index(4);
        let bytes = rewritten(&seed, |_, t, data| {
            let hit = t == topic && in_topic == wanted;
            if t == topic {
                in_topic += 1;
            }
            if hit && data.first() == Some(&b'{') {
                replace_number(data, &number, EXTREMES[value])
            } else {
                data.to_vec()
            }
        });
        read_and_replay(&bytes);
    }
}
