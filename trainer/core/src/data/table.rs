//! Delimited text: a header of column names and rows of numbers, each row
//! with its 1-based line in the file, so that every problem names the
//! file and line ([`CsvError`]). A line is split at the separator, one
//! with quotes by the `csv` crate's reader.
//!
//! The file is read in one pass, a line at a time ([`Table::from_reader`]):
//! the lines before the first data row are held to find the header
//! (at most [`HEAD_BYTES_MAX`] of them), and each row after it is kept as its
//! numbers, not its text, column by column (8 bytes a field and 4 for its
//! line), so the memory a table takes grows with its rows' numbers alone.
//! A line over [`LINE_BYTES_MAX`] is an error.
//!
//! The separator is a comma, a tab or a semicolon, whichever the header
//! line has most of. Blank lines are skipped; rows may have fewer or more
//! fields than the header (the reader that asks for a field says which is
//! missing). A byte-order mark at the start is ignored, CRLF and a
//! carriage return alone read as LF, UTF-16 with its mark is read, and a
//! line that is not UTF-8 is read as Latin-1 (a `°` written by a Windows
//! tool). Every field is read as a number by one reader ([`number`]).

use std::io::{BufRead, BufReader, Read};

pub use super::number::number;
pub use super::text::{CsvError, LINE_BYTES_MAX};
use super::text::{Lines, Utf16ToUtf8};
use std::path::{Path, PathBuf};

/// Most bytes of lines held before the first data row (16 MiB): a
/// logger's messages or a tool's preamble run to tens of lines (a live
/// logger's, thousands, well under a megabyte); a file with no data row
/// in its first 16 MiB is not a table of a recording.
pub const HEAD_BYTES_MAX: usize = 16 << 20;

/// The bits of a field that is empty or absent: a NaN with a payload of
/// its own, told apart from a `NaN` written in the file
/// ([`Table::is_blank`]); both read as no value.
const BLANK: u64 = 0x7FF8_0000_B1A4_0001;

/// Rows read before the room for the rest is reserved from the text's
/// size and the bytes a row has taken so far.
pub const RESERVE_AFTER: usize = 1024;

/// Items as an error lists them: the first [`LIST_MAX`] joined by `sep`,
/// then how many more (an archive of 20,000 entries gives a line, not a
/// megabyte).
pub fn listed(items: &[String], sep: &str) -> String {
    let mut text = items
        .iter()
        .take(LIST_MAX)
        .cloned()
        .collect::<Vec<_>>()
        .join(sep);
    if items.len() > LIST_MAX {
        text.push_str(&format!("{sep}and {} more", items.len() - LIST_MAX));
    }
    text
}

/// Most items an error names ([`listed`]).
pub const LIST_MAX: usize = 10;

/// A file's header and rows.
#[derive(Debug, Clone, PartialEq)]
pub struct Table {
    /// The file (for errors).
    pub path: PathBuf,
    /// The lines before the header (a Tracker track's name, a logger's
    /// messages), trimmed, blank ones left out.
    pub preamble: Vec<String>,
    /// The header's fields, trimmed, as written; `column 1`, `column 2`,
    /// ... where the file has no header line ([`Table::named`] false).
    pub header: Vec<String>,
    /// Whether the header is the file's own.
    pub named: bool,
    /// The separator: `,`, tab, `;` or a space (runs of spaces).
    pub separator: u8,
    /// Each column's values, a row each: NaN where the field is empty,
    /// absent, `NaN` or text ([`Table::is_blank`], [`Table::first_text`]
    /// tell which).
    columns: Vec<Vec<f64>>,
    /// Each row's 1-based line.
    lines: Vec<u32>,
    /// Each column's first field that is text where a number belongs:
    /// its row and the text.
    text: Vec<Option<(usize, String)>>,
    /// The first row with another number of fields than the header: its
    /// row and its number of fields.
    ragged: Option<(usize, usize)>,
}

