//! The free swings in a recording with several releases: a rig held
//! still, lifted by hand, let go, left to stop, and lifted again.
//!
//! A free swing loses amplitude every half swing; a hand adds it, and a
//! rest has none. Steps:
//! 1. The turning points, by hysteresis: the running extreme is a turning
//!    point once the angle has come back from it by [`HYSTERESIS`] of the
//!    recording's span.
//! 2. A false pair of turns taken out: noise near a true turning point
//!    can turn the angle back by the hysteresis and on again. A half
//!    swing shorter than 0.3 of the swing's period (the median wide half
//!    swing's, twice) and no wider than either half swing beside it is
//!    merged with them into one (its two turning points dropped; the
//!    half swings beside it hold the true extremes).
//! 3. Each half swing (between two turning points) is free where it lasts
//!    between [`SHORTEST`] and 0.8 of the swing's period, spans at least
//!    [`FLOOR`] of the largest half swing and [`NOISE_SPANS`] times the
//!    recording's noise ([`noise()`]), and is at most [`GROWTH`] times the
//!    one before it.
//! 4. A release is a run of at least [`MIN_HALVES`] free half swings, from
//!    the turning point it is let go at to the last one.
//! 5. A run that begins no wider than [`CONTINUES`] times the end of the
//!    run before it, with no hand between them, continues that run: noise
//!    broke one swing's decay where it neared the hysteresis.
//!
//! The recording is split only where it holds a rest or a hand's motion
//! outside its releases: a half swing slower than a swing's, or a still
//! start or end of over [`MIN_OTHER`] swing periods. A recording that is
//! one free swing from start to end stays whole, and so does one whose
//! swing a tracker's glitches break (the caller leaves the glitches out
//! first); one free swing dying into the noise is one release.

use std::ops::Range;

/// The shortest free half swing, as a fraction of the swing's period;
/// a shorter one no wider than its neighbours is a false pair of turns.
pub const SHORTEST: f64 = 0.3;
/// The hysteresis, as a fraction of the recording's span of angles.
pub const HYSTERESIS: f64 = 0.02;
/// The least half swing of a release, as a fraction of the largest.
pub const FLOOR: f64 = 0.03;
/// The least half swing of a release, in standard deviations of the
/// recording's noise. The noise alone spans about 6 of them over a half
/// swing (60 Hz; 7 at 1 kHz); below 16 the last third's envelope reads
/// the noise as much as the swing. On envelope seeds 481-520 (360
/// recordings), at 0 (none), 10, 16 and 24: `Q` at the end within 25% of
/// that envelope on 74%, 76%, 82% and 85%, the lengths trusted 317, 317,
/// 318 and 311.
pub const NOISE_SPANS: f64 = 16.0;
/// The most a free half swing grows over the one before (noise).
pub const GROWTH: f64 = 1.15;
/// The fewest half swings a release holds.
pub const MIN_HALVES: usize = 8;
/// The most a release's last half swing keeps of its first: a swing
/// kept up (driven, or moved by hand) is no free one.
pub const DECAY: f64 = 0.7;
/// Swing periods of rest or hand outside the one release that split it off.
pub const MIN_OTHER: f64 = 2.0;
/// The most a run of free half swings begins over the last of the run
/// before it and still continues that run's decay.
pub const CONTINUES: f64 = 1.5;

