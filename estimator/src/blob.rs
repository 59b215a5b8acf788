//! The weights blob: one type definition for the trainer (which writes it)
//! and the estimator (which reads it where it lies, e.g. in flash).
//!
//! # Layout
//!
//! `[header][body][crc32]`, all postcard:
//! - [`Header`]: magic `b"KKF1"`, format version, and the dimensions the
//!   blob was made for. It is read first, on its own, so that a file of the
//!   wrong kind gets [`Error::BlobBadMagic`] rather than a decoding error.
//! - [`Body`]: sampling interval, activation, normalisation, the
//!   parameters (name, training range, [`Reading`]), the filter's `Q`,
//!   `R` and prior, the trust calibration, then 0-3 padding bytes and
//!   the weight arena: every weight of the MLPs, `F` and `B` as one run of
//!   little-endian `f32` ([`F32s`]). The
//!   padding puts the arena at a multiple of 4 bytes from the blob's first
//!   byte, so a blob lying at an aligned address (flash, a heap buffer,
//!   [`Aligned`]) is read as `&[f32]` in place: nothing proportional to its
//!   size is copied, and a Cortex-M4F loads the weights with `vldr`/`vldm`.
//! - a CRC-32 (CRC_32_ISCSI) over header and body, as postcard's
//!   `use-crc` flavour writes it (4 bytes, little-endian).
//!
//! Trailing bytes after the CRC are refused ([`Error::BlobTrailingBytes`]).
//!
//! Format 8 added the rig's geometry ([`Body::rig`], [`Rig`]): which
//! length the first parameter is (a string's or a rod's), so that every
//! report can name it; and the model family ([`Body::family`],
//! [`Family`]): the paper's linear `F`, or a bilinear `F(q)` whose
//! frequencies move with the parameters (see "The bilinear arena"). A
//! format-7 blob is a rod's, linear; `koopman calibrate` upgrades it.
//!
//! Format 9 added the largest mean normalised innovation the verdict
//! trusts ([`TrustSpec::max_nis`]: measurements that disagree with the
//! model while the states stay on the envelope) and how far the measured
//! rate may disagree with the angle's change over the blob's interval
//! ([`TrustSpec::max_rate_mismatch`]: measurements at another interval).
//! `koopman calibrate` upgrades a format-8 blob.
//!
//! Format 10 added the consistency check's law
//! ([`TrustSpec::nis_law`]): the mean normalised innovation is read
//! against what held-out rollouts of the same length and swing give, so
//! that noise on a small swing of a long pendulum is seen as well as on a
//! short one's. Two thresholds changed meaning with it:
//! [`TrustSpec::max_unevenness`] bounds the largest unevenness remembered
//! over every swing at least [`TrustSpec::min_swing`], not the latest,
//! and below that swing the estimate is held. `koopman calibrate`
//! upgrades a format-9 blob (law `[0, 0]`) and sets them again.
//!
//! Format 7 added the largest unevenness of the swing the verdict trusts
//! ([`TrustSpec::max_unevenness`]): friction, a torque or a sensor offset
//! that the envelope does not see.
//!
//! Format 6 added the gravity the model was trained at ([`Body::g`]),
//! which parameters the dynamics see only through it
//! ([`ParamSpec::scales_with_g`]) and the smallest swing the verdict
//! trusts ([`TrustSpec::min_swing`]), so that a user who declares their g
//! gets the length of their pendulum rather than of the trained one
//! (`Estimator::with_gravity`).
//!
//! Format 5 added [`TrustSpec`]: the checks of the trust verdict beyond
//! sigma (the training envelope as an occupancy map, the calibrated range
//! of the first parameter) and the calibration of the reported standard
//! deviations, all set by `koopman calibrate` on held-out rollouts.
//!
//! # The arena (format version 4)
//! In order, with the sizes of [`Layout::encoder_shapes`] and
//! [`Layout::decoder_shapes`] at the header's hidden width (one of
//! [`HIDDEN_WIDTHS`](crate::HIDDEN_WIDTHS)):
//! for each encoder layer then each decoder layer, its weight `W` then its
//! bias `b`; then `F` ([`AUG_DIM`] x [`AUG_DIM`], row-major), then `B`
//! ([`AUG_DIM`] x [`INPUT_DIM`], row-major); then the gain schedule of
//! [`FilterSpec::schedule_steps`] updates (see below). A dense layer
//! `out = W^T in + b` stores `W` input-major: `d_in` rows of `d_out`
//! weights (burn's `Linear::weight` layout, the transpose of PyTorch's).
//! Each input's weights are contiguous, so a layer is a sum of scaled rows
//! and an input that is zero (half of them after a ReLU) is skipped.
//! [`Layout`] gives the offsets ([`Blob::layout`] a blob's); [`F_AT`],
//! [`SCHEDULE_AT`], [`arena_len`] and [`layer_span`] are the widest
//! layout's.
//!
//! # The bilinear arena
//! A [`Family::Bilinear`] blob holds, after the encoder and decoder (at
//! [`Layout::f_at`]), [`BILINEAR_BLOCKS`] matrices of [`LATENT_DIM`] square,
//! row-major: `F_0`, `F_1`, `F_2`, `F_11`, so that
//! `y' = F(q) y`, `F(q) = F_0 + q_1 F_1 + q_2 F_2 + q_1^2 F_11` with `q`
//! the parameters' coordinates (static). Nothing follows them: no `B`
//! and no gain schedule (the extended filter's gains depend on the
//! state), so [`FilterSpec::schedule_steps`] is 0.
//!
//! # The gain schedule
//! The filter's covariance recursion does not depend on the measurements:
//! from the prior, `F`, `Q` and `R` alone, the gains `K_1, K_2, ...` of the
//! updates are the same for every trajectory. The exporter runs that
//! recursion once, in f64, for the first `T =`
//! [`FilterSpec::schedule_steps`] updates and stores, per update `n`
//! (`1..=T`), [`SCHEDULE_STEP_LEN`] values: `K_n^T` ([`LATENT_DIM`] rows of
//! [`AUG_DIM`]: row `k` says how innovation `k` moves `[y; p]`), then the
//! parameters' standard deviations after the update, `sqrt(diag P_pp)`.
//!
//! After the `T` steps comes the tail ([`TAIL_LEN`] values), which carries
//! the filter on after update `T` in Friedland's two-stage form (exact for
//! static parameters, `Q_p = 0`, which a blob with a schedule must have):
//! a bias-free filter over `y` alone, whose gain `K~ = I - R S~^-1` has
//! converged by update `T` (the exporter checks it) and is held, and a
//! filter over the parameters with the sensitivity `V` of `y` to them. In
//! order: `S~^-1` (the inverse of the bias-free innovation covariance,
//! [`LATENT_DIM`] square, symmetric), `P~` (the bias-free covariance after
//! an update, symmetric), `V_T` ([`PARAM_DIM`] columns of [`LATENT_DIM`])
//! and `P_b,T` (the parameters' covariance, [`PARAM_DIM`] squared,
//! symmetric). See [`crate::filter`] for the
//! update. With `T = 0` there is no schedule and no tail.

