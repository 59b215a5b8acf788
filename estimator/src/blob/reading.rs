//! How a parameter's filter coordinate reads as its value.

use serde::{Deserialize, Serialize};

use crate::Error;

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
    /// value ([`Body::g`](super::Body::g) the training gravity).
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

    /// The trained range's width in the filter's coordinate: `hi - lo`
    /// where the coordinate is the parameter moved or reciprocated (`Direct`,
    /// `Centred`, `Reciprocal`), 2 where it is scaled to `[-1, 1]`.
    pub fn coordinate_span(&self) -> f32 {
        let [lo, hi] = self.train_range;
        match self.reading {
            Reading::Direct | Reading::Centred | Reading::Reciprocal => hi - lo,
            Reading::ReciprocalUnit | Reading::Unit => 2.0,
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

    /// Refuses a value no blob may hold.
    pub(crate) fn check(&self) -> Result<(), Error> {
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
