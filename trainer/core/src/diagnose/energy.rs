//! What the swings say: dissipation from the energy lost between turning
//! points, a sensor offset from their centres, and whether anything is
//! left that no candidate explains. In the manner of PySINDy, as separate
//! pieces: the candidate library ([`columns`]), the fit ([`fit`]), the
//! selection ([`select`]) and the verdict ([`diagnose_swings`]).
//!
//! **The balance.** With `theta_ddot = -w^2 sin(theta) + d(theta_dot)`, the
//! energy `E = theta_dot^2 / 2 + w^2 (1 - cos(theta))` changes by
//! `dE/dt = theta_dot d(theta_dot)`: multiplying the equation by the rate
//! and integrating over a half swing (a weak form whose test function is
//! the rate) gives, between turning points `k` and `k + 1` (where the
//! rate is 0 and `E = w^2 (1 - cos(A))`),
//!
//! `w^2 (cos A_{k+1} - cos A_k) = c_v I_2 + c_c I_1 + c_d I_3`,
//!
//! with, on the free swing of amplitude `A` (the mean of the two):
//! `I_1 = int |theta_dot| dt = A_k + A_{k+1}` (exact), `I_2 = int
//! theta_dot^2 dt = w J(A)`, `J(A) = 4 k^2 int cos^2(phi) / sqrt(1 - k^2
//! sin^2(phi))` over `(-pi/2, pi/2)`, `k = sin(A / 2)`, and `I_3 = int
//! |theta_dot|^3 dt = 4 w^2 (sin A - A cos A)`. Viscous damping
//! (`-c_v theta_dot`), Coulomb friction (`-c_c sign(theta_dot)`) and drag
//! (`-c_d theta_dot |theta_dot|`) lose energy in proportion to `A^2`, `A`
//! and `A^3` per swing: exponential, linear and `1 / (1 + b t)` envelopes.
//!
//! **The fit** is on the energies themselves, `e_k = 1 - cos(A_k)`, against
//! the cumulative sums of the columns (so each measured amplitude enters
//! once, with its own error): `e_k = e_0 - sum_j beta_j D_kj`, weighted by
//! `1 / Var(e_k)` from the window fits ([`super::swings`]).
//!
//! **Selection**: every subset of the three, each coefficient positive (a
//! loss), by BIC; then a term is dropped while its `|t|` is below
//! [`T_KEEP`] (standard errors inflated for the residuals' lag-1
//! correlation). That fixes how many terms the swings support; which
//! ones is then the best BIC among the subsets of that size whose terms
//! are each positive and over [`T_KEEP`]. Over a short record (an
//! amplitude falling by a factor of 2) Coulomb friction and drag
//! together mimic viscous damping (`A + A^3` against `A^2`), and the
//! elimination from that pair kept whichever of the two was stronger.
//!
//! **The offset**: the windows' centres, weighted; named when the mean is
//! over [`T_KEEP`] standard errors and over [`OFFSET_RESOLUTION`]. A
//! constant torque moves the centre the same way (it moves the
//! equilibrium, the offset moves the reading); on swings this size the
//! two cannot be told apart, and the sensor's offset is the likelier.
//!
//! **Unexplained**: the chosen terms leave the energies, or the centres,
//! scattered more than [`STRUCTURE`] times their variance from the
//! window fits' own noise, and by more than [`STRUCTURE_RESOLUTION`]
//! beyond it (a forcing beats against the swing and moves both).

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use super::swings::{Swings, Turn};
use crate::metrics::{correlation_inflation, lag1_autocorrelation, median};
use crate::physics::EffectKind;

/// `|t|` a kept term must reach.
pub const T_KEEP: f64 = 4.0;
/// Smallest offset named, rad.
pub const OFFSET_RESOLUTION: f64 = 0.005;
/// Variance ratio above which structure is left...
pub const STRUCTURE: f64 = 4.0;
/// ...when it is also this large, rad: the RMS of the amplitudes' or the
/// centres' scatter beyond their noise (an encoder's counts are so fine
/// that the window fits' own approximation shows; a forcing the recording
/// shows moves them by several times this).
pub const STRUCTURE_RESOLUTION: f64 = 0.005;
/// The dissipative candidates, in column order.
pub const DISSIPATION: [EffectKind; 3] =
    [EffectKind::Viscous, EffectKind::Coulomb, EffectKind::Drag];

/// One term found.
#[derive(Debug, Clone, Serialize)]
pub struct Term {
    /// Which.
    pub name: EffectKind,
    /// Coefficient, in the effect's unit.
    pub coefficient: f64,
    /// Its standard error.
    pub se: f64,
    /// 95% interval.
    pub ci: [f64; 2],
}