/// A line's separator: a tab where it has one, else a semicolon where it
/// has one, else a comma where it has one or no space, else a space
/// (columns aligned by runs of spaces).
pub fn separator(line: &str) -> u8 {
    if line.contains('\t') {
        b'\t'
    } else if line.contains(';') {
        b';'
    } else if line.contains(',') || !line.trim().contains(' ') {
        b','
    } else {
        b' '
    }
}

/// A line's fields split at `sep` by the csv crate (quotes, spaces), a
/// list's brackets (`[1.0, 2.0]`, as a logger prints a row) left out;
/// `None` for an empty line.
fn fields(text_line: &str, sep: u8) -> Result<Option<Vec<String>>, csv::Error> {
    let trimmed = text_line.trim();
    if sep == b' ' {
        // Columns aligned by runs of (ASCII) spaces: a no-break or thin
        // space groups a number's digits.
        return Ok((!trimmed.is_empty()).then(|| {
            trimmed
                .split_ascii_whitespace()
                .map(str::to_string)
                .collect()
        }));
    }
    let inner = trimmed
        .strip_prefix('[')
        .and_then(|l| l.strip_suffix(']'))
        .unwrap_or(trimmed);
    // A byte-order mark left at a line's start (a file written twice
    // over), as the csv crate's reader drops it.
    let inner = inner.strip_prefix('\u{feff}').unwrap_or(inner);
    if !inner.contains('"') && sep.is_ascii() {
        // No quotes: the csv crate's split, without building a reader a
        // line (a million-row log read in seconds, not minutes).
        return Ok((!inner.is_empty()).then(|| {
            inner
                .split(char::from(sep))
                .map(|f| f.trim().to_string())
                .collect()
        }));
    }
    csv_fields(inner, sep)
}

/// A line's fields split at `sep` by a csv reader (quotes).
fn csv_fields(inner: &str, sep: u8) -> Result<Option<Vec<String>>, csv::Error> {
    let mut reader = csv::ReaderBuilder::new()
        .delimiter(sep)
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .buffer_capacity(inner.len() + 8)
        .from_reader(inner.as_bytes());
    let mut record = csv::StringRecord::new();
    Ok(reader
        .read_record(&mut record)?
        .then(|| record.iter().map(str::to_string).collect()))
}

/// The finite numbers among `fields`, where each is a number, `NaN` or
/// empty (`None` where one is text).
fn numbers_in(fields: &[String]) -> Option<usize> {
    fields
        .iter()
        .all(|f| f.is_empty() || number(f).is_some())
        .then(|| {
            fields
                .iter()
                .filter(|f| number(f).is_some_and(f64::is_finite))
                .count()
        })
}

/// Whether `fields` is a data row: two or more fields, each a number,
/// `NaN` or empty, at least two of them finite numbers.
pub(crate) fn is_data(fields: &[String]) -> bool {
    numbers_in(fields).is_some_and(|n| n >= 2)
}

/// Whether a line, split at its own separator, is a data row
/// ([`is_data`]), as [`Table::parse`] finds the first.
pub(crate) fn line_is_data(line: &str) -> bool {
    let sep = separator(line);
    fields(line, sep)
        .ok()
        .flatten()
        .is_some_and(|f| is_data(&f))
}

/// Whether `fields` is a data row with values missing: each field a
/// number, `NaN` or empty, at least one a finite number.
fn is_partial_data(fields: &[String]) -> bool {
    numbers_in(fields).is_some_and(|n| n >= 1)
}

/// A field as an error quotes it: at most 40 characters.
fn quoted(field: &str) -> String {
    match field.char_indices().nth(40) {
        Some((at, _)) => format!("{:?}...", &field[..at]),
        None => format!("{field:?}"),
    }
}

impl Table {
    /// Parses `text` (the contents of `path`).
    pub fn parse(path: &Path, text: &str) -> Result<Table, CsvError> {
        Table::from_lines(path, Lines::new(text.as_bytes()), Some(text.len() as u64))
    }

