//! Reading a recording back: checks what the file is (an MCAP file, an mmt recording, of this
//! format version, of a kind the caller can use — refused otherwise, saying what it is), then
//! reads its messages in file order into typed lists.
//!
//! A file cut short (a killed run: no summary, maybe half a chunk at the end) is read up to its
//! last complete chunk; [`Recording::truncated`] says where and why reading stopped.

use std::io::Read;
use std::path::{Path, PathBuf};

use mcap::read::Options;
use prost::Message as _;

use crate::encode::points_of;
use crate::schema::{
    CloudRec, ContactRec, EventRec, FORMAT_VERSION, Header, Kind, Level, LinkRec, METADATA_NAME,
    MeasurementRec, OperatorTick, ParametersRec, RunEnd, RunStart, Side, StateSyncRec,
    TelerobotTick, topic,
};
use crate::stream::Messages;

/// Why a file was refused.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// The file could not be read.
    #[error("cannot read {path}: {error}")]
    Io {
        /// The file.
        path: String,
        /// The OS error.
        error: std::io::Error,
    },
    /// Not an MCAP file.
    #[error("{path} is not an MCAP file ({reason})")]
    NotMcap {
        /// The file.
        path: String,
        /// What was found.
        reason: String,
    },
    /// An MCAP file, but not one of ours.
    #[error(
        "{path} is an MCAP file but not an mmt recording (no '{METADATA_NAME}' metadata; written by '{library}', profile '{profile}')"
    )]
    NotOurs {
        /// The file.
        path: String,
        /// The writer's library string.
        library: String,
        /// The MCAP profile.
        profile: String,
    },
    /// One of ours, of another format version.
    #[error(
        "{path} is an mmt {kind} recording of format version {version} (written by mmt {mmt_version}); this build reads version {FORMAT_VERSION} only"
    )]
    Version {
        /// The file.
        path: String,
        /// Its kind, as written.
        kind: String,
        /// Its format version.
        version: String,
        /// The mmt version that wrote it.
        mmt_version: String,
    },
    /// One of ours, of this version, of a kind this build does not know.
    #[error(
        "{path} is an mmt recording of an unknown kind '{kind}' (written by mmt {mmt_version}); this build knows {known} recordings"
    )]
    UnknownKind {
        /// The file.
        path: String,
        /// Its kind, as written.
        kind: String,
        /// The mmt version that wrote it.
        mmt_version: String,
        /// The kinds this build reads ([`Kind::ALL`]).
        known: String,
    },
    /// One of ours, of a kind the caller cannot use.
    #[error("{path} is {what}; {needed}")]
    Kind {
        /// The file.
        path: String,
        /// What it is (`a telerobot recording of scene exp1, 60.0 s`).
        what: String,
        /// What the caller needs.
        needed: String,
    },
    /// A message that does not decode as its topic's type.
    #[error("{path}: message {index} on {topic}: {error}")]
    Message {
        /// The file.
        path: String,
        /// Its index in the file.
        index: u64,
        /// Its topic.
        topic: String,
        /// What went wrong.
        error: String,
    },
}

/// A recording, read back.
#[derive(Clone, Debug, Default)]
pub struct Recording {
    /// The file.
    pub path: PathBuf,
    /// What it says about itself.
    pub header: Option<Header>,
    /// `/run`, in order.
    pub runs: Vec<RunStart>,
    /// `/run/end`, in order (the last of a side counts).
    pub ends: Vec<RunEnd>,
    /// `/operator/tick`.
    pub operator_ticks: Vec<OperatorTick>,
    /// `/operator/measurement`.
    pub measurements: Vec<MeasurementRec>,
    /// `/telerobot/tick`.
    pub telerobot_ticks: Vec<TelerobotTick>,
    /// `/{side}/parameters`.
    pub parameters: Vec<(Side, ParametersRec)>,
    /// `/{side}/contact`.
    pub contacts: Vec<(Side, ContactRec)>,
    /// `/{side}/state_sync`.
    pub state_syncs: Vec<(Side, StateSyncRec)>,
    /// `/{side}/link`.
    pub links: Vec<(Side, LinkRec)>,
    /// `/{side}/cloud`.
    pub clouds: Vec<(Side, CloudRec)>,
    /// `/events`, with their log times \[ns since the Unix epoch\].
    pub events: Vec<(u64, EventRec)>,
    /// Messages read (every topic).
    pub messages: u64,
    /// Messages on topics left out by the caller or not known to this build.
    pub skipped: u64,
    /// Why reading stopped before the file's end, if it did (a file cut short).
    pub truncated: Option<String>,
}

impl Recording {
    /// The kind (every read recording has a header).
    pub fn kind(&self) -> Option<Kind> {
        self.header.as_ref().map(|h| h.kind)
    }

