//! Single-frame tracker spikes in a recording's raw angle, found before
//! it is differentiated (a spike would poison the derived rate).
//!
//! The test is Hampel's on what the swing leaves: each sample's residual
//! from the least-squares quadratic in time through its [`FIT`] nearest
//! kept neighbours on each side (the sample left out), against the
//! residuals within [`SPREAD`] samples either side. A sample is a glitch
//! where its residual is over [`K`] times their spread (a robust std) and
//! over [`FLOOR`]. A Hampel test on the angle itself, the distance from
//! the median of 7 neighbours on each side, cannot see a spike of 0.3 rad
//! in a 0.58 rad swing tracked at 12 Hz: the 15 samples span two thirds
//! of a period, and their scaled MAD is 0.76 rad. The quadratic follows
//! the swing (at 23 samples a period it leaves 0.4% of the swing, at 11
//! about 7%), and the spread scales the test to what it leaves and to
//! the tracker's noise.
//!
//! A spike moves its neighbours' residuals too (by up to 0.43 of itself),
//! so only the largest excess within [`FIT`] samples is taken at a time,
//! and the test is repeated without the samples taken, until no glitch is
//! left. A glitch is one frame: a sample beside one taken is kept (a
//! recording that jumps to another swing for good would otherwise be
//! eaten from the jump on, a frame a round), and a sample taken whose
//! neighbours still stand out without it is given back (that jump's
//! first frame). Two spikes two frames apart
//! can leave the frame between them the larger residual: then none of
//! the three is taken. The first and last [`FIT`] samples, where the fit
//! would extrapolate, are kept.
//!
//! What it takes from the shared video recordings (12 Hz): in q2, three
//! frames the tracker repeated or stuck while the bob swung fast (at
//! 19.92 s the angle of the frame before, -1.1677 rad, 0.12 rad off the
//! swing; at 24.00 and 189.35 s, 0.20 and 0.10 rad off); from q4b_1
//! (which jumps to another swing at 12.0 s) and q4b_2..5, none. From 270 clean lab recordings (`koopman generate
//! --lab 1..30`, 12 to 1000 Hz, noise to 0.01 rad, jittered stamps),
//! none.

use super::differentiate::quadratic_at;

/// Kept neighbours on each side the quadratic is fitted through.
pub const FIT: usize = 3;
/// Residuals on each side whose spread scales the test.
pub const SPREAD: usize = 20;
/// Spreads of the residuals (robust stds) a glitch's residual lies beyond.
pub const K: f64 = 5.0;
/// Least residual of a glitch, rad: under it, a tracker's noise, a
/// quantised angle, jittered stamps or a coarse source's turning point
/// (at 0.05, 8 of 270 clean lab recordings lost a sample or more).
pub const FLOOR: f64 = 0.08;
/// Most rounds of the test (each takes the largest excess per cluster).
const ROUNDS: usize = 16;

/// Which samples of `(t, theta)` are glitches (`t` increasing).
pub fn glitches(t: &[f64], theta: &[f64]) -> Vec<bool> {
    let n = theta.len().min(t.len());
    let mut dropped = vec![false; n];
    if n < 2 * FIT + 1 {
        return dropped;
    }
    let mut excess = excesses(t, theta, &dropped);
    for _ in 0..ROUNDS {
        let taken: Vec<usize> = (0..n)
            .filter(|&i| excess[i] > 1.0 && largest_near(&excess, i) && !beside(&dropped, i))
            .collect();
        if taken.is_empty() {
            break;
        }
        for i in taken {
            dropped[i] = true;
        }
        excess = excesses(t, theta, &dropped);
    }
    // Dropped, a sample whose neighbours still stand out was one frame of
    // a longer event (a jump to another swing): kept.
    let longer: Vec<usize> = (0..n)
        .filter(|&i| {
            let near = i.saturating_sub(FIT)..(i + FIT + 1).min(n);
            dropped[i] && near.into_iter().any(|j| excess[j] > 1.0)
        })
        .collect();
    for i in longer {
        dropped[i] = false;
    }
    dropped
}

/// Each sample's residual over what it must exceed (NaN where it is not
/// tested).
fn excesses(t: &[f64], theta: &[f64], dropped: &[bool]) -> Vec<f64> {
    let residual: Vec<f64> = (0..theta.len())
        .map(|i| residual(t, theta, dropped, i))
        .collect();
    (0..residual.len())
        .map(|i| residual[i].abs() / threshold(&residual, i))
        .collect()
}

/// Sample `i`'s residual from the quadratic through its [`FIT`] nearest
/// kept neighbours on each side; NaN where it is dropped or has fewer on
/// a side (near the ends, where the fit would extrapolate).
fn residual(t: &[f64], theta: &[f64], dropped: &[bool], i: usize) -> f64 {
    if dropped[i] {
        return f64::NAN;
    }
    let kept = |k: &usize| !dropped[*k];
    // The neighbours in time order, then the sample itself (on the
    // stack: this runs for every sample of an hour's recording).
    let mut at = [0usize; 2 * FIT + 1];
    let mut n = 0;
    for k in (0..i).rev().filter(kept).take(FIT) {
        at[FIT - 1 - n] = k;
        n += 1;
    }
    if n < FIT {
        return f64::NAN;
    }
    for k in (i + 1..theta.len()).filter(kept).take(FIT) {
        at[n] = k;
        n += 1;
    }
    if n < 2 * FIT {
        return f64::NAN;
    }
    at[2 * FIT] = i;
    let values = at.map(|k| theta[k]);
    let m = at.len() - 1;
    let (fit, _) = quadratic_at(|k| t[at[k]], &values, 0, m - 1, m);
    theta[i] - fit
}