    /// Reads and parses the file at `path` in one pass.
    pub fn read(path: &Path) -> Result<Table, CsvError> {
        let file = std::fs::File::open(path)
            .map_err(|e| CsvError::new(path, 0, format!("cannot read: {e}")))?;
        let size = file.metadata().ok().map(|m| m.len());
        Table::from_sized_reader(path, file, size)
    }

    /// Reads a table from `reader` (the contents of `path`) in one pass:
    /// UTF-16 with its mark transcoded as it is read.
    pub fn from_reader(path: &Path, reader: impl Read) -> Result<Table, CsvError> {
        Table::from_sized_reader(path, reader, None)
    }

    /// [`Table::from_reader`] of a text of `size` bytes where known: the
    /// rows' room is reserved from it once a thousand rows are read
    /// ([`RESERVE_AFTER`]), not doubled as they come.
    pub fn from_sized_reader(
        path: &Path,
        reader: impl Read,
        size: Option<u64>,
    ) -> Result<Table, CsvError> {
        let mut reader = BufReader::with_capacity(256 * 1024, reader);
        let mark = reader
            .fill_buf()
            .map_err(|e| CsvError::new(path, 0, format!("cannot read: {e}")))?;
        let le = match mark.get(..2) {
            Some([0xFF, 0xFE]) => Some(true),
            Some([0xFE, 0xFF]) => Some(false),
            _ => None,
        };
        match le {
            Some(le) => {
                reader.consume(2);
                let utf8 = Utf16ToUtf8::new(reader, le);
                let size = size.map(|s| s / 2 * 3);
                Table::from_lines(path, Lines::new(BufReader::new(utf8)), size)
            }
            None => Table::from_lines(path, Lines::new(reader), size),
        }
    }

    /// The table of `lines`.
    ///
    /// The header is the line just before the first data row (two or more
    /// fields, all numbers, `NaN` or empty) where it has as many fields or
    /// two or more and is no data row itself; the lines above it are the
    /// preamble. A file whose first data row follows no such line has no
    /// header: its columns are named `column 1`, `column 2`, ... and every
    /// line above is preamble (a logger's messages).
    fn from_lines<R: BufRead>(
        path: &Path,
        mut lines: Lines<R>,
        size: Option<u64>,
    ) -> Result<Table, CsvError> {
        let unreadable =
            |line: usize, e: csv::Error| CsvError::new(path, line, format!("unreadable: {e}"));
        // The lines up to the first data row, held.
        let mut head: Vec<(usize, String)> = Vec::new();
        let mut head_bytes = 0;
        let mut first_data = None;
        while let Some((line, mut text)) = lines.next_line(path)? {
            if line == 1 && text.starts_with('\u{feff}') {
                text.drain(..'\u{feff}'.len_utf8());
            }
            if text.trim().is_empty() {
                continue;
            }
            let sep = separator(&text);
            let f = fields(&text, sep).map_err(|e| unreadable(line, e))?;
            head_bytes += text.len();
            head.push((line, text));
            if let Some(f) = f
                && is_data(&f)
            {
                // Rows just above it no wider, values missing (a first
                // frame the tracker lost), are data too, not its header.
                let mut k = head.len() - 1;
                while let Some((_, above)) = k.checked_sub(1).and_then(|j| head.get(j)) {
                    match fields(above, sep) {
                        Ok(Some(g)) if g.len() <= f.len() && is_partial_data(&g) => k -= 1,
                        _ => break,
                    }
                }
                first_data = Some((k, sep, f.len()));
                break;
            }
            if head_bytes > HEAD_BYTES_MAX {
                return Err(CsvError::new(
                    path,
                    0,
                    format!(
                        "no row of numbers in its first {} MiB ({} lines): not a table of a recording",
                        HEAD_BYTES_MAX >> 20,
                        head.len()
                    ),
                ));
            }
        }
        if head.is_empty() {
            return Err(CsvError::new(path, 0, "empty file"));
        }
        // No data row: the first line is the header (the readers say what
        // is missing).
        let (data_at, sep, width) = first_data.unwrap_or((1, separator(&head[0].1), 0));
        let header_at = data_at.checked_sub(1).filter(|&k| {
            let f = fields(&head[k].1, sep).ok().flatten().unwrap_or_default();
            first_data.is_none() || ((f.len() == width || f.len() >= 2) && !is_data(&f))
        });
        let header = match header_at {
            Some(k) => fields(&head[k].1, sep)
                .map_err(|e| unreadable(head[k].0, e))?
                .unwrap_or_default(),
            None => (1..=width).map(|c| format!("column {c}")).collect(),
        };
        let preamble = head[..header_at.unwrap_or(data_at)]
            .iter()
            .map(|(_, l)| l.trim().to_string())
            .collect();
        let mut table = Table {
            path: path.to_path_buf(),
            preamble,
            named: header_at.is_some(),
            columns: vec![Vec::new(); header.len()],
            text: vec![None; header.len()],
            header,
            lines: Vec::new(),
            ragged: None,
            separator: sep,
        };
        for (line, text) in head.iter().skip(data_at) {
            table.push_line(*line, text)?;
        }
        drop(head);
        let mut reserved = false;
        while let Some((line, text)) = lines.next_line(path)? {
            table.push_line(line, &text)?;
            if !reserved && table.len() >= RESERVE_AFTER {
                reserved = true;
                if let Some(size) = size {
                    let per_row = lines.bytes as f64 / table.len() as f64;
                    let rest = size.saturating_sub(lines.bytes) as f64 / per_row;
                    table.reserve((1.05 * rest) as usize + 16);
                }
            }
        }
        Ok(table)
    }

