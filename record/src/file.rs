//! The MCAP file of a recording: created (as [`partial_path`]) with its header, written one
//! message at a time on the recorder thread, chunked and compressed by the `mcap` crate.

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::encode::ChannelSchema;
use crate::schema::{self, LIBRARY, METADATA_NAME};
use crate::writer::{CHUNK_BYTES, FLUSH_EVERY, RecordError};

/// Where a recording to `path` is written until it is finished: `path` with `.partial`
/// appended (`run.mcap` → `run.mcap.partial`).
pub fn partial_path(path: &Path) -> PathBuf {
    let mut name = path.as_os_str().to_owned();
    name.push(".partial");
    PathBuf::from(name)
}

/// The MCAP file.
pub(crate) struct McapOut {
    pub(crate) writer: mcap::Writer<BufWriter<File>>,
    pub(crate) path: PathBuf,
    channels: HashMap<&'static str, (u16, u32)>,
    flushed: Instant,
}

impl McapOut {
    pub(crate) fn create(path: &Path, header: &schema::Header) -> Result<McapOut, RecordError> {
        let err = |e: &dyn std::fmt::Display| RecordError::File {
            path: path.display().to_string(),
            error: e.to_string(),
        };
        if path.file_name().is_none() || path.is_dir() {
            return Err(err(
                &"is a directory, expected a file name such as run.mcap",
            ));
        }
        let file = File::create(partial_path(path)).map_err(|e| err(&e))?;
        let options = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .compression_threads(0)
            .chunk_size(Some(CHUNK_BYTES))
            .library(LIBRARY)
            .profile("");
        let mut writer = options.create(BufWriter::new(file)).map_err(|e| err(&e))?;
        let metadata = BTreeMap::from([
            (
                "format_version".to_owned(),
                header.format_version.to_string(),
            ),
            ("kind".to_owned(), header.kind.name().to_owned()),
            ("mmt_version".to_owned(), header.mmt_version.clone()),
            (
                "created_unix_ns".to_owned(),
                header.created_unix_ns.to_string(),
            ),
            (
                "clock_origin_ns".to_owned(),
                header.clock_origin_ns.to_string(),
            ),
        ]);
        writer
            .write_metadata(&mcap::records::Metadata {
                name: METADATA_NAME.to_owned(),
                metadata,
            })
            .map_err(|e| err(&e))?;
        writer.flush().map_err(|e| err(&e))?;
        Ok(McapOut {
            writer,
            path: path.to_owned(),
            channels: HashMap::new(),
            flushed: Instant::now(),
        })
    }

    pub(crate) fn write(
        &mut self,
        topic: &'static str,
        schema: &ChannelSchema,
        log_time: u64,
        data: &[u8],
    ) -> mcap::McapResult<()> {
        let (id, sequence) = match self.channels.get_mut(topic) {
            Some(c) => {
                c.1 += 1;
                *c
            }
            None => {
                let schema_id =
                    self.writer
                        .add_schema(&schema.name, schema.schema_encoding, &schema.data)?;
                let id = self.writer.add_channel(
                    schema_id,
                    topic,
                    schema.message_encoding,
                    &BTreeMap::new(),
                )?;
                self.channels.insert(topic, (id, 1));
                (id, 1)
            }
        };
        self.writer.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: id,
                sequence,
                log_time,
                publish_time: log_time,
            },
            data,
        )?;
        if self.flushed.elapsed() >= FLUSH_EVERY {
            self.flushed = Instant::now();
            self.writer.flush()?;
        }
        Ok(())
    }
}