    /// The last `/run/end` of `side`.
    pub fn end(&self, side: Side) -> Option<&RunEnd> {
        self.ends.iter().rev().find(|e| e.side == side)
    }

    /// The first `/run` of `side`.
    pub fn run(&self, side: Side) -> Option<&RunStart> {
        self.runs.iter().find(|r| r.side == side)
    }

    /// Refuses a recording of a kind not in `kinds`: `needed` says what the caller needs.
    pub fn require(&self, kinds: &[Kind], needed: &str) -> Result<(), ReadError> {
        match self.kind() {
            Some(k) if kinds.contains(&k) => Ok(()),
            _ => Err(ReadError::Kind {
                path: self.path.display().to_string(),
                what: self.describe(),
                needed: needed.to_owned(),
            }),
        }
    }

    /// What it is, in words: `a telerobot recording of scene exp1 (60.0 s, mmt 0.1.0)`.
    pub fn describe(&self) -> String {
        let Some(h) = &self.header else {
            return "a recording without a header".to_owned();
        };
        let run = self.runs.first();
        let scene = run.map_or(String::new(), |r| format!(" of scene {}", r.scene_name));
        let experiment = run
            .filter(|r| !r.experiment.is_empty())
            .map_or(String::new(), |r| format!(" ({})", r.experiment));
        // Its length from the ticks read, or else from the run ends' counts (a caller that
        // skipped the tick topics), or not at all.
        let read = self.operator_ticks.len().max(self.telerobot_ticks.len()) as u64;
        let ticks = (read > 0)
            .then_some(read)
            .or_else(|| self.ends.iter().map(|e| e.ticks).max());
        let period = run.map_or(1_000_000, |r| r.period_ns.max(1));
        let length = ticks.map_or(String::new(), |t| {
            format!(", {:.1} s", t as f64 * period as f64 * 1e-9)
        });
        format!(
            "{} {} recording{experiment}{scene}{length}, written by mmt {}",
            if h.kind == Kind::Operator || h.kind == Kind::Experiment {
                "an"
            } else {
                "a"
            },
            h.kind,
            h.mmt_version
        )
    }
}

/// Reads the recording at `path`. `topics`: the topics to decode (empty: all); the others are
/// counted in [`Recording::skipped`].
pub fn read(path: &Path, topics: &[&str]) -> Result<Recording, ReadError> {
    let name = path.display().to_string();
    let io = |error| ReadError::Io {
        path: name.clone(),
        error,
    };
    let mut file = std::fs::File::open(path).map_err(io)?;
    let len = file.metadata().map_err(io)?.len();
    // The header and its metadata come first: a prefix is enough to say what the file is.
    let mut prefix = Vec::new();
    file.by_ref()
        .take(HEADER_PREFIX)
        .read_to_end(&mut prefix)
        .map_err(io)?;
    let header = header(&prefix, &name)?;
    let source = std::io::BufReader::new(prefix.as_slice().chain(file));
    let mut rec = read_messages(Messages::new(source, len), header, &name, topics)?;
    rec.path = path.to_owned();
    Ok(rec)
}

/// [`read`] on a file's bytes (no file system access); `name` names the source in errors and
/// becomes [`Recording::path`]. Whatever the bytes, an error or a recording, never a panic.
pub fn read_bytes(bytes: &[u8], name: &str, topics: &[&str]) -> Result<Recording, ReadError> {
    let header = header(bytes, name)?;
    read_messages(
        Messages::new(bytes, bytes.len() as u64),
        header,
        name,
        topics,
    )
}

/// Bytes read first to find the header metadata \[bytes\] (it is the file's second record).
const HEADER_PREFIX: u64 = 1 << 20;

/// The messages of a file whose header is `header`, on `topics` (all if empty), into lists.
fn read_messages(
    messages: Messages<impl Read>,
    header: Header,
    name: &str,
    topics: &[&str],
) -> Result<Recording, ReadError> {
    let mut rec = Recording {
        path: PathBuf::from(name),
        header: Some(header),
        ..Recording::default()
    };
    for (index, message) in messages.enumerate() {
        let message = match message {
            Ok(m) => m,
            Err(e) => {
                rec.truncated = Some(format!(
                    "the file ends or is damaged after {} messages: {e}",
                    rec.messages
                ));
                break;
            }
        };
        rec.messages += 1;
        let topic_name = message.topic.as_str();
        if !topics.is_empty() && !topics.contains(&topic_name) {
            rec.skipped += 1;
            continue;
        }
        take(&mut rec, topic_name, &message.data, message.log_time).map_err(|error| {
            ReadError::Message {
                path: name.to_owned(),
                index: index as u64,
                topic: topic_name.to_owned(),
                error,
            }
        })?;
    }
    Ok(rec)
}

