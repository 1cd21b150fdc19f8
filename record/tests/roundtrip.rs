//! A recording read back gives the same samples; a file cut short (truncated, or its writer
//! killed) is read up to its last complete chunk; files of another kind or version are refused
//! saying what they are.
#![allow(clippy::unwrap_used)]

mod common;

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Duration;

use common::*;
use record::schema::{FORMAT_VERSION, METADATA_NAME, OperatorTick, topic};
use record::{
    Kind, Message, ReadError, RecordError, Recorder, RecorderConfig, Side, partial_path, read,
};

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("record-tests-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn record(path: &std::path::Path, ticks: u64) -> record::RecorderReport {
    let recorder = Recorder::start(RecorderConfig {
        mcap: Some(path.to_owned()),
        live: None,
        kind: Kind::Demo,
        clock_origin_ns: 0,
    })
    .unwrap();
    let sink = recorder.sink();
    for batch in batches(ticks) {
        // A full queue drops (counted): wait for room instead, the test wants everything.
        let mut batch = Some(batch);
        while let Some(b) = batch.take() {
            let n = b.len();
            if !sink.send(b.clone()) {
                std::thread::sleep(Duration::from_millis(1));
                batch = Some(b);
                assert!(n > 0);
            }
        }
    }
    recorder.finish().unwrap()
}

#[test]
fn a_recording_read_back_gives_the_same_samples() {
    let path = temp("roundtrip.mcap");
    let ticks = 3000;
    let report = record(&path, ticks);
    assert!(report.bytes > 0);
    let rec = read(&path, &[]).unwrap();
    assert!(rec.truncated.is_none(), "{:?}", rec.truncated);
    assert_eq!(rec.kind(), Some(Kind::Demo));
    assert_eq!(rec.operator_ticks.len() as u64, ticks);
    for (k, t) in rec.operator_ticks.iter().enumerate() {
        assert_eq!(*t, operator_tick(k as u64), "operator tick {k}");
    }
    for (k, t) in rec.telerobot_ticks.iter().enumerate() {
        assert_eq!(*t, telerobot_tick(k as u64), "telerobot tick {k}");
    }
    for (k, m) in rec.measurements.iter().enumerate() {
        assert_eq!(*m, measurement(k as u64), "measurement {k}");
    }
    assert_eq!(rec.contacts.len() as u64, ticks);
    assert!(
        rec.contacts
            .iter()
            .enumerate()
            .all(|(k, (s, c))| *s == Side::Telerobot && *c == contact(k as u64))
    );
    let params: Vec<_> = (0..ticks).step_by(100).map(parameters).collect();
    assert_eq!(
        rec.parameters.iter().map(|(_, p)| *p).collect::<Vec<_>>(),
        params
    );
    let clouds: Vec<_> = (0..ticks).step_by(33).map(cloud).collect();
    assert_eq!(rec.clouds.len(), clouds.len());
    for ((_, got), want) in rec.clouds.iter().zip(&clouds) {
        assert_eq!(got.timestamp_ns, want.timestamp_ns);
        assert_eq!(got.points, want.points);
    }
    assert_eq!(rec.run(Side::Operator), Some(&run_start(Side::Operator)));
    let end = rec.end(Side::Operator).unwrap();
    assert_eq!(end.final_offset_ns, Some(-5));
    assert_eq!(end.nodes, Some(metrics::NodeInfo::default()));
    assert_eq!(rec.events.len() as u64, ticks.div_ceil(100));
}

/// Before: the file was created before the live view was bound, so a port already taken left
/// an empty `FILE.mcap.partial` behind the error.
#[test]
fn a_live_port_that_is_taken_leaves_no_file_behind() {
    let path = temp("port-taken.mcap");
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let e = Recorder::start(RecorderConfig {
        mcap: Some(path.clone()),
        live: Some(taken.local_addr().unwrap()),
        kind: Kind::Operator,
        clock_origin_ns: 0,
    })
    .err()
    .unwrap();
    assert!(
        e.to_string()
            .contains(&taken.local_addr().unwrap().to_string()),
        "{e}"
    );
    assert!(!partial_path(&path).exists() && !path.exists(), "{e}");
}

