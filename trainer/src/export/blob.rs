//! The blob writer: the trained MLPs, `F` and the gain schedule laid out
//! in the weight arena `estimator::blob` reads, and the serialised blob.

use anyhow::Result;
use burn::nn::Linear;
use estimator::blob::{Blob, Body, F32s, Family, FilterSpec, Header, Layout, ParamSpec, TrustSpec};
use estimator::{AUG_DIM, INPUT_DIM, PARAM_DIM};

use super::schedule::{ScheduleCheck, gain_schedule};
use crate::learn::config::TrainConfig;
use crate::learn::model::Mlp;
use crate::learn::run::Norm;

/// Little-endian bytes of `f32` values.
pub fn le_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// A burn `Linear` (weight `[d_in, d_out]`, `y = x W + b`) as the blob
/// stores it: `(d_in, d_out, W, b)` with `W` input-major, `d_in` rows of
/// `d_out` (burn's own layout, copied as it is).
pub fn linear_to_blob(l: &Linear) -> (usize, usize, Vec<f32>, Vec<f32>) {
    let w = l.weight.val();
    let [d_in, d_out] = w.dims();
    let w: Vec<f32> = w
        .into_data()
        .convert::<f32>()
        .try_to_vec::<f32>()
        .unwrap_or_default();
    let b: Vec<f32> = match &l.bias {
        Some(b) => b
            .val()
            .into_data()
            .convert::<f32>()
            .try_to_vec::<f32>()
            .unwrap_or_default(),
        None => vec![0.0; d_out],
    };
    (d_in, d_out, w, b)
}

/// The weight arena a [`Blob`] borrows from, as little-endian bytes, the
/// family whose layout it has and the layout (the MLPs' hidden width).
#[derive(Clone)]
pub struct BlobParts {
    arena: Vec<u8>,
    family: Family,
    layout: Layout,
}

/// The encoder's and decoder's layers in the arena's order, and their
/// layout (the hidden width: the encoder's first layer's outputs).
fn mlp_values(enc: &Mlp, dec: &Mlp) -> (Vec<f32>, Layout) {
    let mut arena = Vec::new();
    let [_, hidden] = enc.l0.weight.val().dims();
    for l in [&enc.l0, &enc.l1, &enc.l2, &dec.l0, &dec.l1, &dec.l2] {
        let (_, _, w, b) = linear_to_blob(l);
        arena.extend(w);
        arena.extend(b);
    }
    (arena, Layout { hidden })
}

impl BlobParts {
    /// From the MLPs, `F` (row-major AUG x AUG) and `B` (AUG x 1; its
    /// parameter rows zero), in the arena's order (see `estimator::blob`):
    /// encoder layers, decoder layers (weight then bias each), `F`, `B`.
    /// No gain schedule: see [`BlobParts::set_schedule`].
    pub fn new(enc: &Mlp, dec: &Mlp, f: &[f32], b: &[f32]) -> Self {
        let (mut arena, layout) = mlp_values(enc, dec);
        arena.extend_from_slice(f);
        let mut torque = [0.0f32; AUG_DIM * INPUT_DIM];
        for (d, v) in torque.iter_mut().zip(b).take(estimator::LATENT_DIM) {
            *d = *v;
        }
        arena.extend(torque);
        BlobParts {
            arena: le_bytes(&arena),
            family: Family::Linear,
            layout,
        }
    }

    /// The bilinear family's arena (see `estimator::blob`, "The bilinear
    /// arena"): encoder and decoder layers, then `F_0, F_1, F_2, F_11`
    /// (`blocks`, each row-major), then `B_0, B_1, B_2, B_11` (`torque`,
    /// each a latent column; zero for a free model).
    pub fn bilinear(enc: &Mlp, dec: &Mlp, blocks: &[f32], torque: &[f32]) -> Self {
        let (mut arena, layout) = mlp_values(enc, dec);
        arena.extend_from_slice(blocks);
        arena.extend_from_slice(torque);
        BlobParts {
            arena: le_bytes(&arena),
            family: Family::Bilinear,
            layout,
        }
    }