/// The file's header: its `mmt.recording` metadata, checked.
fn header(bytes: &[u8], name: &str) -> Result<Header, ReadError> {
    let not_mcap = |reason: String| ReadError::NotMcap {
        path: name.to_owned(),
        reason,
    };
    let reader = mcap::read::LinearReader::new_with_options(bytes, Options::IgnoreEndMagic.into())
        .map_err(|e| not_mcap(e.to_string()))?;
    let (mut library, mut profile) = (String::new(), String::new());
    for record in reader {
        match record.map_err(|e| not_mcap(e.to_string()))? {
            mcap::records::Record::Header(h) => {
                library = h.library;
                profile = h.profile;
            }
            mcap::records::Record::Metadata(m) if m.name == METADATA_NAME => {
                return parse_header(&m.metadata, name);
            }
            // The header metadata is written first: a file whose first data is something else
            // is not one of ours.
            mcap::records::Record::Metadata(_) => {}
            _ => break,
        }
    }
    Err(ReadError::NotOurs {
        path: name.to_owned(),
        library,
        profile,
    })
}

fn parse_header(
    m: &std::collections::BTreeMap<String, String>,
    name: &str,
) -> Result<Header, ReadError> {
    let field = |key: &str| m.get(key).cloned().unwrap_or_default();
    let version = field("format_version");
    let version_error = || ReadError::Version {
        path: name.to_owned(),
        kind: field("kind"),
        version: field("format_version"),
        mmt_version: field("mmt_version"),
    };
    if version.parse::<u32>().ok() != Some(FORMAT_VERSION) {
        return Err(version_error());
    }
    Ok(Header {
        format_version: FORMAT_VERSION,
        kind: Kind::parse(&field("kind")).ok_or_else(|| ReadError::UnknownKind {
            path: name.to_owned(),
            kind: field("kind"),
            mmt_version: field("mmt_version"),
            known: Kind::ALL.map(Kind::name).join(", "),
        })?,
        mmt_version: field("mmt_version"),
        created_unix_ns: field("created_unix_ns").parse().unwrap_or(0),
        clock_origin_ns: field("clock_origin_ns").parse().unwrap_or(0),
    })
}

/// Decodes one message into its list.
fn take(rec: &mut Recording, topic_name: &str, data: &[u8], log_time: u64) -> Result<(), String> {
    fn json<T: serde::de::DeserializeOwned>(data: &[u8]) -> Result<T, String> {
        crate::lenient::from_slice(data)
    }
    use Side::{Operator as O, Telerobot as T};
    match topic_name {
        topic::RUN => rec.runs.push(json(data)?),
        topic::RUN_END => rec.ends.push(json(data)?),
        topic::OPERATOR_TICK => rec.operator_ticks.push(json(data)?),
        topic::OPERATOR_MEASUREMENT => rec.measurements.push(json(data)?),
        topic::TELEROBOT_TICK => rec.telerobot_ticks.push(json(data)?),
        topic::OPERATOR_PARAMETERS => rec.parameters.push((O, json(data)?)),
        topic::TELEROBOT_PARAMETERS => rec.parameters.push((T, json(data)?)),
        topic::OPERATOR_CONTACT => rec.contacts.push((O, json(data)?)),
        topic::TELEROBOT_CONTACT => rec.contacts.push((T, json(data)?)),
        topic::OPERATOR_STATE_SYNC => rec.state_syncs.push((O, json(data)?)),
        topic::TELEROBOT_STATE_SYNC => rec.state_syncs.push((T, json(data)?)),
        topic::OPERATOR_LINK => rec.links.push((O, json(data)?)),
        topic::TELEROBOT_LINK => rec.links.push((T, json(data)?)),
        topic::OPERATOR_CLOUD | topic::TELEROBOT_CLOUD => {
            let side = if topic_name == topic::OPERATOR_CLOUD {
                O
            } else {
                T
            };
            let cloud = foxglove::messages::PointCloud::decode(data).map_err(|e| e.to_string())?;
            let points =
                points_of(&cloud).ok_or("a point cloud whose fields are not x, y, z as float32")?;
            rec.clouds.push((
                side,
                CloudRec {
                    frame_id: 0,
                    timestamp_ns: cloud
                        .timestamp
                        .map_or(0, |t| i64::try_from(t.total_nanos()).unwrap_or(i64::MAX)),
                    points: std::sync::Arc::new(points),
                },
            ));
        }
        topic::EVENTS => {
            let log = foxglove::messages::Log::decode(data).map_err(|e| e.to_string())?;
            let level = match log.level {
                l if l >= foxglove::messages::log::Level::Error as i32 => Level::Error,
                l if l == foxglove::messages::log::Level::Warning as i32 => Level::Warning,
                _ => Level::Info,
            };
            rec.events.push((
                log_time,
                EventRec {
                    level,
                    source: "recorded",
                    text: format!("{}: {}", log.name, log.message),
                },
            ));
        }
        _ => rec.skipped += 1,
    }
    Ok(())
}
