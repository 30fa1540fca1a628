//! The telemetry log: everything the device sent during a replay, append-only, readable up to
//! the last whole record after a crash or a `kill -9`.
//!
//! ```text
//! file    = magic record*
//! magic   = "LSSITLM" 0x01                      8 bytes; the last one is the format version
//! record  = len:u32le crc:u32le body            crc = CRC-32C(body), len = body's length
//! body    = kind:u8 time_us:u64le data          time_us: host clock, µs since the Unix epoch
//! ```
//!
//! | kind | data |
//! |---|---|
//! | 1 session | UTF-8 JSON: tool version, input, port, configuration (one per replay) |
//! | 2 frame | one device → host frame exactly as received: its COBS bytes, without the `0x00` |
//! | 3 defmt | raw defmt bytes that came outside the frames (QEMU's semihosting stdout) |
//! | 4 note | UTF-8 text: a host event worth keeping (why a replay stopped, a dropped tail) |
//! | 5 summary | UTF-8 JSON: the link counters at the end of a replay |
//!
//! Each record is built in memory and handed to the kernel with one `write`, as soon as its
//! frame has arrived, so a killed writer leaves at most one partial record at the end of the
//! file. [`read_log`] returns every whole record and says whether a partial tail was skipped;
//! [`TelemetryLog::open`] cuts such a tail off (and notes it) before appending a new session.
//! Frames are stored raw, CRC errors included, and decoded only when read: a log keeps what the
//! wire carried even if a later protocol reads it differently. The device's own log lines come
//! as defmt bytes, which [`defmt`] decodes with the tables in the firmware's ELF; [`decode`] turns records
//! into what `lssi log` prints.
//!
//! ```
//! use lssi_host::telemetry::{read_log, RecordKind, TelemetryLog};
//!
//! let dir = tempfile::tempdir().unwrap();
//! let path = dir.path().join("run.tlm");
//! let mut log = TelemetryLog::open(&path).unwrap();
//! log.note("hello").unwrap();
//! drop(log);
//! let contents = read_log(&std::fs::read(&path).unwrap()).unwrap();
//! assert_eq!(contents.records[0].kind, RecordKind::Note);
//! assert_eq!(contents.records[0].data, b"hello");
//! assert!(contents.partial_tail.is_none());
//! ```

pub mod decode;
pub mod defmt;

use std::fs::{File, OpenOptions};
use std::io::{self, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use crc::{CRC_32_ISCSI, Crc};

/// The first 8 bytes of every telemetry log (the last byte is the format version).
pub const MAGIC: [u8; 8] = *b"LSSITLM\x01";
/// Bytes before a record's body: its length and its CRC.
pub const RECORD_HEADER_LEN: usize = 8;
/// Bytes of a body before its data: the kind and the host time.
pub const BODY_HEADER_LEN: usize = 9;
/// The longest body a writer produces; a longer length field means a corrupt record.
pub const MAX_BODY_LEN: usize = 1 << 20;

static CRC32C: Crc<u32> = Crc::<u32>::new(&CRC_32_ISCSI);

/// What a record holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RecordKind {
    /// The start of a replay: JSON describing it.
    Session,
    /// A device → host frame as received (COBS bytes, no delimiter).
    Frame,
    /// Raw defmt bytes received outside the frames.
    Defmt,
    /// A host event, as text.
    Note,
    /// The link counters at the end of a replay, as JSON.
    Summary,
}

impl RecordKind {
    /// The byte that stands for this kind in a record.
    pub const fn code(self) -> u8 {
        match self {
            RecordKind::Session => 1,
            RecordKind::Frame => 2,
            RecordKind::Defmt => 3,
            RecordKind::Note => 4,
            RecordKind::Summary => 5,
        }
    }

    /// The kind a byte stands for.
    pub const fn from_code(code: u8) -> Option<Self> {
        match code {
            1 => Some(RecordKind::Session),
            2 => Some(RecordKind::Frame),
            3 => Some(RecordKind::Defmt),
            4 => Some(RecordKind::Note),
            5 => Some(RecordKind::Summary),
            _ => None,
        }
    }
}

/// One whole record read back.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Record {
    /// What it holds.
    pub kind: RecordKind,
    /// When the host wrote it, µs since the Unix epoch.
    pub time_us: u64,
    /// The data.
    pub data: Vec<u8>,
    /// Byte offset of the record in the file.
    pub offset: u64,
}

/// A partial record at the end of a log (a writer stopped in the middle of it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PartialTail {
    /// Where it starts.
    pub offset: u64,
    /// How many bytes of it there are.
    pub len: u64,
}