/// The samples of each release, where the recording `(t, theta)` is to be
/// split (see the module docs); `None` to keep it whole.
pub fn releases(t: &[f64], theta: &[f64]) -> Option<Vec<Range<usize>>> {
    let turns = turning_points(theta);
    if turns.len() < MIN_HALVES + 1 {
        return None;
    }
    let (period, turns) = period_and_turns(&turns, t, theta)?;
    if turns.len() < MIN_HALVES + 1 {
        return None;
    }
    let halves = halves_of(&turns, t, theta);
    let largest = halves.iter().map(|h| h.1).fold(0.0, f64::max);
    let least = (FLOOR * largest).max(NOISE_SPANS * noise(t, theta));
    let fits = |d: f64| (SHORTEST * period..=0.8 * period).contains(&d);
    let free: Vec<bool> = halves
        .iter()
        .enumerate()
        .map(|(k, &(d, a))| {
            // Grown over a half swing before it (a hand's lift lasts longer).
            let grows = k > 0 && fits(halves[k - 1].0) && a > GROWTH * halves[k - 1].1;
            fits(d) && a >= least && !grows
        })
        .collect();
    // Runs of free half swings, as half-swing indices `f..k`.
    let mut runs: Vec<(usize, usize)> = Vec::new();
    let mut from = None;
    for k in 0..=free.len() {
        match (free.get(k).copied().unwrap_or(false), from) {
            (true, None) => from = Some(k),
            (false, Some(f)) => {
                let decays = halves[k - 1].1 <= DECAY * halves[f].1;
                if k - f >= MIN_HALVES && decays {
                    runs.push((f, k));
                }
                from = None;
            }
            _ => {}
        }
    }
    // A half swing slower than a swing's: a rest or a hand.
    let slow = |k: usize| halves[k].0 > 0.8 * period;
    // A hand's lift between two runs: slow, wide, and wider than the half
    // swing before it (a swing dying into the noise, whose turning points
    // the hysteresis misses, is slow but no wider).
    let hand = |k: usize| {
        let a = halves[k].1;
        slow(k) && a >= FLOOR * largest && (k == 0 || a > CONTINUES * halves[k - 1].1)
    };
    let runs = continued(runs, &halves, hand);
    // A rest or a hand: a half swing outside the releases slower than a
    // swing's, or a still start or end of over MIN_OTHER periods.
    let inside = |k: usize| runs.iter().any(|&(f, e)| (f..e).contains(&k));
    let slow_outside = (0..halves.len()).any(|k| !inside(k) && slow(k));
    let still_ends = t[turns[0]] - t[0] > MIN_OTHER * period
        || t[t.len() - 1] - t[turns[turns.len() - 1]] > MIN_OTHER * period;
    (!runs.is_empty() && (slow_outside || still_ends))
        .then(|| runs.iter().map(|&(f, e)| turns[f]..turns[e] + 1).collect())
}

/// The standard deviation of the recording's noise: the median absolute
/// departure of each angle from the line through its neighbours, scaled
/// to a deviation (1.4826, and the departure's own deviation, `sqrt(1 +
/// w^2 + (1 - w)^2)` of the noise's, `w` the sample's place between its
/// neighbours). The swing's own curvature adds `a (omega dt)^2 / 2` at most,
/// which reads a coarse source's noise high.
pub fn noise(t: &[f64], theta: &[f64]) -> f64 {
    let mut d: Vec<f64> = t
        .windows(3)
        .zip(theta.windows(3))
        .filter_map(|(t, th)| {
            let span = t[2] - t[0];
            let w = (t[1] - t[0]) / span;
            let line = th[0] + w * (th[2] - th[0]);
            let scale = (1.0 + w * w + (1.0 - w) * (1.0 - w)).sqrt();
            (span > 0.0).then(|| (th[1] - line).abs() / scale)
        })
        .collect();
    if d.is_empty() {
        return 0.0;
    }
    let mid = d.len() / 2;
    let (_, m, _) = d.select_nth_unstable_by(mid, f64::total_cmp);
    1.4826 * *m
}

/// Each half swing between consecutive `turns`: its duration and its span
/// of angles.
fn halves_of(turns: &[usize], t: &[f64], theta: &[f64]) -> Vec<(f64, f64)> {
    turns
        .windows(2)
        .map(|w| (t[w[1]] - t[w[0]], (theta[w[1]] - theta[w[0]]).abs()))
        .collect()
}

/// The swing's period: twice the median duration of the half swings that
/// span at least 0.2 of the widest.
fn swing_period(halves: &[(f64, f64)]) -> Option<f64> {
    let largest = halves.iter().map(|h| h.1).fold(0.0, f64::max);
    let mut durations: Vec<f64> = halves
        .iter()
        .filter(|h| h.1 >= 0.2 * largest)
        .map(|h| h.0)
        .collect();
    durations.sort_by(f64::total_cmp);
    durations.get(durations.len() / 2).map(|d| 2.0 * d)
}

/// The swing's period and the turning points without false pairs (step
/// 2 of the module docs). False pairs shorten the half swings the period
/// is read from (a swing of 0.1 rad under 0.004 rad of noise read 0.4 s
/// for 2 s), so the period is read again from the turns without them,
/// and they are taken out again at that period, until it holds within 1%
/// (once or twice).
fn period_and_turns(raw: &[usize], t: &[f64], theta: &[f64]) -> Option<(f64, Vec<usize>)> {
    let mut period = swing_period(&halves_of(raw, t, theta))?;
    let mut turns = without_false_turns(raw, t, theta, SHORTEST * period);
    for _ in 0..3 {
        let next = swing_period(&halves_of(&turns, t, theta))?;
        if (next - period).abs() <= 0.01 * period {
            break;
        }
        period = next;
        turns = without_false_turns(raw, t, theta, SHORTEST * period);
    }
    Some((period, turns))
}

