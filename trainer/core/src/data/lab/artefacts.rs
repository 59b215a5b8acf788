//! What a video tracker's log carries beyond noise and quantisation:
//! frame times rounded to the logger's step, dropped frames (some in runs
//! that leave gaps of up to [`LONGEST_GAP`]) and single-frame spikes (the
//! tracker on another object for a frame).

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::Recording;

/// The longest gap a run of dropped frames leaves between the frames
/// around it, s (a single dropped frame at a lower rate leaves more).
pub const LONGEST_GAP: f64 = 0.3;
/// The share of runs of dropped frames that are longer than one frame.
const RUN_SHARE: f64 = 0.2;
/// The size of a spike, rad: uniform over it, either sign.
pub const SPIKE: [f64; 2] = [0.1, 0.5];

/// A recording's artefacts (all 0: none, and nothing drawn).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Artefacts {
    /// Frame times rounded to this step, s (0.001 or 0.01 as video logs
    /// write them; 0: exact). A frame whose rounded time repeats the one
    /// before is not written (a log keyed by its time).
    pub stamp_round: f64,
    /// Share of frames missing, in `[0, 1)`: most alone, one run in five
    /// of several frames (a gap of up to [`LONGEST_GAP`]).
    pub dropped: f64,
    /// Share of frames, in `[0, 1)`, whose angle jumps by [`SPIKE`] for
    /// that frame alone.
    pub spikes: f64,
}

impl Artefacts {
    /// None at all.
    pub const NONE: Artefacts = Artefacts {
        stamp_round: 0.0,
        dropped: 0.0,
        spikes: 0.0,
    };

    /// Whether there are none.
    pub fn is_none(&self) -> bool {
        *self == Artefacts::NONE
    }

    /// Whether each lies in its range (an error names the first that does not).
    pub fn check(&self) -> anyhow::Result<()> {
        let share = |v: f64| (0.0..1.0).contains(&v);
        anyhow::ensure!(
            self.stamp_round.is_finite() && self.stamp_round >= 0.0,
            "the stamps' rounding must be 0 or a positive step, s"
        );
        anyhow::ensure!(
            share(self.dropped) && share(self.spikes),
            "the shares of dropped frames and spikes must lie in [0, 1)"
        );
        Ok(())
    }

    /// `rec` (sampled at `rate`, its angles in steps of `quantum`) with
    /// the artefacts, drawn from `rng`: the spikes, then the drops, then
    /// the stamps rounded. Nothing is drawn for an artefact that is 0.
    pub fn apply(
        &self,
        rec: &Recording,
        rate: f64,
        quantum: f64,
        rng: &mut ChaCha8Rng,
    ) -> Recording {
        let mut out = rec.clone();
        if self.spikes > 0.0 {
            spike(&mut out.theta, self.spikes, quantum, rng);
        }
        if self.dropped > 0.0 {
            let keep = kept_frames(out.t.len(), self.dropped, rate, rng);
            out = select(&out, &keep);
        }
        if self.stamp_round > 0.0 {
            let keep = round_stamps(&mut out.t, self.stamp_round);
            out = select(&out, &keep);
        }
        out
    }
}

/// Moves a share `p` of the angles (never two in a row, nor the first)
/// by [`SPIKE`], either sign, requantised to `quantum`.
fn spike(theta: &mut [f64], p: f64, quantum: f64, rng: &mut ChaCha8Rng) {
    let mut last = true;
    for v in theta.iter_mut() {
        let now = !last && rng.random_bool(p);
        if now {
            let jump = rng.random_range(SPIKE[0]..SPIKE[1]);
            let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            *v = ((*v + sign * jump) / quantum).round() * quantum;
        }
        last = now;
    }
}

/// Which of `n` frames at `rate` are kept when a share `p` is dropped:
/// runs start at a frame with the probability that makes `p` the
/// expected share, one in five several frames long (up to a gap of
/// [`LONGEST_GAP`]), each followed by a kept frame. The first frame is
/// kept.
fn kept_frames(n: usize, p: f64, rate: f64, rng: &mut ChaCha8Rng) -> Vec<bool> {
    let longest = ((LONGEST_GAP * rate).floor() as usize)
        .saturating_sub(1)
        .max(1);
    let mean_run = if longest >= 2 {
        (1.0 - RUN_SHARE) + RUN_SHARE * (2 + longest) as f64 / 2.0
    } else {
        1.0
    };
    // A frame starts a run with `q` (then one is kept), else is kept:
    // p = q m / (1 + q m).
    let q = p / (mean_run * (1.0 - p));
    let mut keep = vec![true; n];
    let mut k = 1;
    while k < n {
        if rng.random_bool(q) {
            let run = if longest >= 2 && rng.random_bool(RUN_SHARE) {
                rng.random_range(2..=longest)
            } else {
                1
            };
            for kept in keep.iter_mut().skip(k).take(run) {
                *kept = false;
            }
            k += run + 1;
        } else {
            k += 1;
        }
    }
    keep
}

