//! A synthetic bilinear blob ([`Family::Bilinear`]) for the tests of the
//! extended filter: no training, every number from a fixed formula or a
//! ChaCha8 stream, so that every run builds the same bytes: the MLPs'
//! weights from seed [`BILINEAR_SEED`], the dynamics' basis from
//! `BILINEAR_SEED + 1`.
//!
//! - Encoder and decoder: `tanh` MLPs whose weights are uniform in
//!   `+-1 / sqrt(d_in)` and biases in `+-0.1`, so that no layer saturates
//!   on the normalised states of a swing.
//! - Dynamics: in a random orthonormal basis `U` (the QR factor of a
//!   matrix of uniform entries), eight 2x2 blocks; block `k` turns by
//!   about `w_k (1 + a q_1)` per step, `w_k = 0.08 (k + 1)` rad and
//!   `a = `[`FREQUENCY_SLOPE`], and shrinks by about `rho (1 - b q_2)`,
//!   `rho = `[`RADIUS`], `b = `[`DAMPING_SLOPE`]. With `R(w)` the rotation
//!   by `w`, `J` the rotation by `pi / 2` and `d = a w_k q_1`,
//!   `R(w_k + d) ~ R(w_k) (I + d J - d^2 / 2 I)`, so block `k` of `F_0` is
//!   `rho R(w_k)`, of `F_1` `rho a w_k R(w_k) J`, of `F_11`
//!   `-rho (a w_k)^2 / 2 R(w_k)` and of `F_2` `-rho b R(w_k)`; each matrix
//!   is `U blocks U^T`. Block `k` of `F(q)` is then
//!   `rho R(w_k) ((1 - b q_2 - d^2 / 2) I + d J)`, whose eigenvalues have
//!   the modulus `rho sqrt((1 - b q_2 - d^2 / 2)^2 + d^2)`: at most
//!   0.99497 over the training square `q in [-1, 1]^2` (the fastest block
//!   at `q = (+-1, -1)`), so rollouts stay bounded.
//! - Parameters: the length of a simple pendulum read
//!   [`Reading::ReciprocalUnit`] over `[0.1, 1.5]` m, and a declared
//!   damping read [`Reading::Unit`] over `[0, 0.2]`.
//! - Filter: `Q`, `R`, prior as in [`bilinear_filter`], no schedule;
//!   trust: [`permissive`].

use estimator::blob::{
    Activation, BILINEAR_BLOCK_LEN, BILINEAR_BLOCKS, Blob, Body, F32s, Family, FilterSpec, Header,
    Layout, N_LAYERS, Net, ParamSpec, Reading,
};
use estimator::{AUG_DIM, HIDDEN_DIM, LATENT_DIM, PARAM_DIM, Rig};
use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use trainer_core::calibrate::{CalibrateConfig, blob_bytes, map_bytes, permissive};

/// The seed of the ChaCha8 stream the MLPs' weights are drawn from (the
/// dynamics' basis is drawn from the next seed).
pub const BILINEAR_SEED: u64 = 20_240_817;
/// The synthetic blob's arena: hidden layers [`HIDDEN_DIM`] wide.
pub const LAYOUT: Layout = Layout { hidden: HIDDEN_DIM };
/// `rho`: every block's radius at `q_2 = 0`.
pub const RADIUS: f64 = 0.99;
/// `a`: the frequencies scale by `1 + a q_1`.
pub const FREQUENCY_SLOPE: f64 = 0.25;
/// `b`: the radius scales by `1 - b q_2`.
pub const DAMPING_SLOPE: f64 = 0.005;
/// The sampling interval, s.
pub const DT: f32 = 0.02;

/// The filter settings: `Q` 1e-4 on the latent and 1e-6 on each
/// coordinate (so the parameters' process noise is exercised), `R` 1e-2,
/// prior variance 1e-2 on the latent and 0.25 on each coordinate (a
/// standard deviation of half the training range's half-width) around 0,
/// the middle of the range; no gain schedule.
pub fn bilinear_filter() -> FilterSpec {
    let mut q = [1e-4; AUG_DIM];
    let mut prior_var = [1e-2; AUG_DIM];
    for k in LATENT_DIM..AUG_DIM {
        q[k] = 1e-6;
        prior_var[k] = 0.25;
    }
    FilterSpec {
        q,
        r: [1e-2; LATENT_DIM],
        prior_mean: [0.0; PARAM_DIM],
        prior_var,
        burn_in: 32,
        sigma_threshold: 0.05,
        schedule_steps: 0,
    }
}

/// The parameters: a simple pendulum's length over `[0.1, 1.5]` m, read
/// [`Reading::ReciprocalUnit`], and a damping over `[0, 0.2]`, read
/// [`Reading::Unit`].
pub fn bilinear_params() -> [ParamSpec<'static>; PARAM_DIM] {
    [
        ParamSpec {
            name: "length",
            declared: true,
            train_range: [0.1, 1.5],
            reading: Reading::ReciprocalUnit,
            scales_with_g: true,
        },
        ParamSpec {
            name: "damping",
            declared: true,
            train_range: [0.0, 0.2],
            reading: Reading::Unit,
            scales_with_g: false,
        },
    ]
}

