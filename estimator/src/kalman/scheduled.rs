//! Updates `1..=T` on the blob's gain schedule.

use super::Kalman;
use super::kernels::{all_finite, combo, tail};
use crate::{AUG_DIM, Aug, Error, LATENT_DIM, Latent};

impl Kalman<'_> {
    /// One update with a precomputed gain `K` (given as `K^T`, row `k` for
    /// innovation `k`): `g' = F g`, `nu = z - y'`, `g = g' + K nu`. Leaves
    /// `self` alone.
    pub(crate) fn scheduled_update(
        &self,
        z: &Latent,
        kt: &[[f32; AUG_DIM]; LATENT_DIM],
    ) -> Result<Aug, Error> {
        let (y, nu) = self.predict_latent(z);
        let dg = combo(nu.iter().copied().zip(kt));
        let mut m = self.mean;
        for ((mi, pred), d) in m.iter_mut().zip(y.iter().chain(tail(&self.mean))).zip(&dg) {
            *mi = pred + d;
        }
        if all_finite(&m) {
            Ok(m)
        } else {
            Err(Error::FilterNonFinite)
        }
    }
}
