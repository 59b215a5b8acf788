//! The protocol's two baselines at test time (host only; they do not ship).
//!
//! - **MLP**: a regressor reads the first `window` (64) normalised states of a
//!   rollout and answers the length; the KLM then simulates with it.
//! - **CBM**: the encoder/decoder trained on curated batches. `K` (latent
//!   only, no `p`) is identified from the encoded first 64 states: of one
//!   rollout (one-shot) or of the 10 rollouts of one length (few-shot), by
//!   ridge least squares `y_{t+1} = K y_t` in f64 with the same relative
//!   ridge as training. The simulation encodes `x_0`, applies `K` 127 times
//!   and decodes.

use std::path::Path;

use anyhow::{Context, Result};
use burn::tensor::{Device, Tensor, TensorData};
use estimator::LATENT_DIM;
use nalgebra::DMatrix;

use trainer_core::metrics::scaled_mse;
use trainer_core::protocol::WINDOW;

use crate::export::baseline::{BaselineInfo, baseline_sidecar};
use crate::learn::config::{ModelKind, TrainConfig};
use crate::learn::model::{Klm, Regressor};
use crate::learn::run::{Norm, load_module};

/// Reads a baseline's sidecar and checks its kind.
fn read_info(path: &Path, kind: ModelKind) -> Result<BaselineInfo> {
    let side = baseline_sidecar(path);
    let info: BaselineInfo = serde_json::from_str(
        &std::fs::read_to_string(&side)
            .with_context(|| format!("{}: cannot read", side.display()))?,
    )
    .with_context(|| format!("{}", side.display()))?;
    anyhow::ensure!(
        info.config.model == kind,
        "{}: a {:?} model, not {kind:?}",
        side.display(),
        info.config.model
    );
    Ok(info)
}

/// Normalised states as a `[1, T, 2]`-shaped flat vector.
fn normalised(norm: &Norm, xs: &[[f64; 2]]) -> Vec<f32> {
    xs.iter().flat_map(|&x| norm.apply(x)).collect()
}

fn to_vec(t: Tensor<2>) -> Result<Vec<f32>> {
    t.into_data()
        .try_to_vec::<f32>()
        .map_err(|e| anyhow::anyhow!("{e:?}"))
}

/// The MLP baseline, loaded from `mlp.bpk` and its sidecar.
pub struct MlpBaseline {
    model: Regressor,
    /// What the export recorded.
    pub info: BaselineInfo,
    device: Device,
}

impl MlpBaseline {
    /// Loads `path` (burnpack) and `path.json`.
    pub fn load(path: &Path) -> Result<Self> {
        let info = read_info(path, ModelKind::Mlp)?;
        let device = Device::flex();
        let model = load_module(path, &info.config, &device)?;
        Ok(MlpBaseline {
            model,
            info,
            device,
        })
    }

    /// The length it reads from the first `window` states of each rollout.
    pub fn estimate(&self, rollouts: &[&[[f64; 2]]]) -> Result<Vec<f32>> {
        let w = self.info.config.window;
        let mut x = Vec::with_capacity(rollouts.len() * w * 2);
        for xs in rollouts {
            anyhow::ensure!(xs.len() >= w, "the MLP needs {w} states, got {}", xs.len());
            x.extend(normalised(&self.info.norm, &xs[..w]));
        }
        let x = Tensor::<3>::from_data(TensorData::new(x, [rollouts.len(), w, 2]), &self.device);
        let out = self
            .model
            .forward(x, self.info.config.activation)
            .reshape([rollouts.len(), 1]);
        to_vec(out)
    }
}

/// The CBM baseline, loaded from `cbm.bpk` and its sidecar.
pub struct CbmBaseline {
    model: Klm,
    /// What the export recorded.
    pub info: BaselineInfo,
    device: Device,
}

/// A latent trajectory, f64.
pub type Latents = Vec<[f64; LATENT_DIM]>;

impl CbmBaseline {
    /// Loads `path` (burnpack) and `path.json`.
    pub fn load(path: &Path) -> Result<Self> {
        let info = read_info(path, ModelKind::Cbm)?;
        let device = Device::flex();
        let model = load_module(path, &info.config, &device)?;
        Ok(CbmBaseline {
            model,
            info,
            device,
        })
    }

    fn cfg(&self) -> &TrainConfig {
        &self.info.config
    }

    /// Encodes raw states.
    pub fn encode(&self, xs: &[[f64; 2]]) -> Result<Latents> {
        let x = Tensor::<2>::from_data(
            TensorData::new(normalised(&self.info.norm, xs), [xs.len(), 2]),
            &self.device,
        );
        let y = to_vec(self.model.enc.forward(x, self.cfg().activation))?;
        Ok(y.chunks_exact(LATENT_DIM)
            .map(|c| std::array::from_fn(|k| c[k] as f64))
            .collect())
    }

