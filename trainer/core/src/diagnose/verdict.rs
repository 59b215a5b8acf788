//! The verdict: a residual has structure left when it is above the
//! resolution and its lag-1 autocorrelation exceeds [`STRUCTURE`] (noise
//! on the measured rate enters the residual differenced, with an
//! autocorrelation near -0.5; a smooth unmodelled effect's is near 1).

use super::fit::Fit;

/// Lag-1 autocorrelation above which a residual has structure left.
pub const STRUCTURE: f64 = 0.5;

/// `none`: nothing selected and no structure; `unexplained`: structure
/// that the selected effects (or none) leave; `explained`: effects
/// selected and no structure left. `nuisance_only` is the fit with the
/// length correction alone, `selected` the fit with the selected effects,
/// `floor` the resolution in RMS.
pub fn verdict(
    any_selected: bool,
    nuisance_only: &Fit,
    selected: &Fit,
    floor: f64,
) -> &'static str {
    let rms = |f: &Fit| crate::metrics::rms(f.resid.iter().copied());
    let structured = |f: &Fit| f.rho > STRUCTURE && rms(f) >= floor;
    match (
        any_selected,
        structured(if any_selected {
            selected
        } else {
            nuisance_only
        }),
    ) {
        (false, false) => "none",
        (true, false) => "explained",
        (_, true) => "unexplained",
    }
}
