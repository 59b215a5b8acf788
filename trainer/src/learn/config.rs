//! The training recipe: one struct with defaults, saved beside every run.

use estimator::blob::{Activation, ParamSpec, Reading};
use serde::{Deserialize, Serialize};
use trainer_core::data::RolloutMeta;
use trainer_core::data::drawn::LabDraw;
use trainer_core::physics::{EffectRange, Rig};
use trainer_core::protocol::{DT, G, ROLLOUT_LEN, THETA0, TRAIN_LENGTHS};

/// Which model a run trains (the protocol's three).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum ModelKind {
    /// Encoder/decoder, one global `K` over `[y; p]` fitted on batches that
    /// mix the training lengths (the filter estimates `p`).
    #[default]
    Klm,
    /// The same Koopman model without `p`: curated batches of one length
    /// each; `K` is identified at test time from latent data.
    Cbm,
    /// An MLP that regresses the length from a window of states.
    Mlp,
    /// Encoder/decoder with latent dynamics that depend on the parameters,
    /// `y' = F(q) y` (`learn::bilinear`), fitted on batches that mix the
    /// parameters; the filter is an extended Kalman filter.
    Bilinear,
}

impl ModelKind {
    /// Whether the model is a Koopman model exported as a blob with a
    /// filter (the KLM and the bilinear family).
    pub const fn is_koopman_blob(self) -> bool {
        matches!(self, ModelKind::Klm | ModelKind::Bilinear)
    }
}

/// Everything a training run depends on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct TrainConfig {
    /// The model trained.
    pub model: ModelKind,
    /// Seed of the training data and of the weights' initialisation.
    pub seed: u64,
    /// The rig whose length the training lengths are (the protocol's: a
    /// rod); the blob records it.
    pub rig: Rig,
    /// Training lengths, m: the grid of the protocol's sets, or (with
    /// `lab`) the range drawn from.
    pub lengths: Vec<f64>,
    /// Gravity of the simulated training data, m/s^2.
    pub g: f64,
    /// Observation interval, s (the model's `dt`, written into the blob).
    pub dt: f64,
    /// Range of the training rollouts' initial angle, rad.
    pub theta0: [f64; 2],
    /// An effect trained as the second physical parameter (none: the second
    /// parameter is an unused zero).
    pub effect: Option<EffectRange>,
    /// Filter: prior standard deviation of the effect's coefficient (prior
    /// mean: the middle of its training range); 0 means half that range.
    pub prior_std_effect: f64,
    /// Rollouts per training length.
    pub rollouts_per_length: usize,
    /// Draw the protocol set's lengths instead of taking `lengths` as a
    /// grid: as many rollouts as the grid would give, each its own length
    /// uniform between the smallest and the largest of `lengths`
    /// (`data::uniform_lengths`). A family whose dynamics move with the
    /// length learns the continuum, not two values.
    pub draw_lengths: bool,
    /// Draw the training rollouts lab-like instead (`data::drawn`): each
    /// its own length (log-uniform between the smallest and the largest
    /// of `lengths`), release angle (log-uniform over `theta0`) and effect
    /// coefficient, recorded with tracking noise and quantisation and
    /// imported as a user's recording. `g` must be the lab's, 9.81.
    pub lab: Option<LabDraw>,
    /// Measurements per training rollout, each released from rest (the
    /// protocol's 128). Longer than [`TrainConfig::window`], the windows
    /// start at every phase of the swing, not only at a turning point: a
    /// model that forecasts from any measured state needs them.
    pub rollout_steps: usize,
    /// Training window, observations (the protocol's rollouts have 128; the
    /// paper used 64; we train on whole rollouts for the 127-step horizon).
    pub window: usize,
    /// Windows per batch (half of each length, stratified).
    pub batch: usize,
    /// Optimiser steps (the KLM's 2000 and its filter's `Q` and `R`
    /// were chosen on validation rollouts: see `docs/recipe-selection.md`).
    pub iterations: usize,
    /// Adam learning rate at the start; cosine decay to `lr_final`.
    pub lr: f64,
    /// Learning rate at the end.
    pub lr_final: f64,
    /// Largest norm of each parameter's gradient (0: not clipped). A
    /// batch whose fitted `F(q)` grows on some `q` sends its rollout, and
    /// the gradient, up by orders of magnitude; one such step can kill
    /// the encoder's units.
    pub grad_clip: f64,
    /// Ridge of the batch least-squares fit, relative to `trace(G^T G / N) / n`.
    pub ridge: f64,
    /// Weight of the multi-step latent prediction loss.
    pub w_lin: f64,
    /// Hidden activation.
    pub activation: Activation,
    /// Hidden width.
    pub hidden: usize,
    /// Checkpoint every this many iterations.
    pub checkpoint_every: usize,
    /// Rayon threads for the flex backend (0: rayon's default).
    pub threads: usize,
    /// Filter: process noise of the latent, relative to the one-step residual variance.
    pub q_latent: f64,
    /// Filter: measurement noise, relative to the one-step residual variance.
    pub r_latent: f64,
    /// Filter: prior standard deviation of the length's coordinate (prior
    /// mean 0).
    pub prior_std_length: f64,
    /// How the filter's length coordinate reads as the length (the model
    /// is trained on the coordinate, which equals the length at both ends
    /// of the training range; see `estimator::blob::Reading`).
    pub length_reading: Reading,
    /// Trust: threshold = this factor x the largest sigma over training rollouts.
    pub trust_factor: f64,
    /// A Koopman blob whose encoder and decoder (and normalisation) the
    /// training starts from, instead of freshly drawn weights: a
    /// fine-tuning (`learn::warm`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub warm_start: Option<std::path::PathBuf>,
    /// Trust: the least largest unevenness the verdict lets pass (`None`:
    /// the calibration's own floor). A blob made from another keeps that
    /// one's, which real rigs were read with.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unevenness_floor: Option<f64>,
    /// Iterations after which a copy of the model is kept beside the
    /// checkpoint (`learn::run::snapshot_path`; 0: the start, which a
    /// fine-tuning has loaded): a caller may choose among them.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub snapshots: Vec<usize>,
    /// Train on the lab draws' noise-free twin
    /// (`data::drawn::LabDraw::noise_free`): the same pendulums without
    /// the tracker's noise, quantisation and artefacts. The export's noise
    /// choice and calibration still draw `lab` as it is.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub noise_free_training: bool,
    /// The families of torques the training rollouts are driven by, taking
    /// turns (`physics::drive`); empty: the protocol's free rollouts, and a
    /// model without `B`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub drives: Vec<trainer_core::physics::DriveKind>,
}