/// `turns` without the false pairs noise made (step 2 of the module
/// docs): a half swing shorter than `shortest` and no wider than either
/// half swing beside it loses its two turning points. One pass: each
/// turn is pushed once, and a merge is checked again where it widened
/// the newest half swing.
fn without_false_turns(turns: &[usize], t: &[f64], theta: &[f64], shortest: f64) -> Vec<usize> {
    let span = |a: usize, b: usize| (theta[b] - theta[a]).abs();
    let mut kept: Vec<usize> = Vec::with_capacity(turns.len());
    for &turn in turns {
        kept.push(turn);
        while let [.., a, b, c, d] = kept[..] {
            let inner = span(b, c);
            if t[c] - t[b] < shortest && inner <= span(a, b) && inner <= span(c, d) {
                kept.truncate(kept.len() - 3);
                kept.push(d);
            } else {
                break;
            }
        }
    }
    kept
}

/// The runs with each one that continues the run before it joined to it:
/// one that begins no wider than [`CONTINUES`] times the last half swing
/// of the one before, with no hand's lift between them (noise broke
/// one free swing's decay; a hand's lift widens the swing).
fn continued(
    runs: Vec<(usize, usize)>,
    halves: &[(f64, f64)],
    hand: impl Fn(usize) -> bool,
) -> Vec<(usize, usize)> {
    let mut out: Vec<(usize, usize)> = Vec::new();
    for (f, e) in runs {
        match out.last_mut() {
            Some(prev)
                if halves[f].1 <= CONTINUES * halves[prev.1 - 1].1 && !(prev.1..f).any(&hand) =>
            {
                prev.1 = e;
            }
            _ => out.push((f, e)),
        }
    }
    out
}