/// Every whole record of a log.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LogContents {
    /// The records, in file order.
    pub records: Vec<Record>,
    /// A partial last record, skipped.
    pub partial_tail: Option<PartialTail>,
    /// Damaged stretches skipped: the reader went on at the next byte where a whole record
    /// with a good CRC starts.
    pub skipped: Vec<Skipped>,
}

/// A damaged stretch of a log, skipped by the reader.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Skipped {
    /// Where it starts.
    pub offset: u64,
    /// Its length in bytes.
    pub len: u64,
    /// What was wrong with the record that started there, as the end of a sentence.
    pub reason: String,
}

/// Why a log cannot be read.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum LogError {
    /// The file does not start with [`MAGIC`].
    #[error("the file is not an lssi telemetry log (it does not start with LSSITLM)")]
    NotALog,
    /// The file starts with the magic of another format version.
    #[error(
        "the file is a telemetry log of format version {theirs}, but this build reads version {ours}",
        theirs = .0,
        ours = MAGIC[7]
    )]
    Version(u8),
}

/// Reads every whole record of a log held in memory.
///
/// A record that runs past the end of the file is a partial tail (reported in
/// [`LogContents::partial_tail`], not an error). A whole record whose length, CRC or kind is
/// wrong starts a damaged stretch: the reader skips to the next byte where a whole record with
/// a good CRC starts and goes on from there ([`LogContents::skipped`]), so every intact record
/// is read. Only a file that is not a log, or a log of another version, is an error.
pub fn read_log(bytes: &[u8]) -> Result<LogContents, LogError> {
    if bytes.len() < MAGIC.len() {
        if MAGIC.starts_with(bytes) {
            // A writer killed while writing the magic: nothing was logged yet.
            return Ok(LogContents {
                records: Vec::new(),
                partial_tail: (!bytes.is_empty()).then_some(PartialTail {
                    offset: 0,
                    len: bytes.len() as u64,
                }),
                skipped: Vec::new(),
            });
        }
        return Err(LogError::NotALog);
    }
    if bytes[..7] != MAGIC[..7] {
        return Err(LogError::NotALog);
    }
    if bytes[7] != MAGIC[7] {
        return Err(LogError::Version(bytes[7]));
    }
    let mut contents = LogContents {
        records: Vec::new(),
        partial_tail: None,
        skipped: Vec::new(),
    };
    let mut at = MAGIC.len();
    while at < bytes.len() {
        match record_at(bytes, at) {
            Parsed::Whole(record, next) => {
                contents.records.push(record);
                at = next;
            }
            parsed => {
                let resume = (at + 1..bytes.len())
                    .find(|&k| matches!(record_at(bytes, k), Parsed::Whole(..)));
                let reason = match (parsed, resume) {
                    // Runs past the end with nothing whole after it: a stopped writer's tail.
                    (Parsed::Partial, None) => {
                        contents.partial_tail = Some(PartialTail {
                            offset: at as u64,
                            len: (bytes.len() - at) as u64,
                        });
                        break;
                    }
                    (Parsed::Damaged(reason), _) => reason,
                    _ => "its length field runs past the end of the file".into(),
                };
                let resume = resume.unwrap_or(bytes.len());
                contents.skipped.push(Skipped {
                    offset: at as u64,
                    len: (resume - at) as u64,
                    reason,
                });
                at = resume;
            }
        }
    }
    Ok(contents)
}

/// What starts at a byte of a log.
enum Parsed {
    /// A whole record with a good CRC, and where the next one starts.
    Whole(Record, usize),
    /// A record that runs past the end of the file.
    Partial,
    /// Not a record: why.
    Damaged(String),
}

fn record_at(bytes: &[u8], at: usize) -> Parsed {
    let rest = &bytes[at..];
    let Some(header) = rest.get(..RECORD_HEADER_LEN) else {
        return Parsed::Partial;
    };
    let len = u32::from_le_bytes([header[0], header[1], header[2], header[3]]) as usize;
    let crc = u32::from_le_bytes([header[4], header[5], header[6], header[7]]);
    if !(BODY_HEADER_LEN..=MAX_BODY_LEN).contains(&len) {
        return Parsed::Damaged(format!("its length field says {len} bytes"));
    }
    let Some(body) = rest.get(RECORD_HEADER_LEN..RECORD_HEADER_LEN + len) else {
        return Parsed::Partial;
    };
    if CRC32C.checksum(body) != crc {
        return Parsed::Damaged("its CRC-32C does not match".into());
    }
    let Some(kind) = RecordKind::from_code(body[0]) else {
        return Parsed::Damaged(format!("its kind byte is {}", body[0]));
    };
    let mut time = [0u8; 8];
    time.copy_from_slice(&body[1..BODY_HEADER_LEN]);
    Parsed::Whole(
        Record {
            kind,
            time_us: u64::from_le_bytes(time),
            data: body[BODY_HEADER_LEN..].to_vec(),
            offset: at as u64,
        },
        at + RECORD_HEADER_LEN + len,
    )
}

