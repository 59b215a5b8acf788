//! Steps 1 to 3 of the loop: read the recordings both ways, keep the part
//! of each the loop can use, split it at [`FIT_SHARE`], diagnose the first
//! part from its swings and subtract the swing's centre from the angle
//! (where significant, named as an offset or not:
//! [`SwingDiagnosis::centre_found`]).

use std::path::PathBuf;

use anyhow::{Context, Result};

use trainer_core::data::import::{ImportOptions, Recording};
use trainer_core::data::{self, Dataset, Rollout, Sidecar};
use trainer_core::diagnose::{self, energy::SwingDiagnosis};

use super::{AT_REST_AFTER_PERIODS, AT_REST_SCATTER, FIT_SHARE};

/// Step 1: the recordings as recorded (their own stamps, for the
/// diagnosis), each with what it was read from, and imported on the
/// model's grid (for the models), one rollout each.
pub(super) fn read_both(
    inputs: &[PathBuf],
    import: &ImportOptions,
) -> Result<(Vec<(String, Recording)>, Dataset)> {
    let recs = data::read_recordings(inputs, import)?;
    let ds = data::read_inputs(inputs, import)?;
    anyhow::ensure!(
        recs.len() == ds.rollouts.len(),
        "{} recordings read but {} imported",
        recs.len(),
        ds.rollouts.len()
    );
    Ok((recs, ds))
}

/// One recording as the loop uses it: its usable part, split, diagnosed
/// and corrected (steps 2 and 3).
#[derive(Debug, Clone)]
pub(super) struct Part {
    /// What it was imported from.
    pub source: String,
    /// Its usable part on the model's grid, the swing's centre subtracted
    /// from the angle: `xs[..cut]` is diagnosed and trained on, the rest held
    /// out.
    pub series: Rollout,
    /// Where the held-out part begins.
    pub cut: usize,
    /// The swing diagnosis of the first part.
    pub diagnosis: SwingDiagnosis,
    /// The swing's centre subtracted from the angle, rad
    /// ([`SwingDiagnosis::centre_found`]).
    pub centre: f64,
    /// Where the usable part ends, and why.
    pub end: UsablePart,
}

impl Part {
    /// The first part, trained on.
    fn first(&self) -> Rollout {
        Rollout {
            id: self.series.id,
            t: self.series.t[..self.cut].to_vec(),
            xs: self.series.xs[..self.cut].to_vec(),
            us: Vec::new(),
        }
    }
}

/// Steps 2 and 3 for each recording of `recs` and its import in `ds`
/// ([`read_both`]; `start`: the import's trim, s), in order; says where
/// one is cut short and what each diagnosis found.
pub(super) fn split_all(
    recs: &[(String, Recording)],
    ds: &Dataset,
    start: f64,
    say: &dyn Fn(&str),
) -> Result<Vec<Part>> {
    recs.iter()
        .zip(&ds.rollouts)
        .map(|((source, rec), r)| split(source, rec, r, start, ds.sidecar.dt, say))
        .collect()
}

/// The first parts of `parts`, as the data set trained on (and written
/// as `fit.csv`).
pub(super) fn first_parts(parts: &[Part], sidecar: &Sidecar) -> Dataset {
    Dataset {
        rollouts: parts.iter().map(Part::first).collect(),
        sidecar: sidecar.clone(),
    }
}

/// One recording `rec` from `source` and its import `r` (at `dt`, trimmed
/// by `start`): its usable part split at [`FIT_SHARE`], the first part
/// diagnosed, the swing's centre subtracted.
fn split(
    source: &str,
    rec: &Recording,
    r: &Rollout,
    start: f64,
    dt: f64,
    say: &dyn Fn(&str),
) -> Result<Part> {
    // The longest unbroken stretch between gaps in the time stamps (a
    // tracker's dropped frames; an encoder logged per count stops
    // logging when the swing dies out), up to where the swing dies out
    // in the noise (friction stops a pendulum: a forecast of one at rest
    // shows no dynamics).
    let end = usable_part(rec, rec.t[0] + start, &r.t, dt);
    let (from, n) = (end.from, end.steps);
    let t_start = rec.t[0] + start + end.from_s;
    if let Some(why) = end.said() {
        say(&format!("{source}: {why}"));
    }
    let cut = (FIT_SHARE * n as f64).round() as usize;
    let d = diagnose_first_part(source, rec, t_start, cut, dt, &end)?;
    let centre = d.centre_found();
    let xs: Vec<[f64; 2]> = r.xs[from..from + n]
        .iter()
        .map(|x| [x[0] - centre, x[1]])
        .collect();
    let centred = if centre == 0.0 {
        String::new()
    } else {
        format!(", its swings centred on {centre:+.4} rad (subtracted)")
    };
    say(&format!(
        "{source}: {} ({} turning points){centred}",
        d.verdict, d.turns
    ));
    Ok(Part {
        source: source.to_string(),
        series: Rollout {
            id: r.id,
            t: (0..n).map(|k| k as f64 * dt).collect(),
            xs,
            us: Vec::new(),
        },
        cut,
        diagnosis: d,
        centre,
        end,
    })
}

