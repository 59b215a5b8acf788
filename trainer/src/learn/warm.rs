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

#[cfg(test)]
mod tests {
    use super::*;
    use estimator::Model;
    use estimator::blob::Activation;

    /// `mlp` on the one input `x`.
    fn forward(mlp: &Mlp, x: &[f32], act: Activation, device: &Device) -> Vec<f32> {
        let input = Tensor::<2>::from_data(TensorData::new(x.to_vec(), [1, x.len()]), device);
        mlp.forward(input, act)
            .into_data()
            .try_to_vec::<f32>()
            .unwrap()
    }

    /// The shipped rig blob's MLPs, loaded into burn, compute what the
    /// estimator's own no_std MLPs compute on the same normalised states
    /// (to 1e-5 of the latent's scale, f32 sums in another order), and its
    /// normalisation comes along: a fine-tuning starts where the blob is.
    #[test]
    fn a_blob_loads_into_the_model_it_was_exported_from() {
        let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../weights/rig.kkf"));
        let bytes = std::fs::read(path).unwrap();
        let model = Model::from_bytes(&bytes).unwrap();
        let act = model.blob().body.activation;
        let device = Device::flex();
        let (enc, dec, norm) = mlps_of(path, 64, &device).unwrap();
        assert_eq!(norm.mu[0], f64::from(model.blob().body.norm_mu[0]));
        assert_eq!(norm.s[1], f64::from(model.blob().body.norm_s[1]));
        for x in [[0.0f32, 0.0], [0.8, -1.3], [-2.5, 3.0]] {
            let y_ref = model.encode(&x);
            let y = forward(&enc, &x, act, &device);
            let scale = y_ref.iter().fold(1.0f32, |a, v| a.max(v.abs()));
            for (a, b) in y.iter().zip(&y_ref) {
                assert!((a - b).abs() <= 1e-5 * scale, "{y:?} vs {y_ref:?}");
            }
            let x_ref = model.decode(&y_ref);
            let x_back = forward(&dec, &y_ref, act, &device);
            for (a, b) in x_back.iter().zip(&x_ref) {
                assert!(
                    (a - b).abs() <= 1e-5 * (1.0 + b.abs()),
                    "{x_back:?} vs {x_ref:?}"
                );
            }
        }
        // Another width is refused, naming both.
        let e = mlps_of(path, 128, &device).unwrap_err().to_string();
        assert!(e.contains("64 wide") && e.contains("128"), "{e}");
    }
}