    /// The family of the arena.
    pub fn family(&self) -> Family {
        self.family
    }

    /// `F` (row-major) as stored in the arena.
    fn f(&self) -> Vec<f32> {
        F32s(&self.arena)
            .iter()
            .skip(self.layout.f_at())
            .take(AUG_DIM * AUG_DIM)
            .collect()
    }

    /// Replaces the arena's gain schedule with the one of `filter` (its
    /// `schedule_steps` updates, from [`gain_schedule`]); a blob must be
    /// made with the same `filter`.
    pub fn set_schedule(&mut self, filter: &FilterSpec) -> Result<ScheduleCheck> {
        anyhow::ensure!(
            self.family == Family::Linear,
            "a gain schedule is for the linear family (the extended filter's gains depend on the state)"
        );
        let (schedule, check) = gain_schedule(&self.f(), filter)?;
        self.arena.truncate(self.layout.schedule_at() * 4);
        self.arena.extend(le_bytes(&schedule));
        Ok(check)
    }

    /// The blob, borrowing from `self`.
    pub fn blob<'a>(
        &'a self,
        norm: &Norm,
        cfg: &TrainConfig,
        filter: FilterSpec,
        params: [ParamSpec<'a>; PARAM_DIM],
        trust: TrustSpec<'a>,
    ) -> Blob<'a> {
        Blob {
            header: Header::with_hidden(self.layout.hidden as u16),
            body: Body {
                dt: cfg.dt as f32,
                g: cfg.g as f32,
                rig: cfg.rig,
                family: self.family,
                activation: cfg.activation,
                norm_mu: norm.mu.map(|v| v as f32),
                norm_s: norm.s.map(|v| v as f32),
                params,
                filter,
                trust,
                pad: &[],
                weights: F32s(&self.arena),
            },
        }
    }
}

pub use trainer_core::calibrate::blob_bytes;

#[cfg(test)]
mod tests {
    use super::*;
    use burn::module::Param;
    use burn::tensor::{Device, Tensor, TensorData};
    use estimator::{LATENT_DIM, Model};
    use trainer_core::calibrate::{CalibrateConfig, map_bytes, permissive};

    /// A 2 -> 3 layer with every weight distinct: `W[i][o] = 10 (i + 1) + (o + 1)`,
    /// `b[o] = -(o + 1)`. burn stores it `[d_in, d_out]`; `y = x W + b`.
    fn asymmetric_linear(d_in: usize, d_out: usize) -> Linear {
        let device = Device::flex();
        let w: Vec<f32> = (0..d_in)
            .flat_map(|i| (0..d_out).map(move |o| (10 * (i + 1) + o + 1) as f32))
            .collect();
        let b: Vec<f32> = (0..d_out).map(|o| -((o + 1) as f32)).collect();
        Linear {
            weight: Param::from_tensor(Tensor::from_data(
                TensorData::new(w, [d_in, d_out]),
                &device,
            )),
            bias: Some(Param::from_tensor(Tensor::from_data(
                TensorData::new(b, [d_out]),
                &device,
            ))),
        }
    }

    #[test]
    fn linear_lands_input_major() {
        let (d_in, d_out, w, b) = linear_to_blob(&asymmetric_linear(2, 3));
        assert_eq!((d_in, d_out), (2, 3));
        // Golden, from the formula above: row i holds W[i][0..3].
        assert_eq!(w, [11.0, 12.0, 13.0, 21.0, 22.0, 23.0]);
        assert_eq!(b, [-1.0, -2.0, -3.0]);
    }

    #[test]
    fn blob_round_trips_and_computes_what_burn_computes() {
        // At every hidden width the estimator runs: the header records
        // it and the arena is laid out for it.
        for width in estimator::HIDDEN_WIDTHS {
            round_trip(width);
        }
    }

