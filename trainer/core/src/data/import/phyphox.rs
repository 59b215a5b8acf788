//! phyphox's own `.phyphox` file: the experiment saved with its data.
//!
//! Its structure, from the app's sources (phyphox-android
//! `PhyphoxExperiment.writeStateFile` and `PhyphoxFile`'s container
//! parser; phyphox-ios `LegacyStateSerializer`; the experiments'
//! definitions in phyphox-experiments, all at their 2025-07-02 heads):
//! the experiment's XML as it was loaded (`<phyphox>` with its title,
//! translations, `<data-containers>`, `<input>`, `<views>`, `<analysis>`,
//! `<export>`), each `<container>` given an `init` attribute that holds
//! its buffer's values, comma-separated (`0.#########E0`: `4.4677716E-2`,
//! `0E0`, `NaN`), the buffer's name the element's text, and
//! `<state-title>`, `<color>` and `<events>` added at the end.
//!
//! Read here: each `<set>` of `<export>` (`<data name="Time (s)">gyr_time</data>`
//! ...) becomes the table its CSV export would hold, its columns named as
//! the export names them and filled from the buffers, so the file imports
//! as that CSV would (the gyroscope's `Raw Data`: `Time (s)`, `Gyroscope
//! x (rad/s)`, ...; the pendulum's: `Rotation x (rad/s)`, ...). A file
//! without `<export>` gives one table of the buffers as they are named
//! (`gyr_time` read as the time, `gyrX` as a rate axis), those as long as
//! its first buffer named `..time`. A file with neither gets an error that
//! names its buffers and how many values each holds.
//!
//! The file is read as XML by `quick-xml` (the reader `calamine` uses),
//! one element at a time; a buffer's values are held once, as numbers.

use std::io::BufReader;
use std::path::{Path, PathBuf};

use quick_xml::Reader;
use quick_xml::events::{BytesStart, Event};

use crate::data::table::{CsvError, Table, listed, number};

/// A buffer of the file: its name and values.
struct Buffer {
    name: String,
    values: Vec<f64>,
}

/// A set of the file's export: its name and its columns, each a name
/// and the buffer it is filled from.
struct ExportSet {
    name: String,
    columns: Vec<(String, String)>,
}

/// What a `.phyphox` file holds.
struct Saved {
    buffers: Vec<Buffer>,
    sets: Vec<ExportSet>,
}

/// An attribute of `e` by name, unescaped.
fn attribute(e: &BytesStart<'_>, key: &str) -> Option<String> {
    e.attributes()
        .flatten()
        .find(|a| a.key.0 == key)
        .and_then(|a| {
            a.normalized_value(quick_xml::XmlVersion::default())
                .ok()
                .map(|v| v.into_owned())
        })
}

/// A buffer's `init` values as numbers (one not a number as NaN, as the
/// app reads it).
fn values(init: &str) -> Vec<f64> {
    if init.trim().is_empty() {
        return Vec::new();
    }
    init.split(',')
        .map(|v| number(v).unwrap_or(f64::NAN))
        .collect()
}

/// Reads the buffers and the export of the file at `path`.
fn read(path: &Path) -> Result<Saved, CsvError> {
    let bad =
        |e: &dyn std::fmt::Display| CsvError::new(path, 0, format!("unreadable phyphox file: {e}"));
    let file = std::fs::File::open(path)
        .map_err(|e| CsvError::new(path, 0, format!("cannot read: {e}")))?;
    let mut reader = Reader::from_reader(BufReader::new(file));
    let mut buf = Vec::new();
    let mut saved = Saved {
        buffers: Vec::new(),
        sets: Vec::new(),
    };
    // Where the reader is: inside <data-containers>, a <container> (its
    // values), an export <set>, a <data> (its column's name).
    let mut in_containers = false;
    let mut container: Option<Vec<f64>> = None;
    let mut data: Option<String> = None;
    let mut text = String::new();
    let mut root = false;
    loop {
        match reader.read_event_into(&mut buf).map_err(|e| bad(&e))? {
            Event::Start(e) => {
                let name = e.local_name();
                match name.as_ref() {
                    "phyphox" => root = true,
                    "data-containers" => in_containers = true,
                    "container" if in_containers => {
                        container = Some(values(&attribute(&e, "init").unwrap_or_default()));
                    }
                    "set" => saved.sets.push(ExportSet {
                        name: attribute(&e, "name").unwrap_or_default(),
                        columns: Vec::new(),
                    }),
                    "data" if !saved.sets.is_empty() => {
                        data = Some(attribute(&e, "name").unwrap_or_default());
                    }
                    _ => {}
                }
                text.clear();
            }
            Event::Text(t) => text.push_str(&t),
            Event::End(e) => {
                let name = e.local_name();
                match name.as_ref() {
                    "data-containers" => in_containers = false,
                    "container" => {
                        if let Some(values) = container.take() {
                            saved.buffers.push(Buffer {
                                name: text.trim().to_string(),
                                values,
                            });
                        }
                    }
                    "data" => {
                        if let (Some(column), Some(set)) = (data.take(), saved.sets.last_mut()) {
                            set.columns.push((column, text.trim().to_string()));
                        }
                    }
                    _ => {}
                }
                text.clear();
            }
            Event::Eof => break,
            _ => {}
        }
        buf.clear();
    }
    if !root {
        return Err(bad(&"no <phyphox> element: not a phyphox file"));
    }
    Ok(saved)
}

/// The tables of a `.phyphox` file (see the module docs); at least one.
pub fn tables(path: &Path) -> Result<Vec<Table>, CsvError> {
    let saved = read(path)?;
    let buffer = |name: &str| saved.buffers.iter().find(|b| b.name == name);
    let mut tables = Vec::new();
    for set in &saved.sets {
        let filled: Vec<(String, Vec<f64>)> = set
            .columns
            .iter()
            .filter_map(|(column, name)| buffer(name).map(|b| (column.clone(), b.values.clone())))
            .collect();
        if filled.iter().filter(|(_, v)| !v.is_empty()).count() < 2 {
            continue;
        }
        let (header, columns) = filled.into_iter().unzip();
        let named = PathBuf::from(format!("{}:{}", path.display(), set.name));
        tables.push(Table::of_columns(&named, header, columns));
    }
    if tables.is_empty()
        && let Some(time) = saved
            .buffers
            .iter()
            .find(|b| b.name.to_lowercase().ends_with("time") && b.values.len() >= 3)
    {
        let same: Vec<&Buffer> = saved
            .buffers
            .iter()
            .filter(|b| b.values.len() == time.values.len() && b.name != time.name)
            .collect();
        if !same.is_empty() {
            let header = std::iter::once("t".to_string())
                .chain(same.iter().map(|b| b.name.clone()))
                .collect();
            let columns = std::iter::once(time.values.clone())
                .chain(same.iter().map(|b| b.values.clone()))
                .collect();
            tables.push(Table::of_columns(path, header, columns));
        }
    }
    if tables.is_empty() {
        let held: Vec<String> = saved
            .buffers
            .iter()
            .map(|b| format!("{} ({} values)", b.name, b.values.len()))
            .collect();
        return Err(CsvError::new(
            path,
            0,
            format!(
                "a phyphox file with no recorded buffers to import (no export set of two filled buffers, no time buffer): its buffers are {}",
                if held.is_empty() {
                    "none".to_string()
                } else {
                    listed(&held, ", ")
                }
            ),
        ));
    }
    Ok(tables)
}