/// Before: JSON has no NaN; a tick holding one (a faulty device's reading, which the safety
/// layer exists to catch) was written as `null` and refused on reading, and the recording with
/// it. It reads back, the NaN (or infinity: its sign is lost) as NaN, and the ticks after it.
#[test]
fn a_tick_holding_a_nan_reads_back_with_the_ticks_after_it() {
    let path = temp("nan.mcap");
    let recorder = Recorder::start(RecorderConfig {
        mcap: Some(path.clone()),
        live: None,
        kind: Kind::Operator,
        clock_origin_ns: 0,
    })
    .unwrap();
    let mut batch = vec![record::Timed {
        t_ns: 0,
        message: Message::Run(Box::new(run_start(Side::Operator))),
    }];
    for k in 0..50 {
        let mut tick = operator_tick(k);
        if k == 10 {
            tick.device_position_m = [f64::NAN, 0.0, f64::INFINITY];
        }
        batch.push(record::Timed {
            t_ns: k as i64 * 1_000_000,
            message: Message::OperatorTick(Box::new(tick)),
        });
    }
    assert!(recorder.sink().send(batch));
    recorder.finish().unwrap();
    let rec = read(&path, &[]).unwrap();
    assert_eq!(rec.operator_ticks.len(), 50, "{}", rec.describe());
    let bad = &rec.operator_ticks[10];
    assert!(bad.device_position_m[0].is_nan() && bad.device_position_m[2].is_nan());
    assert_eq!(rec.operator_ticks[11], operator_tick(11));
}

/// The same file through the `mcap` crate alone: every JSON message parses as its schema's
/// type, every channel has a schema, and the scene was drawn at display rate.
#[test]
fn the_mcap_crate_reads_every_channel_with_its_schema() {
    let path = temp("plain.mcap");
    record(&path, 2000);
    let bytes = std::fs::read(&path).unwrap();
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    let topics: BTreeMap<String, (String, String)> = summary
        .channels
        .values()
        .map(|c| {
            let schema = c.schema.as_ref().unwrap();
            (
                c.topic.clone(),
                (schema.name.clone(), schema.encoding.clone()),
            )
        })
        .collect();
    assert_eq!(topics[topic::SCENE].0, "foxglove.SceneUpdate");
    assert_eq!(topics[topic::TELEROBOT_CLOUD].0, "foxglove.PointCloud");
    assert_eq!(topics[topic::EVENTS].0, "foxglove.Log");
    assert_eq!(topics[topic::OPERATOR_TICK].1, "jsonschema");
    let compressed = summary
        .chunk_indexes
        .iter()
        .all(|c| c.compression == "zstd");
    assert!(compressed && summary.chunk_indexes.len() > 1);
    let mut ticks = Vec::new();
    let mut scenes = 0;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        match m.channel.topic.as_str() {
            topic::OPERATOR_TICK => {
                ticks.push(serde_json::from_slice::<OperatorTick>(&m.data).unwrap())
            }
            topic::SCENE => scenes += 1,
            _ => {}
        }
    }
    assert_eq!(ticks, (0..2000).map(operator_tick).collect::<Vec<_>>());
    // 2 s at 50 scenes a second.
    assert!((99..=101).contains(&scenes), "{scenes} scenes");
}

/// Cut anywhere, a file gives back a prefix of its messages: all those of its complete chunks
/// (and those of the cut chunk that were decompressed whole before the cut, if any).
#[test]
fn the_file_is_checked_at_start_and_renamed_into_place_when_finished() {
    let path = temp("atomic.mcap");
    let _ = std::fs::remove_file(&path);
    let start = |mcap: PathBuf| {
        Recorder::start(RecorderConfig {
            mcap: Some(mcap),
            live: None,
            kind: Kind::Operator,
            clock_origin_ns: 0,
        })
    };
    let recorder = start(path.clone()).unwrap();
    // Created (with its header) at start; the final name only once finished.
    assert!(partial_path(&path).exists());
    assert!(!path.exists());
    recorder
        .sink()
        .send_one(0, Message::OperatorTick(Box::new(operator_tick(0))));
    let report = recorder.finish().unwrap();
    assert!(!partial_path(&path).exists());
    assert_eq!(report.bytes, std::fs::metadata(&path).unwrap().len());
    assert_eq!(read(&path, &[]).unwrap().operator_ticks, [operator_tick(0)]);
    // Refused before any run: a directory, a directory that does not exist.
    for bad in [temp(""), temp("no-such-dir").join("run.mcap")] {
        let Err(e) = start(bad.clone()) else {
            panic!("{} accepted", bad.display());
        };
        assert!(matches!(e, RecordError::File { .. }), "{e}");
        assert!(e.to_string().contains(&bad.display().to_string()), "{e}");
    }
}