use serde::{Deserialize, Serialize};

pub use crate::rig::Rig;
use crate::{
    AUG_DIM, Error, HIDDEN_DIM, HIDDEN_WIDTHS, INPUT_DIM, LATENT_DIM, PARAM_DIM, STATE_DIM, State,
};

/// First four bytes of every blob.
pub const MAGIC: [u8; 4] = *b"KKF1";
/// Format version this build reads and writes.
pub const FORMAT_VERSION: u16 = 10;
/// Number of dense layers in the encoder and in the decoder.
pub const N_LAYERS: usize = 3;

/// The fixed-size header, read before anything else.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header {
    /// Always [`MAGIC`].
    pub magic: [u8; 4],
    /// Always [`FORMAT_VERSION`].
    pub version: u16,
    /// Measured state size (`theta`, `theta_dot`).
    pub state_dim: u16,
    /// Latent size of the encoder's output.
    pub latent_dim: u16,
    /// Number of physical parameters riding along in the filter state.
    pub param_dim: u16,
    /// Width of the MLPs' hidden layers.
    pub hidden_dim: u16,
    /// Number of control inputs (torque).
    pub input_dim: u16,
}

impl Header {
    /// The header this build expects.
    pub const CURRENT: Header = Header {
        magic: MAGIC,
        version: FORMAT_VERSION,
        state_dim: STATE_DIM as u16,
        latent_dim: LATENT_DIM as u16,
        param_dim: PARAM_DIM as u16,
        hidden_dim: HIDDEN_DIM as u16,
        input_dim: INPUT_DIM as u16,
    };

    /// This build's dimensions, with a hidden width it runs; else
    /// [`Error::BlobShapeMismatch`].
    pub fn check_dims(&self) -> Result<(), Error> {
        if *self == Header::with_hidden(self.hidden_dim) && Layout::of(self).is_some() {
            Ok(())
        } else {
            Err(Error::BlobShapeMismatch)
        }
    }

    /// The current header of a blob whose hidden layers are `hidden`
    /// wide (one of [`HIDDEN_WIDTHS`](crate::HIDDEN_WIDTHS)).
    pub const fn with_hidden(hidden: u16) -> Header {
        Header {
            hidden_dim: hidden,
            ..Header::CURRENT
        }
    }
}

/// A borrowed run of little-endian `f32` values.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
#[serde(transparent)]
pub struct F32s<'a>(#[serde(borrow)] pub &'a [u8]);

impl<'a> F32s<'a> {
    /// Number of `f32` values (the byte length must be a multiple of 4).
    pub fn len(&self) -> usize {
        self.0.len() / 4
    }

    /// True when there are no values.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// The `i`-th value, or `None` past the end.
    #[inline]
    pub fn get(&self, i: usize) -> Option<f32> {
        let b = self.0.get(i * 4..)?.first_chunk::<4>()?;
        Some(f32::from_le_bytes(*b))
    }

    /// All values in order.
    pub fn iter(&self) -> impl Iterator<Item = f32> + 'a {
        // `chunks_exact(4)` yields 4-byte chunks only; the fallback is
        // never taken but keeps the code free of panic paths.
        self.0.chunks_exact(4).map(|c| {
            c.first_chunk::<4>()
                .map_or(f32::NAN, |a| f32::from_le_bytes(*a))
        })
    }
    fn check(&self, n: usize) -> Result<(), Error> {
        if self.0.len() != n * 4 {
            return Err(Error::BlobShapeMismatch);
        }
        if self.iter().all(f32::is_finite) {
            Ok(())
        } else {
            Err(Error::BlobNonFinite)
        }
    }
}

/// The hidden layers' activation function.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
pub enum Activation {
    /// `max(x, 0)`.
    Relu,
    /// `tanh(x)`.
    Tanh,
}

/// Which MLP a layer belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Net {
    /// The encoder `phi`.
    Encoder,
    /// The decoder `phi^-1`.
    Decoder,
}

