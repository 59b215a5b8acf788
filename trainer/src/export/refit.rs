//! The refit of `F` (or, for the bilinear family, of `F_0 .. F_11`): once
//! over every training transition with the trained encoder (the global
//! matrices the batches converged to), and the one-step latent residual
//! variance that scales `Q` and `R`.

use anyhow::{Context, Result};
use burn::tensor::{Tensor, TensorData};
use estimator::{AUG_DIM, LATENT_DIM};
use trainer_core::data::Dataset;

use crate::learn::bilinear::{BLOCKS, Bilinear};
use crate::learn::config::TrainConfig;
use crate::learn::model::{Klm, fit_koopman};
use crate::learn::run::{Norm, device};
use nalgebra::{DMatrix, DVector};

/// Every transition of `ds`, encoded: `y` `[B, T, latent]`, the
/// parameters' coordinates `[B, 2]` and, for a driven set, the torques
/// `[B, T]`.
fn encoded(
    enc: &crate::learn::model::Mlp,
    ds: &Dataset,
    norm: &Norm,
    cfg: &TrainConfig,
) -> Result<(Tensor<3>, Tensor<2>, Option<Tensor<2>>)> {
    let device = device();
    let t = ds.rollouts.first().context("empty data set")?.xs.len();
    let driven = ds.rollouts.iter().any(|r| !r.us.is_empty());
    let mut x = Vec::new();
    let mut p = Vec::new();
    let mut u = Vec::new();
    for r in &ds.rollouts {
        anyhow::ensure!(r.xs.len() == t, "rollouts of unequal length");
        x.extend(r.xs.iter().flat_map(|&v| norm.apply(v)));
        let m = ds.meta(r.id).context("rollout without truth")?;
        p.extend(cfg.coordinates(m)?);
        if driven {
            u.extend((0..t).map(|k| r.u(k) as f32));
        }
    }
    let b = ds.rollouts.len();
    let x = Tensor::<3>::from_data(TensorData::new(x, [b, t, 2]), &device);
    let p = Tensor::<2>::from_data(TensorData::new(p, [b, 2]), &device);
    let u = driven.then(|| Tensor::<2>::from_data(TensorData::new(u, [b, t]), &device));
    Ok((enc.forward(x, cfg.activation).detach(), p, u))
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
/// order, as the blob stores them) and `B_0 .. B_11` (each a latent column;
/// zero for a free set) fitted over every transition of `ds` with the
/// trained encoder, and the one-step latent residual variance per
/// dimension.
///
/// In f64 (normal equations accumulated over every transition, solved by
/// Cholesky), not by the training's f32 elimination: the columns `y`,
/// `q_1 y` and `q_1^2 y` are nearly collinear, and f32 leaves one-step
/// errors near 1e-2 of the latent's scale on exact data
/// (`learn::bilinear`'s test), which a filter reading the frequency
/// from `F(q)` cannot afford. The ridge is the training's,
/// `ridge * trace(G^T G / N) / n`.
pub fn global_bilinear(
    model: &Bilinear,
    ds: &Dataset,
    norm: &Norm,
    cfg: &TrainConfig,
) -> Result<(Vec<f32>, Vec<f32>, [f32; LATENT_DIM])> {
    let (y, q, u) = encoded(&model.enc, ds, norm, cfg)?;
    let [b, t, l] = y.dims();
    let y = values(y)?;
    let q = values(q)?;
    let u = u.map(values).transpose()?;
    let driven = u.is_some();
    let n = BLOCKS * l + if driven { BLOCKS } else { 0 };
    let latent = |r: usize, k: usize| &y[(r * t + k) * l..(r * t + k + 1) * l];
    let columns = |r: usize, k: usize| -> Vec<f64> {
        let (q1, q2) = (f64::from(q[2 * r]), f64::from(q[2 * r + 1]));
        let scales = [1.0, q1, q2, q1 * q1];
        let mut g: Vec<f64> = scales
            .iter()
            .flat_map(|s| latent(r, k).iter().map(move |v| s * f64::from(*v)))
            .collect();
        if let Some(u) = &u {
            let uk = f64::from(u[r * t + k]);
            g.extend(scales.iter().map(|s| s * uk));
        }
        g
    };
    let mut gtg = DMatrix::<f64>::zeros(n, n);
    let mut gty = DMatrix::<f64>::zeros(n, l);
    let rows = (b * (t - 1)) as f64;
    for r in 0..b {
        for k in 0..t - 1 {
            let g = DVector::from_vec(columns(r, k));
            let target = DVector::from_iterator(l, latent(r, k + 1).iter().map(|v| f64::from(*v)));
            gtg.ger(1.0 / rows, &g, &g, 1.0);
            gty.ger(1.0 / rows, &g, &target, 1.0);
        }
    }
    let lambda = cfg.ridge * gtg.trace() / n as f64 + 1e-12;
    for i in 0..n {
        gtg[(i, i)] += lambda;
    }
    let kt = gtg
        .cholesky()
        .context("the bilinear refit's normal equations are not positive definite")?
        .solve(&gty); // [4 l, l]: row block k is F_k^T
    // The one-step residual with the refitted matrices.
    let mut sums = [0.0f64; LATENT_DIM];
    for r in 0..b {
        for k in 0..t - 1 {
            let g = DVector::from_vec(columns(r, k));
            let pred = kt.tr_mul(&g);
            for (d, (p, v)) in sums.iter_mut().zip(pred.iter().zip(latent(r, k + 1))) {
                *d += (f64::from(*v) - p).powi(2) / rows;
            }
        }
    }
    let mut residual_var = [0.0f32; LATENT_DIM];
    for (d, s) in residual_var.iter_mut().zip(&sums) {
        *d = (*s as f32).max(1e-10);
    }
    // F_k row-major: F_k[i][j] = F_k^T[j][i] = kt[k l + j, i].
    let mut blocks = Vec::with_capacity(BLOCKS * l * l);
    for blk in 0..BLOCKS {
        for i in 0..l {
            for j in 0..l {
                blocks.push(kt[(blk * l + j, i)] as f32);
            }
        }
    }
    // B_k: its row of K^T, kt[4 l + k, i] (zero when free).
    let mut torque = vec![0.0f32; BLOCKS * l];
    if driven {
        for blk in 0..BLOCKS {
            for i in 0..l {
                torque[blk * l + i] = kt[(BLOCKS * l + blk, i)] as f32;
            }
        }
    }
    Ok((blocks, torque, residual_var))
}

/// `F` (row-major, AUG x AUG) and `B` (AUG x 1; zero for a free set, and
/// in its parameter rows) fitted together over every transition of `ds`,
/// and the one-step latent residual variance per dimension.
pub fn global_koopman(
    model: &Klm,
    ds: &Dataset,
    norm: &Norm,
    cfg: &TrainConfig,
) -> Result<(Vec<f32>, Vec<f32>, [f32; LATENT_DIM])> {
    let (y, p, u) = encoded(&model.enc, ds, norm, cfg)?;
    let [b, t, l] = y.dims();
    let k = fit_koopman(y.clone(), Some(p.clone()), u.clone(), cfg.ridge);
    let kct = k.ct.context("the KLM's K has a parameter block")?;
    let at = values(k.at.clone())?;
    let ct = values(kct.clone())?;
    let mut torque = vec![0.0f32; AUG_DIM];
    if let Some(bt) = &k.bt {
        for (d, v) in torque.iter_mut().zip(values(bt.clone())?) {
            *d = v;
        }
    }
    // One-step residual.
    let g_y = y.clone().slice([0..b, 0..t - 1, 0..l]);
    let mut pred = g_y.matmul(k.at.unsqueeze_dim::<3>(0)) + p.matmul(kct).unsqueeze_dim::<3>(1);
    if let (Some(bt), Some(u)) = (k.bt, u) {
        let us = u.slice([0..b, 0..t - 1]).reshape([b, t - 1, 1]);
        pred = pred + us.matmul(bt.unsqueeze_dim::<3>(0));
    }
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
    Ok((f, torque, residual_var))
}
