//! The weights blob: one type definition for the trainer (which writes it)
//! and the estimator (which reads it where it lies, e.g. in flash).
//!
//! # Layout
//!
//! `[header][body][crc32]`, all postcard:
//! - [`Header`]: magic `b"KKF1"`, format version, and the dimensions the
//!   blob was made for. It is read first, on its own, so that a file of the
//!   wrong kind gets [`Error::BlobBadMagic`] rather than a decoding error.
//! - [`Body`]: normalisation, the MLPs, the augmented Koopman matrix `F`,
//!   the filter's `Q`, `R` and prior, and the trust calibration. Every
//!   weight array is a borrowed run of little-endian `f32` bytes
//!   ([`F32s`]), so reading a blob copies nothing proportional to its size.
//! - a CRC-32 (CRC_32_ISCSI) over header and body, as postcard's
//!   `use-crc` flavour writes it.
//!
//! Trailing bytes after the CRC are refused ([`Error::BlobTrailingBytes`]).
//!
//! # Matrix layouts
//! - A dense layer `out = act(W in + b)` stores `W` output-major:
//!   `d_out` rows of `d_in` weights (the PyTorch layout, the transpose of
//!   burn's `Linear::weight`, which is `[d_in, d_out]`). Each output's
//!   weights are contiguous, which is what a dot-product loop wants.
//! - `F` is [`AUG_DIM`] x [`AUG_DIM`], row-major; `B` is [`AUG_DIM`] x
//!   [`INPUT_DIM`], row-major.

use serde::{Deserialize, Serialize};

use crate::{AUG_DIM, Error, HIDDEN_DIM, INPUT_DIM, LATENT_DIM, PARAM_DIM, STATE_DIM};

/// First four bytes of every blob.
pub const MAGIC: [u8; 4] = *b"KKF1";
/// Format version this build reads and writes.
pub const FORMAT_VERSION: u16 = 1;
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

/// One dense layer, `out = W in + b` (activation applied by the caller on
/// every layer but the last).
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layer<'a> {
    /// Input width.
    pub d_in: u16,
    /// Output width.
    pub d_out: u16,
    /// `d_out` rows of `d_in` weights (output-major).
    #[serde(borrow)]
    pub weight: F32s<'a>,
    /// `d_out` biases.
    #[serde(borrow)]
    pub bias: F32s<'a>,
}

impl Layer<'_> {
    fn check(&self, d_in: usize, d_out: usize) -> Result<(), Error> {
        if usize::from(self.d_in) != d_in || usize::from(self.d_out) != d_out {
            return Err(Error::BlobShapeMismatch);
        }
        self.weight.check(d_in * d_out)?;
        self.bias.check(d_out)
    }
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

/// Everything after the header.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq)]
pub struct Body<'a> {
    /// Sampling interval of the model, seconds.
    pub dt: f32,
    /// Hidden activation of both MLPs.
    pub activation: Activation,
    /// Normalisation offset `mu` (`x_n = (x - mu) / s`).
    pub norm_mu: [f32; STATE_DIM],
    /// Normalisation scale `s`.
    pub norm_s: [f32; STATE_DIM],
    /// The physical parameters, in filter-state order.
    #[serde(borrow)]
    pub params: [ParamSpec<'a>; PARAM_DIM],
    /// Encoder `phi`: STATE -> HIDDEN -> HIDDEN -> LATENT.
    #[serde(borrow)]
    pub encoder: [Layer<'a>; N_LAYERS],
    /// Decoder `phi^-1`: LATENT -> HIDDEN -> HIDDEN -> STATE.
    #[serde(borrow)]
    pub decoder: [Layer<'a>; N_LAYERS],
    /// Augmented Koopman matrix `F` over `[y; p]`, row-major, AUG x AUG.
    #[serde(borrow)]
    pub f: F32s<'a>,
    /// Input matrix `B` (AUG x INPUT, row-major; zero rows for `p`).
    #[serde(borrow)]
    pub b: F32s<'a>,
    /// Kalman filter settings.
    pub filter: FilterSpec,
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
        if header != Header::CURRENT {
            return Err(Error::BlobShapeMismatch);
        }
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
    pub fn to_slice<'b>(&self, buf: &'b mut [u8]) -> Result<&'b mut [u8], Error> {
        postcard::to_slice_crc32(self, buf, CRC.digest()).map_err(|_| Error::InputBadLength)
    }

    /// Checks every array's length and every value's finiteness.
    pub fn validate(&self) -> Result<(), Error> {
        let b = &self.body;
        let finite = |a: &[f32]| a.iter().all(|v| v.is_finite());
        if !(b.dt.is_finite() && b.dt > 0.0 && finite(&b.norm_mu)) {
            return Err(Error::BlobNonFinite);
        }
        if !b.norm_s.iter().all(|v| v.is_finite() && *v > 0.0) {
            return Err(Error::BlobNonFinite);
        }
        let enc = [
            (STATE_DIM, HIDDEN_DIM),
            (HIDDEN_DIM, HIDDEN_DIM),
            (HIDDEN_DIM, LATENT_DIM),
        ];
        let dec = [
            (LATENT_DIM, HIDDEN_DIM),
            (HIDDEN_DIM, HIDDEN_DIM),
            (HIDDEN_DIM, STATE_DIM),
        ];
        for (layer, (i, o)) in b.encoder.iter().zip(enc) {
            layer.check(i, o)?;
        }
        for (layer, (i, o)) in b.decoder.iter().zip(dec) {
            layer.check(i, o)?;
        }
        b.f.check(AUG_DIM * AUG_DIM)?;
        // The filter treats the parameters as static: their rows of F must
        // be the identity.
        let param_rows_identity =
            b.f.iter()
                .enumerate()
                .skip(LATENT_DIM * AUG_DIM)
                .all(|(k, v)| {
                    let (i, j) = (k / AUG_DIM, k % AUG_DIM);
                    v == if i == j { 1.0 } else { 0.0 }
                });
        if !param_rows_identity {
            return Err(Error::BlobParamsNotStatic);
        }
        b.b.check(AUG_DIM * INPUT_DIM)?;
        if !b.params.iter().all(|p| finite(&p.train_range)) {
            return Err(Error::BlobNonFinite);
        }
        b.filter.check()
    }
}
