//! A recording imported as it is written (`koopman estimate --follow`):
//! lines in, samples on the model's grid out, each as `import` makes it.
//!
//! Steps, per line: until the first data row the lines are the preamble
//! and the header (read as [`Table::parse`] reads a file); from it the
//! columns are taken ([`super::read::stream_columns`]: an angle, a rate or
//! not); each row is read as `import` reads it (a row without a value or
//! with a repeated time skipped, one out of time order put at its time
//! among the rows held, [`super::order`]). Every
//! [`BATCH`] rows the rows held are imported as one recording on the grid
//! of the first time stamp ([`super::rollout_on_grid`]), and the grid's
//! samples that lie more than a margin before the last row are given out:
//! there, nothing later can change them (the glitch test's neighbours, the
//! differentiator's window), so they equal the samples `import` makes of
//! the whole file. The rows older than two margins are let go. At the end
//! of the input the rest is given out.
//!
//! Where the rate is derived, `import` takes the differentiator's window
//! from the whole recording's period; a stream takes it from its first
//! [`PERIODS_FOR_WINDOW`] swing periods (or `--smooth`, which makes both
//! the same), and says which.

use anyhow::Result;

use super::order::BACK_MAX_S;
use super::read::{Layout, RowRead, StreamColumns, read_row, stream_columns};
use super::{ImportOptions, Recording, rollout_on_grid, rough_period};
use crate::data::SourceMeta;
use crate::data::table::{Table, line_is_data};

/// Rows read between imports.
pub const BATCH: usize = 64;
/// Rows before the last one a sample waits for (the glitch test's
/// neighbours over its rounds), beside the differentiator's window.
pub const MARGIN_ROWS: usize = 96;
/// Swing periods read before the differentiator's window is fixed.
pub const PERIODS_FOR_WINDOW: f64 = 4.0;

/// A recording read line by line (see the module docs).
pub struct Stream {
    opts: ImportOptions,
    /// What the lines come from, as errors name it (`-`: standard input).
    name: std::path::PathBuf,
    /// The lines before the first data row, as the file has them.
    head: String,
    /// Lines read.
    lines: usize,
    /// The header, once found (no rows kept in it).
    table: Option<Table>,
    columns: Option<StreamColumns>,
    /// The rows held, read.
    rec: Recording,
    /// The first time stamp: the grid's origin.
    origin: Option<f64>,
    /// The next grid point to give out.
    next: usize,
    /// Rows read since the last import.
    pending: usize,
    /// Rows read in all (for the times of a file without a time column).
    rows: usize,
    /// Rows skipped without a value, or too late to place.
    skipped: usize,
    /// Rows skipped whose time repeats one held.
    repeated: usize,
    /// Rows put at their time among the rows held.
    reordered: usize,
    /// The last source record of an import.
    source: Option<SourceMeta>,
}

impl Stream {
    /// A stream imported with `opts` (its `dt` the model's).
    pub fn new(opts: ImportOptions) -> Self {
        Stream {
            opts,
            name: "-".into(),
            head: String::new(),
            lines: 0,
            table: None,
            columns: None,
            rec: Recording {
                t: Vec::new(),
                theta: Vec::new(),
                theta_dot: None,
                torque: None,
            },
            origin: None,
            next: 0,
            pending: 0,
            rows: 0,
            skipped: 0,
            repeated: 0,
            reordered: 0,
            source: None,
        }
    }

    /// The same, its errors naming `name` (the file followed).
    pub fn named(self, name: &std::path::Path) -> Self {
        Stream {
            name: name.to_path_buf(),
            ..self
        }
    }

    /// What was taken from the header, once it is read.
    pub fn layout(&self) -> Option<&Layout> {
        self.columns.as_ref().map(|c| &c.layout)
    }

    /// How the rows so far were sampled (their median interval and
    /// largest gap, the glitches of the rows held), after a first import.
    pub fn source(&self) -> Option<&SourceMeta> {
        self.source.as_ref()
    }

    /// The differentiator's half-window, s, where the rate is derived and
    /// it is fixed.
    pub fn smooth(&self) -> Option<f64> {
        self.opts.smooth
    }