/// Step 3: the swing diagnosis of `rec` (as recorded) from `t_start` up to
/// `cut` steps of `dt` on, the first part of its usable part `end`; an
/// error says which part that was.
fn diagnose_first_part(
    source: &str,
    rec: &Recording,
    t_start: f64,
    cut: usize,
    dt: f64,
    end: &UsablePart,
) -> Result<SwingDiagnosis> {
    let n = end.steps;
    let t_cut = t_start + cut as f64 * dt;
    let k0 = rec.t.partition_point(|&x| x < t_start);
    let k = rec.t.partition_point(|&x| x < t_cut).max(k0);
    diagnose::diagnose_recording(&rec.t[k0..k], &rec.theta[k0..k]).with_context(|| {
        let used = n as f64 * dt;
        match (&end.gaps, end.at_rest_after_s) {
            (Some(_), _) => format!(
                "{source}: the first {:.0}% of the part used ({}; close the loop on another part: --start, --duration)",
                100.0 * FIT_SHARE,
                end.said().unwrap_or_default()
            ),
            (None, Some(_)) => format!(
                "{source}: the first {:.0}% of the {used:.2} s before its swing is lost in the noise",
                100.0 * FIT_SHARE
            ),
            (None, None) => format!("{source}: the first {:.0}% of it", 100.0 * FIT_SHARE),
        }
    })
}

/// Where a recording's usable part begins and ends.
#[derive(Debug, Clone, Copy)]
pub(super) struct UsablePart {
    /// Its first step on the model's grid.
    pub from: usize,
    /// Where it begins, s after the start.
    pub from_s: f64,
    /// Steps on the model's grid.
    pub steps: usize,
    /// The gaps in the time stamps (`None`: none).
    pub gaps: Option<Gaps>,
    /// Where the swing is lost in the noise, s after the start (`None`:
    /// not before the end or the gap).
    pub at_rest_after_s: Option<f64>,
}

/// Gaps in a recording's time stamps: the loop uses its longest
/// unbroken stretch.
#[derive(Debug, Clone, Copy)]
pub(super) struct Gaps {
    /// How many.
    pub count: usize,
    /// Where the stretch ends, s after the start.
    pub to_s: f64,
}

impl UsablePart {
    /// Where and why the part used is less than the whole recording
    /// (`None`: it is all of it).
    pub fn said(&self) -> Option<String> {
        let gaps = self.gaps.map(|g| {
            format!(
                "{} gap{} in its time stamps: the loop used its longest unbroken stretch, {:.2} to {:.2} s",
                g.count,
                if g.count == 1 { "" } else { "s" },
                self.from_s,
                g.to_s
            )
        });
        let rest = self.at_rest_after_s.map(|t| {
            format!(
                "its swing is lost in the noise after {t:.2} s: the loop used the part before it"
            )
        });
        match (gaps, rest) {
            (Some(g), Some(r)) => Some(format!("{g}; {r}")),
            (g, r) => g.or(r),
        }
    }
}

