//! The device's defmt log lines: decoded with the firmware's ELF (its defmt tables) when one
//! is given, otherwise shown as raw bytes with a hint.
//!
//! defmt sends indices into tables that live only in the ELF, so the bytes alone cannot be
//! read. The bytes arrive in pieces (`DeviceMsg::Log` frames of at most 96 bytes, or chunks of
//! QEMU's semihosting output); a [`DefmtLines`] joins them into one stream and returns each
//! log line once it is whole.

use std::fmt;
use std::path::{Path, PathBuf};

use defmt_decoder::{DecodeError, StreamDecoder, Table};

/// The hint shown with raw defmt bytes.
pub const RAW_HINT: &str = "raw defmt bytes; give the firmware's ELF (--elf) to decode them";

/// Why a firmware's defmt tables cannot be used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{}: {reason}", path.display())]
pub struct ElfError {
    /// The ELF file.
    pub path: PathBuf,
    /// Why, as the end of a sentence.
    pub reason: String,
}

/// The defmt tables of a firmware image.
pub struct Tables {
    table: &'static Table,
}

impl fmt::Debug for Tables {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Tables").finish_non_exhaustive()
    }
}

impl Tables {
    /// Reads the defmt tables of the ELF at `path`.
    ///
    /// The table is kept for the rest of the process (leaked): the stream decoders borrow it,
    /// and a command reads one firmware once.
    pub fn load(path: &Path) -> Result<Self, ElfError> {
        let error = |reason: String| ElfError {
            path: path.to_path_buf(),
            reason,
        };
        let bytes =
            std::fs::read(path).map_err(|e| error(format!("cannot read the firmware ELF: {e}")))?;
        match Table::parse(&bytes) {
            Ok(Some(table)) => Ok(Self {
                table: Box::leak(Box::new(table)),
            }),
            Ok(None) => Err(error(
                "the ELF has no defmt tables (was it built with defmt?)".into(),
            )),
            Err(e) => Err(error(format!("cannot read its defmt tables: {e}"))),
        }
    }
}

/// Turns pieces of a defmt byte stream into text lines.
pub struct DefmtLines {
    decoder: Option<Box<dyn StreamDecoder + Send + Sync>>,
    hinted: bool,
}

impl fmt::Debug for DefmtLines {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("DefmtLines")
            .field("decoding", &self.decoder.is_some())
            .finish()
    }
}

impl DefmtLines {
    /// Decodes with `tables`, or shows raw bytes without them.
    pub fn new(tables: Option<&Tables>) -> Self {
        Self {
            decoder: tables.map(|t| t.table.new_stream_decoder()),
            hinted: false,
        }
    }

    /// Whether the lines are decoded (an ELF was given).
    pub fn decoding(&self) -> bool {
        self.decoder.is_some()
    }

    /// Takes the next piece of the stream; returns the lines it completes.
    pub fn push(&mut self, bytes: &[u8]) -> Vec<String> {
        let Some(decoder) = self.decoder.as_mut() else {
            let hint = if std::mem::replace(&mut self.hinted, true) {
                String::new()
            } else {
                format!(" ({RAW_HINT})")
            };
            return vec![format!("{}{hint}", hex(bytes))];
        };
        decoder.received(bytes);
        let mut lines = Vec::new();
        loop {
            match decoder.decode() {
                Ok(frame) => {
                    let level = frame.level().map_or_else(String::new, |l| {
                        format!("{:<5} ", l.as_str().to_uppercase())
                    });
                    let time = frame
                        .display_timestamp()
                        .map_or_else(String::new, |t| format!("{t} "));
                    lines.push(format!("{time}{level}{}", frame.display_message()));
                }
                Err(DecodeError::UnexpectedEof) => break,
                Err(DecodeError::Malformed) => {
                    // The decoder has dropped the bad frame; the next chunk starts afresh.
                    lines.push(
                        "(a defmt frame did not decode with this ELF; is it the firmware that ran?)"
                            .into(),
                    );
                    break;
                }
            }
        }
        lines
    }
}

/// Bytes as space-separated hex.
pub fn hex(bytes: &[u8]) -> String {
    bytes
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect::<Vec<_>>()
        .join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn without_an_elf_bytes_are_shown_raw_with_the_hint_once() {
        let mut lines = DefmtLines::new(None);
        assert!(!lines.decoding());
        assert_eq!(lines.push(&[1, 0xab]), vec![format!("01 ab ({RAW_HINT})")]);
        assert_eq!(lines.push(&[2]), vec!["02".to_string()]);
    }

    #[test]
    fn a_missing_elf_is_an_error_naming_it() {
        let error = Tables::load(Path::new("/nonexistent/fw.elf")).unwrap_err();
        assert!(
            error
                .to_string()
                .starts_with("/nonexistent/fw.elf: cannot read")
        );
    }
}