/// Length of one layer in the arena: weight then bias.
const fn layer_len((d_in, d_out): (usize, usize)) -> usize {
    d_in * d_out + d_out
}

const fn mlp_len(shapes: &[(usize, usize); N_LAYERS]) -> usize {
    let [l0, l1, l2] = *shapes;
    layer_len(l0) + layer_len(l1) + layer_len(l2)
}

/// Where everything lies in a weight arena whose MLPs have hidden layers
/// `hidden` wide (the header's `hidden_dim`, one of
/// [`HIDDEN_WIDTHS`](crate::HIDDEN_WIDTHS)). Offsets are in `f32`s.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layout {
    /// Width of the encoder's and the decoder's hidden layers.
    pub hidden: usize,
}

impl Layout {
    /// The widest, [`HIDDEN_DIM`]: the protocol's blob's.
    pub const WIDEST: Layout = Layout { hidden: HIDDEN_DIM };

    /// The layout of a blob with this header; `None` for a hidden width
    /// this build does not run.
    pub const fn of(header: &Header) -> Option<Layout> {
        let hidden = header.hidden_dim as usize;
        let [narrow, wide] = HIDDEN_WIDTHS;
        if hidden == narrow || hidden == wide {
            Some(Layout { hidden })
        } else {
            None
        }
    }

    /// `(d_in, d_out)` of the encoder's layers: STATE -> HIDDEN -> HIDDEN
    /// -> LATENT.
    pub const fn encoder_shapes(self) -> [(usize, usize); N_LAYERS] {
        let h = self.hidden;
        [(STATE_DIM, h), (h, h), (h, LATENT_DIM)]
    }

    /// `(d_in, d_out)` of the decoder's layers: LATENT -> HIDDEN -> HIDDEN
    /// -> STATE.
    pub const fn decoder_shapes(self) -> [(usize, usize); N_LAYERS] {
        let h = self.hidden;
        [(LATENT_DIM, h), (h, h), (h, STATE_DIM)]
    }

    /// Where layer `k` of `net` lies: `(weight offset, d_in, d_out)`; its
    /// bias follows the weight at `offset + d_in * d_out`. `None` for
    /// `k >= N_LAYERS`.
    pub const fn layer_span(self, net: Net, k: usize) -> Option<(usize, usize, usize)> {
        let (shapes, at) = match net {
            Net::Encoder => (self.encoder_shapes(), 0),
            Net::Decoder => (self.decoder_shapes(), mlp_len(&self.encoder_shapes())),
        };
        let [l0, l1, l2] = shapes;
        match k {
            0 => Some((at, l0.0, l0.1)),
            1 => Some((at + layer_len(l0), l1.0, l1.1)),
            2 => Some((at + layer_len(l0) + layer_len(l1), l2.0, l2.1)),
            _ => None,
        }
    }

    /// Offset of `F` (or of the bilinear matrices): after both MLPs.
    pub const fn f_at(self) -> usize {
        mlp_len(&self.encoder_shapes()) + mlp_len(&self.decoder_shapes())
    }

    /// Offset of `B`.
    pub const fn b_at(self) -> usize {
        self.f_at() + AUG_DIM * AUG_DIM
    }

    /// Offset of the gain schedule: the length of a linear arena without
    /// one.
    pub const fn schedule_at(self) -> usize {
        self.b_at() + AUG_DIM * INPUT_DIM
    }

    /// Length of a linear arena with a schedule of `steps` updates: the
    /// weights, `steps` scheduled updates and, when `steps > 0`, the tail.
    pub const fn arena_len(self, steps: u16) -> usize {
        let steps = steps as usize;
        let tail = if steps > 0 { TAIL_LEN } else { 0 };
        self.schedule_at() + steps * SCHEDULE_STEP_LEN + tail
    }

    /// Length of a bilinear arena.
    pub const fn bilinear_arena_len(self) -> usize {
        self.f_at() + BILINEAR_BLOCKS * BILINEAR_BLOCK_LEN
    }
}

/// `(d_in, d_out)` of the encoder's layers in the widest layout.
pub const ENCODER_SHAPES: [(usize, usize); N_LAYERS] = Layout::WIDEST.encoder_shapes();
/// `(d_in, d_out)` of the decoder's layers in the widest layout.
pub const DECODER_SHAPES: [(usize, usize); N_LAYERS] = Layout::WIDEST.decoder_shapes();
/// Offset of `F` in the widest layout's arena, in `f32`s.
pub const F_AT: usize = Layout::WIDEST.f_at();
/// Offset of `B` in the widest layout's arena, in `f32`s.
pub const B_AT: usize = Layout::WIDEST.b_at();
/// Offset of the gain schedule in the widest layout's arena, in `f32`s.
pub const SCHEDULE_AT: usize = Layout::WIDEST.schedule_at();
/// Values of one scheduled update: `K^T` then the parameters' standard
/// deviations.
pub const SCHEDULE_STEP_LEN: usize = LATENT_DIM * AUG_DIM + PARAM_DIM;

/// Values of the schedule's tail: `S~^-1`, `P~`, `V_T`, `P_b,T`.
pub const TAIL_LEN: usize =
    2 * LATENT_DIM * LATENT_DIM + PARAM_DIM * LATENT_DIM + PARAM_DIM * PARAM_DIM;

/// Length of the widest layout's linear arena with a schedule of `steps`
/// updates, in `f32`s ([`Layout::arena_len`]).
pub const fn arena_len(steps: u16) -> usize {
    Layout::WIDEST.arena_len(steps)
}