/// The host clock in µs since the Unix epoch (0 if the clock is before it).
pub fn now_us() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_micros()).unwrap_or(u64::MAX))
}

/// Encodes one record (header and body) as it goes into the file.
pub fn encode_record(kind: RecordKind, time_us: u64, data: &[u8]) -> Vec<u8> {
    let len = BODY_HEADER_LEN + data.len();
    let mut record = Vec::with_capacity(RECORD_HEADER_LEN + len);
    record.extend_from_slice(&(len as u32).to_le_bytes());
    record.extend_from_slice(&[0; 4]);
    record.push(kind.code());
    record.extend_from_slice(&time_us.to_le_bytes());
    record.extend_from_slice(data);
    let crc = CRC32C.checksum(&record[RECORD_HEADER_LEN..]);
    record[4..8].copy_from_slice(&crc.to_le_bytes());
    record
}

/// An open telemetry log, appended to one whole record at a time.
#[derive(Debug)]
pub struct TelemetryLog {
    file: File,
    path: PathBuf,
    records: u64,
}

impl TelemetryLog {
    /// Opens (or creates) a log for appending.
    ///
    /// An existing file must be a log; a partial record left at its end by a killed writer is
    /// cut off and a note says so, so that the new records stay readable after it.
    pub fn open(path: impl AsRef<Path>) -> io::Result<Self> {
        let path = path.as_ref().to_path_buf();
        // A device, a FIFO or a directory is no log to append to (reading /dev/zero to find
        // the end would never end).
        if let Ok(meta) = std::fs::metadata(&path)
            && !meta.is_file()
        {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "it exists and is not a regular file",
            ));
        }
        let mut file = OpenOptions::new()
            .read(true)
            .append(true)
            .create(true)
            .open(&path)?;
        let mut existing = Vec::new();
        file.read_to_end(&mut existing)?;
        let mut dropped = None;
        if existing.is_empty() {
            file.write_all(&MAGIC)?;
        } else {
            let contents = read_log(&existing)
                .map_err(|e| io::Error::new(io::ErrorKind::InvalidData, e.to_string()))?;
            if let Some(tail) = contents.partial_tail {
                file.set_len(tail.offset)?;
                file.seek(SeekFrom::End(0))?;
                if tail.offset == 0 {
                    file.write_all(&MAGIC)?;
                }
                dropped = Some(tail.len);
            }
        }
        let mut log = Self {
            file,
            path,
            records: 0,
        };
        if let Some(len) = dropped {
            log.note(&format!(
                "a partial record of {len} bytes, left by an interrupted writer, was cut off before this session"
            ))?;
        }
        Ok(log)
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Records appended since [`TelemetryLog::open`].
    pub fn records(&self) -> u64 {
        self.records
    }

    /// Appends one record, stamped with the host clock now.
    pub fn append(&mut self, kind: RecordKind, data: &[u8]) -> io::Result<()> {
        self.append_at(kind, now_us(), data)
    }

    /// Appends one record with a given time stamp (µs since the Unix epoch).
    pub fn append_at(&mut self, kind: RecordKind, time_us: u64, data: &[u8]) -> io::Result<()> {
        // One write per record: a killed writer leaves at most this record partial.
        self.file.write_all(&encode_record(kind, time_us, data))?;
        self.records += 1;
        Ok(())
    }

    /// Appends a note.
    pub fn note(&mut self, text: &str) -> io::Result<()> {
        self.append(RecordKind::Note, text.as_bytes())
    }

    /// Flushes the file to the disk (not needed to survive a killed process, only a lost
    /// machine).
    pub fn sync(&mut self) -> io::Result<()> {
        self.file.sync_data()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn log_with(records: &[(RecordKind, &[u8])]) -> Vec<u8> {
        let mut bytes = MAGIC.to_vec();
        for (i, (kind, data)) in records.iter().enumerate() {
            bytes.extend(encode_record(*kind, i as u64, data));
        }
        bytes
    }

    #[test]
    fn every_truncation_reads_the_whole_records_before_it() {
        let full = log_with(&[
            (RecordKind::Session, b"{}"),
            (RecordKind::Frame, &[1, 2, 3]),
            (RecordKind::Note, b"end"),
        ]);
        let whole = read_log(&full).unwrap();
        assert_eq!(whole.records.len(), 3);
        assert!(whole.partial_tail.is_none());
        let ends: Vec<u64> = whole
            .records
            .iter()
            .skip(1)
            .map(|r| r.offset)
            .chain([full.len() as u64])
            .collect();
        for cut in 0..full.len() {
            let contents = read_log(&full[..cut]).unwrap();
            let expected = ends.iter().filter(|&&e| e as usize <= cut).count();
            assert_eq!(contents.records.len(), expected, "cut at {cut}");
            assert_eq!(contents.records[..], whole.records[..expected]);
            let at_boundary = cut == MAGIC.len() || ends.contains(&(cut as u64)) || cut == 0;
            assert_eq!(contents.partial_tail.is_none(), at_boundary, "cut at {cut}");
        }
    }

    #[test]
    fn a_flipped_bit_in_a_whole_record_is_skipped_and_the_records_around_it_are_kept() {
        let mut bytes = log_with(&[(RecordKind::Note, b"one"), (RecordKind::Note, b"two")]);
        let last = bytes.len() - 1;
        bytes[last] ^= 0x10;
        let contents = read_log(&bytes).unwrap();
        assert_eq!(contents.records.len(), 1);
        assert_eq!(contents.skipped.len(), 1);
        assert!(contents.skipped[0].reason.contains("CRC"));
    }

    /// Resynchronisation: damage in record 2 of 5 (its CRC, then its length field) loses
    /// record 2 only; records 1, 3, 4 and 5 are read, and the skipped stretch is reported.
    #[test]
    fn the_reader_resynchronises_after_a_damaged_record() {
        let records: Vec<(RecordKind, &[u8])> = vec![
            (RecordKind::Session, b"{}"),
            (RecordKind::Frame, b"second record"),
            (RecordKind::Note, b"third"),
            (RecordKind::Frame, &[9, 8, 7, 6]),
            (RecordKind::Note, b"fifth"),
        ];
        let clean = log_with(&records);
        let whole = read_log(&clean).unwrap();
        let second = whole.records[1].offset as usize;
        let third = whole.records[2].offset as usize;
        for damage in [second + RECORD_HEADER_LEN + 3, second, second + 2] {
            let mut bytes = clean.clone();
            bytes[damage] ^= 0xA5;
            let contents = read_log(&bytes).unwrap();
            let kept: Vec<&Record> = contents.records.iter().collect();
            assert_eq!(kept.len(), 4, "damage at {damage}");
            assert_eq!(*kept[0], whole.records[0]);
            assert_eq!(
                kept[1..].to_vec(),
                whole.records[2..].iter().collect::<Vec<_>>()
            );
            assert_eq!(contents.skipped.len(), 1, "damage at {damage}");
            assert_eq!(contents.skipped[0].offset as usize, second);
            assert_eq!(contents.skipped[0].len as usize, third - second);
            assert!(contents.partial_tail.is_none());
        }
    }

    #[test]
    fn other_files_are_refused() {
        assert_eq!(read_log(b"t,x\n0,1\n"), Err(LogError::NotALog));
        assert_eq!(read_log(b"LSSITLM\x07"), Err(LogError::Version(7)));
    }

    #[test]
    fn reopening_cuts_a_partial_tail_and_appends_after_it() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.tlm");
        let mut log = TelemetryLog::open(&path).unwrap();
        log.note("first").unwrap();
        drop(log);
        let mut bytes = std::fs::read(&path).unwrap();
        bytes.extend(&encode_record(RecordKind::Note, 0, b"lost")[..6]);
        std::fs::write(&path, &bytes).unwrap();
        assert!(read_log(&bytes).unwrap().partial_tail.is_some());

        let mut log = TelemetryLog::open(&path).unwrap();
        log.note("second").unwrap();
        drop(log);
        let contents = read_log(&std::fs::read(&path).unwrap()).unwrap();
        let texts: Vec<&[u8]> = contents.records.iter().map(|r| &r.data[..]).collect();
        assert_eq!(texts.len(), 3);
        assert_eq!(texts[0], b"first");
        assert!(String::from_utf8_lossy(texts[1]).contains("partial record of 6 bytes"));
        assert_eq!(texts[2], b"second");
        assert!(contents.partial_tail.is_none());
    }
}
