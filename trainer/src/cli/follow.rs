//! `koopman estimate --follow`: the on-device estimator over a recording
//! as it is written (a logger's file, a serial port's text, standard
//! input), its raw columns imported on the fly ([`Stream`]).
//!
//! A thread reads the lines and hands them over; Ctrl-C hands over an end.
//! Each sample the stream settles is filtered as `estimate` filters a
//! rollout (a gap bridged by the filter's prediction); every `--every`
//! measurements and at the end the estimate is printed as `estimate`
//! prints a rollout's (text or `--json`), `steps` the measurements so far.

use std::io::BufRead;
use std::path::Path;
use std::sync::mpsc::{self, Sender};
use std::time::{Duration, Instant};

use anyhow::Result;
use estimator::Estimator;
use trainer_core::data::import::Stream;
use trainer_core::track::Run;

use super::estimate::{Args, Report};

/// What the reading thread hands over.
enum Input {
    /// A line.
    Line(String),
    /// The input ended (its end, the file idle, or Ctrl-C).
    End(&'static str),
    /// It could not be read.
    Failed(String),
}

/// Runs the estimator over `source` as it is written.
pub fn run(a: &Args, source: &Path) -> Result<()> {
    let bytes = super::read_blob(&a.weights)?;
    let model = &super::model(&a.weights, &bytes)?;
    let fresh = &super::estimate::fresh(a, model)?;
    let body = model.blob().body;
    // The blob's interval as a user gives it to `import` (`--dt 0.04`, not
    // the f32's 0.03999999910593033), so that both make the same grid.
    let dt: f64 = body.dt.to_string().parse()?;
    let opts = trainer_core::data::import::ImportOptions {
        dt,
        ..a.recording.options()?
    };
    let (tx, rx) = mpsc::channel();
    let interrupt = tx.clone();
    ctrlc::set_handler(move || {
        let _ = interrupt.send(Input::End("Ctrl-C"));
    })
    .map_err(|e| anyhow::anyhow!("cannot catch Ctrl-C: {e}"))?;
    spawn_reader(source, a.idle, tx)?;
    let report = Report::of(a, body, true);
    let mut follow = Follow {
        stream: Stream::new(opts).named(source),
        est: None,
        run: Run::default(),
        printed: 0,
        every: a.every,
        dt,
    };
    let mut told = false;
    loop {
        let (samples, end) = match rx.recv() {
            Ok(Input::Line(line)) => (follow.stream.push(&line)?, None),
            Ok(Input::End(why)) => (follow.stream.finish()?, Some(why)),
            Ok(Input::Failed(e)) => anyhow::bail!("{}: {e}", source.display()),
            Err(_) => (follow.stream.finish()?, Some("end of input")),
        };
        if !told && let Some(layout) = follow.stream.layout() {
            eprintln!("{}: {}", source.display(), layout.describe());
            if !a.json {
                report.header()?;
            }
            told = true;
        }
        for (t, x) in samples {
            if follow.filter(&report, fresh, t, x)? {
                follow.print(&report, a.json)?;
            }
        }
        if let Some(why) = end {
            anyhow::ensure!(
                follow.measured() > 0,
                "{}: ended ({why}) with no measurement the filter could take; `koopman import {}` says why",
                source.display(),
                source.display()
            );
            if follow.printed != follow.measured() {
                follow.print(&report, a.json)?;
            }
            if let Some(w) = follow.stream.smooth() {
                eprintln!(
                    "{}: ended ({why}); the rate derived over +-{w:.4} s (`import --smooth {w:.4}` imports the file alike)",
                    source.display()
                );
            } else {
                eprintln!("{}: ended ({why})", source.display());
            }
            return Ok(());
        }
    }
}

/// The estimator over the samples settled so far.
struct Follow<'m> {
    stream: Stream,
    /// Made at the first sample, told the source's interval.
    est: Option<Estimator<'m>>,
    run: Run,
    /// Measurements at the last print.
    printed: usize,
    every: u64,
    dt: f64,
}

impl<'m> Follow<'m> {
    /// Measurements filtered.
    fn measured(&self) -> usize {
        self.run.tracked.as_ref().map_or(0, |t| t.measured)
    }

    /// Filters the sample `x` at `t`; whether a print is due.
    fn filter(
        &mut self,
        report: &Report<'_>,
        fresh: &Estimator<'m>,
        t: f64,
        x: [f64; 2],
    ) -> Result<bool> {
        let est = match &mut self.est {
            Some(est) => est,
            None => self
                .est
                .insert(report.estimator(fresh, 1, self.stream.source())?),
        };
        let measured = self.run.sample(est, t, &x, 0.0, self.dt)?.measured;
        Ok(measured as u64 % self.every == 0)
    }

    /// Prints the estimate so far as `estimate` prints a rollout's.
    fn print(&mut self, report: &Report<'_>, json: bool) -> Result<()> {
        let Some(tracked) = &self.run.tracked else {
            return Ok(());
        };
        self.printed = tracked.measured;
        if json {
            report.json(1, tracked, self.stream.source(), None)
        } else {
            report.text(1, tracked, self.stream.source())
        }
    }
}

/// A thread that reads `source` line by line: standard input to its end,
/// a file until it has not grown for `idle` s.
fn spawn_reader(source: &Path, idle: f64, tx: Sender<Input>) -> Result<()> {
    let reader: Box<dyn BufRead + Send> = if source == Path::new("-") {
        Box::new(std::io::BufReader::new(std::io::stdin()))
    } else {
        let f = std::fs::File::open(source)
            .map_err(|e| anyhow::anyhow!("{}: cannot read: {e}", source.display()))?;
        Box::new(std::io::BufReader::new(f))
    };
    let tail = source != Path::new("-");
    std::thread::spawn(move || read_lines(reader, tail, idle, &tx));
    Ok(())
}

/// Hands over each line of `reader`; at its end, waits for more where
/// `tail` (a file being written) until `idle` s pass without any.
fn read_lines(mut reader: Box<dyn BufRead + Send>, tail: bool, idle: f64, tx: &Sender<Input>) {
    let mut line = String::new();
    let mut quiet_since = Instant::now();
    loop {
        match reader.read_line(&mut line) {
            Ok(0) if tail && quiet_since.elapsed().as_secs_f64() < idle => {
                std::thread::sleep(Duration::from_millis(100));
            }
            Ok(0) => {
                if !line.trim().is_empty() {
                    let _ = tx.send(Input::Line(line.trim_end_matches(['\n', '\r']).to_string()));
                }
                let _ = tx.send(Input::End(if tail {
                    "the file stopped growing"
                } else {
                    "end of input"
                }));
                return;
            }
            // A line still being written waits for its end.
            Ok(_) if tail && !line.ends_with('\n') => {}
            Ok(_) => {
                quiet_since = Instant::now();
                let text = line.trim_end_matches(['\n', '\r']).to_string();
                line.clear();
                if tx.send(Input::Line(text)).is_err() {
                    return;
                }
            }
            Err(e) => {
                let _ = tx.send(Input::Failed(e.to_string()));
                return;
            }
        }
    }
}
