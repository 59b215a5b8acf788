//! The weights blob: one definition for the trainer, which writes it, and
//! the estimator, which reads it where it lies (in flash, say).
//!
//! `[header][body][crc32]`, all postcard; the one specification, field by
//! field and version by version, is `docs/blob-format.md`.
//! - [`Header`]: magic `b"KKF1"`, [`FORMAT_VERSION`] and the dimensions,
//!   read first and on its own, so that a file of the wrong kind gets
//!   [`Error::BlobBadMagic`] rather than a decoding error.
//! - [`Body`]: the sampling interval, normalisation, the parameters
//!   ([`ParamSpec`], [`Reading`]), the filter's settings ([`FilterSpec`]),
//!   the trust calibration ([`TrustSpec`], [`Envelope`]), then 0-3 padding
//!   bytes and the weight arena as little-endian `f32`s ([`F32s`]). The
//!   padding puts the arena at a multiple of 4 bytes from the blob's
//!   first byte, so a blob at an aligned address ([`Aligned`]) is read as
//!   `f32`s in place: nothing proportional to its size is copied.
//! - a CRC-32 (CRC-32/ISCSI) over header and body, little-endian.
//!
//! Trailing bytes after the CRC are refused ([`Error::BlobTrailingBytes`]).
//!
//! # Examples
//!
//! ```
//! use estimator::blob::{Aligned, Blob, FORMAT_VERSION};
//!
//! static RIG: &Aligned<[u8]> = &Aligned(*include_bytes!("../../../weights/rig.kkf"));
//!
//! // The current format; a bilinear arena without the torque's columns
//! // (its length says so): a model of the free pendulum.
//! let blob = Blob::from_bytes(&RIG.0)?;
//! assert_eq!(blob.header.version, FORMAT_VERSION);
//! assert_eq!(blob.body.params[0].name, "length");
//! assert_eq!(blob.body.dt, 0.04);
//! # Ok::<(), estimator::Error>(())
//! ```

mod envelope;
mod format;
mod layout;
mod older;
mod reading;

use serde::{Deserialize, Serialize};

pub use envelope::Envelope;
pub use format::{
    Activation, Body, F32s, FORMAT_VERSION, Family, FilterSpec, Header, MAGIC, OLDEST_READ_VERSION,
    SWING_VERSION, TrustSpec,
};
internal! {
    pub use layout::{
        BILINEAR_BLOCK_LEN, BILINEAR_BLOCKS, DRIVEN_VERSION, Layout, N_LAYERS, Net, SCHEDULE_STEP_LEN,
        TAIL_LEN,
    };
}
pub use reading::{ParamSpec, Reading};

use crate::{AUG_DIM, Error, LATENT_DIM, PARAM_DIM};

/// Bytes kept at an address aligned to 4, so that a blob compiled into
/// firmware can be read in place:
/// `static BLOB: &Aligned<[u8]> = &Aligned(*include_bytes!("pendulum.kkf"));`
/// then `Model::from_bytes(&BLOB.0)`.
#[repr(C, align(4))]
#[derive(Debug)]
pub struct Aligned<T: ?Sized>(pub T);

/// A whole blob.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq)]
pub struct Blob<'a> {
    /// Magic, version, dimensions.
    pub header: Header,
    /// The model.
    #[serde(borrow)]
    pub body: Body<'a>,
}

internal! {
    /// The blob's CRC-32 algorithm (the one definition; the trainer's
    /// upgrade of old formats reads with it too).
    pub static CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISCSI);
}

impl<'a> Blob<'a> {
    /// Reads and validates a blob, borrowing its weights from `bytes`.
    ///
    /// # Errors
    ///
    /// Checked in this order: the header ([`Error::BlobTruncated`],
    /// [`Error::BlobBadMagic`], [`Error::BlobBadVersion`],
    /// [`Error::BlobShapeMismatch`]), the body's decoding and CRC
    /// ([`Error::BlobMalformed`], [`Error::BlobBadCrc`]), trailing bytes
    /// ([`Error::BlobTrailingBytes`]), then [`Blob::validate`]'s checks.
    pub fn from_bytes(bytes: &'a [u8]) -> Result<Self, Error> {
        let (header, _) =
            postcard::take_from_bytes::<Header>(bytes).map_err(|_| Error::BlobTruncated)?;
        if header.magic != MAGIC {
            return Err(Error::BlobBadMagic);
        }
        if !(OLDEST_READ_VERSION..=FORMAT_VERSION).contains(&header.version) {
            return Err(Error::BlobBadVersion);
        }
        header.check_dims()?;
        let read_error = |e| match e {
            postcard::Error::DeserializeBadCrc => Error::BlobBadCrc,
            postcard::Error::DeserializeUnexpectedEnd => Error::BlobTruncated,
            _ => Error::BlobMalformed,
        };
        let (blob, rest) = if header.version < SWING_VERSION {
            let (old, rest) =
                postcard::take_from_bytes_crc32::<older::BlobV12<'a>>(bytes, CRC.digest())
                    .map_err(read_error)?;
            let header = old.header;
            (
                Blob {
                    header,
                    body: old.body(),
                },
                rest,
            )
        } else {
            postcard::take_from_bytes_crc32::<Blob<'a>>(bytes, CRC.digest()).map_err(read_error)?
        };
        if !rest.is_empty() {
            return Err(Error::BlobTrailingBytes);
        }
        blob.validate()?;
        Ok(blob)
    }

    /// Writes the blob with its CRC into `buf`, returning the used part.
    /// `body.pad` is chosen here (its value in `self` is ignored) so that
    /// the arena starts at a multiple of 4 bytes from `buf[0]`.
    ///
    /// # Errors
    ///
    /// [`Error::InputBadLength`] when `buf` is too short.
    pub fn to_slice<'b>(&self, buf: &'b mut [u8]) -> Result<&'b mut [u8], Error> {
        const ZEROS: [u8; 3] = [0; 3];
        let mut blob = *self;
        // Written in the current layout, whatever format it was read from
        // (a bilinear arena's length says whether it carries `B(q)`).
        blob.header.version = FORMAT_VERSION;
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
    ///
    /// # Errors
    ///
    /// [`Error::BlobShapeMismatch`] for a size that does not fit,
    /// [`Error::BlobNonFinite`] for a value no blob may hold (not finite, or
    /// a variance, standard deviation or threshold below zero),
    /// [`Error::BlobMisaligned`] for padding other than 0-3 zero bytes,
    /// [`Error::BlobParamsNotStatic`], [`Error::BlobBadReading`].
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
            Family::Bilinear if b.filter.schedule_steps == 0 => {
                self.layout().bilinear_arena_len(self.bilinear_driven())
            }
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
        // ... and the torque moves the latent only: `B`'s parameter rows zero.
        let torque_static = self.b().iter().skip(LATENT_DIM).all(|v| v == 0.0);
        if !(param_rows_identity && torque_static) {
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
