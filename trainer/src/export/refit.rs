//! The refit of `F`: once over every training transition with the trained
//! encoder (the global matrix the batches converged to), and the one-step
//! latent residual variance that scales `Q` and `R`.

use anyhow::{Context, Result};
use burn::tensor::{Tensor, TensorData};
use estimator::{AUG_DIM, LATENT_DIM};
use trainer_core::data::Dataset;

use crate::learn::config::TrainConfig;
use crate::learn::model::{Klm, fit_koopman};
use crate::learn::run::{Norm, device};

/// `F` (row-major, AUG x AUG) fitted over every transition of `ds`, and
/// the one-step latent residual variance per dimension.
pub fn global_koopman(
    model: &Klm,
    ds: &Dataset,
    norm: &Norm,
    cfg: &TrainConfig,
) -> Result<(Vec<f32>, [f32; LATENT_DIM])> {
    let device = device();
    let t = ds.rollouts.first().context("empty data set")?.xs.len();
    let mut x = Vec::new();
    let mut p = Vec::new();
    for r in &ds.rollouts {
        anyhow::ensure!(r.xs.len() == t, "rollouts of unequal length");
        x.extend(r.xs.iter().flat_map(|&v| norm.apply(v)));
        let m = ds.meta(r.id).context("rollout without truth")?;
        p.extend(cfg.coordinates(m)?);
    }
    let b = ds.rollouts.len();
    let x = Tensor::<3>::from_data(TensorData::new(x, [b, t, 2]), &device);
    let p = Tensor::<2>::from_data(TensorData::new(p, [b, 2]), &device);
    let y = model.enc.forward(x, cfg.activation).detach();
    let k = fit_koopman(y.clone(), Some(p.clone()), cfg.ridge);
    let kct = k.ct.context("the KLM's K has a parameter block")?;
    let at: Vec<f32> =
        k.at.clone()
            .into_data()
            .try_to_vec::<f32>()
            .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let ct: Vec<f32> = kct
        .clone()
        .into_data()
        .try_to_vec::<f32>()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let l = LATENT_DIM;
    // One-step residual.
    let g_y = y.clone().slice([0..b, 0..t - 1, 0..l]);
    let pred = g_y.matmul(k.at.unsqueeze_dim::<3>(0)) + p.matmul(kct).unsqueeze_dim::<3>(1);
    let res = (y.slice([0..b, 1..t, 0..l]) - pred)
        .powi_scalar(2)
        .reshape([b * (t - 1), l])
        .mean_dim(0);
    let res: Vec<f32> = res
        .into_data()
        .try_to_vec::<f32>()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let mut residual_var = [0.0f32; LATENT_DIM];
    for (d, s) in residual_var.iter_mut().zip(&res) {
        *d = s.max(1e-10);
    }
    let mut f = vec![0.0f32; AUG_DIM * AUG_DIM];
    for i in 0..l {
        for j in 0..l {
            f[i * AUG_DIM + j] = at[j * l + i];
        }
        f[i * AUG_DIM + l] = ct[i]; // length column
        if cfg.effect.is_some() {
            f[i * AUG_DIM + l + 1] = ct[l + i]; // the effect's column (else it stays 0)
        }
    }
    for k in l..AUG_DIM {
        f[k * AUG_DIM + k] = 1.0;
    }
    Ok((f, residual_var))
}