/// Matrices of a bilinear arena: `F_0`, `F_1`, `F_2`, `F_11`.
pub const BILINEAR_BLOCKS: usize = 4;
/// Values of one bilinear matrix.
pub const BILINEAR_BLOCK_LEN: usize = LATENT_DIM * LATENT_DIM;
/// Length of the widest layout's bilinear arena, in `f32`s.
pub const BILINEAR_ARENA_LEN: usize = Layout::WIDEST.bilinear_arena_len();

/// Which Koopman model a blob holds: how `[y; p]` advances.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
pub enum Family {
    /// The paper's: one augmented matrix `F` ([`AUG_DIM`] square, its
    /// parameter rows the identity), `y' = A y + C p`. Its frequencies are
    /// `A`'s eigenvalues, the same for every `p`: a family whose frequency
    /// moves with the parameter is a blend of fixed modes.
    Linear,
    /// Parameter-varying: `y' = F(q) y`, `F(q) = F_0 + q_1 F_1 + q_2 F_2 +
    /// q_1^2 F_11` (see "The bilinear arena"); its frequencies move with
    /// `q`. The filter is an extended Kalman filter over `[y; q]`.
    Bilinear,
}

/// Where layer `k` of `net` lies in the widest layout's arena
/// ([`Layout::layer_span`]).
pub const fn layer_span(net: Net, k: usize) -> Option<(usize, usize, usize)> {
    Layout::WIDEST.layer_span(net, k)
}

/// Bytes kept at an address aligned to 4, so that a blob compiled into
/// firmware can be read in place:
/// `static BLOB: &Aligned<[u8]> = &Aligned(*include_bytes!("pendulum.kkf"));`
/// then `Model::from_bytes(&BLOB.0)`.
#[repr(C, align(4))]
#[derive(Debug)]
pub struct Aligned<T: ?Sized>(pub T);

/// How the filter's coordinate `q` of a parameter reads as the parameter's
/// value `p`.
///
/// The model is trained with `q = p` at both ends of the training range
/// `[lo, hi]`; between and beyond them, the value of `q` that the latent
/// dynamics line up with is whatever the physics makes linear. A pendulum's
/// length enters its dynamics as `3 g / (2 L)`, so the learned linear
/// model, which interpolates the dynamics, is affine in `1 / L`:
/// [`Reading::Reciprocal`].
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reading {
    /// `p = q`.
    Direct,
    /// `q = lo + hi - lo hi / p`, affine in `1 / p` and equal to `p` at
    /// `lo` and `hi`; so `p = lo hi / (lo + hi - q)`. Needs `0 < lo`.
    /// `q` at or above `lo + hi` reads as an infinite or negative value,
    /// reported as it is.
    Reciprocal,
    /// `q = p - (lo + hi) / 2`: the value less the middle of its training
    /// range. A coefficient trained over a narrow range away from zero
    /// (an effect diagnosed on a recording) would otherwise enter the
    /// least-squares fit of `F` as a nearly constant column, nearly
    /// collinear with the length's.
    Centred,
    /// `q` affine in `1 / p`, `-1` at `lo` and `+1` at `hi`:
    /// `q = (1/lo + 1/hi - 2/p) / (1/lo - 1/hi)`, so
    /// `p = 2 / (1/lo + 1/hi - q (1/lo - 1/hi))`. A pendulum's `w^2`
    /// scaled to `[-1, 1]` over the training range (the bilinear family's
    /// length). Needs `0 < lo < hi`.
    ReciprocalUnit,
    /// `q` affine in `p`, `-1` at `lo` and `+1` at `hi`:
    /// `q = (2 p - lo - hi) / (hi - lo)`. Needs `lo < hi`.
    Unit,
}

/// One physical parameter carried in the filter state.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq)]
pub struct ParamSpec<'a> {
    /// Its name (`"length"`, `"viscous"`, ...), for reports.
    pub name: &'a str,
    /// False for a padding parameter of a one-parameter model: it is kept
    /// constant with zero process noise and zero prior variance.
    pub declared: bool,
    /// The range it was trained on, `[lo, hi]`.
    pub train_range: [f32; 2],
    /// How the filter's coordinate reads as the parameter.
    pub reading: Reading,
    /// True when the dynamics see the parameter only through `g / p` (a
    /// pendulum's length: `w^2 = 3 g / (2 L)` for a rod): the motion of
    /// `p` at gravity `g'` is the trained motion of `p g / g'`, so at a
    /// declared `g'` the estimate reads as `g' / g` times the trained
    /// value ([`Body::g`] the training gravity).
    pub scales_with_g: bool,
}

