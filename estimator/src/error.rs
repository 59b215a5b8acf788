//! The crate's one error type.

use core::fmt;

/// Everything that can go wrong when reading a blob or stepping the filter.
///
/// Variants are named phase-then-problem: `Blob*` while reading weights,
/// `Input*`/`NonFiniteInput` for a measurement, `Filter*` inside the filter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Error {
    /// The blob ended before its header or body was complete.
    BlobTruncated,
    /// The blob does not start with [`crate::blob::MAGIC`].
    BlobBadMagic,
    /// The blob's format version is not [`crate::blob::FORMAT_VERSION`].
    BlobBadVersion,
    /// The blob's declared dimensions, or the length of one of its arrays,
    /// differ from the sizes this build was compiled for.
    BlobShapeMismatch,
    /// The body decoded but its CRC-32 does not match.
    BlobBadCrc,
    /// The body could not be decoded (bad varint, bad enum tag, bad UTF-8...).
    BlobMalformed,
    /// Bytes follow the end of the blob.
    BlobTrailingBytes,
    /// A weight, a normalisation constant or a filter setting is NaN or
    /// infinite, or a variance, the sampling interval or the gravity is
    /// not positive.
    BlobNonFinite,
    /// The rows of `F` for the parameters are not the identity: the blob
    /// does not keep the parameters static, which the filter relies on.
    BlobParamsNotStatic,
    /// A parameter's reading ([`crate::blob::Reading`]) is not defined on
    /// its training range (a reciprocal reading needs `0 < lo <= hi`).
    BlobBadReading,
    /// The blob's weights do not lie at a 4-byte aligned address (keep the
    /// blob in a buffer aligned to 4, e.g. [`crate::blob::Aligned`]), or
    /// its padding is not what the format writes.
    BlobMisaligned,
    /// A measurement holds NaN or an infinity, or is too large to be a
    /// real reading; the filter state was left unchanged.
    NonFiniteInput,
    /// The innovation covariance `S` lost positive definiteness, or `P`
    /// has a negative variance; the filter state was left unchanged.
    FilterNotPositiveDefinite,
    /// An output buffer or argument has the wrong size.
    InputBadLength,
    /// The filter produced a non-finite state; the step was rolled back.
    FilterNonFinite,
    /// A prediction without a measurement was asked of a filter that has
    /// not seen its first measurement (there is no state to advance).
    FilterNotStarted,
    /// The gravity declared to the estimator is not finite and positive.
    InputBadGravity,
    /// A source interval that is not finite and positive
    /// ([`Estimator::with_source_interval`](crate::Estimator::with_source_interval)).
    InputBadInterval,
    /// A torque limit that is not finite and positive
    /// ([`Pilot::new`](crate::control::Pilot::new)).
    InputBadTorqueLimit,
}

impl Error {
    /// What went wrong, as a static message (the [`Display`](fmt::Display)
    /// text), for firmware that prints without `core::fmt`.
    pub const fn message(&self) -> &'static str {
        match self {
            Error::BlobTruncated => "blob: truncated",
            Error::BlobBadMagic => "blob: bad magic (not a Koopman weights blob)",
            Error::BlobBadVersion => "blob: unsupported format version",
            Error::BlobShapeMismatch => "blob: dimensions differ from this build's",
            Error::BlobBadCrc => "blob: CRC mismatch (corrupted)",
            Error::BlobMalformed => "blob: body could not be decoded",
            Error::BlobTrailingBytes => "blob: trailing bytes after the end",
            Error::BlobNonFinite => {
                "blob: non-finite weight, or non-positive variance, interval or gravity"
            }
            Error::BlobParamsNotStatic => "blob: F does not keep the parameters static",
            Error::BlobBadReading => "blob: a parameter's reading is undefined on its range",
            Error::BlobMisaligned => "blob: weights not 4-byte aligned in memory",
            Error::NonFiniteInput => "input: measurement is NaN, infinite or absurdly large",
            Error::FilterNotPositiveDefinite => "filter: covariance not positive definite",
            Error::InputBadLength => "input: buffer has the wrong length",
            Error::FilterNonFinite => "filter: update produced a non-finite state",
            Error::FilterNotStarted => "filter: no first measurement to predict from",
            Error::InputBadGravity => "input: gravity must be finite and positive",
            Error::InputBadInterval => "input: the source interval must be finite and positive",
            Error::InputBadTorqueLimit => "input: the torque limit must be finite and positive",
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.message())
    }
}

impl core::error::Error for Error {}