#[test]
fn a_truncated_file_is_read_up_to_its_last_complete_chunk() {
    let path = temp("whole.mcap");
    record(&path, 6000);
    let bytes = std::fs::read(&path).unwrap();
    let whole = read(&path, &[topic::OPERATOR_TICK]).unwrap();
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    assert!(summary.chunk_indexes.len() >= 4);
    for (i, cut_at) in [0.3, 0.55, 0.8, 0.97].into_iter().enumerate() {
        let cut = (bytes.len() as f64 * cut_at) as usize;
        // Messages in chunks that end before the cut.
        let complete: u64 = summary
            .chunk_indexes
            .iter()
            .filter(|c| (c.chunk_start_offset + c.chunk_length) as usize <= cut)
            .map(|c| {
                summary
                    .read_message_indexes(&bytes, c)
                    .unwrap()
                    .iter()
                    .filter(|(ch, _)| ch.topic == topic::OPERATOR_TICK)
                    .map(|(_, e)| e.len() as u64)
                    .sum::<u64>()
            })
            .sum();
        let short = temp(&format!("cut{i}.mcap"));
        std::fs::write(&short, &bytes[..cut]).unwrap();
        let rec = read(&short, &[topic::OPERATOR_TICK]).unwrap();
        assert!(rec.truncated.is_some(), "cut at {cut}: not noticed");
        let n = rec.operator_ticks.len();
        assert!(n as u64 >= complete, "cut at {cut}: {n} of {complete}");
        assert!(n < whole.operator_ticks.len(), "cut at {cut}: {n}");
        assert_eq!(
            rec.operator_ticks[..],
            whole.operator_ticks[..n],
            "cut at {cut}"
        );
    }
}

/// Before: `read` loaded the whole file and then parsed it (167 MB of memory for a 107 MB
/// recording); it now reads a prefix for the header and streams the rest. A file many times
/// that prefix reads exactly as its bytes do, whole and cut short.
#[test]
fn a_file_is_streamed_and_reads_as_its_bytes_do() {
    let path = temp("streamed.mcap");
    record(&path, 40_000);
    let bytes = std::fs::read(&path).unwrap();
    assert!(bytes.len() > 3 << 20, "only {} bytes", bytes.len());
    for cut in [bytes.len(), bytes.len() * 2 / 3] {
        let file = temp("streamed-cut.mcap");
        std::fs::write(&file, &bytes[..cut]).unwrap();
        let streamed = read(&file, &[]).unwrap();
        let held = record::read_bytes(&bytes[..cut], "held", &[]).unwrap();
        assert_eq!(streamed.messages, held.messages, "cut at {cut}");
        assert!(streamed.messages > 40_000, "{}", streamed.messages);
        assert_eq!(streamed.operator_ticks, held.operator_ticks, "cut at {cut}");
        assert_eq!(streamed.truncated.is_some(), cut < bytes.len());
    }
}

/// The child of [`a_killed_recorder_leaves_a_readable_file`]: records until it is killed.
#[test]
#[ignore = "run by a_killed_recorder_leaves_a_readable_file"]
fn recorder_child_until_killed() {
    let Some(path) = std::env::var_os("RECORD_CHILD_FILE") else {
        return;
    };
    let recorder = Recorder::start(RecorderConfig {
        mcap: Some(path.into()),
        live: None,
        kind: Kind::Operator,
        clock_origin_ns: 0,
    })
    .unwrap();
    let sink = recorder.sink();
    sink.send_one(0, Message::Run(Box::new(run_start(Side::Operator))));
    for k in 0.. {
        let t = k as i64 * 1_000_000;
        sink.send_one(t, Message::OperatorTick(Box::new(operator_tick(k))));
        if k % 1000 == 0 {
            println!("ticks {k}");
        }
        std::thread::sleep(Duration::from_micros(200));
    }
    drop(recorder);
}

