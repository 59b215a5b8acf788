//! A table split by the runs its columns are marked with (`Run 1:`,
//! `Run #2`), and the Phidget logger's rows named.

use std::borrow::Cow;

use crate::data::table::Table;

use super::names::run_of;

/// The Phidget Spatial logger's rows, `[t, ax, ay, az, gx, gy, gz]`
/// after its messages (which name the device), without a header: named,
/// the rates in degrees per second as the device gives them.
pub(super) fn known_headerless(table: &Table) -> (Cow<'_, Table>, Option<&'static str>) {
    let phidget = !table.named
        && table.header.len() == 7
        && table
            .preamble
            .iter()
            .any(|l| l.to_lowercase().contains("phidget"));
    if !phidget {
        return (Cow::Borrowed(table), None);
    }
    let mut named = table.clone();
    named.header = [
        "t (s)",
        "ax (g)",
        "ay (g)",
        "az (g)",
        "gx (°/s)",
        "gy (°/s)",
        "gz (°/s)",
    ]
    .map(String::from)
    .to_vec();
    (Cow::Owned(named), Some("Phidget Spatial logger"))
}

/// The table split by run where its columns are marked with two or more
/// (a column marked with none goes with every run); else the table as it
/// is. A run's rows are those with a value in one of its columns.
pub(super) fn split_runs(table: &Table) -> Vec<(Option<String>, Cow<'_, Table>)> {
    let marks: Vec<Option<String>> = table.header.iter().map(|h| run_of(h)).collect();
    let mut runs: Vec<String> = Vec::new();
    for m in marks.iter().flatten() {
        if !runs.contains(m) {
            runs.push(m.clone());
        }
    }
    if runs.len() < 2 {
        return vec![(None, Cow::Borrowed(table))];
    }
    runs.into_iter()
        .map(|run| {
            let cols: Vec<usize> = (0..table.header.len())
                .filter(|&k| marks[k].as_ref().is_none_or(|m| *m == run))
                .collect();
            let mut sub = table.select(&cols);
            let has_value = |r: usize| (0..cols.len()).any(|c| !sub.is_blank(r, c));
            let keep: Vec<bool> = (0..sub.len()).map(has_value).collect();
            sub.retain_rows(|r| keep[r]);
            (Some(run), Cow::Owned(sub))
        })
        .collect()
}