/// `F_0, F_1, F_2, F_11` in f64 (see the module docs), each
/// [`LATENT_DIM`] square, before they are rounded to the blob's f32.
pub fn bilinear_matrices() -> [DMatrix<f64>; BILINEAR_BLOCKS] {
    let mut rng = ChaCha8Rng::seed_from_u64(BILINEAR_SEED + 1);
    let basis = DMatrix::from_fn(LATENT_DIM, LATENT_DIM, |_, _| rng.random_range(-1.0..1.0));
    let u = basis.qr().q();
    let (rho, a, b) = (RADIUS, FREQUENCY_SLOPE, DAMPING_SLOPE);
    let mut blocks: [DMatrix<f64>; BILINEAR_BLOCKS] =
        std::array::from_fn(|_| DMatrix::zeros(LATENT_DIM, LATENT_DIM));
    for k in 0..LATENT_DIM / 2 {
        let w = 0.08 * (k + 1) as f64;
        let (c, s) = (w.cos(), w.sin());
        // R(w), and R(w) J = R(w + pi / 2).
        let rot = [[c, -s], [s, c]];
        let rot_j = [[-s, -c], [c, -s]];
        let scaled = [
            (rho, rot),
            (rho * a * w, rot_j),
            (-rho * b, rot),
            (-rho * (a * w) * (a * w) / 2.0, rot),
        ];
        for (m, (scale, r)) in blocks.iter_mut().zip(scaled) {
            for (i, row) in r.iter().enumerate() {
                for (j, v) in row.iter().enumerate() {
                    m[(2 * k + i, 2 * k + j)] = scale * v;
                }
            }
        }
    }
    blocks.map(|m| &u * m * u.transpose())
}

/// The arena: encoder and decoder layers (weight then bias, in
/// [`Layout::layer_span`]'s order), then `F_0, F_1, F_2, F_11` row-major,
/// then the torque's columns `B_0, B_1, B_2, B_11` ([`bilinear_b`]).
fn arena() -> Vec<f32> {
    let mut rng = ChaCha8Rng::seed_from_u64(BILINEAR_SEED);
    let mut arena = vec![0.0f32; LAYOUT.bilinear_arena_len(true)];
    for net in [Net::Encoder, Net::Decoder] {
        for k in 0..N_LAYERS {
            let Some((at, d_in, d_out)) = LAYOUT.layer_span(net, k) else {
                continue;
            };
            let bound = 1.0 / (d_in as f32).sqrt();
            for w in &mut arena[at..at + d_in * d_out] {
                *w = rng.random_range(-bound..bound);
            }
            for b in &mut arena[at + d_in * d_out..at + d_in * d_out + d_out] {
                *b = rng.random_range(-0.1..0.1);
            }
        }
    }
    for (k, m) in bilinear_matrices().iter().enumerate() {
        let at = LAYOUT.f_at() + k * BILINEAR_BLOCK_LEN;
        for i in 0..LATENT_DIM {
            for j in 0..LATENT_DIM {
                arena[at + i * LATENT_DIM + j] = m[(i, j)] as f32;
            }
        }
    }
    for (k, b) in bilinear_b().iter().enumerate() {
        let at = LAYOUT.bilinear_b_at() + k * LATENT_DIM;
        arena[at..at + LATENT_DIM].copy_from_slice(b);
    }
    arena
}

/// The synthetic blob's torque columns `B_0, B_1, B_2, B_11`: a torque
/// pushes the latent along a fixed direction, more at one end of the
/// length's range (`B_1`), a little with the damping (`B_2`), curved
/// (`B_11`). Exact multiples of 1/64, from a formula (no RNG).
pub fn bilinear_b() -> [[f32; LATENT_DIM]; 4] {
    let scale = [0.125f32, 0.0625, 0.015625, 0.03125];
    core::array::from_fn(|k| {
        core::array::from_fn(|i| scale[k] * ((i * (k + 3)) % 5) as f32 - scale[k])
    })
}

/// The synthetic bilinear blob's bytes (see the module docs), as
/// [`trainer_core::calibrate::blob_bytes`] writes them: read in place by
/// [`estimator::Model::from_bytes`].
pub fn bilinear_blob() -> Vec<u8> {
    let arena = arena();
    let le: Vec<u8> = arena.iter().flat_map(|v| v.to_le_bytes()).collect();
    let cfg = CalibrateConfig::default();
    let bits = vec![0xffu8; map_bytes(&cfg)];
    let params = bilinear_params();
    let q_range = params[0].train_range.map(|v| params[0].coordinate(v));
    let blob = Blob {
        header: Header::CURRENT,
        body: Body {
            dt: DT,
            g: 9.81,
            rig: Rig::Simple,
            family: Family::Bilinear,
            activation: Activation::Tanh,
            norm_mu: [0.0, 0.0],
            norm_s: [1.0, 4.0],
            params,
            filter: bilinear_filter(),
            trust: permissive(&cfg, q_range, &bits),
            pad: &[],
            weights: F32s(&le),
        },
    };
    blob_bytes(&blob).unwrap_or_else(|e| panic!("the synthetic bilinear blob: {e}"))
}