    fn round_trip(width: usize) {
        let bits = vec![0xffu8; map_bytes(&CalibrateConfig::default())];
        let device = Device::flex();
        device.seed(3);
        let mut enc = Mlp::new(2, width, LATENT_DIM, &device);
        enc.l0 = asymmetric_linear(2, width); // large but exact
        enc.l0.weight = enc.l0.weight.map(|w| w.mul_scalar(0.01));
        let dec = Mlp::new(LATENT_DIM, width, 2, &device);
        // Latent rows arbitrary; parameter rows the identity, as the filter
        // requires (a blob without it is refused, checked at the end).
        let f: Vec<f32> = (0..AUG_DIM * AUG_DIM)
            .map(|k| match (k / AUG_DIM, k % AUG_DIM) {
                (i, j) if i >= LATENT_DIM => f32::from(u8::from(i == j)),
                _ => (k as f32 * 0.37).sin(),
            })
            .collect();
        let parts = BlobParts::new(&enc, &dec, &f, &[]);
        let cfg = TrainConfig::default();
        let norm = Norm {
            mu: [0.5, -0.25],
            s: [2.0, 4.0],
        };
        let filter = FilterSpec {
            q: [0.1; AUG_DIM],
            r: [0.2; LATENT_DIM],
            prior_mean: [0.0; PARAM_DIM],
            prior_var: [1.0; AUG_DIM],
            burn_in: 32,
            sigma_threshold: 0.05,
            schedule_steps: 0,
        };
        // The protocol's: lengths 2 and 5 read reciprocally, no effect.
        let params = [cfg.length_spec(), cfg.effect_spec()];
        let trust = permissive(&CalibrateConfig::default(), [2.0, 5.0], &bits);
        let blob = parts.blob(&norm, &cfg, filter, params, trust);
        let bytes = blob_bytes(&blob).unwrap();
        let back = Model::from_bytes(&bytes).unwrap();
        // Exactly the same numbers come back (the blob stores f32 bits),
        // with the 0-3 padding bytes the writer chose, which put the arena
        // at a multiple of 4 bytes from the blob's start.
        let pad = back.blob().body.pad;
        assert!(pad.len() <= 3 && pad.iter().all(|b| *b == 0));
        let offset = back.blob().body.weights.0.as_ptr() as usize - bytes.as_ptr() as usize;
        assert_eq!(offset % 4, 0, "arena at byte {offset}");
        let mut want = blob;
        want.body.pad = pad;
        assert_eq!(*back.blob(), want);
        assert_eq!(usize::from(back.blob().header.hidden_dim), width);
        assert_eq!(back.blob().layout().hidden, width);
        assert_eq!(
            back.blob().body.weights.len(),
            back.blob().layout().arena_len(0)
        );
        for (i, j) in [(0, 0), (3, 17), (17, 2), (17, 17)] {
            assert_eq!(back.f(i, j), f[i * AUG_DIM + j]);
        }
        // And the estimator's encoder computes burn's forward pass.
        let x = [0.3f32, -1.2];
        let burn_y: Vec<f32> = enc
            .forward(
                Tensor::<2>::from_data(TensorData::new(x.to_vec(), [1, 2]), &device),
                cfg.activation,
            )
            .into_data()
            .try_to_vec::<f32>()
            .unwrap();
        let y = back.encode(&x);
        for (a, b) in y.iter().zip(&burn_y) {
            // Same f32 sums in another order: relative 1e-5 of the magnitude.
            assert!((a - b).abs() <= 1e-5 * b.abs().max(1.0), "{a} vs {b}");
        }
        // A length that would drift (F[16][16] != 1) is refused.
        let mut drifting = f.clone();
        drifting[LATENT_DIM * AUG_DIM + LATENT_DIM] = 0.99;
        let parts = BlobParts::new(&enc, &dec, &drifting, &[]);
        let blob = parts.blob(&norm, &cfg, filter, params, trust);
        let bytes = blob_bytes(&blob).unwrap();
        assert_eq!(
            Model::from_bytes(&bytes).unwrap_err(),
            estimator::Error::BlobParamsNotStatic
        );
    }
}