/// Rounds the stamps `t` to `step`; which frames are kept (not those
/// whose rounded stamp does not pass the one kept before).
fn round_stamps(t: &mut [f64], step: f64) -> Vec<bool> {
    let mut last = f64::NEG_INFINITY;
    t.iter_mut()
        .map(|s| {
            *s = (*s / step).round() * step;
            let keep = *s > last;
            if keep {
                last = *s;
            }
            keep
        })
        .collect()
}

/// The rows of `rec` that `keep` marks.
fn select(rec: &Recording, keep: &[bool]) -> Recording {
    let pick = |v: &[f64]| {
        v.iter()
            .zip(keep)
            .filter(|(_, k)| **k)
            .map(|(x, _)| *x)
            .collect::<Vec<f64>>()
    };
    Recording {
        t: pick(&rec.t),
        theta: pick(&rec.theta),
        theta_dot: rec.theta_dot.as_deref().map(pick),
        torque: rec.torque.as_deref().map(pick),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    /// A 25 Hz recording of `n` frames of a slow ramp.
    fn ramp(n: usize) -> Recording {
        Recording {
            t: (0..n).map(|k| k as f64 / 25.0).collect(),
            theta: (0..n).map(|k| 1e-3 * k as f64).collect(),
            theta_dot: None,
            torque: None,
        }
    }

    #[test]
    fn none_draws_nothing_and_changes_nothing() {
        let rec = ramp(100);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let before = rng.clone();
        assert_eq!(Artefacts::NONE.apply(&rec, 25.0, 1e-9, &mut rng), rec);
        assert_eq!(rng, before);
    }

    #[test]
    fn the_shares_and_sizes_are_as_asked() {
        let n = 100_000;
        let rec = ramp(n);
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let a = Artefacts {
            stamp_round: 0.01,
            dropped: 0.02,
            spikes: 0.01,
        };
        let out = a.apply(&rec, 25.0, 1e-9, &mut rng);
        let kept = out.t.len() as f64 / n as f64;
        assert!((kept - 0.98).abs() < 0.003, "kept {kept}");
        // Stamps on the 10 ms grid, increasing, gaps of at most 0.3 s.
        let mut widest: f64 = 0.0;
        for w in out.t.windows(2) {
            assert!(w[1] > w[0]);
            widest = widest.max(w[1] - w[0]);
        }
        assert!(
            out.t
                .iter()
                .all(|s| ((s / 0.01) - (s / 0.01).round()).abs() < 1e-6)
        );
        assert!(widest > 0.2 && widest <= LONGEST_GAP + 0.011, "{widest}");
        // Spikes: the angle off its ramp by 0.1 to 0.5 rad, alone.
        let off: Vec<usize> = out
            .theta
            .iter()
            .enumerate()
            .filter(|(k, v)| {
                let truth = 1e-3 * (out.t[*k] * 25.0).round();
                (*v - truth).abs() > 0.05
            })
            .map(|(k, _)| k)
            .collect();
        let share = off.len() as f64 / out.t.len() as f64;
        assert!((share - 0.01).abs() < 0.002, "spikes {share}");
        assert!(
            off.windows(2)
                .all(|w| w[1] > w[0] + 1 || out.t[w[1]] - out.t[w[0]] > 0.05)
        );
    }

    #[test]
    fn rounding_keeps_one_frame_a_stamp() {
        let mut t: Vec<f64> = (0..10).map(|k| k as f64 / 240.0).collect();
        let keep = round_stamps(&mut t, 0.01);
        let kept: Vec<f64> = t
            .iter()
            .zip(&keep)
            .filter(|(_, k)| **k)
            .map(|(s, _)| *s)
            .collect();
        // 0, 0.01, 0.02, 0.03 and 0.04 s.
        assert_eq!(kept.len(), 5);
        assert!(kept.windows(2).all(|w| w[1] > w[0]));
    }
}