    /// A further line of this table's file (at 1-based `line`) kept as a
    /// row; `false` where it is blank.
    pub fn push_line(&mut self, line: usize, text_line: &str) -> Result<bool, CsvError> {
        let Some(fields) = fields(text_line, self.separator)
            .map_err(|e| self.error(line, format!("unreadable: {e}")))?
        else {
            return Ok(false);
        };
        let row = self.lines.len();
        if fields.len() != self.header.len() && self.ragged.is_none() {
            self.ragged = Some((row, fields.len()));
        }
        for (k, column) in self.columns.iter_mut().enumerate() {
            let field = fields.get(k).map_or("", String::as_str);
            let v = if field.is_empty() {
                f64::from_bits(BLANK)
            } else {
                match number(field) {
                    Some(v) => v,
                    None => {
                        let first = &mut self.text[k];
                        if first.is_none() {
                            *first = Some((row, field.to_string()));
                        }
                        f64::NAN
                    }
                }
            };
            column.push(v);
        }
        self.lines.push(u32::try_from(line).unwrap_or(u32::MAX));
        Ok(true)
    }

    /// Room for `more` rows.
    fn reserve(&mut self, more: usize) {
        self.columns.iter_mut().for_each(|c| c.reserve_exact(more));
        self.lines.reserve_exact(more);
    }

    /// Rows kept.
    pub fn len(&self) -> usize {
        self.lines.len()
    }

    /// Whether no row is kept.
    pub fn is_empty(&self) -> bool {
        self.lines.is_empty()
    }

    /// Row `row`'s 1-based line in the file.
    pub fn line(&self, row: usize) -> usize {
        self.lines.get(row).map_or(0, |&l| l as usize)
    }

    /// Column `k`'s values (NaN where a row has none).
    pub fn column(&self, k: usize) -> &[f64] {
        self.columns.get(k).map_or(&[], Vec::as_slice)
    }

    /// The first row whose number of fields is not the header's: its row
    /// and its number of fields.
    pub fn ragged(&self) -> Option<(usize, usize)> {
        self.ragged
    }

