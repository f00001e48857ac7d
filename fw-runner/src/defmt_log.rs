//! The firmware's defmt log, decoded in-process from the ELF's own format table.
//!
//! The firmware writes rzCOBS-framed defmt frames to semihosting (QEMU's standard output).
//! [`LogDecoder::from_elf`] reads the table from the ELF's `.defmt` section;
//! [`LogStream::push`] takes bytes as they arrive and hands over one text line per frame.
//! rzCOBS resynchronises at the next frame separator, so a damaged frame costs that frame
//! only; [`LogStream::finish`] reports how many were damaged and whether the stream ended
//! inside a frame (as it does when QEMU is killed).

use defmt_decoder::{DecodeError, StreamDecoder, Table};
use std::fmt;
use std::path::Path;

/// How a frame becomes a line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LineFormat {
    /// Timestamp (if the firmware has one), level and message.
    Full,
    /// The message alone (`cargo fw-bench` prints `name: value` lines this way).
    Plain,
}

/// Why a log cannot be decoded at all.
#[derive(Debug)]
pub enum LogError {
    /// The ELF could not be read.
    Io(std::io::Error),
    /// The ELF's defmt table could not be parsed.
    Table(String),
    /// The ELF has no `.defmt` section.
    NoTable,
    /// The table uses an encoding that cannot resynchronise after a damaged frame.
    Unrecoverable,
}

impl fmt::Display for LogError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Io(e) => write!(f, "cannot read the firmware ELF: {e}"),
            Self::Table(e) => write!(f, "cannot parse the ELF's defmt table: {e}"),
            Self::NoTable => write!(f, "the ELF has no .defmt section"),
            Self::Unrecoverable => write!(
                f,
                "the firmware uses raw defmt encoding; build it with rzcobs (the default)"
            ),
        }
    }
}

impl std::error::Error for LogError {}

/// The format table of one firmware image.
pub struct LogDecoder {
    table: Table,
}

impl LogDecoder {
    /// Reads the defmt table of the ELF at `elf`.
    pub fn from_elf(elf: &Path) -> Result<Self, LogError> {
        let bytes = std::fs::read(elf).map_err(LogError::Io)?;
        Self::from_elf_bytes(&bytes)
    }

    /// Reads the defmt table of an ELF image in memory.
    pub fn from_elf_bytes(bytes: &[u8]) -> Result<Self, LogError> {
        let table = Table::parse(bytes)
            .map_err(|e| LogError::Table(e.to_string()))?
            .ok_or(LogError::NoTable)?;
        if !table.encoding().can_recover() {
            return Err(LogError::Unrecoverable);
        }
        Ok(Self { table })
    }

    /// A decoder for one byte stream.
    #[must_use]
    pub fn stream(&self, format: LineFormat) -> LogStream<'_> {
        LogStream {
            decoder: self.table.new_stream_decoder(),
            format,
            frames: 0,
            malformed: 0,
            pending: false,
        }
    }

    /// Decodes a whole recorded log into lines, with the closing note of
    /// [`LogStream::finish`] as the last line when there is one.
    #[must_use]
    pub fn decode_all(&self, raw: &[u8], format: LineFormat) -> Vec<String> {
        let mut lines = Vec::new();
        let mut stream = self.stream(format);
        stream.push(raw, |l| lines.push(l));
        if let Some(note) = stream.finish().note() {
            lines.push(note);
        }
        lines
    }
}

/// A defmt byte stream being decoded.
pub struct LogStream<'t> {
    decoder: Box<dyn StreamDecoder + Send + Sync + 't>,
    format: LineFormat,
    frames: usize,
    malformed: usize,
    pending: bool,
}

/// What a finished stream held.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StreamSummary {
    /// Frames decoded.
    pub frames: usize,
    /// Damaged frames skipped.
    pub malformed: usize,
    /// Whether the stream ended inside a frame.
    pub truncated: bool,
}

impl StreamSummary {
    /// A line saying what was lost, if anything was.
    #[must_use]
    pub fn note(&self) -> Option<String> {
        match (self.malformed, self.truncated) {
            (0, false) => None,
            (m, t) => Some(format!(
                "(defmt log: {m} damaged frame(s) skipped{})",
                if t {
                    "; the log ends inside a frame"
                } else {
                    ""
                }
            )),
        }
    }
}

impl LogStream<'_> {
    /// Takes `bytes` and calls `line` once per complete frame, in order.
    pub fn push(&mut self, bytes: &[u8], mut line: impl FnMut(String)) {
        if let Some(&last) = bytes.last() {
            self.decoder.received(bytes);
            // A frame ends at a zero byte: anything after the last one is incomplete.
            self.pending = last != 0;
        }
        loop {
            match self.decoder.decode() {
                Ok(frame) => {
                    self.frames += 1;
                    line(match self.format {
                        LineFormat::Full => frame.display(false).to_string(),
                        LineFormat::Plain => frame.display_message().to_string(),
                    });
                }
                Err(DecodeError::UnexpectedEof) => break,
                // rzCOBS drops the damaged frame and resumes at the next separator.
                Err(DecodeError::Malformed) => self.malformed += 1,
            }
        }
    }

    /// Ends the stream.
    #[must_use]
    pub fn finish(self) -> StreamSummary {
        StreamSummary {
            frames: self.frames,
            malformed: self.malformed,
            truncated: self.pending,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_that_is_not_an_elf_is_a_table_error() {
        assert!(matches!(
            LogDecoder::from_elf_bytes(b"not an elf"),
            Err(LogError::Table(_))
        ));
    }

    #[test]
    fn nothing_lost_means_no_note() {
        assert_eq!(StreamSummary::default().note(), None);
        let s = StreamSummary {
            frames: 3,
            malformed: 1,
            truncated: true,
        };
        let note = s.note().unwrap_or_default();
        assert!(
            note.contains("1 damaged") && note.contains("inside a frame"),
            "{note}"
        );
    }
}