impl ParamSpec<'_> {
    /// The parameter's value at the filter's coordinate `q`.
    #[inline]
    pub fn read(&self, q: f32) -> f32 {
        match self.reading {
            Reading::Direct => q,
            Reading::Reciprocal => {
                let [lo, hi] = self.train_range;
                lo * hi / (lo + hi - q)
            }
            Reading::Centred => q + self.middle(),
            Reading::ReciprocalUnit => {
                let (sum, diff) = self.reciprocals();
                2.0 / (sum - q * diff)
            }
            Reading::Unit => {
                let [lo, hi] = self.train_range;
                0.5 * (lo + hi + q * (hi - lo))
            }
        }
    }

    /// `(1/lo + 1/hi, 1/lo - 1/hi)`.
    #[inline]
    fn reciprocals(&self) -> (f32, f32) {
        let [lo, hi] = self.train_range;
        (1.0 / lo + 1.0 / hi, 1.0 / lo - 1.0 / hi)
    }

    /// The middle of the training range, `(lo + hi) / 2`.
    #[inline]
    fn middle(&self) -> f32 {
        0.5 * (self.train_range[0] + self.train_range[1])
    }

    /// `dp/dq` at the filter's coordinate `q`: what turns the coordinate's
    /// standard deviation into the parameter's (to first order).
    #[inline]
    pub fn slope(&self, q: f32) -> f32 {
        match self.reading {
            Reading::Direct | Reading::Centred => 1.0,
            Reading::Reciprocal => {
                let [lo, hi] = self.train_range;
                let d = lo + hi - q;
                lo * hi / (d * d)
            }
            Reading::ReciprocalUnit => {
                let (sum, diff) = self.reciprocals();
                let d = sum - q * diff;
                2.0 * diff / (d * d)
            }
            Reading::Unit => {
                let [lo, hi] = self.train_range;
                0.5 * (hi - lo)
            }
        }
    }

    /// Whether `p` is a value a physical system can have: finite, and
    /// positive when the parameter was trained on positive values only
    /// (a length; a range that reaches 0 or below, like a friction
    /// coefficient's or a torque's, allows any finite value).
    #[inline]
    pub fn physical(&self, p: f32) -> bool {
        p.is_finite() && (self.train_range[0] <= 0.0 || p > 0.0)
    }

    /// The filter's coordinate of the value `p` (the inverse of
    /// [`ParamSpec::read`]); not finite for `p = 0` with a reciprocal
    /// reading.
    #[inline]
    pub fn coordinate(&self, p: f32) -> f32 {
        match self.reading {
            Reading::Direct => p,
            Reading::Reciprocal => {
                let [lo, hi] = self.train_range;
                lo + hi - lo * hi / p
            }
            Reading::Centred => p - self.middle(),
            Reading::ReciprocalUnit => {
                let (sum, diff) = self.reciprocals();
                (sum - 2.0 / p) / diff
            }
            Reading::Unit => {
                let [lo, hi] = self.train_range;
                (2.0 * p - lo - hi) / (hi - lo)
            }
        }
    }

    fn check(&self) -> Result<(), Error> {
        let [lo, hi] = self.train_range;
        if !(lo.is_finite() && hi.is_finite()) {
            return Err(Error::BlobNonFinite);
        }
        match self.reading {
            Reading::Reciprocal if !(lo > 0.0 && lo <= hi) => Err(Error::BlobBadReading),
            Reading::ReciprocalUnit if !(lo > 0.0 && lo < hi) => Err(Error::BlobBadReading),
            Reading::Unit if lo >= hi => Err(Error::BlobBadReading),
            _ => Ok(()),
        }
    }
}

/// The Kalman filter's settings. `Q` and `R` are diagonal.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq)]
pub struct FilterSpec {
    /// Diagonal of the process noise `Q` over `[y; p]`.
    pub q: [f32; AUG_DIM],
    /// Diagonal of the measurement noise `R` over `y`.
    pub r: [f32; LATENT_DIM],
    /// Prior mean of the parameters (the protocol's hypothesis is `L = 0`).
    pub prior_mean: [f32; PARAM_DIM],
    /// Prior variance diagonal over `[y; p]` (latent part: around `phi(x_0)`).
    pub prior_var: [f32; AUG_DIM],
    /// Updates before the corrections count towards sigma (protocol: 32).
    pub burn_in: u16,
    /// Sigma of the first parameter's corrections above which an estimate
    /// is not trusted (calibrated on training data at export).
    pub sigma_threshold: f32,
    /// Updates whose gains are precomputed in the arena (see the module's
    /// "gain schedule"); 0 for none.
    pub schedule_steps: u16,
}

impl FilterSpec {
    fn check(&self) -> Result<(), Error> {
        let q_ok = self.q.iter().all(|v| v.is_finite() && *v >= 0.0);
        let r_ok = self.r.iter().all(|v| v.is_finite() && *v > 0.0);
        let p_ok = self.prior_var.iter().all(|v| v.is_finite() && *v >= 0.0);
        let m_ok = self.prior_mean.iter().all(|v| v.is_finite());
        let t_ok = self.sigma_threshold.is_finite() && self.sigma_threshold > 0.0;
        if q_ok && r_ok && p_ok && m_ok && t_ok {
            Ok(())
        } else {
            Err(Error::BlobNonFinite)
        }
    }
}

/// The training envelope: which cells of the normalised measured state
/// space `(theta, theta_dot)` held-out rollouts from the blob's declared
/// operating range visit, per bin of the first parameter's coordinate.
///
/// A state `x_n` (normalised) falls in cell `(i, j)` with
/// `i = floor((x_n[0] + extent) / (2 extent) * theta_cells)` and `j` the
/// same for the rate; outside `[-extent, extent)` it falls in no cell. The
/// coordinate `q` falls in bin `floor((q - q_lo) / q_width)`. Bit
/// `(b * theta_cells + i) * rate_cells + j` of [`Envelope::bits`]
/// (least significant bit first in each byte) is set when bin `b` visits
/// cell `(i, j)`.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq)]
pub struct Envelope<'a> {
    /// Half-width of the mapped square, in normalised units.
    pub extent: f32,
    /// Cells along the angle.
    pub theta_cells: u16,
    /// Cells along the rate.
    pub rate_cells: u16,
    /// Lower edge of the first coordinate bin.
    pub q_lo: f32,
    /// Width of a coordinate bin.
    pub q_width: f32,
    /// Number of coordinate bins.
    pub q_bins: u16,
    /// The occupancy bits (see the type's docs).
    #[serde(borrow)]
    pub bits: &'a [u8],
}