#[test]
fn a_killed_recorder_leaves_a_readable_file() {
    let path = temp("killed.mcap");
    let _ = std::fs::remove_file(&path);
    let mut child = std::process::Command::new(std::env::current_exe().unwrap())
        .args([
            "--ignored",
            "--exact",
            "recorder_child_until_killed",
            "--nocapture",
        ])
        .env("RECORD_CHILD_FILE", &path)
        .stdout(std::process::Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(3500));
    child.kill().unwrap(); // SIGKILL: no destructor runs, no summary is written
    child.wait().unwrap();
    // Never finished, so never renamed: what there is lies in FILE.partial.
    assert!(!path.exists(), "{} exists", path.display());
    let rec = read(&partial_path(&path), &[]).unwrap();
    assert!(rec.truncated.is_some() || rec.operator_ticks.is_empty());
    // At least two flushes (one a second) made it to the file, as a prefix of what was sent.
    assert!(
        rec.operator_ticks.len() > 500,
        "{}",
        rec.operator_ticks.len()
    );
    for (k, t) in rec.operator_ticks.iter().enumerate() {
        assert_eq!(*t, operator_tick(k as u64));
    }
    assert_eq!(rec.kind(), Some(Kind::Operator));
    assert!(rec.end(Side::Operator).is_none());
}

fn write_raw(path: &std::path::Path, metadata: Option<BTreeMap<String, String>>) {
    let mut w = mcap::WriteOptions::new()
        .library("someone else")
        .profile("ros2")
        .create(std::io::BufWriter::new(
            std::fs::File::create(path).unwrap(),
        ))
        .unwrap();
    if let Some(metadata) = metadata {
        w.write_metadata(&mcap::records::Metadata {
            name: METADATA_NAME.into(),
            metadata,
        })
        .unwrap();
    }
    w.finish().unwrap();
}

#[test]
fn recordings_of_another_kind_or_version_are_refused_saying_what_they_are() {
    let path = temp("kind.mcap");
    record(&path, 100);
    let rec = read(&path, &[]).unwrap();
    let e = rec
        .require(
            &[Kind::Telerobot],
            "mmt estimate --from needs a telerobot recording",
        )
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("a demo recording (exp3) of scene exp1, 0.1 s"),
        "{e}"
    );
    assert!(e.contains("needs a telerobot recording"), "{e}");
    rec.require(&[Kind::Demo, Kind::Operator], "").unwrap();
    // Before: read without its tick topics it said "0.0 s"; the run end has the count.
    let runs_only = read(&path, &[topic::RUN, topic::RUN_END]).unwrap();
    assert!(
        runs_only.describe().contains("of scene exp1, 0.1 s"),
        "{}",
        runs_only.describe()
    );
    let start_only = read(&path, &[topic::RUN]).unwrap();
    assert!(
        !start_only.describe().contains(" s,"),
        "{}",
        start_only.describe()
    );

    let other = temp("other.mcap");
    write_raw(&other, None);
    let e = read(&other, &[]).unwrap_err();
    assert!(matches!(e, ReadError::NotOurs { .. }), "{e}");
    assert!(
        e.to_string()
            .contains("written by 'someone else', profile 'ros2'"),
        "{e}"
    );

    let newer = temp("newer.mcap");
    let meta = BTreeMap::from([
        (
            "format_version".to_owned(),
            (FORMAT_VERSION + 1).to_string(),
        ),
        ("kind".to_owned(), "operator".to_owned()),
        ("mmt_version".to_owned(), "9.9.9".to_owned()),
    ]);
    write_raw(&newer, Some(meta));
    let e = read(&newer, &[]).unwrap_err().to_string();
    assert!(
        e.contains(&format!(
            "an mmt operator recording of format version {} (written by mmt 9.9.9)",
            FORMAT_VERSION + 1
        )),
        "{e}"
    );

    // Before: an unknown kind in a file of this version was reported as another version.
    let unknown = temp("unknown-kind.mcap");
    let meta = BTreeMap::from([
        ("format_version".to_owned(), FORMAT_VERSION.to_string()),
        ("kind".to_owned(), "bag".to_owned()),
        ("mmt_version".to_owned(), "9.9.9".to_owned()),
    ]);
    write_raw(&unknown, Some(meta));
    let e = read(&unknown, &[]).unwrap_err();
    assert!(matches!(e, ReadError::UnknownKind { .. }), "{e}");
    assert!(e.to_string().contains("unknown kind 'bag'"), "{e}");

    let csv = temp("not.mcap");
    std::fs::write(&csv, "t_s,x,y,z\n0,0,0,0\n").unwrap();
    let e = read(&csv, &[]).unwrap_err();
    assert!(matches!(e, ReadError::NotMcap { .. }), "{e}");
    let e = read(&temp("missing.mcap"), &[]).unwrap_err();
    assert!(matches!(e, ReadError::Io { .. }), "{e}");
}
