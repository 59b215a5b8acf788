//! The tables in a file: a text table as it is; each CSV of a zip (as
//! phyphox exports one a data set, its `meta/` left out); each sheet of a
//! workbook (`.xlsx`, `.xls`, `.ods`, read by `calamine`, the pure-Rust
//! reader most used for them). An archive's tables are named
//! `file.zip:entry` or `file.xlsx:sheet` in errors.

use std::io::Read;
use std::path::{Path, PathBuf};

use calamine::{Data, Reader, open_workbook_auto};

use crate::data::table::{CsvError, Table, decode};

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
        "xlsx" | "xls" | "xlsm" | "ods" => sheet_tables(path)?,
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

/// Each CSV entry of a zip, `meta/` left out.
fn zip_tables(path: &Path) -> Result<Vec<Table>, CsvError> {
    let bad = |e: &dyn std::fmt::Display| CsvError::new(path, 0, format!("unreadable zip: {e}"));
    let file = std::fs::File::open(path)
        .map_err(|e| CsvError::new(path, 0, format!("cannot read: {e}")))?;
    let mut zip = zip::ZipArchive::new(file).map_err(|e| bad(&e))?;
    let mut tables = Vec::new();
    for k in 0..zip.len() {
        let mut entry = zip.by_index(k).map_err(|e| bad(&e))?;
        let name = entry.name().map_err(|e| bad(&e))?.to_string();
        let lower = name.to_lowercase();
        if !entry.is_file() || !lower.ends_with(".csv") || lower.starts_with("meta/") {
            continue;
        }
        let mut bytes = Vec::new();
        entry.read_to_end(&mut bytes).map_err(|e| bad(&e))?;
        let named = PathBuf::from(format!("{}:{name}", path.display()));
        tables.push(Table::parse(&named, &decode(bytes))?);
    }
    Ok(tables)
}

/// Each sheet of a workbook with rows, written as tab-separated text.
fn sheet_tables(path: &Path) -> Result<Vec<Table>, CsvError> {
    let mut book = open_workbook_auto(path)
        .map_err(|e| CsvError::new(path, 0, format!("unreadable workbook: {e}")))?;
    let mut tables = Vec::new();
    for (name, range) in book.worksheets() {
        let text: String = range
            .rows()
            .map(|row| {
                let cells: Vec<String> = row.iter().map(cell).collect();
                cells.join("\t") + "\n"
            })
            .collect();
        if text.trim().is_empty() {
            continue;
        }
        let named = PathBuf::from(format!("{}:{name}", path.display()));
        tables.push(Table::parse(&named, &text)?);
    }
    Ok(tables)
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