    /// `K` from latent trajectories, with the run's ridge (see [`identify`]).
    pub fn identify(&self, latents: &[&Latents]) -> Result<DMatrix<f64>> {
        identify(latents, self.cfg().ridge)
    }
}

/// `K` (`LATENT x LATENT`) from the transitions of each latent trajectory's
/// first 64 states: `K^T = (G^T G / N + lambda I)^-1 G^T Y / N` with
/// `lambda = ridge trace(G^T G / N) / n`, as in training.
pub fn identify(latents: &[&Latents], ridge: f64) -> Result<DMatrix<f64>> {
    let n = LATENT_DIM;
    let mut a = DMatrix::<f64>::zeros(n, n);
    let mut b = DMatrix::<f64>::zeros(n, n);
    let mut count = 0usize;
    for ys in latents {
        let ys = &ys[..WINDOW.min(ys.len())];
        for w in ys.windows(2) {
            for i in 0..n {
                for j in 0..n {
                    a[(i, j)] += w[0][i] * w[0][j];
                    b[(i, j)] += w[0][i] * w[1][j];
                }
            }
            count += 1;
        }
    }
    anyhow::ensure!(count > 0, "no transitions to identify K from");
    a /= count as f64;
    b /= count as f64;
    let lambda = ridge * a.trace() / n as f64 + 1e-12;
    for i in 0..n {
        a[(i, i)] += lambda;
    }
    let kt = a
        .cholesky()
        .context("the CBM's normal equations are not positive definite")?
        .solve(&b);
    Ok(kt.transpose())
}

impl CbmBaseline {
    /// Simulates `steps` states after `x0` with `K`; returns normalised states.
    pub fn simulate(&self, k: &DMatrix<f64>, x0: [f64; 2], steps: usize) -> Result<Vec<[f32; 2]>> {
        let y0 = self.encode(&[x0])?;
        let mut y = nalgebra::DVector::from_row_slice(&y0[0]);
        let mut flat = Vec::with_capacity(steps * LATENT_DIM);
        for _ in 0..steps {
            y = k * y;
            flat.extend(y.iter().map(|&v| v as f32));
        }
        let yt = Tensor::<2>::from_data(TensorData::new(flat, [steps, LATENT_DIM]), &self.device);
        let x = to_vec(self.model.dec.forward(yt, self.cfg().activation))?;
        Ok(x.chunks_exact(2).map(|c| [c[0], c[1]]).collect())
    }

    /// The protocol's MSE (`trainer_core::metrics`) of the simulation from
    /// `xs[0]` against `xs[1..]`, in the run's normalised units.
    pub fn sim_mse(&self, k: &DMatrix<f64>, xs: &[[f64; 2]]) -> Result<f64> {
        let norm = &self.info.norm;
        let sim: Vec<[f64; 2]> = self
            .simulate(k, xs[0], xs.len() - 1)?
            .iter()
            .map(|s| std::array::from_fn(|d| f64::from(s[d]) * norm.s[d] + norm.mu[d]))
            .collect();
        Ok(scaled_mse(&xs[1..], &sim, norm.s))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identify_recovers_a_known_koopman_matrix() {
        // K: a block-diagonal of 8 rotations by different angles, scaled
        // 0.99, so 63 transitions of one trajectory from a generic start
        // excite every direction. Exact data, so the only error is the
        // ridge's bias: ridge 1e-9 of the trace moves K by about 1e-9 times
        // its condition (~1e2), far below the 1e-6 asserted.
        let n = LATENT_DIM;
        let mut k = DMatrix::<f64>::zeros(n, n);
        for b in 0..n / 2 {
            let a = 0.1 + 0.17 * b as f64;
            let (s, c) = a.sin_cos();
            k[(2 * b, 2 * b)] = 0.99 * c;
            k[(2 * b, 2 * b + 1)] = -0.99 * s;
            k[(2 * b + 1, 2 * b)] = 0.99 * s;
            k[(2 * b + 1, 2 * b + 1)] = 0.99 * c;
        }
        let mut y = nalgebra::DVector::<f64>::from_fn(n, |i, _| 1.0 + 0.1 * i as f64);
        let mut traj: Latents = Vec::new();
        for _ in 0..WINDOW {
            traj.push(std::array::from_fn(|i| y[i]));
            y = &k * y;
        }
        let got = identify(&[&traj], 1e-9).unwrap();
        let err = (&got - &k).abs().max();
        assert!(err < 1e-6, "largest error {err}");
        // Only the first 64 states count: a wild tail changes nothing.
        let mut long = traj.clone();
        long.push([1e6; LATENT_DIM]);
        assert_eq!(identify(&[&long], 1e-9).unwrap(), got);
        assert!(identify(&[], 1e-9).is_err());
    }
}