/// What sample `i`'s residual must exceed: [`K`] times the spread of
/// the residuals within [`SPREAD`] of it, and [`FLOOR`]. The spread is
/// the lower quartile of their absolute deviations from their median,
/// over the normal's (0.3186 of its std): the median absolute deviation's
/// measure, but undisturbed while up to three quarters of the residuals
/// are moved by spikes (each moves seven; at 5% of the samples, half of
/// them). A coarse source's residual, a sine over the swing, reads
/// 1.2 times its amplitude either way.
fn threshold(residual: &[f64], i: usize) -> f64 {
    let window = &residual[i.saturating_sub(SPREAD)..(i + SPREAD + 1).min(residual.len())];
    // On the stack: this runs for every sample of an hour's recording.
    let mut buf = [0.0; 2 * SPREAD + 1];
    let mut n = 0;
    for v in window.iter().filter(|v| v.is_finite()) {
        buf[n] = *v;
        n += 1;
    }
    if n == 0 {
        return FLOOR;
    }
    let r = &mut buf[..n];
    let centre = quantile(r, 0.5);
    r.iter_mut().for_each(|v| *v = (*v - centre).abs());
    (K * quantile(r, 0.25) / 0.3186).max(FLOOR)
}

/// The `q` quantile of `v` (the sample at `q n`, rounded down, of `v`
/// sorted), selected in place.
fn quantile(v: &mut [f64], q: f64) -> f64 {
    let at = ((q * v.len() as f64) as usize).min(v.len() - 1);
    *v.select_nth_unstable_by(at, f64::total_cmp).1
}

/// Whether a sample next to `i` is dropped.
fn beside(dropped: &[bool], i: usize) -> bool {
    (i > 0 && dropped[i - 1]) || dropped.get(i + 1).copied().unwrap_or(false)
}

/// Whether `excess[i]` is the largest within [`FIT`] samples of it (the
/// earlier of equals; a NaN, a sample not tested, is the least).
fn largest_near(excess: &[f64], i: usize) -> bool {
    let e = |j: usize| {
        if excess[j].is_nan() {
            f64::NEG_INFINITY
        } else {
            excess[j]
        }
    };
    let near = i.saturating_sub(FIT)..(i + FIT + 1).min(excess.len());
    near.into_iter()
        .all(|j| j == i || e(j) < e(i) || (j > i && e(j) == e(i)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A clean lab-like recording: a 0.9 m string at g = 9.81 swinging
    /// 0.58 rad, decaying, tracked at `hz` for 60 s with noise of up to
    /// 0.01 rad and rounded to 0.1 degree.
    fn clean(hz: f64, swing: f64, seed: u64) -> (Vec<f64>, Vec<f64>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let w = (9.81f64 / 0.9).sqrt();
        let step = 0.1f64.to_radians();
        let t: Vec<f64> = (0..(60.0 * hz) as usize).map(|k| k as f64 / hz).collect();
        let theta = t
            .iter()
            .map(|&x| {
                let v = swing * (-0.02 * x).exp() * (w * x).cos() + rng.random_range(-0.01..0.01);
                (v / step).round() * step
            })
            .collect();
        (t, theta)
    }

    /// `share` of the samples [`FIT`] or more from the ends replaced by single-frame
    /// spikes of 0.3 rad either way, no two within [`FIT`] samples: their
    /// indices.
    fn spike(theta: &mut [f64], share: f64, seed: u64) -> Vec<usize> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let n = theta.len();
        let mut at: Vec<usize> = Vec::new();
        while (at.len() as f64) < share * n as f64 {
            let k = rng.random_range(FIT..n - FIT);
            if !at.iter().any(|a| a.abs_diff(k) <= FIT) {
                at.push(k);
            }
        }
        for &k in &at {
            theta[k] += if rng.random_bool(0.5) { 0.3 } else { -0.3 };
        }
        at.sort_unstable();
        at
    }

    #[test]
    fn a_clean_recording_loses_none() {
        // Sources from 5 to 240 Hz, swings from 0.05 to 1.5 rad.
        for (k, hz) in [5.0, 12.0, 25.0, 60.0, 240.0].into_iter().enumerate() {
            for swing in [0.05, 0.58, 1.5] {
                let (t, theta) = clean(hz, swing, k as u64);
                let dropped = glitches(&t, &theta);
                let n = dropped.iter().filter(|d| **d).count();
                assert_eq!(n, 0, "{hz} Hz, swing {swing}: {n} dropped");
            }
        }
    }

    /// A recording that jumps for good (the tracker moved to another
    /// point, as q4b_1 does at its end) loses no frame at the jump.
    #[test]
    fn a_jump_for_good_is_no_glitch() {
        for hz in [12.0, 25.0] {
            let (t, mut theta) = clean(hz, 0.58, 5);
            let at = theta.len() / 2;
            for v in &mut theta[at..] {
                *v -= 0.5;
            }
            let n = glitches(&t, &theta).iter().filter(|d| **d).count();
            assert_eq!(n, 0, "{hz} Hz: {n} dropped");
        }
    }

    #[test]
    fn spikes_at_1_and_5_percent_are_found() {
        for (hz, share) in [(12.0, 0.01), (12.0, 0.05), (25.0, 0.01), (25.0, 0.05)] {
            let (t, mut theta) = clean(hz, 0.58, 3);
            let spikes = spike(&mut theta, share, 4);
            let dropped = glitches(&t, &theta);
            let found: Vec<usize> = (0..t.len()).filter(|&k| dropped[k]).collect();
            assert_eq!(found, spikes, "{hz} Hz, {share}");
        }
    }
}