    /// The rows `keep` says, and only those (a run's rows, or none: a
    /// stream lets its rows go).
    pub fn retain_rows(&mut self, keep: impl Fn(usize) -> bool) {
        let kept: Vec<bool> = (0..self.len()).map(keep).collect();
        let mut new_index = vec![usize::MAX; kept.len()];
        let mut n = 0;
        for (k, &keep) in kept.iter().enumerate() {
            if keep {
                new_index[k] = n;
                n += 1;
            }
        }
        let pick = |v: &mut Vec<f64>| {
            let mut k = 0;
            v.retain(|_| {
                k += 1;
                kept[k - 1]
            });
        };
        self.columns.iter_mut().for_each(pick);
        let mut k = 0;
        self.lines.retain(|_| {
            k += 1;
            kept[k - 1]
        });
        for t in &mut self.text {
            *t = t
                .take()
                .and_then(|(r, s)| (new_index[r] != usize::MAX).then(|| (new_index[r], s)));
        }
        self.ragged = self
            .ragged
            .and_then(|(r, n)| (new_index[r] != usize::MAX).then(|| (new_index[r], n)));
    }

    /// The same rows with only the columns `cols` (in that order).
    pub fn select(&self, cols: &[usize]) -> Table {
        let get = |k: usize| self.columns.get(k).cloned().unwrap_or_default();
        Table {
            path: self.path.clone(),
            preamble: self.preamble.clone(),
            header: cols
                .iter()
                .map(|&k| self.header.get(k).cloned().unwrap_or_default())
                .collect(),
            named: self.named,
            separator: self.separator,
            columns: cols.iter().map(|&k| get(k)).collect(),
            lines: self.lines.clone(),
            text: cols
                .iter()
                .map(|&k| self.text.get(k).cloned().flatten())
                .collect(),
            ragged: None,
        }
    }

    /// A table of columns given whole (a workbook's sheet, a phyphox
    /// file's buffers): `header` and the values, the same number of each,
    /// each row on the line of its place.
    pub fn of_columns(path: &Path, header: Vec<String>, columns: Vec<Vec<f64>>) -> Table {
        let rows = columns.iter().map(Vec::len).max().unwrap_or(0);
        let columns: Vec<Vec<f64>> = columns
            .into_iter()
            .map(|mut c| {
                c.resize(rows, f64::from_bits(BLANK));
                c
            })
            .collect();
        Table {
            path: path.to_path_buf(),
            preamble: Vec::new(),
            text: vec![None; header.len()],
            header,
            named: true,
            separator: b',',
            columns,
            lines: (1..=rows)
                .map(|r| u32::try_from(r + 1).unwrap_or(u32::MAX))
                .collect(),
            ragged: None,
        }
    }

    /// A problem at `line`.
    pub fn error(&self, line: usize, problem: impl Into<String>) -> CsvError {
        CsvError::new(&self.path, line, problem)
    }

    /// Field `k` of row `row` as a finite number; `what` names it in errors.
    pub fn number(&self, row: usize, k: usize, what: &str) -> Result<f64, CsvError> {
        match self.value(row, k, what)? {
            Some(v) if v.is_finite() => Ok(v),
            Some(v) => Err(self.error(
                self.line(row),
                format!("{what} is {v}, not a finite number"),
            )),
            None if self.is_blank(row, k) => {
                Err(self.error(self.line(row), format!("missing {what} (column {})", k + 1)))
            }
            None => Err(self.error(
                self.line(row),
                format!("{what} is NaN, not a finite number"),
            )),
        }
    }

    /// Field `k` of row `row` as a number, `None` where it is empty,
    /// missing or `NaN`; text and an infinity are errors.
    pub fn value(&self, row: usize, k: usize, what: &str) -> Result<Option<f64>, CsvError> {
        if let Some(Some((r, text))) = self.text.get(k)
            && *r == row
        {
            return Err(self.error(
                self.line(row),
                format!("{what} {} is not a number", quoted(text)),
            ));
        }
        let v = self
            .columns
            .get(k)
            .and_then(|c| c.get(row))
            .copied()
            .unwrap_or(f64::NAN);
        if v.is_infinite() {
            return Err(self.error(
                self.line(row),
                format!("{what} is {v}, not a finite number"),
            ));
        }
        Ok((!v.is_nan()).then_some(v))
    }