/// Step 2: the part of `rec` (as recorded, from `t_start`) and of its
/// import on the grid `t` (at `dt`, from 0) that the loop uses: its
/// longest unbroken stretch between gaps in the time stamps, and up to [`AT_REST_AFTER_PERIODS`] after
/// the last turning point above the noise ([`diagnose::swings::swings`])
/// when the recording runs on for longer than that, at rest
/// ([`AT_REST_SCATTER`]). The end is read from the whole recording,
/// held-out part included: like a gap, it says which data can be scored,
/// not what the models learn.
fn usable_part(rec: &Recording, t_start: f64, t: &[f64], dt: f64) -> UsablePart {
    let (stretch, count) = data::longest_unbroken(t, dt);
    let (from, n) = (stretch.start, stretch.len().max(1));
    let from_s = t.get(from).copied().unwrap_or(0.0);
    let to_s = t.get(from + n - 1).copied().unwrap_or(from_s);
    let gaps = (count > 0).then_some(Gaps { count, to_s });
    let t_start = t_start + from_s;
    let t_end = t_start + (to_s - from_s);
    let k0 = rec.t.partition_point(|&x| x < t_start);
    let k1 = rec.t.partition_point(|&x| x <= t_end).max(k0);
    let (ts, thetas) = diagnose::without_glitches(&rec.t[k0..k1], &rec.theta[k0..k1]);
    let rest = diagnose::swings::swings(&ts, &thetas).ok().and_then(|sw| {
        let last = sw.turns.last()?.t;
        let at = last + AT_REST_AFTER_PERIODS * sw.period;
        // The swing finder also stops at a glitch or a slip of phase:
        // at rest only if what follows scatters about its middle by
        // no more than [`AT_REST_SCATTER`] times the noise.
        let k = rec.t.partition_point(|&x| x < at).max(k0);
        let after = rec.theta.get(k..k1).filter(|a| a.len() >= 2)?;
        let mid = trainer_core::metrics::median(&mut after.to_vec());
        let rms =
            (after.iter().map(|v| (v - mid).powi(2)).sum::<f64>() / after.len() as f64).sqrt();
        (at < t_end && rms <= AT_REST_SCATTER * sw.noise).then_some(at - t_start)
    });
    match rest {
        Some(at) => UsablePart {
            from,
            from_s,
            steps: ((at / dt).floor() as usize + 1).min(n),
            gaps,
            at_rest_after_s: Some(from_s + at),
        },
        None => UsablePart {
            from,
            from_s,
            steps: n,
            gaps,
            at_rest_after_s: None,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use trainer_core::physics::{Effect, EffectKind, Pendulum};

    /// 30 s of a 0.85 m rod from 0.3 rad at 25 Hz with `effect`, uniform
    /// noise of +-0.01 rad (seed 1); the recording and its grid.
    fn recorded(effect: Effect) -> (Recording, Vec<f64>, Vec<[f64; 2]>) {
        let dt = 0.04;
        let mut p = Pendulum::new(0.85);
        p.g = 9.81;
        p.effects = vec![effect];
        let xs = p.rollout([0.3, 0.0], 750, dt);
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let t: Vec<f64> = (0..xs.len()).map(|k| k as f64 * dt).collect();
        let theta = xs
            .iter()
            .map(|x| x[0] + rng.random_range(-0.01..0.01))
            .collect();
        let rec = Recording {
            t: t.clone(),
            theta,
            theta_dot: None,
            torque: None,
        };
        (rec, t, xs)
    }

    /// A swing about 0.004 rad off its zero (under the 0.005 a diagnosis
    /// names as an offset, over 4 of its standard errors here) is centred
    /// before it is read; one about its zero is left as it is.
    #[test]
    fn a_swing_off_its_zero_by_less_than_an_offset_named_is_centred() {
        let dt = 0.04;
        for offset in [0.004, 0.0] {
            let (mut rec, t, xs) = recorded(Effect::new(EffectKind::Viscous, 0.02));
            rec.theta.iter_mut().for_each(|a| *a += offset);
            let r = Rollout {
                id: 0,
                t: t.clone(),
                xs: rec.theta.iter().zip(&xs).map(|(a, x)| [*a, x[1]]).collect(),
                us: Vec::new(),
            };
            let part = split("rod", &rec, &r, 0.0, dt, &|_| {}).unwrap();
            let d = &part.diagnosis;
            assert!(
                d.effects.iter().all(|e| e.name != EffectKind::Offset),
                "{d:?}"
            );
            if offset == 0.0 {
                assert_eq!(part.centre, 0.0, "{:?}", d.centre);
            } else {
                assert!(
                    d.centre[0].abs() > trainer_core::diagnose::energy::T_KEEP * d.centre[1],
                    "{:?}",
                    d.centre
                );
                assert!(
                    (part.centre - offset).abs() < 1e-3,
                    "centred by {} where the swing is {offset} off, {:?}",
                    part.centre,
                    d.centre
                );
            }
            assert!((part.series.xs[0][0] - (r.xs[0][0] - part.centre)).abs() < 1e-12);
        }
    }

    /// Frames dropped for 0.3 s at 2 s and for 0.2 s at 5 s of a 30 s
    /// recording: the loop uses the 25 s after the second gap, from its
    /// first step on the grid, and says so; the recording whole, none.
    #[test]
    fn a_gapped_recording_is_used_over_its_longest_stretch() {
        let dt = 0.04;
        let (mut rec, _, _) = recorded(Effect::new(EffectKind::Viscous, 0.02));
        let keep: Vec<usize> = (0..rec.t.len())
            .filter(|&k| !(2.0..2.3).contains(&rec.t[k]) && !(5.0..5.2).contains(&rec.t[k]))
            .collect();
        rec.t = keep.iter().map(|&k| rec.t[k]).collect();
        rec.theta = keep.iter().map(|&k| rec.theta[k]).collect();
        let part = usable_part(&rec, 0.0, &rec.t.clone(), dt);
        let g = part.gaps.expect("two gaps");
        assert_eq!(g.count, 2);
        assert!((part.from_s - 5.2).abs() < 1e-9, "{part:?}");
        assert_eq!(part.from, rec.t.iter().position(|&t| t >= 5.2).unwrap());
        assert_eq!(part.steps, rec.t.len() - part.from);
        assert!((g.to_s - rec.t[rec.t.len() - 1]).abs() < 1e-9);
        let said = part.said().unwrap();
        assert!(
            said.contains("2 gaps") && said.contains("5.20 to 29.96 s"),
            "{said}"
        );
        let (rec, t, _) = recorded(Effect::new(EffectKind::Viscous, 0.02));
        let part = usable_part(&rec, 0.0, &t, dt);
        assert!(part.gaps.is_none() && part.from == 0 && part.said().is_none());
    }

    /// Coulomb friction of 0.19 rad/s^2 stops the rod after about 8 s: the
    /// loop uses the part up to 1.5 periods after the last swing above
    /// the noise, so from two periods before to 1.5 after where the clean
    /// swing falls under the noise (0.01 rad). Light viscous damping
    /// swings to the end: all of it.
    #[test]
    fn a_swing_that_dies_out_is_used_up_to_where_it_does() {
        let dt = 0.04;
        let (rec, t, xs) = recorded(Effect::new(EffectKind::Coulomb, 0.19));
        // Where the clean swing last reaches the noise's size.
        let k_stop = xs.iter().rposition(|x| x[0].abs() > 0.01).unwrap();
        let t_stop = t[k_stop];
        let part = usable_part(&rec, 0.0, &t, dt);
        let at = part.at_rest_after_s.expect("the swing dies out");
        let period = 2.0 * std::f64::consts::PI / (1.5 * 9.81 / 0.85f64).sqrt();
        assert!(
            at > t_stop - 2.0 * period && at < t_stop + 1.5 * period,
            "at rest after {at:.2} s; the clean swing under the noise after {t_stop:.2} s"
        );
        assert_eq!(part.steps, (at / dt).floor() as usize + 1);
        assert!(part.gaps.is_none() && part.from == 0);
        let (rec, t, _) = recorded(Effect::new(EffectKind::Viscous, 0.02));
        let part = usable_part(&rec, 0.0, &t, dt);
        assert!(part.at_rest_after_s.is_none(), "{part:?}");
        assert_eq!(part.steps, t.len());
        // A slip of half a period at 10 s (a tracker that lost frames, or
        // flipped its sign) breaks the alternation of the turning points
        // and stops the swing finder there, but the rod swings on: not at
        // rest.
        let (mut rec, t, _) = recorded(Effect::new(EffectKind::Viscous, 0.02));
        let slip = (0.5 * period / dt).round() as usize;
        let k = (10.0 / dt) as usize;
        let later: Vec<f64> = rec.theta[k + slip..].to_vec();
        rec.theta.truncate(k);
        rec.theta.extend(later);
        rec.t.truncate(rec.theta.len());
        let t = &t[..rec.t.len()];
        let sw = diagnose::swings::swings(&rec.t, &rec.theta).unwrap();
        let last = sw.turns.last().unwrap().t;
        assert!(
            last < 12.0,
            "the finder went on past the slip, to {last:.2} s"
        );
        let part = usable_part(&rec, 0.0, t, dt);
        assert!(part.at_rest_after_s.is_none(), "{part:?}");
        assert_eq!(part.steps, t.len());
    }
}