/// What the swings say.
#[derive(Debug, Clone, Serialize)]
pub struct SwingDiagnosis {
    /// `none`, `explained` or `unexplained`.
    pub verdict: String,
    /// The terms named (dissipation, then the offset).
    pub effects: Vec<Term>,
    /// `w` of the free small swing, rad/s.
    pub w: f64,
    /// Turning points used.
    pub turns: usize,
    /// First and last amplitude, rad.
    pub amplitude: [f64; 2],
    /// The window fits' noise level, rad.
    pub noise: f64,
    /// Weighted residual variance of the energies (1 = the noise).
    pub energy_scatter: f64,
    /// Weighted variance of the centres about their mean (1 = the noise).
    pub centre_scatter: f64,
    /// The centres' weighted mean and its standard error, rad.
    ///
    /// The swing's zero, named as an offset or not
    /// ([`SwingDiagnosis::centre_found`]).
    pub centre: [f64; 2],
    /// How it was decided, in words.
    pub criterion: String,
}

impl SwingDiagnosis {
    /// The swing's centre where it lies over [`T_KEEP`] standard errors
    /// from zero, else 0, rad: what to subtract from the angle to centre
    /// the swing, also below the [`OFFSET_RESOLUTION`] named as an effect.
    pub fn centre_found(&self) -> f64 {
        let [c, se] = self.centre;
        if significant(c, se) { c } else { 0.0 }
    }
}

/// Whether a centre `c` with standard error `se` is over [`T_KEEP`] of
/// them from zero.
fn significant(c: f64, se: f64) -> bool {
    c.abs() > T_KEEP * se
}

/// `K(k)`, the complete elliptic integral of the first kind, by the AGM.
fn ellip_k(k: f64) -> f64 {
    let (mut a, mut b) = (1.0, (1.0 - k * k).max(0.0).sqrt());
    for _ in 0..30 {
        (a, b) = (0.5 * (a + b), (a * b).sqrt());
    }
    std::f64::consts::PI / (2.0 * a)
}

/// `J(A)` of the module docs, by 64-point Simpson (the integrand is smooth).
fn j2(a: f64) -> f64 {
    let k = (0.5 * a).sin();
    let n = 64;
    let h = std::f64::consts::PI / n as f64;
    let f = |phi: f64| {
        let s = phi.sin();
        phi.cos().powi(2) / (1.0 - k * k * s * s).sqrt()
    };
    let mut sum = f(-0.5 * std::f64::consts::PI) + f(0.5 * std::f64::consts::PI);
    for i in 1..n {
        let phi = -0.5 * std::f64::consts::PI + i as f64 * h;
        sum += if i % 2 == 1 { 4.0 } else { 2.0 } * f(phi);
    }
    4.0 * k * k * sum * h / 3.0
}

/// The free swing's `w` from the turning points' spacing: each half swing
/// lasts `2 K(sin(A / 2)) / w`; the median over half swings.
pub fn free_w(turns: &[Turn]) -> f64 {
    let mut ws: Vec<f64> = turns
        .windows(2)
        .map(|p| {
            let a = 0.5 * (p[0].amplitude + p[1].amplitude);
            2.0 * ellip_k((0.5 * a).sin()) / (p[1].t - p[0].t)
        })
        .collect();
    median(&mut ws)
}

/// The library: per half swing `k -> k + 1`, each candidate's energy loss
/// per unit coefficient, divided by `w^2` (so it is in units of `e`).
pub fn columns(kind: EffectKind, a0: f64, a1: f64, w: f64) -> f64 {
    let a = 0.5 * (a0 + a1);
    match kind {
        EffectKind::Viscous => j2(a) / w,
        EffectKind::Coulomb => (a0 + a1) / (w * w),
        EffectKind::Drag => 4.0 * (a.sin() - a * a.cos()),
        _ => 0.0,
    }
}

/// A weighted fit of the energies.
pub struct EnergyFit {
    /// The terms, in the order given.
    pub kinds: Vec<EffectKind>,
    /// Their coefficients.
    pub beta: Vec<f64>,
    /// Their standard errors (inflated for correlation).
    pub se: Vec<f64>,
    /// Weighted residual sum of squares.
    pub rss: f64,
    /// Samples.
    pub n: usize,
}

impl EnergyFit {
    /// Bayesian information criterion with the residual scale estimated.
    pub fn bic(&self) -> f64 {
        let n = self.n as f64;
        n * (self.rss / n).max(1e-300).ln() + (self.kinds.len() + 1) as f64 * n.ln()
    }
}

