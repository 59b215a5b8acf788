//! Delimited text, read through the `csv` crate: a header of column names
//! and rows of fields, each row with its 1-based line in the file, so
//! that every problem names the file and line ([`CsvError`]).
//!
//! The separator is a comma, a tab or a semicolon, whichever the header
//! line has most of; with a tab or a semicolon a number may have a decimal
//! comma (`0,25`). Blank lines are skipped; rows may have fewer or more
//! fields than the header (the reader that asks for a field says which is
//! missing). A byte-order mark at the start is ignored, CRLF reads as LF,
//! and a file that is not UTF-8 is read as Latin-1 (a `°` written by a
//! Windows tool).

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
    /// The header's fields, trimmed, as written.
    pub header: Vec<String>,
    /// The data rows after the header.
    pub rows: Vec<Row>,
    /// The separator: `,`, tab or `;`.
    pub separator: u8,
}

/// The separator the header line uses most: `,`, tab or `;` (`,` when it
/// has none).
pub fn separator(header_line: &str) -> u8 {
    [b',', b'\t', b';']
        .into_iter()
        .max_by_key(|&c| (header_line.bytes().filter(|&b| b == c).count(), c == b','))
        .unwrap_or(b',')
}

impl Table {
    /// Parses `text` (the contents of `path`): the first non-blank line is
    /// the header.
    pub fn parse(path: &Path, text: &str) -> Result<Table, CsvError> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let first = text.lines().find(|l| !l.trim().is_empty()).unwrap_or("");
        let sep = separator(first);
        let mut header: Option<Vec<String>> = None;
        let mut rows = Vec::new();
        // Line by line, so that the line numbers are the file's (the csv
        // crate's own count skips blank lines); each line's fields are
        // split by the csv crate (quotes, separators, spaces).
        for (i, text_line) in text.lines().enumerate() {
            if text_line.trim().is_empty() {
                continue;
            }
            let line = i + 1;
            let mut reader = csv::ReaderBuilder::new()
                .delimiter(sep)
                .has_headers(false)
                .flexible(true)
                .trim(csv::Trim::All)
                .buffer_capacity(text_line.len() + 8)
                .from_reader(text_line.as_bytes());
            let mut record = csv::StringRecord::new();
            let got = reader
                .read_record(&mut record)
                .map_err(|e| CsvError::new(path, line, format!("unreadable: {e}")))?;
            if !got {
                continue;
            }
            let fields: Vec<String> = record.iter().map(str::to_string).collect();
            match header {
                None => header = Some(fields),
                Some(_) => rows.push(Row { line, fields }),
            }
        }
        let header = header.ok_or_else(|| CsvError::new(path, 0, "empty file"))?;
        Ok(Table {
            path: path.to_path_buf(),
            header,
            rows,
            separator: sep,
        })
    }

    /// Reads and parses the file at `path`.
    pub fn read(path: &Path) -> Result<Table, CsvError> {
        let bytes =
            std::fs::read(path).map_err(|e| CsvError::new(path, 0, format!("cannot read: {e}")))?;
        let text = String::from_utf8(bytes)
            .unwrap_or_else(|e| e.into_bytes().iter().map(|&b| char::from(b)).collect());
        Table::parse(path, &text)
    }

    /// A problem at `line`.
    pub fn error(&self, line: usize, problem: impl Into<String>) -> CsvError {
        CsvError::new(&self.path, line, problem)
    }

    /// Field `k` of `row` as a finite number; `what` names it in errors.
    pub fn number(&self, row: &Row, k: usize, what: &str) -> Result<f64, CsvError> {
        let f = row
            .fields
            .get(k)
            .ok_or_else(|| self.error(row.line, format!("missing {what} (column {})", k + 1)))?;
        let v: f64 = self
            .decimal_point(f)
            .parse()
            .map_err(|_| self.error(row.line, format!("{what} {f:?} is not a number")))?;
        if !v.is_finite() {
            return Err(self.error(row.line, format!("{what} is {v}, not a finite number")));
        }
        Ok(v)
    }

    /// `field` with a decimal comma made a point, where the separator is
    /// not a comma and the field has one comma and no point.
    fn decimal_point<'a>(&self, field: &'a str) -> std::borrow::Cow<'a, str> {
        let one_comma = field.matches(',').count() == 1 && !field.contains('.');
        if self.separator != b',' && one_comma {
            field.replace(',', ".").into()
        } else {
            field.into()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