impl Envelope<'_> {
    /// Number of bits the map holds.
    pub const fn cells(&self) -> usize {
        self.q_bins as usize * self.theta_cells as usize * self.rate_cells as usize
    }

    /// The cell index `i * rate_cells + j` of the normalised state, or
    /// `None` outside the mapped square.
    #[inline]
    pub fn cell(&self, x_n: &State) -> Option<usize> {
        let [a, r] = *x_n;
        let index = |v: f32, n: u16| {
            let k = libm::floorf((v + self.extent) / (2.0 * self.extent) * f32::from(n));
            (k >= 0.0 && k < f32::from(n)).then_some(k as usize)
        };
        Some(
            index(a, self.theta_cells)? * usize::from(self.rate_cells) + index(r, self.rate_cells)?,
        )
    }

    /// The coordinate bin of `q`, or `None` outside the bins.
    #[inline]
    pub fn bin(&self, q: f32) -> Option<usize> {
        let k = libm::floorf((q - self.q_lo) / self.q_width);
        (k >= 0.0 && k < f32::from(self.q_bins)).then_some(k as usize)
    }

    /// Whether bin `bin` visits cell `cell`.
    #[inline]
    pub fn visited(&self, bin: usize, cell: usize) -> bool {
        let per_bin = usize::from(self.theta_cells) * usize::from(self.rate_cells);
        let k = bin * per_bin + cell;
        self.bits
            .get(k / 8)
            .is_some_and(|byte| byte >> (k % 8) & 1 == 1)
    }

    /// Whether the normalised state lies in the envelope: at the coordinate
    /// `q` when one is given, or at any coordinate (`None`).
    pub fn contains(&self, x_n: &State, q: Option<f32>) -> bool {
        let Some(cell) = self.cell(x_n) else {
            return false;
        };
        match q {
            Some(q) => self.bin(q).is_some_and(|b| self.visited(b, cell)),
            None => (0..usize::from(self.q_bins)).any(|b| self.visited(b, cell)),
        }
    }

    fn check(&self) -> Result<(), Error> {
        let sizes = self.theta_cells > 0 && self.rate_cells > 0 && self.q_bins > 0;
        if !(sizes && self.bits.len() == self.cells().div_ceil(8)) {
            return Err(Error::BlobShapeMismatch);
        }
        let ok = self.extent.is_finite()
            && self.extent > 0.0
            && self.q_lo.is_finite()
            && self.q_width.is_finite()
            && self.q_width > 0.0;
        if ok {
            Ok(())
        } else {
            Err(Error::BlobNonFinite)
        }
    }
}

/// The trust verdict's calibration (format 5): set at export by
/// `koopman calibrate` on held-out rollouts from the blob's declared
/// operating range, so that its in-distribution false-flag rate is a
/// stated number (recorded beside the blob, in its JSON).
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq)]
pub struct TrustSpec<'a> {
    /// The training envelope.
    #[serde(borrow)]
    pub envelope: Envelope<'a>,
    /// Most measurements off the envelope among any
    /// [`WINDOW`](crate::WINDOW) consecutive ones that still pass.
    pub envelope_max_off: u16,
    /// The first parameter's coordinate range that passes, `[lo, hi]`.
    pub range: [f32; 2],
    /// Reported coordinate standard deviation: `sqrt((a s)^2 + b^2)` with
    /// `s` the filter's, `a` this scale...
    pub std_scale: [f32; PARAM_DIM],
    /// ... and `b` this floor (the model's own error, in the coordinate).
    pub std_floor: [f32; PARAM_DIM],
    /// The smallest widest swing since the start (half the range of
    /// `theta` over [`WINDOW`](crate::WINDOW) to 2 [`WINDOW`](crate::WINDOW)
    /// measurements, rad) that passes: below it held-out rollouts read
    /// the length off by the calibration's accuracy or more (20% for the
    /// protocol blob, 5% for the rig blob; 0: every swing passes). From
    /// format 10 on, a recent swing below it also holds the estimate
    /// (`StepOutput::held`), and the unevenness of a smaller swing is not
    /// remembered.
    pub min_swing: f32,
    /// The largest unevenness of the swing that passes (how far the middle
    /// of its range lies from zero, as a share of it: see
    /// [`crate::trust`]; format 7): from format 10 on, the largest
    /// remembered over every swing at least [`TrustSpec::min_swing`].
    pub max_unevenness: f32,
    /// The largest consistency statistic that passes: the mean normalised
    /// innovation squared since the burn-in, scaled by
    /// [`TrustSpec::nis_law`] ([`crate::trust::consistency_statistic`];
    /// format 9).
    pub max_nis: f32,
    /// The exponents `[a, b]` of the consistency statistic's scaling: the
    /// mean normalised innovation times `L^a / s^b`, with `L` the first
    /// parameter read at the blob's gravity and `s` the widest swing
    /// (rad). Fitted at calibration to how the mean grows with the length
    /// and the swing in held-out rollouts (a short pendulum and a wide
    /// swing leave larger innovations for the same noise); `[0, 0]` reads
    /// the plain mean (format 10).
    pub nis_law: [f32; 2],
    /// The largest departure from 1 of the angle's change over the change
    /// the measured rates predict that passes ([`crate::trust`]; format
    /// 9).
    pub max_rate_mismatch: f32,
}