    /// Reads one line; the grid samples it settles, `(t, [theta,
    /// theta_dot])` with `t` from the first stamp.
    pub fn push(&mut self, text_line: &str) -> Result<Vec<(f64, [f64; 2])>> {
        self.lines += 1;
        if self.table.is_none() {
            self.head.push_str(text_line);
            self.head.push('\n');
            // The head is parsed again only at a line that may be the
            // first data row (a long preamble stays linear).
            return if line_is_data(text_line) {
                self.try_header()
            } else {
                Ok(Vec::new())
            };
        };
        let line = self.lines;
        if let Some(table) = &mut self.table
            && table.push_line(line, text_line)?
        {
            self.take(0)?;
        }
        self.pending += 1;
        if self.pending >= BATCH {
            return self.settle(false);
        }
        Ok(Vec::new())
    }

    /// The end of the input: the samples left.
    pub fn finish(&mut self) -> Result<Vec<(f64, [f64; 2])>> {
        anyhow::ensure!(
            self.columns.is_some(),
            "the input ended before its first data row"
        );
        self.settle(true)
    }

    /// The header and the first rows, once a data row has come.
    fn try_header(&mut self) -> Result<Vec<(f64, [f64; 2])>> {
        let table = Table::parse(&self.name, &self.head)?;
        if table.is_empty() || !self.head.lines().any(line_is_data) {
            return Ok(Vec::new());
        }
        let columns = stream_columns(&table, &self.opts)?;
        self.rec.theta_dot = columns.rate.map(|_| Vec::new());
        self.columns = Some(columns);
        self.table = Some(table);
        self.take(0)?;
        self.head = String::new();
        Ok(Vec::new())
    }

    /// The table's rows from `from` read into the recording, as `import`
    /// reads them ([`read_row`]), then let go: a row out of time order is
    /// put at its time among the rows held ([`super::order`]), a
    /// repeated time skipped.
    fn take(&mut self, from: usize) -> Result<()> {
        let (Some(table), Some(c)) = (&mut self.table, &self.columns) else {
            return Ok(());
        };
        let cols: Vec<usize> = std::iter::once(c.angle.0)
            .chain(c.rate.map(|r| r.0))
            .collect();
        for row in from..table.len() {
            let place = self.rows;
            self.rows += 1;
            let RowRead::Values(time, got) =
                read_row(table, row, place, (c.time, self.opts.rate), &cols)?
            else {
                self.skipped += 1;
                continue;
            };
            let theta = got[0] * c.angle.1;
            let rate = got.get(1).zip(c.rate).map(|(r, (_, s))| r * s);
            let at = self.rec.t.partition_point(|&t| t <= time);
            let last = self.rec.t.last().copied();
            if at > 0 && self.rec.t[at - 1] == time {
                self.repeated += 1;
                continue;
            }
            if let Some(last) = last
                && time < last
            {
                let settled = self
                    .origin
                    .map_or(f64::NEG_INFINITY, |o| o + self.next as f64 * self.opts.dt);
                if last - time > BACK_MAX_S {
                    return Err(table
                        .error(
                            table.line(row),
                            format!(
                                "time {time} is {:.3} s before the row above's {last}: a clock reset or two recordings in one input?",
                                last - time
                            ),
                        )
                        .into());
                }
                if time <= settled {
                    // Before a sample already given out: too late to
                    // place, skipped and counted.
                    self.skipped += 1;
                    continue;
                }
                self.reordered += 1;
            }
            self.origin.get_or_insert(time);
            self.rec.t.insert(at, time);
            self.rec.theta.insert(at, theta);
            if let (Some(v), Some(r)) = (&mut self.rec.theta_dot, rate) {
                v.insert(at, r);
            }
        }
        table.retain_rows(|_| false);
        Ok(())
    }

