//! The training envelope: the occupancy map of the measured states.

use serde::{Deserialize, Serialize};

use crate::{Error, State};

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

    /// Refuses a value no blob may hold.
    pub(crate) fn check(&self) -> Result<(), Error> {
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