    /// Whether field `k` of row `row` is empty or absent (not `NaN`, not
    /// text).
    pub fn is_blank(&self, row: usize, k: usize) -> bool {
        self.columns
            .get(k)
            .and_then(|c| c.get(row))
            .is_none_or(|v| v.to_bits() == BLANK)
    }

    /// The first row of column `k` whose field is text, if one.
    pub fn first_text(&self, k: usize) -> Option<usize> {
        self.text.get(k).and_then(|t| t.as_ref().map(|(r, _)| *r))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A line without quotes is split as the csv crate's reader splits it.
    #[test]
    fn an_unquoted_line_splits_as_the_csv_crate_splits_it() {
        let lines = [
            "0, 0.25 ,x",
            "a\t\tb",
            "1;2;;3",
            ",",
            "t,\u{b0}C ,z",
            "1,0 ;2",
            "x",
        ];
        for line in lines {
            for sep in [b',', b'\t', b';'] {
                assert_eq!(
                    fields(line, sep).unwrap(),
                    csv_fields(line, sep).unwrap(),
                    "{line:?} at {sep}"
                );
            }
        }
        assert_eq!(fields("  ", b',').unwrap(), None);
        assert_eq!(fields("\u{feff}t,x", b',').unwrap().unwrap(), ["t", "x"]);
        // A carriage return alone ends a line, among LF and CRLF ones.
        let t = Table::parse(Path::new("m.csv"), "t,x\n0,1\r1,2\r\n2,3\n").unwrap();
        assert_eq!(t.len(), 3);
        assert_eq!((t.line(2), t.column(1)[2]), (4, 3.0));
        assert_eq!(fields("[1.0, 2.0]", b',').unwrap().unwrap(), ["1.0", "2.0"]);
    }

    #[test]
    fn separators_lines_and_blank_rows() {
        let text = "\nt\ttheta [deg]\n0\t1\n\n0.1\t2\n";
        let t = Table::parse(Path::new("a.tsv"), text).unwrap();
        assert_eq!(t.header, ["t", "theta [deg]"]);
        assert_eq!(t.len(), 2);
        // Lines are the file's: the header is on line 2, the last row on 5.
        assert_eq!(t.line(1), 5);
        assert_eq!(t.number(1, 1, "theta").unwrap(), 2.0);
        let e = t.number(1, 2, "rate").unwrap_err();
        assert_eq!(e.to_string(), "a.tsv:5: missing rate (column 3)");
        assert_eq!(separator("a;b;c"), b';');
        assert_eq!(separator("a,b"), b',');
        assert_eq!(separator("single"), b',');
        let e = Table::parse(Path::new("e.csv"), " \n\n").unwrap_err();
        assert_eq!(e.to_string(), "e.csv: empty file");
        let t = Table::parse(Path::new("n.csv"), "t,x\n0,NaN\n1,abc\n").unwrap();
        assert!(
            t.number(0, 1, "x")
                .unwrap_err()
                .to_string()
                .starts_with("n.csv:2: x is NaN")
        );
        assert!(
            t.number(1, 1, "x")
                .unwrap_err()
                .to_string()
                .contains("n.csv:3: x \"abc\" is not a number")
        );
    }

    /// A first frame with its values missing (a tracker that lost the
    /// bob, tabs trimmed off) is a row, not the header, which stays the
    /// line above it.
    #[test]
    fn a_first_row_with_values_missing_keeps_the_header() {
        let text = "mass_A\nt\tx\ty\n0.0\t\t\n0.02\t728.3\t613.2\n0.04\t727.3\t612.9\n";
        let t = Table::parse(Path::new("tracker.txt"), text).unwrap();
        assert_eq!(t.header, ["t", "x", "y"]);
        assert_eq!(t.preamble, ["mass_A"]);
        assert_eq!(t.len(), 3);
        assert_eq!(t.line(0), 3);
    }

    /// Columns aligned by runs of spaces are read as columns.
    #[test]
    fn columns_aligned_by_spaces() {
        let t = Table::parse(Path::new("s.txt"), "t   theta\n0.00   0.30\n0.02  0.29\n").unwrap();
        assert_eq!(t.header, ["t", "theta"]);
        assert_eq!((t.column(0)[1], t.column(1)[1]), (0.02, 0.29));
    }

    #[test]
    fn a_bom_crlf_and_decimal_commas() {
        let text = "\u{feff}Time (s)\tAngle (rad)\r\n0,0000\t-1,25\r\n\r\n0,0200\t3\r\n";
        let t = Table::parse(Path::new("p.txt"), text).unwrap();
        assert_eq!(t.header, ["Time (s)", "Angle (rad)"]);
        assert_eq!(t.line(1), 4);
        assert_eq!(t.number(0, 1, "angle").unwrap(), -1.25);
        assert_eq!(t.number(1, 0, "time").unwrap(), 0.02);
        let t = Table::parse(Path::new("s.csv"), "t;x\n1,5;2\n1,2,3;4.5\n").unwrap();
        assert_eq!(t.number(0, 0, "t").unwrap(), 1.5);
        assert!(t.number(1, 0, "t").is_err());
        assert_eq!(t.number(1, 1, "x").unwrap(), 4.5);
        // A comma-separated file: a field with a decimal comma is quoted.
        let t = Table::parse(Path::new("c.csv"), "t,x\n1,5\n\"0,5\",\"−1,5E−1\"\n").unwrap();
        assert_eq!(t.column(0), [1.0, 0.5]);
        assert_eq!(t.column(1), [5.0, -0.15]);
    }

    /// A file that is not UTF-8 is read as Latin-1: a Windows tool's `°`.
    #[test]
    fn a_latin_1_file_is_read() {
        let path = std::env::temp_dir().join(format!("koopman-{}-latin1.csv", std::process::id()));
        std::fs::write(&path, b"t,Angle (\xb0)\n0,1\n").unwrap();
        let t = Table::read(&path);
        std::fs::remove_file(&path).unwrap();
        assert_eq!(t.unwrap().header, ["t", "Angle (°)"]);
    }

    /// A Tracker export's track name above its header, and a logger's
    /// messages above rows written as lists, with no header: the first
    /// data row finds the header (or none) and the separator.
    #[test]
    fn a_preamble_and_rows_as_lists() {
        let text = "mass_A\nt\tx\ty\n0,5\t1,0E-1\t-2\n";
        let t = Table::parse(Path::new("tr.txt"), text).unwrap();
        assert_eq!(t.preamble, ["mass_A"]);
        assert_eq!(t.header, ["t", "x", "y"]);
        assert!(t.named);
        assert_eq!(t.number(0, 1, "x").unwrap(), 0.1);
        assert_eq!(t.line(0), 3);
        let text = "Spatial 302088 Attached!\nwaiting 30 seconds to start...\n[31.052, 0.03, 0.99]\n[31.056, NaN, 1e-2]\n";
        let t = Table::parse(Path::new("imu.txt"), text).unwrap();
        assert!(!t.named);
        assert_eq!(t.header, ["column 1", "column 2", "column 3"]);
        assert_eq!(t.preamble.len(), 2);
        assert_eq!(t.column(2)[1], 1e-2);
        assert_eq!(t.value(1, 1, "x").unwrap(), None);
        assert_eq!(t.value(1, 5, "x").unwrap(), None);
        assert!(
            t.number(1, 1, "x")
                .unwrap_err()
                .to_string()
                .contains("imu.txt:4: x is NaN")
        );
    }

    #[test]
    fn a_list_names_ten_then_how_many_more() {
        let items: Vec<String> = (1..=25).map(|k| format!("e{k}")).collect();
        let text = listed(&items, ", ");
        assert!(
            text.starts_with("e1, e2,") && text.ends_with("e10, and 15 more"),
            "{text}"
        );
        assert_eq!(listed(&items[..2], "; "), "e1; e2");
    }
}