/// The turning points of `theta` by hysteresis (see the module docs).
fn turning_points(theta: &[f64]) -> Vec<usize> {
    let (lo, hi) = theta
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let h = HYSTERESIS * (hi - lo);
    let mut turns = Vec::new();
    // The running extreme and its direction (+1 rising, -1 falling, 0 not yet).
    let (mut at, mut dir) = (0usize, 0i8);
    for (k, &v) in theta.iter().enumerate() {
        let best = theta[at];
        match dir {
            0 => {
                if v > best + h {
                    dir = 1;
                    at = k;
                } else if v < best - h {
                    dir = -1;
                    at = k;
                }
            }
            1 if v > best => at = k,
            1 if v < best - h => {
                turns.push(at);
                dir = -1;
                at = k;
            }
            -1 if v < best => at = k,
            -1 if v > best + h => {
                turns.push(at);
                dir = 1;
                at = k;
            }
            _ => {}
        }
    }
    turns
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::import::Recording;
    use crate::data::lab::{Artefacts, Case, LabSpec, Stamps};
    use crate::physics::{Effect, EffectKind, Rig};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// `spec` recorded at the noise's `seed`.
    fn drawn(spec: &LabSpec, seed: u64) -> Recording {
        spec.record(&mut ChaCha8Rng::seed_from_u64(seed))
    }

    /// Rest 5 s, a hand lifting the bob for 2 s, a release at 1.2 rad that
    /// decays to rest over 30 s, rest, and another release: two releases,
    /// each from its first turning point to near its end; one free swing
    /// alone stays whole.
    #[test]
    fn releases_are_found_and_one_swing_stays_whole() {
        let w = 2.0 * std::f64::consts::PI;
        let h = 0.01;
        let swing = |s: f64| 1.2 * (-s / 8.0).exp() * (w * s).cos();
        let theta_at = |s: f64| -> f64 {
            match s {
                s if s < 5.0 => 0.0,
                s if s < 7.0 => 1.2 * (s - 5.0) / 2.0,
                s if s < 37.0 => swing(s - 7.0),
                s if s < 45.0 => 0.0,
                s if s < 47.0 => 1.2 * (s - 45.0) / 2.0,
                s => swing(s - 47.0),
            }
        };
        let t: Vec<f64> = (0..8000).map(|k| k as f64 * h).collect();
        let theta: Vec<f64> = t.iter().map(|&s| theta_at(s)).collect();
        let got = releases(&t, &theta).unwrap();
        assert_eq!(got.len(), 2, "{got:?}");
        assert!((t[got[0].start] - 7.0).abs() < 0.05, "{}", t[got[0].start]);
        assert!((t[got[1].start] - 47.0).abs() < 0.05, "{}", t[got[1].start]);
        assert!(t[got[0].end - 1] > 30.0 && t[got[0].end - 1] < 37.0);
        let alone: Vec<f64> = t.iter().map(|&s| swing(s)).collect();
        assert!(releases(&t[..3000], &alone[..3000]).is_none());
    }

    /// One free swing of a string (lab seed 417's drag recording: 0.38 m,
    /// let go at 1.06 rad, drag and pivot friction, 12 Hz video with
    /// 0.0067 rad of noise and a 0.06 rad offset) that dies into the noise
    /// near the hysteresis over 183 s: one release, whatever the noise's
    /// draw (before runs were continued, the first seed gave two releases,
    /// the second a stub of 6 s that reads no `Q`).
    #[test]
    fn a_swing_dying_into_the_noise_is_one_release() {
        let spec = LabSpec {
            case: Case::Drag,
            length: 0.381,
            rig: Rig::Simple,
            theta0: 1.063,
            duration: 183.0,
            rate: 12.0,
            stamps: Stamps::Even,
            noise: 0.0067,
            quantum: 0.1f64.to_radians(),
            effects: vec![
                Effect::new(EffectKind::Drag, 0.0949),
                Effect::new(EffectKind::Drag, 0.0125),
                Effect::new(EffectKind::Coulomb, 0.0087),
            ],
            offset: -0.0587,
            forcing: None,
            artefacts: Artefacts::NONE,
        };
        for seed in 1..=8 {
            let rec = drawn(&spec, seed);
            let got = releases(&rec.t, &rec.theta);
            assert!(
                got.as_ref().is_none_or(|r| r.len() == 1),
                "seed {seed}: {got:?}"
            );
        }
    }

    /// Envelope seed 501's viscous recording drawn anew (0.978 m, let go
    /// at 0.10 rad, viscous 0.061 1/s with drag and Coulomb friction, 60
    /// Hz with 0.0043 rad of noise, 546 s, most of it at rest): its noise
    /// makes false turns within the swing's half swings, which read the
    /// period as 0.4 s; read again without them it is 2 s, and the
    /// release found is the swing's, not a stretch of noise at rest (at
    /// the first draw, with the period read once, the import refused the
    /// recording: a release spanning 0.0175 rad).
    #[test]
    fn a_period_misread_through_false_turns_is_read_again() {
        let spec = LabSpec {
            case: Case::Viscous,
            length: 0.978,
            rig: Rig::Simple,
            theta0: 0.1016,
            duration: 546.0,
            rate: 60.0,
            stamps: Stamps::Even,
            noise: 0.0043,
            quantum: 0.1f64.to_radians(),
            effects: vec![
                Effect::new(EffectKind::Viscous, 0.0608),
                Effect::new(EffectKind::Drag, 0.0398),
                Effect::new(EffectKind::Coulomb, 0.0024),
            ],
            offset: -0.0317,
            forcing: None,
            artefacts: Artefacts::NONE,
        };
        for seed in 1..=4 {
            let rec = drawn(&spec, seed);
            let turns = turning_points(&rec.theta);
            let (period, _) = period_and_turns(&turns, &rec.t, &rec.theta).unwrap();
            // 2 pi sqrt(L / g), 1.98 s at small swings: within 5%.
            assert!((period / 1.984 - 1.0).abs() < 0.05, "seed {seed}: {period}");
            if let Some(got) = releases(&rec.t, &rec.theta) {
                let first = got.first().map_or(0.0, |r| rec.t[r.start]);
                let span = got.iter().map(|r| {
                    let w = &rec.theta[r.clone()];
                    w.iter().copied().fold(f64::MIN, f64::max)
                        - w.iter().copied().fold(f64::MAX, f64::min)
                });
                let widest = span.fold(0.0, f64::max);
                assert!(first < 2.0 && widest > 0.15, "seed {seed}: {got:?}");
            }
        }
    }

    /// Lab seed 97's viscous + Coulomb recording drawn anew (0.596 m, let
    /// go at 0.75 rad, viscous 0.0595 1/s and Coulomb 0.094 rad/s^2, 100
    /// Hz with jittered stamps, 0.0081 rad of noise): the friction stops
    /// the swing near 28 s and it rests till 54.8 s. Its noise turns the
    /// angle back by the hysteresis (0.03 rad) near a few true turning
    /// points; the release runs on past them to 25 s at least (the first
    /// draw, before the false turns were merged away, ended at 19.6 s,
    /// its swing still 0.18 rad).
    #[test]
    fn false_turns_in_the_noise_do_not_end_a_release() {
        let spec = LabSpec {
            case: Case::ViscousCoulomb,
            length: 0.5964,
            rig: Rig::Simple,
            theta0: 0.7518,
            duration: 54.78,
            rate: 100.0,
            stamps: Stamps::Jittered,
            noise: 0.0081,
            quantum: 0.1f64.to_radians(),
            effects: vec![
                Effect::new(EffectKind::Viscous, 0.0595),
                Effect::new(EffectKind::Coulomb, 0.094),
            ],
            offset: 0.0146,
            forcing: None,
            artefacts: Artefacts::NONE,
        };
        let mut ends = Vec::new();
        for seed in 1..=8 {
            let rec = drawn(&spec, seed);
            // `None`: kept whole, to its last sample.
            let (n, end) = match releases(&rec.t, &rec.theta) {
                Some(got) => (got.len(), got.first().map_or(0.0, |r| rec.t[r.end - 1])),
                None => (1, rec.t[rec.t.len() - 1]),
            };
            ends.push((seed, n, end));
        }
        assert!(
            ends.iter().all(|&(_, n, end)| n == 1 && end > 25.0),
            "{ends:?}"
        );
    }

    /// The noise read from a swing of 0.3 rad at 0.5 Hz, 60 Hz with
    /// jittered stamps and 0.004 rad of Gaussian noise (60 s, seed 3):
    /// within 10% (the median's spread over 3,600 samples is about 2%, the
    /// swing's curvature adds under 1%).
    #[test]
    fn the_noise_is_read_from_a_swing_with_uneven_stamps() {
        use rand::Rng;
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        // Box-Muller.
        let gauss = |rng: &mut ChaCha8Rng| {
            let (u1, u2): (f64, f64) = (1.0 - rng.random::<f64>(), rng.random());
            0.004 * (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
        };
        let t: Vec<f64> = (0..3600)
            .map(|k| (k as f64 + rng.random_range(-0.3..0.3)) / 60.0)
            .collect();
        let theta: Vec<f64> = t
            .iter()
            .map(|&s| 0.3 * (std::f64::consts::PI * s).cos() + gauss(&mut rng))
            .collect();
        let got = noise(&t, &theta);
        assert!((got / 0.004 - 1.0).abs() < 0.1, "{got}");
    }

    /// Envelope seed 483's viscous recording drawn anew (0.642 m, let go
    /// at 0.42 rad, viscous 0.097 1/s with drag and Coulomb friction, 60
    /// Hz with 0.0099 rad of noise, 138 s, most of it at rest): its release
    /// ends while the swing still stands out of the noise, its last swing
    /// at least 5 noise deviations wide (before the noise was read, the
    /// first draw's release ran on to 53.9 s, its last swing 0.030 rad;
    /// the envelope seed's own draw, to 60.6 s, where the envelope of its
    /// last third read `Q` 168 and the truth is 20 to 32).
    #[test]
    fn a_release_ends_where_its_swing_sinks_into_the_noise() {
        let spec = LabSpec {
            case: Case::ViscousOffset,
            length: 0.642,
            rig: Rig::Simple,
            theta0: 0.415,
            duration: 138.2,
            rate: 60.0,
            stamps: Stamps::Even,
            noise: 0.0099,
            quantum: 0.1f64.to_radians(),
            effects: vec![
                Effect::new(EffectKind::Viscous, 0.0972),
                Effect::new(EffectKind::Drag, 0.0219),
                Effect::new(EffectKind::Coulomb, 0.003),
            ],
            offset: 0.013,
            forcing: None,
            artefacts: Artefacts::NONE,
        };
        for seed in 1..=4 {
            let rec = drawn(&spec, seed);
            let got = releases(&rec.t, &rec.theta).unwrap();
            let last = got.last().unwrap();
            // The amplitude over the release's last swing period (1.6 s).
            let end = rec.t[last.end - 1];
            let tail: Vec<f64> = (last.clone())
                .filter(|&k| rec.t[k] > end - 1.6)
                .map(|k| rec.theta[k])
                .collect();
            let amplitude = (tail.iter().copied().fold(f64::MIN, f64::max)
                - tail.iter().copied().fold(f64::MAX, f64::min))
                / 2.0;
            assert!(
                amplitude > 5.0 * 0.0099 && end < 45.0,
                "seed {seed}: ends {end} s at {amplitude} rad"
            );
        }
    }
}