impl TrustSpec<'_> {
    fn check(&self) -> Result<(), Error> {
        self.envelope.check()?;
        let [lo, hi] = self.range;
        let finite = lo.is_finite()
            && hi.is_finite()
            && lo <= hi
            && self.min_swing.is_finite()
            && self.min_swing >= 0.0
            && self.max_unevenness >= 0.0
            && self.max_nis >= 0.0
            && self.nis_law.iter().all(|v| v.is_finite())
            && self.max_rate_mismatch >= 0.0;
        let stds = self.std_scale.iter().all(|v| v.is_finite() && *v > 0.0)
            && self.std_floor.iter().all(|v| v.is_finite() && *v >= 0.0);
        if finite && stds {
            Ok(())
        } else {
            Err(Error::BlobNonFinite)
        }
    }
}

/// Everything after the header.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq)]
pub struct Body<'a> {
    /// Sampling interval of the model, seconds.
    pub dt: f32,
    /// Gravity the model was trained at, m/s^2 (see
    /// [`ParamSpec::scales_with_g`]).
    pub g: f32,
    /// The rig whose length the first parameter is (format 8).
    pub rig: Rig,
    /// How `[y; p]` advances (format 8).
    pub family: Family,
    /// Hidden activation of both MLPs.
    pub activation: Activation,
    /// Normalisation offset `mu` (`x_n = (x - mu) / s`).
    pub norm_mu: [f32; STATE_DIM],
    /// Normalisation scale `s`.
    pub norm_s: [f32; STATE_DIM],
    /// The physical parameters, in filter-state order.
    #[serde(borrow)]
    pub params: [ParamSpec<'a>; PARAM_DIM],
    /// Kalman filter settings.
    pub filter: FilterSpec,
    /// The trust verdict's calibration.
    #[serde(borrow)]
    pub trust: TrustSpec<'a>,
    /// 0-3 zero bytes putting `weights` at a multiple of 4 bytes from the
    /// blob's start (see [`Blob::to_slice`], which chooses them).
    #[serde(borrow)]
    pub pad: &'a [u8],
    /// The weight arena, [`Layout::arena_len`] (or
    /// [`Layout::bilinear_arena_len`]) values in the module's order.
    #[serde(borrow)]
    pub weights: F32s<'a>,
}

impl<'a> Body<'a> {
    /// The `f32`s at `[at, at + len)` of the arena, as little-endian bytes.
    pub fn span(&self, at: usize, len: usize) -> F32s<'a> {
        F32s(self.weights.0.get(at * 4..(at + len) * 4).unwrap_or(&[]))
    }
}

/// A whole blob.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq)]
pub struct Blob<'a> {
    /// Magic, version, dimensions.
    pub header: Header,
    /// The model.
    #[serde(borrow)]
    pub body: Body<'a>,
}

/// The blob's CRC-32 algorithm.
static CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISCSI);

impl<'a> Blob<'a> {
    /// The layout of the arena (its hidden width from the header; the
    /// widest for a width this build does not run, which
    /// [`Blob::from_bytes`] refuses).
    pub fn layout(&self) -> Layout {
        Layout::of(&self.header).unwrap_or(Layout::WIDEST)
    }

