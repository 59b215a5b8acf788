//! What a rig blob makes of a recording's held-out part: its forecasts
//! (as the loop scores every model, [`forecast`]) and the estimate a user
//! gets from that part alone, a fresh filter run over it: the length, the
//! second parameter, the quality factor and the verdict. A held-out part
//! shorter than [`HELD_OUT_LEAST`] measurements is too short for an
//! estimate of its own; the estimate is then the whole recording's, as
//! `koopman estimate` gives it.

use anyhow::Result;
use estimator::{Estimator, Model};
use serde::Serialize;
use trainer_core::data::states_f32;
use trainer_core::protocol::WINDOW;

use super::super::forecast::{self, Score};
use super::super::parts::Part;

/// Fewest measurements a held-out part is read on alone: two of the
/// filter's windows.
pub const HELD_OUT_LEAST: usize = 2 * WINDOW;

/// One blob's reading of a held-out part.
#[derive(Debug, Clone, Serialize)]
pub struct BlobRead {
    /// Held-out forecast error (`None`: the part is too short for
    /// forecasts, see `forecast_refused`).
    pub forecast: Option<Score>,
    /// Why there is none.
    pub forecast_refused: Option<String>,
    /// Measurements the estimate saw (the held-out part's, or the whole
    /// recording's where that is shorter than [`HELD_OUT_LEAST`]).
    pub measured: usize,
    /// Whether the estimate saw the held-out part alone.
    pub held_out_alone: bool,
    /// The length, m, and its standard deviation.
    pub length: f32,
    /// Its standard deviation.
    pub length_std: f32,
    /// The blob's second parameter: its name and unit.
    pub second: String,
    /// Its unit.
    pub second_unit: String,
    /// Its value and standard deviation (`None`: the blob declares none).
    pub second_value: Option<[f32; 2]>,
    /// The quality factor and its standard deviation, once read.
    pub q_factor: Option<[f32; 2]>,
    /// `trusted`, `untrusted` or `pending`.
    pub verdict: String,
    /// Why not trusted.
    pub reasons: Vec<String>,
}

/// `model`'s reading of `part`'s held-out part (steps of `dt`).
pub fn held_out(model: &Model<'_>, part: &Part, dt: f64) -> Result<BlobRead> {
    let xs = &part.series.xs;
    let score = forecast::klm(model, xs, part.cut, dt);
    let alone = xs.len().saturating_sub(part.cut) >= HELD_OUT_LEAST;
    let held = xs
        .get(if alone { part.cut } else { 0 }..)
        .unwrap_or_default();
    let mut est = Estimator::new(model).at_trained_gravity();
    let o = estimator::filter::run(&mut est, &states_f32(held))
        .map_err(|e| anyhow::anyhow!("{}: the held-out part: {e}", part.source))?;
    let spec = model.blob().body.params.get(1);
    let declared = spec.is_some_and(|s| s.declared);
    Ok(BlobRead {
        forecast_refused: score.as_ref().err().map(|e| format!("{e:#}")),
        forecast: score.ok(),
        measured: held.len(),
        held_out_alone: alone,
        length: o.params[0],
        length_std: o.param_std[0],
        second: spec.map_or("none", |s| s.name).to_string(),
        second_unit: unit_of(spec.map_or("none", |s| s.name)).to_string(),
        second_value: declared.then_some([o.params[1], o.param_std[1]]),
        q_factor: o
            .readers
            .q_factor
            .zip(o.readers.q_factor_std)
            .map(|(q, s)| [q, s]),
        verdict: o.trust.as_str().to_string(),
        reasons: o.trust.reasons().iter().map(|r| r.to_string()).collect(),
    })
}

/// The unit of an effect named `name` (empty for none).
fn unit_of(name: &str) -> &'static str {
    trainer_core::physics::EffectKind::parse(name).map_or("", |k| k.unit())
}