impl Default for TrainConfig {
    fn default() -> Self {
        TrainConfig {
            model: ModelKind::Klm,
            seed: 42,
            rig: Rig::Rod,
            lengths: TRAIN_LENGTHS.to_vec(),
            g: G,
            dt: DT,
            theta0: THETA0,
            effect: None,
            prior_std_effect: 0.0,
            rollouts_per_length: 200,
            draw_lengths: false,
            lab: None,
            rollout_steps: ROLLOUT_LEN,
            window: 128,
            batch: 32,
            iterations: 2000,
            lr: 1e-3,
            lr_final: 5e-5,
            grad_clip: 0.0,
            ridge: 1e-6,
            w_lin: 0.1,
            activation: Activation::Relu,
            hidden: estimator::HIDDEN_DIM,
            checkpoint_every: 250,
            threads: 0,
            q_latent: 1.0,
            r_latent: 0.01,
            prior_std_length: 5.0,
            length_reading: Reading::Reciprocal,
            trust_factor: 1.5,
            warm_start: None,
            unevenness_floor: None,
            snapshots: Vec::new(),
            noise_free_training: false,
            drives: Vec::new(),
        }
    }
}

impl TrainConfig {
    /// The defaults for one kind of model: the MLP regresses from the
    /// protocol's 64-step window and trains for fewer, cheaper iterations.
    pub fn for_model(model: ModelKind) -> Self {
        let base = TrainConfig {
            model,
            ..TrainConfig::default()
        };
        match model {
            ModelKind::Klm => base,
            // The CBM has no explicit parameter; the MLP regresses the
            // length itself.
            ModelKind::Cbm => TrainConfig {
                length_reading: Reading::Direct,
                iterations: 8000,
                ..base
            },
            ModelKind::Mlp => TrainConfig {
                length_reading: Reading::Direct,
                window: 64,
                batch: 64,
                hidden: 64,
                iterations: 4000,
                ..base
            },
            // The length's coordinate is w^2 scaled to [-1, 1]; its prior
            // covers the range.
            ModelKind::Bilinear => TrainConfig {
                length_reading: Reading::ReciprocalUnit,
                grad_clip: 1.0,
                prior_std_length: 1.0,
                iterations: 3000,
                ..base
            },
        }
    }

    /// The smallest and the largest training length.
    pub fn length_range(&self) -> [f64; 2] {
        let lo = self.lengths.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = self
            .lengths
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
        [lo, hi]
    }

    /// The length as the filter's first parameter: its training range and
    /// reading.
    pub fn length_spec(&self) -> ParamSpec<'static> {
        let [lo, hi] = self.length_range();
        ParamSpec {
            name: "length",
            declared: true,
            train_range: [lo as f32, hi as f32],
            reading: self.length_reading,
            scales_with_g: true,
        }
    }

    /// The effect as the filter's second parameter (its training range,
    /// read [`Reading::Centred`], or [`Reading::Unit`] for the bilinear
    /// family, whose `F(q)` wants coordinates of one size), or the
    /// undeclared padding parameter.
    pub fn effect_spec(&self) -> ParamSpec<'static> {
        match &self.effect {
            Some(e) => ParamSpec {
                name: e.name.name(),
                declared: true,
                train_range: [e.range[0] as f32, e.range[1] as f32],
                reading: if self.model == ModelKind::Bilinear {
                    Reading::Unit
                } else {
                    Reading::Centred
                },
                scales_with_g: false,
            },
            None => ParamSpec {
                name: "none",
                declared: false,
                train_range: [0.0, 0.0],
                reading: Reading::Direct,
                scales_with_g: false,
            },
        }
    }

    /// The filter's coordinates `q` of a training rollout's truth: the
    /// length's and the effect's (0 without one). The one mapping the
    /// training batches and the exported `F` share.
    pub fn coordinates(&self, m: &RolloutMeta) -> anyhow::Result<[f32; 2]> {
        let second = match &self.effect {
            Some(e) => {
                let c = *m.effects.get(e.name.name()).ok_or_else(|| {
                    anyhow::anyhow!("rollout {} has no {} coefficient", m.rollout, e.name)
                })?;
                self.effect_spec().coordinate(c as f32)
            }
            None => 0.0,
        };
        Ok([self.length_spec().coordinate(m.length as f32), second])
    }

    /// Learning rate at iteration `i` (cosine from `lr` to `lr_final`).
    pub fn lr_at(&self, i: usize) -> f64 {
        let f = i as f64 / self.iterations.max(1) as f64;
        self.lr_final + 0.5 * (self.lr - self.lr_final) * (1.0 + (std::f64::consts::PI * f).cos())
    }
}
