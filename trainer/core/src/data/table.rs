//! Delimited text: a header of column names and rows of fields, each row
//! with its 1-based line in the file, so that every problem names the
//! file and line ([`CsvError`]). A line is split at the separator, one
//! with quotes by the `csv` crate's reader.
//!
//! The separator is a comma, a tab or a semicolon, whichever the header
//! line has most of; with a tab or a semicolon a number may have a decimal
//! comma (`0,25`). Blank lines are skipped; rows may have fewer or more
//! fields than the header (the reader that asks for a field says which is
//! missing). A byte-order mark at the start is ignored, CRLF and a
//! carriage return alone read as LF, and a file that is not UTF-8 is read
//! as Latin-1 (a `°` written by a Windows tool).

use std::fmt;
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

/// One data row: its line and its fields (trimmed).
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// 1-based line in the file.
    pub line: usize,
    /// The fields.
    pub fields: Vec<String>,
}

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
    /// The data rows after the header.
    pub rows: Vec<Row>,
    /// The separator: `,`, tab, `;` or a space (runs of spaces).
    pub separator: u8,
}

/// A line's separator: a tab where it has one, else a semicolon where it
/// has one, else a comma where it has one or no space, else a space
/// (columns aligned by runs of spaces; a decimal comma goes with a tab or
/// a semicolon).
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
        // Columns aligned by runs of spaces.
        return Ok(
            (!trimmed.is_empty()).then(|| trimmed.split_whitespace().map(str::to_string).collect())
        );
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

/// A field as a number: a decimal comma read where `sep` is not a comma;
/// `NaN` (padding) reads as NaN.
fn parse_number(field: &str, sep: u8) -> Option<f64> {
    let one_comma = field.matches(',').count() == 1 && !field.contains('.');
    if sep != b',' && one_comma {
        field.replace(',', ".").parse().ok()
    } else {
        field.parse().ok()
    }
}

/// The finite numbers among `fields`, where each is a number, `NaN` or
/// empty (`None` where one is text).
fn numbers_in(fields: &[String], sep: u8) -> Option<usize> {
    fields
        .iter()
        .all(|f| f.is_empty() || parse_number(f, sep).is_some())
        .then(|| {
            fields
                .iter()
                .filter(|f| parse_number(f, sep).is_some_and(f64::is_finite))
                .count()
        })
}

/// Whether `fields` is a data row: two or more fields, each a number,
/// `NaN` or empty, at least two of them finite numbers.
pub(crate) fn is_data(fields: &[String], sep: u8) -> bool {
    numbers_in(fields, sep).is_some_and(|n| n >= 2)
}

/// Whether a line, split at its own separator, is a data row
/// ([`is_data`]), as [`Table::parse`] finds the first.
pub(crate) fn line_is_data(line: &str) -> bool {
    let sep = separator(line);
    fields(line, sep)
        .ok()
        .flatten()
        .is_some_and(|f| is_data(&f, sep))
}

/// Whether `fields` is a data row with values missing: each field a
/// number, `NaN` or empty, at least one a finite number.
fn is_partial_data(fields: &[String], sep: u8) -> bool {
    numbers_in(fields, sep).is_some_and(|n| n >= 1)
}

