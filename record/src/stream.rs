//! The messages of an MCAP file, in file order, chunks decompressed, with every record's
//! declared length checked against a limit before anything is allocated.
//!
//! `mcap::MessageStream` (mcap 0.26) reads chunks with no record-length limit, so a damaged
//! length inside a chunk made it reserve whatever the length said (an abort: "memory
//! allocation of 3834031346506215745 bytes failed") or overflow `usize` (a panic in builds with
//! overflow checks). Found by the `mcap` fuzz target and `record/tests/fuzz_seeds.rs`; this
//! reader drives mcap's own sans-I/O reader with the limit set instead.

use std::collections::HashMap;
use std::io::Read;

use mcap::records::Record;
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};

/// Largest record the reader loads \[bytes\]: 256 MiB, or the file's size if larger. Far above
/// anything the recorder writes (a chunk is 1 MiB of messages, or one message; the largest
/// message, a 4,194,304-point cloud, is 50 MB), and bounded whatever a damaged length says.
const RECORD_LIMIT: usize = 256 << 20;

/// One message: its topic, log time \[ns\] and payload.
pub(crate) struct StreamMessage {
    pub topic: String,
    pub log_time: u64,
    pub data: Vec<u8>,
}

/// The messages of an MCAP file (with or without its end magic) read from `source` as they are
/// needed: a file is streamed, never held whole.
pub(crate) struct Messages<R> {
    source: R,
    reader: LinearReader,
    topics: HashMap<u16, String>,
    done: bool,
}

impl<R: Read> Messages<R> {
    /// The messages of `source`, which holds `len` bytes (the record-length limit grows with it).
    pub(crate) fn new(source: R, len: u64) -> Messages<R> {
        let len = usize::try_from(len).unwrap_or(usize::MAX);
        Messages {
            source,
            reader: LinearReader::new_with_options(
                LinearReaderOptions::default()
                    .with_record_length_limit(RECORD_LIMIT.max(len))
                    .with_skip_end_magic(true),
            ),
            topics: HashMap::new(),
            done: false,
        }
    }

    /// Reads up to `need` bytes into the reader; 0 at the end of the source.
    fn fill(&mut self, need: usize) -> std::io::Result<usize> {
        let buf = self.reader.insert(need);
        let n = loop {
            match self.source.read(buf) {
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                other => break other,
            }
        };
        // Whatever happened, the reader is told what arrived (nothing on an error).
        self.reader.notify_read(*n.as_ref().unwrap_or(&0));
        n
    }
}

impl<R: Read> Iterator for Messages<R> {
    /// A message, or why reading stopped.
    type Item = Result<StreamMessage, String>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        while let Some(event) = self.reader.next_event() {
            let (opcode, data) = match event {
                Ok(LinearReadEvent::ReadRequest(need)) => {
                    if let Err(e) = self.fill(need) {
                        self.done = true;
                        return Some(Err(format!("cannot read on: {e}")));
                    }
                    continue;
                }
                Ok(LinearReadEvent::Record { opcode, data }) => (opcode, data),
                Err(e) => {
                    self.done = true;
                    return Some(Err(e.to_string()));
                }
            };
            match mcap::parse_record(opcode, data) {
                Ok(Record::Channel(c)) => {
                    self.topics.insert(c.id, c.topic);
                }
                Ok(Record::Message { header, data }) => {
                    let Some(topic) = self.topics.get(&header.channel_id) else {
                        self.done = true;
                        return Some(Err(format!(
                            "a message on channel {}, which no channel record declares",
                            header.channel_id
                        )));
                    };
                    return Some(Ok(StreamMessage {
                        topic: topic.clone(),
                        log_time: header.log_time,
                        data: data.into_owned(),
                    }));
                }
                // The summary repeats what the data section said.
                Ok(Record::DataEnd(_)) => break,
                Ok(_) => {}
                Err(e) => {
                    self.done = true;
                    return Some(Err(e.to_string()));
                }
            }
        }
        self.done = true;
        None
    }
}
