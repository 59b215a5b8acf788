//! Bytes as lines of text: UTF-8, Latin-1 where a line is not, UTF-16
//! with its mark (transcoded as it is read), any line end, each line
//! numbered; an endless line refused ([`LINE_BYTES_MAX`]). A problem names
//! the file and the line ([`CsvError`]).

use std::fmt;
use std::io::{BufRead, Read};
use std::path::{Path, PathBuf};

/// A problem with a file, naming it and the line (1-based).
#[derive(Debug, Clone, PartialEq)]
pub struct CsvError {
    /// The file.
    pub path: PathBuf,
    /// 1-based line, 0 when the problem is the whole file.
    pub line: usize,
    /// What is wrong.
    pub problem: String,
}

impl CsvError {
    /// A problem at `line` of `path` (0: the whole file).
    pub fn new(path: &Path, line: usize, problem: impl Into<String>) -> CsvError {
        CsvError {
            path: path.to_path_buf(),
            line,
            problem: problem.into(),
        }
    }
}

impl fmt::Display for CsvError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line == 0 {
            write!(f, "{}: {}", self.path.display(), self.problem)
        } else {
            write!(f, "{}:{}: {}", self.path.display(), self.line, self.problem)
        }
    }
}

impl std::error::Error for CsvError {}

/// Longest line read, bytes (16 MiB): a header of thousands of columns
/// fits many times over; a file of one endless line (no table, or a
/// binary) is refused before it fills memory.
pub const LINE_BYTES_MAX: usize = 16 << 20;

/// UTF-16 code units (`le`: little-endian) as text, an unpaired half
/// replaced.
pub(crate) fn utf16(bytes: &[u8], le: bool) -> String {
    let units = bytes.chunks_exact(2).map(|c| {
        let pair = [c[0], c[1]];
        if le {
            u16::from_le_bytes(pair)
        } else {
            u16::from_be_bytes(pair)
        }
    });
    char::decode_utf16(units)
        .map(|c| c.unwrap_or(char::REPLACEMENT_CHARACTER))
        .collect()
}

/// Bytes as UTF-8 where they are, else as Latin-1.
pub(crate) fn latin1_unless_utf8(bytes: Vec<u8>) -> String {
    String::from_utf8(bytes)
        .unwrap_or_else(|e| e.into_bytes().iter().map(|&b| char::from(b)).collect())
}

/// The lines of a text, one at a time: split at LF, CRLF or a carriage
/// return alone, each decoded on its own (UTF-8, else Latin-1), numbered
/// from 1.
pub(crate) struct Lines<R> {
    reader: R,
    /// Bytes read so far.
    pub(crate) bytes: u64,
    /// The next line's number.
    next: usize,
    /// A carriage return ended the line before: a LF first is its end.
    after_cr: bool,
    buf: Vec<u8>,
}

impl<R: BufRead> Lines<R> {
    pub(crate) fn new(reader: R) -> Self {
        Lines {
            reader,
            bytes: 0,
            next: 1,
            after_cr: false,
            buf: Vec::new(),
        }
    }

    /// The next line and its number; `None` at the end.
    pub(crate) fn next_line(&mut self, path: &Path) -> Result<Option<(usize, String)>, CsvError> {
        let unreadable = |e: std::io::Error| CsvError::new(path, 0, format!("cannot read: {e}"));
        self.buf.clear();
        let mut ended = false;
        let mut any = false;
        while !ended {
            let chunk = self.reader.fill_buf().map_err(unreadable)?;
            if chunk.is_empty() {
                break;
            }
            any = true;
            let mut used = 0;
            if self.after_cr && chunk.first() == Some(&b'\n') {
                used = 1;
            }
            self.after_cr = false;
            let rest = chunk.get(used..).unwrap_or_default();
            match rest.iter().position(|&b| b == b'\n' || b == b'\r') {
                Some(at) => {
                    self.buf.extend_from_slice(&rest[..at]);
                    self.after_cr = rest[at] == b'\r';
                    used += at + 1;
                    ended = true;
                }
                None => {
                    self.buf.extend_from_slice(rest);
                    used += rest.len();
                }
            }
            self.reader.consume(used);
            self.bytes += used as u64;
            if self.buf.len() > LINE_BYTES_MAX {
                return Err(CsvError::new(
                    path,
                    self.next,
                    format!(
                        "a line over {} MiB: not a table of numbers",
                        LINE_BYTES_MAX >> 20
                    ),
                ));
            }
        }
        if !ended && self.buf.is_empty() && !any {
            return Ok(None);
        }
        if !ended && self.buf.is_empty() {
            // A lone LF after a CR at the very end.
            return Ok(None);
        }
        let line = self.next;
        self.next += 1;
        Ok(Some((
            line,
            latin1_unless_utf8(std::mem::take(&mut self.buf)),
        )))
    }
}

