//! The tables in a file: a text table as it is; each CSV of a zip (as
//! phyphox exports one a data set, its `meta/` left out), read as it
//! inflates; each sheet of a workbook (`.xlsx`, `.xls`, `.ods`, read by
//! `calamine`, the pure-Rust reader most used for them); each export set
//! of phyphox's own `.phyphox` file ([`super::phyphox`]). An archive's
//! tables are named `file.zip:entry` or `file.xlsx:sheet` in errors.
//!
//! An archive's entry is read with limits on what it inflates to
//! ([`INFLATED_MAX`], [`RATIO_MAX`] past [`RATIO_GRACE`]): refused by the
//! size its header states before anything is inflated, and by the bytes
//! it gives as they are read (a header that understates them).

use std::io::Read;
use std::path::{Path, PathBuf};

use calamine::{Data, Reader, open_workbook_auto};

use crate::data::table::{CsvError, Table};

/// Largest inflated size of an archive's entry, bytes (1 GiB): an hour
/// of a phone's gyroscope at 500 Hz exports about 300 MB.
pub const INFLATED_MAX: u64 = 1 << 30;

/// Largest ratio of an entry's inflated size to its compressed size past
/// [`RATIO_GRACE`]: 100, Apache POI's `ZipSecureFile` default (a least
/// inflate ratio of 0.01). A table of measured numbers deflates 2 to 4
/// times; a zip bomb, hundreds to a thousand.
pub const RATIO_MAX: u64 = 100;

/// Inflated bytes of an entry below which its ratio is not checked
/// (100 KiB, as POI's grace size): a tiny file of repeated text may
/// compress well.
pub const RATIO_GRACE: u64 = 100 << 10;

/// The extension of `path`, lower case.
fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_lowercase()
}

/// The tables of the file at `path` (see the module docs); at least one.
pub fn read_tables(path: &Path) -> Result<Vec<Table>, CsvError> {
    let tables = match extension(path).as_str() {
        "zip" => zip_tables(path)?,
        "xlsx" | "xlsm" | "ods" => {
            check_zip_entries(path)?;
            sheet_tables(path)?
        }
        "xls" => sheet_tables(path)?,
        "phyphox" => super::phyphox::tables(path)?,
        _ => return Ok(vec![Table::read(path)?]),
    };
    if tables.is_empty() {
        return Err(CsvError::new(
            path,
            0,
            "holds no table (no CSV file or sheet with rows)",
        ));
    }
    Ok(tables)
}

/// The most an entry of `compressed` bytes may inflate to.
fn inflate_limit(compressed: u64) -> u64 {
    INFLATED_MAX.min(RATIO_GRACE.max(compressed.saturating_mul(RATIO_MAX)))
}

/// Why an entry stating `size` inflated bytes of `compressed` is refused,
/// if it is.
fn too_large(size: u64, compressed: u64) -> Option<String> {
    if size > INFLATED_MAX {
        Some(format!(
            "inflates to {size} bytes, over the limit of {INFLATED_MAX} (1 GiB): refused"
        ))
    } else if size > inflate_limit(compressed) {
        Some(format!(
            "inflates {size} bytes from {compressed}, over {RATIO_MAX} times: refused as a zip bomb"
        ))
    } else {
        None
    }
}

/// A reader that fails once it has given more than `limit` bytes.
struct Bounded<R> {
    inner: R,
    limit: u64,
    read: u64,
}

impl<R: Read> Read for Bounded<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.read += n as u64;
        if self.read > self.limit {
            return Err(std::io::Error::other(format!(
                "inflates past {} bytes, more than its header states or the limit \
                 ({INFLATED_MAX} bytes, {RATIO_MAX} times its compressed size): refused",
                self.limit
            )));
        }
        Ok(n)
    }
}

/// Each CSV entry of a zip, `meta/` left out, each read as it inflates
/// within its limits (see the module docs).
fn zip_tables(path: &Path) -> Result<Vec<Table>, CsvError> {
    let bad = |e: &dyn std::fmt::Display| CsvError::new(path, 0, format!("unreadable zip: {e}"));
    let file = std::fs::File::open(path)
        .map_err(|e| CsvError::new(path, 0, format!("cannot read: {e}")))?;
    let mut zip = zip::ZipArchive::new(file).map_err(|e| bad(&e))?;
    let mut tables = Vec::new();
    for k in 0..zip.len() {
        let entry = zip.by_index(k).map_err(|e| bad(&e))?;
        let name = entry.name().map_err(|e| bad(&e))?.to_string();
        let lower = name.to_lowercase();
        if !entry.is_file() || !lower.ends_with(".csv") || lower.starts_with("meta/") {
            continue;
        }
        let named = PathBuf::from(format!("{}:{name}", path.display()));
        let compressed = entry.compressed_size();
        if let Some(why) = too_large(entry.size(), compressed) {
            return Err(CsvError::new(&named, 0, why));
        }
        let size = entry.size();
        let bounded = Bounded {
            inner: entry,
            limit: size.max(1).min(inflate_limit(compressed)),
            read: 0,
        };
        tables.push(Table::from_sized_reader(&named, bounded, Some(size))?);
    }
    Ok(tables)
}

