//! The refit of `F` (or, for the bilinear family, of `F_0 .. F_11`): once
//! over every training transition with the trained encoder (the global
//! matrices the batches converged to), and the one-step latent residual
//! variance that scales `Q` and `R`.

use anyhow::{Context, Result};
use burn::tensor::{Tensor, TensorData};
use estimator::{AUG_DIM, LATENT_DIM};
use trainer_core::data::Dataset;

use crate::learn::bilinear::{Bilinear, fit_bilinear};
use crate::learn::config::TrainConfig;
use crate::learn::model::{Klm, fit_koopman};
use crate::learn::run::{Norm, device};

/// Every transition of `ds`, encoded: `y` `[B, T, latent]` and the
/// parameters' coordinates `[B, 2]`.
fn encoded(
    enc: &crate::learn::model::Mlp,
    ds: &Dataset,
    norm: &Norm,
    cfg: &TrainConfig,
) -> Result<(Tensor<3>, Tensor<2>)> {
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
    Ok((enc.forward(x, cfg.activation).detach(), p))
}

/// The values of a tensor.
fn values<const D: usize>(t: Tensor<D>) -> Result<Vec<f32>> {
    t.into_data()
        .try_to_vec::<f32>()
        .map_err(|e| anyhow::anyhow!("{e:?}"))
}

/// Per dimension, the mean square of `res` (`[B, T, latent]`), floored
/// at 1e-10.
fn residual_variance(res: Tensor<3>) -> Result<[f32; LATENT_DIM]> {
    let [b, t, l] = res.dims();
    let v = values(res.powi_scalar(2).reshape([b * t, l]).mean_dim(0))?;
    let mut out = [0.0f32; LATENT_DIM];
    for (d, s) in out.iter_mut().zip(&v) {
        *d = s.max(1e-10);
    }
    Ok(out)
}

/// The bilinear family's `F_0, F_1, F_2, F_11` (each row-major, in that
/// order, as the blob stores them) fitted over every transition of `ds`
/// with the trained encoder, and the one-step latent residual variance
/// per dimension.
pub fn global_bilinear(
    model: &Bilinear,
    ds: &Dataset,
    norm: &Norm,
    cfg: &TrainConfig,
) -> Result<(Vec<f32>, [f32; LATENT_DIM])> {
    let (y, q) = encoded(&model.enc, ds, norm, cfg)?;
    let [b, t, l] = y.dims();
    let k = fit_bilinear(y.clone(), q.clone(), cfg.ridge);
    let pred = y.clone().slice([0..b, 0..t - 1, 0..l]).matmul(k.at(q));
    let residual_var = residual_variance(y.slice([0..b, 1..t, 0..l]) - pred)?;
    let mut blocks = Vec::with_capacity(4 * l * l);
    for ft in &k.ft {
        // F_k^T row-major is F_k column-major: transpose back.
        blocks.extend(values(ft.clone().transpose())?);
    }
    Ok((blocks, residual_var))
}

/// `F` (row-major, AUG x AUG) fitted over every transition of `ds`, and
/// the one-step latent residual variance per dimension.
pub fn global_koopman(
    model: &Klm,
    ds: &Dataset,
    norm: &Norm,
    cfg: &TrainConfig,
) -> Result<(Vec<f32>, [f32; LATENT_DIM])> {
    let (y, p) = encoded(&model.enc, ds, norm, cfg)?;
    let [b, t, l] = y.dims();
    let k = fit_koopman(y.clone(), Some(p.clone()), cfg.ridge);
    let kct = k.ct.context("the KLM's K has a parameter block")?;
    let at = values(k.at.clone())?;
    let ct = values(kct.clone())?;
    // One-step residual.
    let g_y = y.clone().slice([0..b, 0..t - 1, 0..l]);
    let pred = g_y.matmul(k.at.unsqueeze_dim::<3>(0)) + p.matmul(kct).unsqueeze_dim::<3>(1);
    let residual_var = residual_variance(y.slice([0..b, 1..t, 0..l]) - pred)?;
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
