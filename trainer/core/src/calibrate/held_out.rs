//! The held-out rollouts every phase runs, and what the estimator reads on
//! them at the checkpoints.

use anyhow::{Context, Result};
use estimator::blob::Blob;
use estimator::{Estimator, Model, StepOutput};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::LabHeldOut;
use crate::data::drawn::{DrawnSet, LabDraw, drawn_set};
use crate::data::states_f32;
use crate::physics::{Pendulum, Rig, RigPhysics};
use crate::protocol::{THETA0, WINDOW};

/// A held-out rollout: the true length and the raw measurements.
pub(super) struct Held {
    pub(super) length: f64,
    /// The effect's coefficient, where the rollout was drawn with one.
    pub(super) effect: Option<f64>,
    pub(super) xs: Vec<[f32; 2]>,
}

/// How a blob's held-out rollouts are made: its rig, sampling interval
/// and gravity, drawn as the protocol's or lab-like.
#[derive(Clone, Copy)]
pub(super) struct Sampling<'c> {
    rig: Rig,
    dt: f64,
    g: f64,
    lab: Option<&'c LabHeldOut>,
}

impl<'c> Sampling<'c> {
    /// The sampling of `blob`'s rollouts, lab-like where `lab` is set.
    pub(super) fn of(blob: &Blob<'_>, lab: Option<&'c LabHeldOut>) -> Self {
        Sampling {
            rig: blob.body.rig,
            dt: f64::from(blob.body.dt),
            g: f64::from(blob.body.g),
            lab,
        }
    }

    /// `n` rollouts of `steps` measurements over `lengths`, from `seed`.
    pub(super) fn rollouts(
        &self,
        lengths: [f32; 2],
        n: usize,
        steps: usize,
        seed: u64,
    ) -> Result<Vec<Held>> {
        if let Some(lab) = self.lab {
            return self.lab_like(lab, lengths, n, steps, seed);
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        Ok((0..n)
            .map(|_| {
                let length = rng.random_range(f64::from(lengths[0])..=f64::from(lengths[1]));
                let theta0 = rng.random_range(THETA0[0]..=THETA0[1]);
                let mut p = Pendulum::of(self.rig, length);
                p.g = self.g;
                Held {
                    length,
                    effect: None,
                    xs: states_f32(&p.rollout([theta0, 0.0], steps, self.dt)),
                }
            })
            .collect())
    }

    /// [`Sampling::rollouts`] drawn as `lab` says.
    fn lab_like(
        &self,
        lab: &LabHeldOut,
        lengths: [f32; 2],
        n: usize,
        steps: usize,
        seed: u64,
    ) -> Result<Vec<Held>> {
        let draw = LabDraw {
            rollouts: n,
            ..lab.draw.clone()
        };
        let ds = drawn_set(
            seed,
            "held-out",
            &DrawnSet {
                rig: self.rig,
                lengths: lengths.map(f64::from),
                theta0: lab.theta0,
                effect: lab.effect.as_ref(),
                dt: self.dt,
                steps,
                draw: &draw,
            },
        )?;
        Ok(ds
            .rollouts
            .iter()
            .zip(&ds.sidecar.rollouts)
            .map(|(r, m)| Held {
                length: m.length,
                effect: lab
                    .effect
                    .as_ref()
                    .and_then(|e| m.effects.get(e.name.name()).copied()),
                xs: states_f32(&r.xs),
            })
            .collect())
    }
}

impl Sampling<'_> {
    /// The fewest samples a period the held-out rollouts over `lengths`
    /// (m) carry: their sources' slowest rate at the shortest length.
    pub(super) fn fewest_samples_per_period(&self, lengths: [f32; 2]) -> f64 {
        let rate = match self.lab {
            Some(lab) => lab.draw.rates.iter().copied().fold(f64::INFINITY, f64::min),
            None => 1.0 / self.dt,
        };
        let shortest = f64::from(lengths[0].min(lengths[1]));
        let period = std::f64::consts::TAU / self.rig.w2(self.g, shortest).sqrt();
        period * rate
    }
}

/// Whether the length estimate of `out` lies within the fraction
/// `accurate` of the truth (what the swing check is set by and the check
/// set's figures count).
pub(super) fn right(out: &StepOutput, truth: f64, accurate: f64) -> bool {
    (f64::from(out.params[0]) - truth).abs() <= accurate * truth
}

/// Runs `xs` through a fresh estimator and returns the outputs after
/// `WINDOW` and after all of `xs`.
pub(super) fn checkpoints(m: &Model<'_>, xs: &[[f32; 2]]) -> Result<(StepOutput, StepOutput)> {
    let (a, b, _) = checkpoints_with_extremes(m, xs)?;
    Ok((a, b))
}

/// What the consistency check reads at one update: the mean normalised
/// innovation, the length at the blob's gravity and the widest swing
/// (the arguments of [`estimator::trust::consistency_statistic`] before
/// the law).
pub(super) type NisSample = [f32; 3];

/// Over the updates from the [`WINDOW`]-th on (where the device applies
/// their checks): the consistency check's inputs at each where measured,
/// and the largest departure of the rate ratio from 1 (`None` where
/// never measured).
#[derive(Debug, Clone, Default)]
pub(super) struct Extremes {
    pub(super) nis: Vec<NisSample>,
    pub(super) rate_off: Option<f32>,
    /// The largest ratio of one update's normalised innovation to the
    /// mean of those before it (the outlier gate's statistic; `None` where
    /// never formed).
    pub(super) step_ratio: Option<f32>,
}

/// [`checkpoints`], and the [`Extremes`] over the run.
pub(super) fn checkpoints_with_extremes(
    m: &Model<'_>,
    xs: &[[f32; 2]],
) -> Result<(StepOutput, StepOutput, Extremes)> {
    let mut est = Estimator::new(m).at_trained_gravity();
    let mut at_window = None;
    let mut last = None;
    let mut ext = Extremes::default();
    let mut mean_before: Option<f32> = None;
    let length = m.blob().body.params[0];
    let most = |a: Option<f32>, b: Option<f32>| match (a, b) {
        (Some(x), Some(y)) => Some(x.max(y)),
        (x, y) => x.or(y),
    };
    for (n, x) in xs.iter().enumerate() {
        let out = est.step(x)?;
        if n + 1 == WINDOW {
            at_window = Some(out.clone());
        }
        if let (Some(v), Some(mean)) = (out.filter.innovation, mean_before.filter(|m| *m > 0.0)) {
            ext.step_ratio = most(ext.step_ratio, Some(v / mean));
        }
        mean_before = out.filter.nis;
        if n + 1 >= WINDOW {
            // The length at the blob's gravity, as the device reads it.
            if let Some(v) = out.filter.nis {
                ext.nis
                    .push([v, length.read(out.filter.coordinate[0]), out.checks.swing]);
            }
            ext.rate_off = most(ext.rate_off, out.checks.rate_ratio.map(|r| (r - 1.0).abs()));
        }
        last = Some(out);
    }
    Ok((
        at_window.context("rollout shorter than the window")?,
        last.context("empty rollout")?,
        ext,
    ))
}
