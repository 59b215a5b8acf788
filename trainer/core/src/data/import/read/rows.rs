//! A table's rows as read: each row's time and values ([`read_row`]),
//! the rows without a value skipped, the rest in time order
//! ([`super::super::order`]).

use crate::data::table::{CsvError, Table};

use super::names::{bare, time_scale};

/// What one row gives, as `import` reads it.
pub(crate) enum RowRead {
    /// Its time and the values of the columns asked for.
    Values(f64, Vec<f64>),
    /// No time or a value missing (empty or `NaN`): skipped.
    Empty,
}

/// Row `row` (the `place`-th of its table): its time (column `ti` times
/// its seconds per unit, else its place at `rate` Hz) and the values of
/// `cols`; text where a number belongs is an error naming the line.
pub(crate) fn read_row(
    table: &Table,
    row: usize,
    place: usize,
    (ti, rate): (Option<(usize, f64)>, Option<f64>),
    cols: &[usize],
) -> Result<RowRead, CsvError> {
    let time = match (ti, rate) {
        (Some((k, scale)), _) => table.value(row, k, "time")?.map(|v| v * scale),
        (None, Some(r)) => Some(place as f64 / r),
        (None, None) => None,
    };
    let mut got = Vec::with_capacity(cols.len());
    for &k in cols {
        got.push(table.value(row, k, &bare(&table.header[k]))?);
    }
    match (
        time.filter(|v| v.is_finite()),
        got.into_iter().collect::<Option<Vec<f64>>>(),
    ) {
        (Some(time), Some(got)) => Ok(RowRead::Values(time, got)),
        _ => Ok(RowRead::Empty),
    }
}

/// The rows of a table as read: times and the values of the columns
/// asked for, in time order, and what was done to get there.
pub(super) struct Rows {
    pub(super) t: Vec<f64>,
    pub(super) values: Vec<Vec<f64>>,
    /// Rows skipped without a value.
    pub(super) skipped: usize,
    /// Rows skipped whose time repeats the one before.
    pub(super) repeated: usize,
    /// Rows put in time order ([`super::order`]).
    pub(super) reordered: usize,
}

/// The rows' times and the values of `cols` ([`read_row`]) in time order
/// ([`super::super::order::in_time_order`]), with the rows skipped without a
/// value, put in order and with a repeated time counted.
pub(super) fn read_rows(
    table: &Table,
    ti: Option<usize>,
    cols: &[usize],
    rate: Option<f64>,
) -> Result<Rows, CsvError> {
    let mut t: Vec<f64> = Vec::with_capacity(table.len());
    let mut values: Vec<Vec<f64>> = (0..cols.len())
        .map(|_| Vec::with_capacity(table.len()))
        .collect();
    // The rows skipped, to find a kept row's line again.
    let mut skipped_rows = Vec::new();
    let time = ti.map(|k| (k, time_scale(&table.header[k])));
    for row in 0..table.len() {
        match read_row(table, row, row, (time, rate), cols)? {
            RowRead::Values(time, got) => {
                t.push(time);
                for (v, x) in values.iter_mut().zip(got) {
                    v.push(x);
                }
            }
            RowRead::Empty => skipped_rows.push(row),
        }
    }
    let line = |kept: usize| {
        let row = skipped_rows
            .iter()
            .fold(kept, |row, &s| if s <= row { row + 1 } else { row });
        table.line(row)
    };
    if t.len() < 2 {
        return Err(table.error(0, "fewer than 2 rows with values"));
    }
    let order = super::super::order::in_time_order(&mut t, &mut values, line)
        .map_err(|(line, problem)| table.error(line, problem))?;
    Ok(Rows {
        t,
        values,
        skipped: skipped_rows.len(),
        repeated: order.repeated,
        reordered: order.reordered,
    })
}
