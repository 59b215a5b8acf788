//! The fewest samples a period of its source a lab blob reads right:
//! lab-like recordings from coarse sources (video at 5 to 25 frames a
//! second, interpolated to the blob's interval), read by the calibrated
//! blob with the source check off. Above the threshold no reading at the
//! end that the other checks trust is wrong (more than the calibration's
//! accuracy off, as its check set counts).

use anyhow::Result;
use estimator::blob::Blob;
use estimator::{Model, Trust};
use serde::{Deserialize, Serialize};

use super::{LabHeldOut, blob_bytes};
use crate::labcheck::{self, LabCheckConfig, Outcome};
use crate::physics::RigPhysics;

/// The coarse sources' rates, Hz (the video rates within).
const RATES: [f64; 2] = [5.0, 25.0];
/// Recordings in the coarse set.
const RECORDINGS: usize = 240;
/// The fewest samples a period ever trusted: below four a swing's shape
/// is not sampled (two a half period).
const FLOOR: f64 = 4.0;
/// The offsets the set carries, rad (real rigs' 0.01 to 0.06).
const OFFSET: f64 = 0.06;

/// What the coarse set showed.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
pub struct CoarseFigures {
    /// Recordings read.
    pub recordings: usize,
    /// Those trusted at the end but wrong, the source check aside: what
    /// sets the threshold.
    pub wrong_and_trusted: usize,
    /// The largest samples a period among them (0: none).
    pub worst: f64,
}

/// The fewest samples a period `blob` (calibrated, source check off)
/// reads right (within `accurate` at the end, where trusted) on coarse
/// lab-like recordings of `lengths` drawn like `lab` from `seed`, at most `fewest`
/// (what the calibration set covers anyway), and what the set showed.
pub(super) fn fewest_read_right(
    blob: &Blob<'_>,
    lab: &LabHeldOut,
    lengths: [f32; 2],
    seed: u64,
    accurate: f64,
    fewest: f64,
) -> Result<(f64, CoarseFigures)> {
    let mut open = *blob;
    open.body.trust.min_samples_per_period = 0.0;
    let bytes = blob_bytes(&open)?;
    let model = Model::from_bytes(&bytes)?;
    let cfg = LabCheckConfig {
        seed,
        recordings: RECORDINGS,
        lengths: lengths.map(f64::from),
        swings: lab.theta0,
        noise: lab.draw.noise,
        offsets: [-OFFSET, OFFSET],
        rates: Some(RATES),
        mixed: true,
        ..LabCheckConfig::default()
    };
    let outcomes = labcheck::run(&model, &cfg)?;
    let (rig, g) = (open.body.rig, f64::from(open.body.g));
    let samples = |o: &Outcome| o.rate * std::f64::consts::TAU / rig.w2(g, o.length).sqrt();
    let bad: Vec<f64> = outcomes
        .iter()
        .filter(|o| o.end.trust == Trust::Trusted && o.end.error(o.length) > accurate)
        .map(samples)
        .collect();
    let worst = bad.iter().copied().fold(0.0, f64::max);
    // Just above the worst: the next tenth of a sample.
    let threshold = ((worst * 10.0).floor() + 1.0) / 10.0;
    let figures = CoarseFigures {
        recordings: outcomes.len(),
        wrong_and_trusted: bad.len(),
        worst,
    };
    Ok((threshold.max(FLOOR).min(fewest), figures))
}
