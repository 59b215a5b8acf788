//! The map phase: the envelope's occupancy map, from
//! [`CalibrateConfig::map_rollouts`] rollouts of [`MAP_STEPS`]
//! measurements with lengths [`CalibrateConfig::map_margin`] beyond the
//! declared range on either side, run on a blob whose map is full (so
//! nothing is flagged). Every measured state after the burn-in sets the
//! bit of its cell in the bin of the coordinate the filter holds then.

use anyhow::Result;
use estimator::{Estimator, LATENT_DIM, Model};

use super::{CalibrateConfig, Progress, Setup, blob_bytes};
use crate::protocol::WINDOW;

/// Measurements per map rollout: two windows and more, so that each
/// rollout's orbit is covered whatever its period.
const MAP_STEPS: usize = 4 * WINDOW;

/// The occupancy map.
pub(super) struct Map {
    /// One bit a cell, bin after bin ([`map_bytes`] bytes).
    pub(super) bits: Vec<u8>,
    /// Cells visited.
    pub(super) visited: usize,
}

/// Bytes of the map for `cfg`.
pub fn map_bytes(cfg: &CalibrateConfig) -> usize {
    (usize::from(cfg.q_bins) * usize::from(cfg.theta_cells) * usize::from(cfg.rate_cells))
        .div_ceil(8)
}

/// Maps the states of the map set.
pub(super) fn map(setup: &Setup<'_, '_>, progress: &mut Progress<'_>) -> Result<Map> {
    let cfg = setup.cfg;
    let full = vec![0xffu8; map_bytes(cfg)];
    let draft = setup.with_map(&full);
    let draft_bytes = blob_bytes(&draft)?;
    let m = Model::from_bytes(&draft_bytes)?;
    let env = draft.body.trust.envelope;
    let burn_in = usize::from(setup.base.body.filter.burn_in);
    let mut bits = vec![0u8; map_bytes(cfg)];
    let per_bin = usize::from(cfg.theta_cells) * usize::from(cfg.rate_cells);
    let [lo_l, hi_l] = setup.lengths();
    let widened = [lo_l * (1.0 - cfg.map_margin), hi_l * (1.0 + cfg.map_margin)];
    for r in setup
        .sampling
        .rollouts(widened, cfg.map_rollouts, MAP_STEPS, cfg.seed)?
    {
        let mut est = Estimator::new(&m).at_trained_gravity();
        let mut seen = Vec::with_capacity(r.xs.len());
        for (n, x) in r.xs.iter().enumerate() {
            let q = est.step(x)?.filter.coordinate[0];
            let cell = env.cell(&m.normalise(x));
            seen.push(cell);
            if n >= burn_in {
                mark(&mut bits, per_bin, env.bin(q), cell);
            }
        }
        // The states before the burn-in, in the bin the estimate settles in.
        let last = env.bin(est.mean()[LATENT_DIM]);
        for cell in seen {
            mark(&mut bits, per_bin, last, cell);
        }
        progress.tick();
    }
    let visited = bits.iter().map(|b| b.count_ones() as usize).sum();
    Ok(Map { bits, visited })
}

/// Sets the bit of `cell` in `bin` (nothing when either is `None`).
fn mark(bits: &mut [u8], per_bin: usize, bin: Option<usize>, cell: Option<usize>) {
    if let (Some(b), Some(c)) = (bin, cell) {
        let k = b * per_bin + c;
        if let Some(byte) = bits.get_mut(k / 8) {
            *byte |= 1 << (k % 8);
        }
    }
}
