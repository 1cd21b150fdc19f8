//! A run's output directory (`--out`): created and checked **before** the run, so that a path
//! that cannot be written costs one error at start instead of a whole session's report; files
//! written into it atomically (a temporary file, then a rename: a reader, or a run killed while
//! writing, never sees half a report); and streams appended as the run goes, so that a killed
//! run leaves a readable file up to its last flush.

use std::fs::{File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Why the output directory or one of its files cannot be written.
#[derive(Debug, thiserror::Error)]
pub enum OutError {
    /// The path exists and is not a directory.
    #[error("--out {0}: exists and is not a directory")]
    NotADirectory(PathBuf),
    /// An operation failed; the OS's reason is the source (printed once, by the caller's chain).
    #[error("--out {path}: cannot {what}")]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// What was being done ("create the directory", "write a file in it", …).
        what: &'static str,
        /// The operating system's reason.
        #[source]
        source: std::io::Error,
    },
}

/// A checked output directory.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OutDir {
    dir: PathBuf,
}

impl OutDir {
    /// Creates `dir` (and its parents) if needed, and checks that a file can be created, written
    /// and removed in it.
    pub fn prepare(dir: &Path) -> Result<OutDir, OutError> {
        if dir.exists() && !dir.is_dir() {
            return Err(OutError::NotADirectory(dir.to_owned()));
        }
        std::fs::create_dir_all(dir).map_err(|source| OutError::Io {
            path: dir.to_owned(),
            what: "create the directory",
            source,
        })?;
        let probe = dir.join(format!(".write-check-{}", std::process::id()));
        let written = File::create(&probe).and_then(|mut f| f.write_all(b"ok"));
        let _ = std::fs::remove_file(&probe);
        written.map_err(|source| OutError::Io {
            path: dir.to_owned(),
            what: "write a file in it",
            source,
        })?;
        Ok(OutDir {
            dir: dir.to_owned(),
        })
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.dir
    }

    /// Writes `name` atomically: `bytes` into `.name.tmp`, synced, then renamed over `name`.
    pub fn write_atomic(&self, name: &str, bytes: &[u8]) -> Result<PathBuf, OutError> {
        let path = self.dir.join(name);
        let tmp = self.dir.join(format!(".{name}.tmp"));
        let io = |what| {
            let path = path.clone();
            move |source| OutError::Io { path, what, source }
        };
        let mut f = File::create(&tmp).map_err(io("create a temporary file for"))?;
        f.write_all(bytes).map_err(io("write"))?;
        f.sync_all().map_err(io("sync"))?;
        drop(f);
        std::fs::rename(&tmp, &path).map_err(io("rename the temporary file to"))?;
        Ok(path)
    }

    /// A new stream file `name` (truncated if it exists), appended to as the run goes.
    pub fn stream(&self, name: &str, header: &str) -> Result<Stream, OutError> {
        let path = self.dir.join(name);
        let file = OpenOptions::new()
            .create(true)
            .write(true)
            .truncate(true)
            .open(&path)
            .map_err(|source| OutError::Io {
                path: path.clone(),
                what: "create",
                source,
            })?;
        let mut s = Stream {
            out: BufWriter::with_capacity(1 << 16, file),
            path,
            failed: false,
        };
        s.line(header);
        s.flush();
        Ok(s)
    }
}

/// A file appended to line by line; [`Stream::flush`] puts what was written on disk. A failed
/// write (a full disk) stops the stream instead of failing the run: [`Stream::failed`] says so.
#[derive(Debug)]
pub struct Stream {
    out: BufWriter<File>,
    path: PathBuf,
    failed: bool,
}

impl Stream {
    /// Appends `line` and a newline.
    pub fn line(&mut self, line: &str) {
        if !self.failed {
            self.failed = writeln!(self.out, "{line}").is_err();
        }
    }

    /// Hands what was written to the operating system (a killed process loses nothing before
    /// this).
    pub fn flush(&mut self) {
        if !self.failed {
            self.failed = self.out.flush().is_err();
        }
    }

    /// A write failed: the stream stopped there.
    pub fn failed(&self) -> bool {
        self.failed
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("rt-out-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    #[test]
    fn a_directory_is_created_and_a_file_or_unwritable_path_is_refused_before_the_run() {
        let d = scratch("create");
        let out = OutDir::prepare(&d.join("a/b")).unwrap();
        assert!(out.path().is_dir());
        assert_eq!(
            std::fs::read_dir(out.path()).unwrap().count(),
            0,
            "probe left"
        );
        let file = d.join("file");
        std::fs::write(&file, "x").unwrap();
        let e = OutDir::prepare(&file).unwrap_err().to_string();
        assert!(e.ends_with("file: exists and is not a directory"), "{e}");
        // Under a file: cannot create the directory; the OS reason is the source, not repeated.
        let e = OutDir::prepare(&file.join("sub")).unwrap_err();
        assert!(
            e.to_string().ends_with("sub: cannot create the directory"),
            "{e}"
        );
        assert!(std::error::Error::source(&e).is_some());
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn files_are_replaced_atomically_and_streams_are_readable_after_each_flush() {
        let d = scratch("atomic");
        let out = OutDir::prepare(&d).unwrap();
        out.write_atomic("report.json", b"one").unwrap();
        let p = out.write_atomic("report.json", b"two").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two");
        let names: Vec<_> = std::fs::read_dir(&d)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("report.json")]);
        let mut s = out.stream("ticks.csv", "a,b").unwrap();
        assert_eq!(std::fs::read_to_string(s.path()).unwrap(), "a,b\n");
        s.line("1,2");
        s.flush();
        s.line("3,4");
        // Only what was flushed is there (the process could be killed now).
        assert_eq!(std::fs::read_to_string(s.path()).unwrap(), "a,b\n1,2\n");
        assert!(!s.failed());
        let _ = std::fs::remove_dir_all(&d);
    }
}