/// A workbook that is a zip (`.xlsx`, `.ods`): each entry's stated size
/// within the limits, before `calamine` inflates its sheets.
fn check_zip_entries(path: &Path) -> Result<(), CsvError> {
    let bad =
        |e: &dyn std::fmt::Display| CsvError::new(path, 0, format!("unreadable workbook: {e}"));
    let file = std::fs::File::open(path)
        .map_err(|e| CsvError::new(path, 0, format!("cannot read: {e}")))?;
    let mut zip = zip::ZipArchive::new(file).map_err(|e| bad(&e))?;
    for k in 0..zip.len() {
        let entry = zip.by_index(k).map_err(|e| bad(&e))?;
        if let Some(why) = too_large(entry.size(), entry.compressed_size()) {
            let name = entry.name().map_err(|e| bad(&e))?.to_string();
            return Err(CsvError::new(
                &PathBuf::from(format!("{}:{name}", path.display())),
                0,
                why,
            ));
        }
    }
    Ok(())
}

/// Each sheet of a workbook with rows, read as a table a row at a time
/// (each row as a tab-separated line, not the sheet as one text).
fn sheet_tables(path: &Path) -> Result<Vec<Table>, CsvError> {
    let mut book = open_workbook_auto(path)
        .map_err(|e| CsvError::new(path, 0, format!("unreadable workbook: {e}")))?;
    let mut tables = Vec::new();
    for (name, range) in book.worksheets() {
        if range
            .used_cells()
            .all(|(_, _, c)| cell(c).trim().is_empty())
        {
            continue;
        }
        let named = PathBuf::from(format!("{}:{name}", path.display()));
        let lines = SheetLines {
            rows: range.rows(),
            line: Vec::new(),
            at: 0,
        };
        tables.push(Table::from_reader(&named, lines)?);
    }
    Ok(tables)
}

/// A sheet's rows as text, a tab-separated line a row, made as they are
/// read.
struct SheetLines<'a> {
    rows: calamine::Rows<'a, Data>,
    /// The line being given out, and how much of it is.
    line: Vec<u8>,
    at: usize,
}

impl Read for SheetLines<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if self.at >= self.line.len() {
            let Some(row) = self.rows.next() else {
                return Ok(0);
            };
            let cells: Vec<String> = row.iter().map(cell).collect();
            self.line = (cells.join("\t") + "\n").into_bytes();
            self.at = 0;
        }
        let n = buf.len().min(self.line.len() - self.at);
        buf[..n].copy_from_slice(&self.line[self.at..self.at + n]);
        self.at += n;
        Ok(n)
    }
}

/// A cell as text: a number as Rust writes it (a point, no rounding).
fn cell(c: &Data) -> String {
    match c {
        Data::Int(v) => v.to_string(),
        Data::Float(v) => v.to_string(),
        Data::Empty => String::new(),
        other => other.to_string().replace('\t', " "),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    /// A zip whose entry states it inflates past [`INFLATED_MAX`] (1 GiB
    /// and a byte of zeros, deflated to about a megabyte, written a chunk
    /// at a time) is refused before it is inflated, with the limit named;
    /// memory stays at the writer's chunk and the reader's buffers.
    #[test]
    fn an_entry_that_inflates_past_the_limit_is_refused() {
        let path = std::env::temp_dir().join(format!("koopman-{}-bomb.zip", std::process::id()));
        {
            let mut zip = zip::ZipWriter::new(std::fs::File::create(&path).unwrap());
            let options = zip::write::SimpleFileOptions::default()
                .compression_method(zip::CompressionMethod::Deflated)
                .compression_level(Some(1))
                .large_file(true);
            zip.start_file("Raw Data.csv", options).unwrap();
            zip.write_all(b"\"Time (s)\",\"Gyroscope x (rad/s)\"\n")
                .unwrap();
            let zeros = vec![b' '; 1 << 20];
            for _ in 0..1024 {
                zip.write_all(&zeros).unwrap();
            }
            zip.finish().unwrap();
        }
        let e = read_tables(&path).unwrap_err().to_string();
        std::fs::remove_file(&path).unwrap();
        assert!(e.contains("Raw Data.csv") && e.contains("1 GiB"), "{e}");
    }

    /// An entry that inflates past what its header states (or a small
    /// limit) fails as it is read, naming the limit.
    #[test]
    fn an_entry_read_past_its_limit_fails_as_it_is_read() {
        let bounded = Bounded {
            inner: std::io::repeat(b' ').take(5000),
            limit: 4096,
            read: 0,
        };
        let e = Table::from_reader(Path::new("x.zip:a.csv"), bounded)
            .unwrap_err()
            .to_string();
        assert!(e.contains("inflates past 4096 bytes"), "{e}");
        assert!(too_large(1 << 20, 1 << 10).is_some_and(|w| w.contains("zip bomb")));
        assert!(too_large(50 << 10, 100).is_none());
        assert!(too_large(3 << 20, 1 << 20).is_none());
    }
}
