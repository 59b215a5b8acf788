//! A training that starts from a blob: the encoder and decoder of a
//! Koopman blob loaded into the model to train, with the blob's own
//! normalisation (the weights read inputs scaled by it). The dynamics
//! are fitted inside every batch, so the MLPs are all a run carries.

use std::path::Path;

use anyhow::{Context, Result};
use burn::module::Param;
use burn::nn::Linear;
use burn::tensor::{Device, Tensor, TensorData};
use estimator::blob::{Blob, F32s, N_LAYERS, Net};

use super::model::Mlp;
use super::run::Norm;

/// The encoder, decoder and normalisation of the blob at `path`, for a
/// model of hidden width `hidden`.
pub fn mlps_of(path: &Path, hidden: usize, device: &Device) -> Result<(Mlp, Mlp, Norm)> {
    let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    let blob = Blob::from_bytes(&bytes)
        .map_err(|e| anyhow::anyhow!("{}: not a blob to start from: {e}", path.display()))?;
    let width = blob.layout().hidden;
    anyhow::ensure!(
        width == hidden,
        "{}: its MLPs are {width} wide, the training's {hidden}",
        path.display()
    );
    let mlp = |net: Net| -> Result<Mlp> {
        let [l0, l1, l2] = [0, 1, 2].map(|k| linear(&blob, net, k, device));
        Ok(Mlp {
            l0: l0?,
            l1: l1?,
            l2: l2?,
        })
    };
    const _: () = assert!(N_LAYERS == 3);
    let norm = Norm {
        mu: blob.body.norm_mu.map(f64::from),
        s: blob.body.norm_s.map(f64::from),
    };
    Ok((mlp(Net::Encoder)?, mlp(Net::Decoder)?, norm))
}

/// Layer `k` of `net` as a burn `Linear` (`y = x W + b`, `W` input-major,
/// the blob's own layout).
fn linear(blob: &Blob<'_>, net: Net, k: usize, device: &Device) -> Result<Linear> {
    let (w, b) = blob.layer(net, k);
    let (_, d_in, d_out) = blob
        .layout()
        .layer_span(net, k)
        .with_context(|| format!("the blob has no layer {k} of its {net:?}"))?;
    let values = |v: F32s<'_>| v.iter().collect::<Vec<f32>>();
    let weight = Tensor::<2>::from_data(TensorData::new(values(w), [d_in, d_out]), device);
    let bias = Tensor::<1>::from_data(TensorData::new(values(b), [d_out]), device);
    Ok(Linear {
        weight: Param::from_tensor(weight),
        bias: Some(Param::from_tensor(bias)),
    })
}