/// Bytes as text: UTF-16 with its mark, UTF-8, else Latin-1 (a Windows
/// tool's `°`).
pub fn decode(bytes: Vec<u8>) -> String {
    // UTF-16 with its byte-order mark (Excel's "Unicode text").
    let utf16 = |le: bool| {
        let units: Vec<u16> = bytes
            .get(2..)
            .unwrap_or_default()
            .chunks_exact(2)
            .map(|c| {
                let pair = [c[0], c[1]];
                if le {
                    u16::from_le_bytes(pair)
                } else {
                    u16::from_be_bytes(pair)
                }
            })
            .collect();
        String::from_utf16_lossy(&units)
    };
    match bytes.get(..2) {
        Some([0xFF, 0xFE]) => return utf16(true),
        Some([0xFE, 0xFF]) => return utf16(false),
        _ => {}
    }
    String::from_utf8(bytes)
        .unwrap_or_else(|e| e.into_bytes().iter().map(|&b| char::from(b)).collect())
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
    ///
    /// The header is the line just before the first data row (two or more
    /// fields, all numbers, `NaN` or empty) where it has as many fields or
    /// two or more and is no data row itself; the lines above it are the preamble. A
    /// file whose first data row follows no such line has no header: its
    /// columns are named `column 1`, `column 2`, ... and every line above
    /// is preamble (a logger's messages).
    pub fn parse(path: &Path, text: &str) -> Result<Table, CsvError> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        // A carriage return alone ends a line too (old Mac line ends, or
        // files joined from several tools).
        let cr_alone;
        let text = if text.split("\r\n").any(|part| part.contains('\r')) {
            cr_alone = text.replace("\r\n", "\n").replace('\r', "\n");
            cr_alone.as_str()
        } else {
            text
        };
        let lines: Vec<(usize, &str)> = text
            .lines()
            .enumerate()
            .map(|(i, l)| (i + 1, l))
            .filter(|(_, l)| !l.trim().is_empty())
            .collect();
        if lines.is_empty() {
            return Err(CsvError::new(path, 0, "empty file"));
        }
        let unreadable =
            |line: usize, e: csv::Error| CsvError::new(path, line, format!("unreadable: {e}"));
        // The first data row, its separator its own.
        let mut first_data = None;
        for (k, &(line, l)) in lines.iter().enumerate() {
            let sep = separator(l);
            if let Some(f) = fields(l, sep).map_err(|e| unreadable(line, e))?
                && is_data(&f, sep)
            {
                // Rows just above it no wider, values missing (a first
                // frame the tracker lost), are data too, not its header.
                let mut k = k;
                while let Some(&(_, above)) = k.checked_sub(1).and_then(|j| lines.get(j)) {
                    match fields(above, sep) {
                        Ok(Some(g)) if g.len() <= f.len() && is_partial_data(&g, sep) => k -= 1,
                        _ => break,
                    }
                }
                first_data = Some((k, sep, f.len()));
                break;
            }
        }
        // No data row: the first line is the header (the readers say what
        // is missing).
        let (data_at, sep, width) = first_data.unwrap_or((1, separator(lines[0].1), 0));
        let header_at = data_at.checked_sub(1).filter(|&k| {
            let (_, l) = lines[k];
            let f = fields(l, sep).ok().flatten().unwrap_or_default();
            first_data.is_none() || ((f.len() == width || f.len() >= 2) && !is_data(&f, sep))
        });
        let header = match header_at {
            Some(k) => fields(lines[k].1, sep)
                .map_err(|e| unreadable(lines[k].0, e))?
                .unwrap_or_default(),
            None => (1..=width).map(|c| format!("column {c}")).collect(),
        };
        let preamble = lines[..header_at.unwrap_or(data_at)]
            .iter()
            .map(|(_, l)| l.trim().to_string())
            .collect();
        let mut rows = Vec::new();
        for &(line, l) in lines.iter().skip(data_at) {
            if let Some(fields) = fields(l, sep).map_err(|e| unreadable(line, e))? {
                rows.push(Row { line, fields });
            }
        }
        Ok(Table {
            path: path.to_path_buf(),
            preamble,
            header,
            named: header_at.is_some(),
            rows,
            separator: sep,
        })
    }

    /// A further line of this table's file (at 1-based `line`) as a row,
    /// `None` where it is blank.
    pub fn row(&self, line: usize, text_line: &str) -> Result<Option<Row>, CsvError> {
        Ok(fields(text_line, self.separator)
            .map_err(|e| self.error(line, format!("unreadable: {e}")))?
            .map(|fields| Row { line, fields }))
    }

    /// Reads and parses the file at `path`.
    pub fn read(path: &Path) -> Result<Table, CsvError> {
        let bytes =
            std::fs::read(path).map_err(|e| CsvError::new(path, 0, format!("cannot read: {e}")))?;
        Table::parse(path, &decode(bytes))
    }

    /// A problem at `line`.
    pub fn error(&self, line: usize, problem: impl Into<String>) -> CsvError {
        CsvError::new(&self.path, line, problem)
    }

    /// Field `k` of `row` as a finite number; `what` names it in errors.
    pub fn number(&self, row: &Row, k: usize, what: &str) -> Result<f64, CsvError> {
        match self.optional_number(row, k, what)? {
            Some(v) if v.is_finite() => Ok(v),
            Some(v) => Err(self.error(row.line, format!("{what} is {v}, not a finite number"))),
            None => Err(self.error(row.line, format!("missing {what} (column {})", k + 1))),
        }
    }

    /// Field `k` of `row` as a number, `None` where it is empty or
    /// missing (`NaN` is returned as NaN); text is an error.
    pub fn optional_number(
        &self,
        row: &Row,
        k: usize,
        what: &str,
    ) -> Result<Option<f64>, CsvError> {
        let Some(f) = row.fields.get(k).filter(|f| !f.is_empty()) else {
            return Ok(None);
        };
        let v = parse_number(f, self.separator)
            .ok_or_else(|| self.error(row.line, format!("{what} {} is not a number", quoted(f))))?;
        if v.is_infinite() {
            return Err(self.error(row.line, format!("{what} is {v}, not a finite number")));
        }
        Ok(Some(v))
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
        assert_eq!(t.rows.len(), 3);
        assert_eq!(t.rows[2].fields, ["2", "3"]);
        assert_eq!(fields("[1.0, 2.0]", b',').unwrap().unwrap(), ["1.0", "2.0"]);
    }

    #[test]
    fn separators_lines_and_blank_rows() {
        let text = "\nt\ttheta [deg]\n0\t1\n\n0.1\t2\n";
        let t = Table::parse(Path::new("a.tsv"), text).unwrap();
        assert_eq!(t.header, ["t", "theta [deg]"]);
        assert_eq!(t.rows.len(), 2);
        // Lines are the file's: the header is on line 2, the last row on 5.
        assert_eq!(t.rows[1].line, 5);
        assert_eq!(t.number(&t.rows[1], 1, "theta").unwrap(), 2.0);
        let e = t.number(&t.rows[1], 2, "rate").unwrap_err();
        assert_eq!(e.to_string(), "a.tsv:5: missing rate (column 3)");
        assert_eq!(separator("a;b;c"), b';');
        assert_eq!(separator("a,b"), b',');
        assert_eq!(separator("single"), b',');
        let e = Table::parse(Path::new("e.csv"), " \n\n").unwrap_err();
        assert_eq!(e.to_string(), "e.csv: empty file");
        let t = Table::parse(Path::new("n.csv"), "t,x\n0,NaN\n1,abc\n").unwrap();
        assert!(
            t.number(&t.rows[0], 1, "x")
                .unwrap_err()
                .to_string()
                .starts_with("n.csv:2: x is NaN")
        );
        assert!(
            t.number(&t.rows[1], 1, "x")
                .unwrap_err()
                .to_string()
                .contains("n.csv:3: x \"abc\" is not a number")
        );
    }

    /// A byte-order mark, CRLF and decimal commas with tab or semicolon
    /// separators; a comma-separated file keeps its commas as separators.
    /// A first frame with its values missing (a tracker that lost the
    /// bob, tabs trimmed off) is a row, not the header, which stays the
    /// line above it.
    #[test]
    fn a_first_row_with_values_missing_keeps_the_header() {
        let text = "mass_A\nt\tx\ty\n0.0\t\t\n0.02\t728.3\t613.2\n0.04\t727.3\t612.9\n";
        let t = Table::parse(Path::new("tracker.txt"), text).unwrap();
        assert_eq!(t.header, ["t", "x", "y"]);
        assert_eq!(t.preamble, ["mass_A"]);
        assert_eq!(t.rows.len(), 3);
        assert_eq!(t.rows[0].line, 3);
    }

    /// UTF-16 with its mark (Excel's "Unicode text", tab-separated) and
    /// a carriage return alone as the line end are read; a long cell where
    /// a number belongs is quoted short in the error.
    #[test]
    fn utf_16_old_mac_line_ends_and_a_long_cell() {
        let text = "Time (s)\tAngle (rad)\r\n0\t0.3\r\n0.02\t0.29\r\n";
        let mut bytes = vec![0xFF, 0xFE];
        bytes.extend(text.encode_utf16().flat_map(u16::to_le_bytes));
        let t = Table::parse(Path::new("u.txt"), &decode(bytes)).unwrap();
        assert_eq!(t.header, ["Time (s)", "Angle (rad)"]);
        assert_eq!(t.rows.len(), 2);
        let t = Table::parse(Path::new("m.csv"), "t,theta\r0,0.3\r0.02,0.29\r").unwrap();
        assert_eq!((t.header.len(), t.rows.len()), (2, 2));
        let long = "x".repeat(100_000);
        let t = Table::parse(
            Path::new("l.csv"),
            &format!("t,theta\n0,0.3\n0.02,{long}\n"),
        )
        .unwrap();
        let e = t.number(&t.rows[1], 1, "theta").unwrap_err().to_string();
        assert!(
            e.len() < 200 && e.contains("..."),
            "{}",
            &e[..e.len().min(300)]
        );
    }

    /// Columns aligned by runs of spaces are read as columns.
    #[test]
    fn columns_aligned_by_spaces() {
        let t = Table::parse(Path::new("s.txt"), "t   theta\n0.00   0.30\n0.02  0.29\n").unwrap();
        assert_eq!(t.header, ["t", "theta"]);
        assert_eq!(t.rows[1].fields, ["0.02", "0.29"]);
    }

    #[test]
    fn a_bom_crlf_and_decimal_commas() {
        let text = "\u{feff}Time (s)\tAngle (rad)\r\n0,0000\t-1,25\r\n\r\n0,0200\t3\r\n";
        let t = Table::parse(Path::new("p.txt"), text).unwrap();
        assert_eq!(t.header, ["Time (s)", "Angle (rad)"]);
        assert_eq!(t.rows[1].line, 4);
        assert_eq!(t.number(&t.rows[0], 1, "angle").unwrap(), -1.25);
        assert_eq!(t.number(&t.rows[1], 0, "time").unwrap(), 0.02);
        let t = Table::parse(Path::new("s.csv"), "t;x\n1,5;2\n1,2,3;4.5\n").unwrap();
        assert_eq!(t.number(&t.rows[0], 0, "t").unwrap(), 1.5);
        assert!(t.number(&t.rows[1], 0, "t").is_err());
        assert_eq!(t.number(&t.rows[1], 1, "x").unwrap(), 4.5);
        let t = Table::parse(Path::new("c.csv"), "t,x\n1,5\n").unwrap();
        assert_eq!(t.rows[0].fields, ["1", "5"]);
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
        assert_eq!(t.number(&t.rows[0], 1, "x").unwrap(), 0.1);
        assert_eq!(t.rows[0].line, 3);
        let text = "Spatial 302088 Attached!\nwaiting 30 seconds to start...\n[31.052, 0.03, 0.99]\n[31.056, NaN, 1e-2]\n";
        let t = Table::parse(Path::new("imu.txt"), text).unwrap();
        assert!(!t.named);
        assert_eq!(t.header, ["column 1", "column 2", "column 3"]);
        assert_eq!(t.preamble.len(), 2);
        assert_eq!(t.rows[1].fields, ["31.056", "NaN", "1e-2"]);
        assert!(
            t.optional_number(&t.rows[1], 1, "x")
                .unwrap()
                .unwrap()
                .is_nan()
        );
        assert_eq!(t.optional_number(&t.rows[1], 5, "x").unwrap(), None);
        assert!(
            t.number(&t.rows[1], 1, "x")
                .unwrap_err()
                .to_string()
                .contains("imu.txt:4: x is NaN")
        );
    }
}