    /// Imports the rows held and gives out the settled samples (all at
    /// the end).
    fn settle(&mut self, end: bool) -> Result<Vec<(f64, [f64; 2])>> {
        self.pending = 0;
        let (Some(origin), n) = (self.origin, self.rec.t.len()) else {
            return Ok(Vec::new());
        };
        if n < 3 || (!end && n <= MARGIN_ROWS) {
            return Ok(Vec::new());
        }
        if self.rec.theta_dot.is_none() && self.opts.smooth.is_none() {
            match self.window(end) {
                Some(w) => self.opts.smooth = Some(w),
                None => return Ok(Vec::new()),
            }
        }
        let (rollout, source) = rollout_on_grid(&self.rec, 1, &self.opts, origin)?;
        self.source = Some(SourceMeta {
            reordered: self.reordered,
            ..source
        });
        let step = self
            .source
            .as_ref()
            .map_or(self.opts.dt, |s| s.median_interval);
        let margin = MARGIN_ROWS as f64 * step + self.opts.smooth.unwrap_or(0.0);
        let until = if end {
            f64::INFINITY
        } else {
            self.rec.t[n - 1] - margin - origin
        };
        let dt = self.opts.dt;
        let mut out = Vec::new();
        for (t, x) in rollout.t.iter().zip(&rollout.xs) {
            let k = (t / dt).round() as usize;
            if k >= self.next && *t <= until {
                out.push((*t, *x));
                self.next = k + 1;
            }
        }
        // Let go of the rows no later sample needs.
        let keep_from = origin + self.next as f64 * dt - 2.0 * margin;
        let drop = self.rec.t.partition_point(|&t| t < keep_from);
        if drop > 0 && n - drop > MARGIN_ROWS {
            self.rec.t.drain(..drop);
            self.rec.theta.drain(..drop);
            if let Some(v) = &mut self.rec.theta_dot {
                v.drain(..drop);
            }
        }
        Ok(out)
    }

    /// The differentiator's half-window, a twentieth of the swing's period
    /// as `import` takes it, once [`PERIODS_FOR_WINDOW`] periods are read
    /// (or at the end, from what there is).
    fn window(&self, end: bool) -> Option<f64> {
        let period = rough_period(&self.rec.t, &self.rec.theta)?;
        let span = self.rec.t[self.rec.t.len() - 1] - self.rec.t[0];
        (end || span >= PERIODS_FOR_WINDOW * period).then_some(period / 20.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A Vernier-like file at 50 Hz fed a line at a time gives out, by
    /// its end, the very samples `import` makes of the whole file (the
    /// differentiator's window given to both); with rows out of time
    /// order too, each put at its time by both.
    #[test]
    fn a_stream_gives_what_import_gives() {
        let mut lines = vec![String::from("\"Latest: Time (s)\",\"Latest: Angle (°)\"")];
        for k in 0..1500 {
            let t = f64::from(k) * 0.02;
            let a = 30.0 * (-t / 20.0).exp() * (4.0 * t).cos() + 0.03 * (f64::from(k) * 7.1).sin();
            lines.push(format!("{t:.2},{a:.3}"));
        }
        let text = lines.join("\n") + "\n";
        same_from_stream_and_import(&text);
        for k in [300, 700, 1201] {
            lines.swap(k, k + 1);
        }
        same_from_stream_and_import(&(lines.join("\n") + "\n"));
    }

    /// `text` fed a line at a time gives out what `import` makes of it.
    fn same_from_stream_and_import(text: &str) {
        let opts = ImportOptions {
            dt: 0.04,
            smooth: Some(0.06),
            ..ImportOptions::default()
        };
        let path = std::env::temp_dir().join(format!("koopman-stream-{}.csv", std::process::id()));
        std::fs::write(&path, text).unwrap();
        let (ds, _, _) = super::super::import_with_layouts(&[path.clone()], &opts).unwrap();
        std::fs::remove_file(&path).unwrap();
        let want = ds.rollouts[0].clone();
        let mut stream = Stream::new(opts);
        let mut got = Vec::new();
        for line in text.lines() {
            got.extend(stream.push(line).unwrap());
        }
        got.extend(stream.finish().unwrap());
        assert_eq!(got.len(), want.xs.len());
        for (k, ((t, x), (tw, xw))) in got.iter().zip(want.t.iter().zip(&want.xs)).enumerate() {
            assert_eq!((t, x), (tw, xw), "sample {k}");
        }
    }
}
