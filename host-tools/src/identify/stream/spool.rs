//! Standard input and other unseekable inputs (a pipe, `/dev/stdin` on a pipe, a process
//! substitution): copied in 64 KiB chunks to a temporary file, then read as a file is (in
//! memory when small, streamed when over [`super::STREAM_BYTES`]), so `cat big.csv | lssi
//! identify -` gives the model `lssi identify big.csv` gives, in the same bounded memory.
//! Messages name the input as the user did (`-`, `/dev/stdin`), not the temporary file.

use std::fs::File;
use std::io::{self, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use crate::recording::{ColumnNames, Recording, RecordingError};

/// Whether `path` names standard input (`-`).
pub fn is_stdin(path: &Path) -> bool {
    path.as_os_str() == "-"
}

/// Whether `path` is something that can be read once only (not a regular file, not a
/// directory: a pipe, a character device such as `/dev/stdin` on a pipe).
fn unseekable(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir())
}

/// A recording's input: the file read, and the name it goes by.
#[derive(Debug)]
pub struct Input {
    file: PathBuf,
    name: PathBuf,
    /// The spooled copy, removed when the input is dropped.
    _spool: Option<tempfile::NamedTempFile>,
}

impl Input {
    /// The input `path`: itself when it is a file or a directory (or does not exist: reading
    /// it says so), else its bytes spooled to a temporary file (`-` is standard input).
    pub fn open(path: &Path) -> Result<Self, RecordingError> {
        let name = path.to_owned();
        let io_error = |source| RecordingError::Io {
            path: name.clone(),
            source,
        };
        if is_stdin(path) {
            return Self::spool(path, io::stdin().lock());
        }
        if unseekable(path) {
            let file = File::open(path).map_err(io_error)?;
            return Self::spool(path, file);
        }
        Ok(Self {
            file: name.clone(),
            name,
            _spool: None,
        })
    }

    /// The file at `path` as it is, never spooled (a batch's arguments).
    pub fn plain(path: &Path) -> Self {
        Self {
            file: path.to_owned(),
            name: path.to_owned(),
            _spool: None,
        }
    }

    /// `reader` copied to a temporary file, named `name`.
    fn spool(name: &Path, mut reader: impl Read) -> Result<Self, RecordingError> {
        let io_error = |source| RecordingError::Io {
            path: name.to_owned(),
            source,
        };
        let spool_error = |e: io::Error| {
            io_error(io::Error::other(format!(
                "cannot copy it to a temporary file in {}: {e}",
                std::env::temp_dir().display()
            )))
        };
        let temp = tempfile::NamedTempFile::new().map_err(spool_error)?;
        let mut out = BufWriter::with_capacity(1 << 16, temp.as_file());
        let mut buffer = vec![0u8; 1 << 16];
        loop {
            let n = match reader.read(&mut buffer) {
                Ok(0) => break,
                Ok(n) => n,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(io_error(e)),
            };
            out.write_all(&buffer[..n]).map_err(spool_error)?;
        }
        out.flush().map_err(spool_error)?;
        drop(out);
        Ok(Self {
            file: temp.path().to_owned(),
            name: name.to_owned(),
            _spool: Some(temp),
        })
    }

    /// The file to read.
    pub fn file(&self) -> &Path {
        &self.file
    }

    /// What messages call it.
    pub fn name(&self) -> &Path {
        &self.name
    }

    /// Whether it was spooled (standard input, a pipe).
    pub fn spooled(&self) -> bool {
        self._spool.is_some()
    }

    /// The whole recording in memory (as [`Recording::read`]), named [`Input::name`].
    pub fn read(&self, columns: &ColumnNames) -> Result<Recording, RecordingError> {
        if !self.spooled() {
            return Recording::read(&self.file, columns);
        }
        let file = File::open(&self.file).map_err(|source| RecordingError::Io {
            path: self.name.clone(),
            source,
        })?;
        crate::recording::parse_csv(self.name.clone(), file, columns)
    }
}
