//! The blob's data types: the header, the body and its sections.

use serde::{Deserialize, Serialize};

use super::{Envelope, Layout, ParamSpec};
use crate::{AUG_DIM, Error, HIDDEN_DIM, INPUT_DIM, LATENT_DIM, PARAM_DIM, Rig, STATE_DIM};

/// First four bytes of every blob.
///
/// Unit: bytes (ASCII `KKF1`). Fixed by the blob format
/// (docs/blob-format.md).
pub const MAGIC: [u8; 4] = *b"KKF1";
/// Format version this build reads and writes.
///
/// Unit: a count (a version number). Set by hand: raised at each change of
/// the format (13: the trust section ends with [`TrustSpec::std_swing`]).
pub const FORMAT_VERSION: u16 = 13;
/// The oldest format this build reads: 11. Formats 11 and 12 have no
/// [`TrustSpec::std_swing`] (read as 0); a bilinear arena of format 11 has
/// no `B(q)` (read as `B = 0`: a model of the free pendulum), one of
/// format 12 has it, and from 13 on its length says which.
///
/// Unit: a count (a version number). Set by hand with [`FORMAT_VERSION`].
pub const OLDEST_READ_VERSION: u16 = 11;
/// The first format whose trust section carries [`TrustSpec::std_swing`].
///
/// Unit: a count (a version number). Set by hand: the format that added
/// it.
pub const SWING_VERSION: u16 = 13;

/// The fixed-size header, read before anything else.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header {
    /// Always [`MAGIC`].
    pub magic: [u8; 4],
    /// [`FORMAT_VERSION`] as written; [`OLDEST_READ_VERSION`] to it as read.
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
    ///
    /// No unit (a header). Derived from [`MAGIC`], [`FORMAT_VERSION`] and the
    /// crate's sizes.
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
        let readable = (OLDEST_READ_VERSION..=FORMAT_VERSION).contains(&self.version);
        let dims = Header {
            version: FORMAT_VERSION,
            ..*self
        };
        if readable && dims == Header::with_hidden(self.hidden_dim) && Layout::of(self).is_some() {
            Ok(())
        } else {
            Err(Error::BlobShapeMismatch)
        }
    }

    /// The current header of a blob whose hidden layers are `hidden`
    /// wide (64 or 128).
    pub const fn with_hidden(hidden: u16) -> Header {
        Header {
            hidden_dim: hidden,
            ..Header::CURRENT
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
    /// Refuses a value no blob may hold.
    pub(crate) fn check(&self) -> Result<(), Error> {
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

/// The trust verdict's calibration: set by
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
    /// The smallest trusted swing, rad: below it held-out rollouts read
    /// the length off by the calibration's accuracy or more (0: every
    /// swing passes). The widest swing is held to it
    /// ([`Reason::SmallSwing`](crate::Reason::SmallSwing)), and a recent
    /// swing below it holds the estimate
    /// ([`StepOutput::held`](crate::StepOutput::held)).
    pub min_swing: f32,
    /// The largest unevenness that passes, remembered over every swing at
    /// least [`TrustSpec::min_swing`]
    /// ([`Reason::UnevenSwing`](crate::Reason::UnevenSwing)).
    pub max_unevenness: f32,
    /// The largest consistency statistic that passes: the mean normalised
    /// innovation squared since the burn-in, scaled by
    /// [`TrustSpec::nis_law`] ([`Reason::Inconsistent`](crate::Reason::Inconsistent)).
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
    /// the measured rates predict that passes
    /// ([`Reason::RateMismatch`](crate::Reason::RateMismatch)).
    pub max_rate_mismatch: f32,
    /// The largest ratio of one measurement's normalised innovation
    /// squared to the mean of those before it that the filter takes:
    /// above it the measurement is refused as an outlier
    /// ([`FilterReport::outlier`](crate::FilterReport::outlier); 0: none is).
    pub max_step_nis: f32,
    /// The fewest samples a period of the source the calibration covers
    /// (0: any source passes;
    /// [`Reason::CoarseSource`](crate::Reason::CoarseSource)).
    pub min_samples_per_period: f32,
    /// The length's relative standard deviation per `c(a) - 1` of the
    /// widest swing `a` (`c(a) = 1 / AGM(1, cos(a / 2))`, the period's
    /// amplitude factor), added to the reported one: the model's own error
    /// grows with the swing, and held-out rollouts at wide swings set how
    /// much (format 13; 0 before: none added).
    pub std_swing: f32,
}

impl TrustSpec<'_> {
    /// Refuses a value no blob may hold.
    pub(crate) fn check(&self) -> Result<(), Error> {
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
            && self.max_rate_mismatch >= 0.0
            && self.max_step_nis >= 0.0
            && self.min_samples_per_period >= 0.0
            && self.std_swing.is_finite()
            && self.std_swing >= 0.0;
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
    /// blob's start (see [`Blob::to_slice`](super::Blob::to_slice), which chooses them).
    #[serde(borrow)]
    pub pad: &'a [u8],
    /// The weight arena, its length set by the header's hidden width and
    /// the family (`docs/blob-format.md`).
    #[serde(borrow)]
    pub weights: F32s<'a>,
}

impl<'a> Body<'a> {
    /// Whether the filter reads parameter `k`: declared, and its
    /// calibrated error alone (`2 b`, twice [`TrustSpec::std_floor`], the
    /// model's own error) narrower than the range it was trained on, in
    /// the filter's coordinate. Where `2 b` spans that range the estimate
    /// says nothing of where in it the rig lies, and its standard
    /// deviation is the range, not a reading (the rig blob's viscous
    /// coefficient: `2 b` = 3.65 of a range of 2; its damping is read as
    /// the quality factor instead, [`Readers::q_factor`](crate::Readers::q_factor)).
    pub fn reads(&self, k: usize) -> bool {
        match (self.params.get(k), self.trust.std_floor.get(k)) {
            (Some(spec), Some(b)) => spec.declared && 2.0 * b < spec.coordinate_span(),
            _ => false,
        }
    }

    internal! {
        /// The `f32`s at `[at, at + len)` of the arena, as little-endian bytes.
        pub fn span(&self, at: usize, len: usize) -> F32s<'a> {
            F32s(self.weights.0.get(at * 4..(at + len) * 4).unwrap_or(&[]))
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

    /// Exactly `n` values, all finite.
    pub(crate) fn check(&self, n: usize) -> Result<(), Error> {
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