/// Fits `e_k = e_0 - sum_j beta_j D_kj` for the `kinds` given.
pub fn fit(turns: &[Turn], w: f64, kinds: &[EffectKind]) -> Option<EnergyFit> {
    let n = turns.len();
    let p = kinds.len() + 1;
    if n <= p + 2 {
        return None;
    }
    let mut x = DMatrix::<f64>::zeros(n, p);
    let mut y = DVector::<f64>::zeros(n);
    let mut cum = vec![0.0; kinds.len()];
    for (k, turn) in turns.iter().enumerate() {
        if k > 0 {
            for (c, kind) in cum.iter_mut().zip(kinds) {
                *c += columns(*kind, turns[k - 1].amplitude, turn.amplitude, w);
            }
        }
        let e = 1.0 - turn.amplitude.cos();
        let sd = (turn.amplitude.sin() * turn.amplitude_sd).max(1e-12);
        y[k] = e / sd;
        x[(k, 0)] = 1.0 / sd;
        for (j, c) in cum.iter().enumerate() {
            x[(k, j + 1)] = -c / sd;
        }
    }
    let xtx = x.transpose() * &x;
    let inv = xtx.try_inverse()?;
    let b = &inv * (x.transpose() * &y);
    let r = &y - &x * &b;
    let rss = r.norm_squared();
    let s2 = rss / (n - p) as f64;
    let inflate = correlation_inflation(lag1_autocorrelation(r.as_slice()), 0.9);
    Some(EnergyFit {
        kinds: kinds.to_vec(),
        beta: (1..p).map(|j| b[j]).collect(),
        se: (1..p)
            .map(|j| (s2 * inv[(j, j)] * inflate).max(0.0).sqrt())
            .collect(),
        rss,
        n,
    })
}

/// Selection (module docs): the best subset by BIC among those with every
/// coefficient positive, then backward elimination below [`T_KEEP`], then
/// the best of that many terms.
pub fn select(turns: &[Turn], w: f64) -> Option<EnergyFit> {
    let loses = |f: &EnergyFit| f.beta.iter().all(|b| *b > 0.0);
    let mut f = best_by_bic(turns, w, &loses)?;
    loop {
        let weakest = f
            .beta
            .iter()
            .zip(&f.se)
            .map(|(b, s)| b / s.max(1e-300))
            .enumerate()
            .filter(|(_, t)| *t < T_KEEP)
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(j, _)| j);
        let Some(j) = weakest else {
            break;
        };
        let mut kinds = f.kinds.clone();
        kinds.remove(j);
        f = fit(turns, w, &kinds)?;
    }
    let size = f.kinds.len();
    let supported = |g: &EnergyFit| {
        g.kinds.len() == size
            && g.beta
                .iter()
                .zip(&g.se)
                .all(|(b, s)| *b > 0.0 && b / s.max(1e-300) >= T_KEEP)
    };
    Some(best_by_bic(turns, w, &supported).unwrap_or(f))
}

/// The fit of least BIC among the subsets of [`DISSIPATION`] that pass
/// `keep`.
fn best_by_bic(turns: &[Turn], w: f64, keep: &dyn Fn(&EnergyFit) -> bool) -> Option<EnergyFit> {
    let mut best: Option<EnergyFit> = None;
    for mask in 0u8..8 {
        let kinds: Vec<EffectKind> = DISSIPATION
            .iter()
            .enumerate()
            .filter(|(j, _)| mask & (1 << j) != 0)
            .map(|(_, k)| *k)
            .collect();
        let Some(f) = fit(turns, w, &kinds) else {
            continue;
        };
        if keep(&f) && best.as_ref().is_none_or(|b| f.bic() < b.bic()) {
            best = Some(f);
        }
    }
    best
}