/// A reader of UTF-16 (`le`: little-endian) that gives UTF-8, a chunk at
/// a time (Excel's "Unicode text" read in one pass).
pub(crate) struct Utf16ToUtf8<R> {
    inner: R,
    le: bool,
    /// A byte or a high surrogate left from the chunk before.
    carry: Vec<u8>,
    out: Vec<u8>,
    at: usize,
}

impl<R: Read> Utf16ToUtf8<R> {
    /// UTF-8 from `inner`, UTF-16 (`le`: little-endian) after its mark.
    pub(crate) fn new(inner: R, le: bool) -> Self {
        Utf16ToUtf8 {
            inner,
            le,
            carry: Vec::new(),
            out: Vec::new(),
            at: 0,
        }
    }
}

impl<R: Read> Read for Utf16ToUtf8<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        while self.at >= self.out.len() {
            let mut raw = std::mem::take(&mut self.carry);
            let have = raw.len();
            raw.resize(have + 64 * 1024, 0);
            let n = self.inner.read(&mut raw[have..])?;
            raw.truncate(have + n);
            if raw.is_empty() {
                return Ok(0);
            }
            let mut whole = raw.len() / 2 * 2;
            if n > 0 {
                // Keep a high surrogate for the next chunk.
                if whole >= 2 {
                    let last = [raw[whole - 2], raw[whole - 1]];
                    let unit = if self.le {
                        u16::from_le_bytes(last)
                    } else {
                        u16::from_be_bytes(last)
                    };
                    if (0xD800..0xDC00).contains(&unit) {
                        whole -= 2;
                    }
                }
            } else {
                whole = raw.len();
            }
            self.carry = raw.split_off(whole);
            if n == 0 {
                self.carry.clear();
            }
            self.out = utf16(&raw, self.le).into_bytes();
            self.at = 0;
        }
        let n = buf.len().min(self.out.len() - self.at);
        buf[..n].copy_from_slice(&self.out[self.at..self.at + n]);
        self.at += n;
        Ok(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::table::Table;

    /// UTF-16 with its mark (Excel's "Unicode text", tab-separated), read
    /// from bytes a chunk at a time, and a carriage return alone as the
    /// line end are read; a long cell where a number belongs is quoted
    /// short in the error.
    #[test]
    fn utf_16_old_mac_line_ends_and_a_long_cell() {
        let text = "Time (s)\tAngle (°)\r\n0\t0.3\r\n0.02\t0.29\r\n";
        for le in [true, false] {
            let mut bytes = if le {
                vec![0xFF, 0xFE]
            } else {
                vec![0xFE, 0xFF]
            };
            bytes.extend(
                text.encode_utf16().flat_map(
                    |u| {
                        if le { u.to_le_bytes() } else { u.to_be_bytes() }
                    },
                ),
            );
            let t = Table::from_reader(Path::new("u.txt"), bytes.as_slice()).unwrap();
            assert_eq!(t.header, ["Time (s)", "Angle (°)"]);
            assert_eq!(t.len(), 2);
            assert_eq!(t.column(1), [0.3, 0.29]);
        }
        let t = Table::parse(Path::new("m.csv"), "t,theta\r0,0.3\r0.02,0.29\r").unwrap();
        assert_eq!((t.header.len(), t.len()), (2, 2));
        let long = "x".repeat(100_000);
        let t = Table::parse(
            Path::new("l.csv"),
            &format!("t,theta\n0,0.3\n0.02,{long}\n"),
        )
        .unwrap();
        let e = t.number(1, 1, "theta").unwrap_err().to_string();
        assert!(
            e.len() < 200 && e.contains("..."),
            "{}",
            &e[..e.len().min(300)]
        );
    }

    /// One endless line (a binary, a file of one line) is refused at
    /// [`LINE_BYTES_MAX`], and endless text with no row of numbers at
    /// `HEAD_BYTES_MAX`, without reading the rest.
    #[test]
    fn an_endless_line_and_an_endless_preamble_are_refused() {
        let endless = std::io::repeat(b'x').take(LINE_BYTES_MAX as u64 + 10);
        let e = Table::from_reader(Path::new("b.bin"), endless).unwrap_err();
        assert!(e.to_string().contains("a line over 16 MiB"), "{e}");
        /// "words\n" without end.
        struct Words(usize);
        impl Read for Words {
            fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
                for b in buf.iter_mut() {
                    *b = b"words\n"[self.0 % 6];
                    self.0 += 1;
                }
                Ok(buf.len())
            }
        }
        let e = Table::from_reader(Path::new("w.txt"), Words(0)).unwrap_err();
        assert!(
            e.to_string()
                .contains("no row of numbers in its first 16 MiB"),
            "{e}"
        );
    }
}