    /// `F`, row-major (empty for a bilinear blob).
    pub fn f(&self) -> F32s<'a> {
        match self.body.family {
            Family::Linear => self.body.span(self.layout().f_at(), AUG_DIM * AUG_DIM),
            Family::Bilinear => F32s(&[]),
        }
    }

    /// Bilinear matrix `k` (`F_0`, `F_1`, `F_2`, `F_11` for `k = 0..4`),
    /// row-major; empty for a linear blob or `k` out of range.
    pub fn bilinear(&self, k: usize) -> F32s<'a> {
        match self.body.family {
            Family::Bilinear if k < BILINEAR_BLOCKS => self.body.span(
                self.layout().f_at() + k * BILINEAR_BLOCK_LEN,
                BILINEAR_BLOCK_LEN,
            ),
            _ => F32s(&[]),
        }
    }

    /// `B`, row-major (empty for a bilinear blob).
    pub fn b(&self) -> F32s<'a> {
        match self.body.family {
            Family::Linear => self.body.span(self.layout().b_at(), AUG_DIM * INPUT_DIM),
            Family::Bilinear => F32s(&[]),
        }
    }

    /// Scheduled update `n` (`1..=schedule_steps`): `K_n^T` ([`LATENT_DIM`]
    /// rows of [`AUG_DIM`]) and the parameters' standard deviations after
    /// it. Empty runs for an `n` outside the schedule.
    pub fn schedule_step(&self, n: usize) -> (F32s<'a>, F32s<'a>) {
        let steps = usize::from(self.body.filter.schedule_steps);
        if n == 0 || n > steps {
            return (F32s(&[]), F32s(&[]));
        }
        let at = self.layout().schedule_at() + (n - 1) * SCHEDULE_STEP_LEN;
        let gain = LATENT_DIM * AUG_DIM;
        (
            self.body.span(at, gain),
            self.body.span(at + gain, PARAM_DIM),
        )
    }

    /// The schedule's tail (see the module docs), empty without a schedule.
    pub fn schedule_tail(&self) -> F32s<'a> {
        let steps = usize::from(self.body.filter.schedule_steps);
        if steps == 0 {
            return F32s(&[]);
        }
        self.body.span(
            self.layout().schedule_at() + steps * SCHEDULE_STEP_LEN,
            TAIL_LEN,
        )
    }

    /// Layer `k` of `net`: its input-major weight and its bias.
    pub fn layer(&self, net: Net, k: usize) -> (F32s<'a>, F32s<'a>) {
        match self.layout().layer_span(net, k) {
            Some((at, i, o)) => (self.body.span(at, i * o), self.body.span(at + i * o, o)),
            None => (F32s(&[]), F32s(&[])),
        }
    }

    /// Reads and validates a blob, borrowing its weights from `bytes`.
    ///
    /// Checks, in order: header (magic, version, dimensions), body decoding
    /// and CRC, trailing bytes, every array's length, finiteness.
    pub fn from_bytes(bytes: &'a [u8]) -> Result<Self, Error> {
        let (header, _) =
            postcard::take_from_bytes::<Header>(bytes).map_err(|_| Error::BlobTruncated)?;
        if header.magic != MAGIC {
            return Err(Error::BlobBadMagic);
        }
        if header.version != FORMAT_VERSION {
            return Err(Error::BlobBadVersion);
        }
        header.check_dims()?;
        let (blob, rest) = postcard::take_from_bytes_crc32::<Blob<'a>>(bytes, CRC.digest())
            .map_err(|e| match e {
                postcard::Error::DeserializeBadCrc => Error::BlobBadCrc,
                postcard::Error::DeserializeUnexpectedEnd => Error::BlobTruncated,
                _ => Error::BlobMalformed,
            })?;
        if !rest.is_empty() {
            return Err(Error::BlobTrailingBytes);
        }
        blob.validate()?;
        Ok(blob)
    }

    /// Writes the blob with its CRC into `buf`, returning the used part.
    /// `body.pad` is chosen here (its value in `self` is ignored) so that
    /// the arena starts at a multiple of 4 bytes from `buf[0]`.
    pub fn to_slice<'b>(&self, buf: &'b mut [u8]) -> Result<&'b mut [u8], Error> {
        const ZEROS: [u8; 3] = [0; 3];
        let mut blob = *self;
        blob.body.pad = &[];
        let n = postcard::to_slice_crc32(&blob, buf, CRC.digest())
            .map_err(|_| Error::InputBadLength)?
            .len();
        // The arena is followed by the 4 CRC bytes only; the pad's length
        // prefix is one byte whatever its length (0-3).
        let start = n
            .checked_sub(4 + blob.body.weights.0.len())
            .ok_or(Error::InputBadLength)?;
        blob.body.pad = ZEROS.get(..(4 - start % 4) % 4).unwrap_or(&[]);
        postcard::to_slice_crc32(&blob, buf, CRC.digest()).map_err(|_| Error::InputBadLength)
    }

    /// Checks the dimensions, every array's length and every value's
    /// finiteness.
    pub fn validate(&self) -> Result<(), Error> {
        // A hand-built blob reaches here without `from_bytes`'s check.
        self.header.check_dims()?;
        let b = &self.body;
        let finite = |a: &[f32]| a.iter().all(|v| v.is_finite());
        let positive = |v: f32| v.is_finite() && v > 0.0;
        if !(positive(b.dt) && positive(b.g) && finite(&b.norm_mu)) {
            return Err(Error::BlobNonFinite);
        }
        if !b.norm_s.iter().all(|v| v.is_finite() && *v > 0.0) {
            return Err(Error::BlobNonFinite);
        }
        if b.pad.len() > 3 || b.pad.iter().any(|v| *v != 0) {
            return Err(Error::BlobMisaligned);
        }
        let len = match b.family {
            Family::Linear => self.layout().arena_len(b.filter.schedule_steps),
            // The extended filter's gains depend on the state: no schedule.
            Family::Bilinear if b.filter.schedule_steps == 0 => self.layout().bilinear_arena_len(),
            Family::Bilinear => return Err(Error::BlobShapeMismatch),
        };
        b.weights.check(len)?;
        // The filter treats the parameters as static: their rows of F must
        // be the identity.
        let param_rows_identity =
            self.f()
                .iter()
                .enumerate()
                .skip(LATENT_DIM * AUG_DIM)
                .all(|(k, v)| {
                    let (i, j) = (k / AUG_DIM, k % AUG_DIM);
                    v == if i == j { 1.0 } else { 0.0 }
                });
        if !param_rows_identity {
            return Err(Error::BlobParamsNotStatic);
        }
        for p in &b.params {
            p.check()?;
        }
        // A schedule needs static parameters; its standard deviations are
        // not negative, and the tail's covariances are symmetric with
        // diagonals that are not negative (S~^-1 symmetric too).
        if b.filter.schedule_steps > 0 && b.filter.q.iter().skip(LATENT_DIM).any(|v| *v != 0.0) {
            return Err(Error::BlobParamsNotStatic);
        }
        let stds_ok = (1..=usize::from(b.filter.schedule_steps))
            .all(|n| self.schedule_step(n).1.iter().all(|v| v >= 0.0));
        let tail = self.schedule_tail();
        let sym = |at: usize, n: usize, diag_sign: bool| {
            let v = |i: usize, j: usize| tail.get(at + i * n + j);
            (0..n).all(|i| {
                (!diag_sign || v(i, i).is_none_or(|d| d >= 0.0))
                    && (0..i).all(|j| v(i, j) == v(j, i))
            })
        };
        let l2 = LATENT_DIM * LATENT_DIM;
        let tail_ok = tail.is_empty()
            || (sym(0, LATENT_DIM, false)
                && sym(l2, LATENT_DIM, true)
                && sym(2 * l2 + PARAM_DIM * LATENT_DIM, PARAM_DIM, true));
        if !(stds_ok && tail_ok) {
            return Err(Error::BlobNonFinite);
        }
        b.filter.check()?;
        b.trust.check()
    }
}