/// The diagnosis from the swings (module docs).
pub fn diagnose_swings(sw: &Swings) -> anyhow::Result<SwingDiagnosis> {
    let turns = &sw.turns;
    let w = free_w(turns);
    anyhow::ensure!(w.is_finite() && w > 0.0, "no period in the swings");
    let chosen =
        select(turns, w).ok_or_else(|| anyhow::anyhow!("the energies cannot be fitted"))?;
    let dof = (chosen.n - chosen.kinds.len() - 1).max(1) as f64;
    let energy_scatter = chosen.rss / dof;
    let mut effects: Vec<Term> = chosen
        .kinds
        .iter()
        .zip(chosen.beta.iter().zip(&chosen.se))
        .map(|(k, (b, s))| Term {
            name: *k,
            coefficient: *b,
            se: *s,
            ci: [b - 1.96 * s, b + 1.96 * s],
        })
        .collect();
    // The centres: weighted mean and scatter.
    let (mut sw_, mut swc) = (0.0, 0.0);
    for t in turns {
        let wt = 1.0 / t.centre_sd.max(1e-12).powi(2);
        sw_ += wt;
        swc += wt * t.centre;
    }
    let centre = swc / sw_;
    let centre_scatter = turns
        .iter()
        .map(|t| ((t.centre - centre) / t.centre_sd.max(1e-12)).powi(2))
        .sum::<f64>()
        / (turns.len() - 1).max(1) as f64;
    // Neighbouring windows share half their samples: the mean's error is
    // about sqrt(2) of the independent one's.
    let centre_se = (centre_scatter.max(1.0) * 2.0 / sw_).sqrt();
    if significant(centre, centre_se) && centre.abs() > OFFSET_RESOLUTION {
        effects.push(Term {
            name: EffectKind::Offset,
            coefficient: centre,
            se: centre_se,
            ci: [centre - 1.96 * centre_se, centre + 1.96 * centre_se],
        });
    }
    // The scatter beyond the noise, in rad: sqrt(ratio - 1) typical sds.
    let typical = |f: &dyn Fn(&Turn) -> f64| median(&mut turns.iter().map(f).collect::<Vec<_>>());
    let excess = |ratio: f64, sd: f64| (ratio - 1.0).max(0.0).sqrt() * sd;
    let energy_excess = excess(energy_scatter, typical(&|t: &Turn| t.amplitude_sd));
    let centre_excess = excess(centre_scatter, typical(&|t: &Turn| t.centre_sd));
    let structured = (energy_scatter > STRUCTURE && energy_excess > STRUCTURE_RESOLUTION)
        || (centre_scatter > STRUCTURE && centre_excess > STRUCTURE_RESOLUTION);
    let verdict = match (effects.is_empty(), structured) {
        (_, true) => "unexplained",
        (true, false) => "none",
        (false, false) => "explained",
    };
    Ok(SwingDiagnosis {
        verdict: verdict.into(),
        effects,
        w,
        turns: turns.len(),
        amplitude: [
            turns.first().map_or(0.0, |t| t.amplitude),
            turns.last().map_or(0.0, |t| t.amplitude),
        ],
        noise: sw.noise,
        energy_scatter,
        centre_scatter,
        centre: [centre, centre_se],
        criterion: format!(
            "energy lost between turning points against viscous (A^2), Coulomb (A) and drag (A^3) per swing; subsets with positive coefficients by BIC, terms kept at |t| >= {T_KEEP}; offset: mean centre over {T_KEEP} standard errors and {OFFSET_RESOLUTION} rad; unexplained: energies or centres scattered over {STRUCTURE} x the window fits' noise and by over {STRUCTURE_RESOLUTION} rad beyond it"
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Over the first 15% of lab seed 21's viscous recording with an
    /// offset (0.25 to 1.2 rad released, the amplitude falling by about
    /// 2), Coulomb friction with drag has the least BIC; the elimination
    /// from that pair kept Coulomb (t 20), where viscous alone fits better
    /// (BIC) and is the truth. Found by comparing the two rules on seeds 1
    /// to 40 (`trainer_core::data::lab::suite`), which they name alike
    /// but for this one and one drag recording both rules misname.
    #[test]
    fn the_terms_kept_are_the_best_of_their_number() {
        use crate::data::lab::{Case, suite};
        let (spec, rec) = suite(21)
            .into_iter()
            .find(|(s, _)| s.case == Case::ViscousOffset)
            .expect("the suite has every case");
        let n = rec.t.len() * 15 / 100;
        let (t, theta) = crate::diagnose::without_glitches(&rec.t[..n], &rec.theta[..n]);
        let sw = super::super::swings::swings(&t, &theta).expect("it swings");
        let w = free_w(&sw.turns);
        let chosen = select(&sw.turns, w).expect("the energies fit");
        assert_eq!(chosen.kinds, vec![EffectKind::Viscous], "{:?}", chosen.beta);
        let truth = spec.effects.first().expect("viscous").coefficient;
        assert!(
            (chosen.beta[0] / truth - 1.0).abs() < 0.1,
            "{} against {truth}",
            chosen.beta[0]
        );
    }

    #[test]
    fn the_free_swing_integrals_match_their_small_angle_limits() {
        // K(0) = pi/2; J(A) -> pi A^2 / 2 as A -> 0 (the harmonic swing's
        // int theta_dot^2 dt over half a period, over w); relative 1e-4 at
        // A = 0.01 (the next term is O(A^2)).
        assert!((ellip_k(0.0) - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        let a = 0.01;
        assert!((j2(a) / (std::f64::consts::PI * a * a / 2.0) - 1.0).abs() < 1e-4);
        // K(sin(pi/4)) = 1.854075 (Abramowitz and Stegun, table 17.1, m = 0.5).
        assert!((ellip_k((0.5f64).sqrt()) - 1.854_074_677).abs() < 1e-8);
    }
}
