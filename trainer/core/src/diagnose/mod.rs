//! `koopman diagnose`: which physical effect a recording's swings show,
//! and the length its period gives, for the declared rig.
//!
//! The one diagnosis is the swings' ([`swings`], then [`energy`]): the
//! turning points, each measured by a fit of one period of samples (no
//! rate or acceleration is differentiated from the data), the energy lost
//! between them against the candidate dissipations, the centres for a
//! sensor offset, and a verdict: `none`, `explained` or `unexplained`.
//!
//! **The length.** The turning points' spacing gives the free small
//! swing's `w0` ([`energy::free_w`]). The motion fixes only the
//! equivalent simple length `l_eq = g / w0^2`; the declared rig says
//! which length that is ([`crate::physics::Rig`]: a string's `L = l_eq`,
//! a rod's `L = 3 l_eq / 2`), and the declared `g` scales it. Without a
//! declared `g` the length is read at the protocol's ([`G`]) and says so.

use anyhow::Result;
use serde::Serialize;

pub mod energy;
pub mod swings;

use crate::physics::{EffectKind, Rig, RigPhysics};
use crate::protocol::G;

/// The gravity lengths are read at: declared by the user, or the
/// protocol's, said so wherever a length is printed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Gravity {
    /// m/s^2.
    pub g: f64,
    /// Whether the user declared it (else it is the protocol's [`G`]).
    pub declared: bool,
}

impl Gravity {
    /// `Some(g)`: declared; `None`: the protocol's. A declared `g` must be
    /// finite and positive.
    pub fn declared_or_protocol(g: Option<f64>) -> Result<Gravity> {
        match g {
            Some(g) => {
                anyhow::ensure!(
                    g.is_finite() && g > 0.0,
                    "--g must be a positive number of m/s^2 (Earth: 9.81), not {g}"
                );
                Ok(Gravity { g, declared: true })
            }
            None => Ok(Gravity {
                g: G,
                declared: false,
            }),
        }
    }

    /// How the lengths are read, in words.
    pub fn note(&self) -> String {
        if self.declared {
            format!("lengths read at the declared g = {} m/s^2", self.g)
        } else {
            format!(
                "g not declared: lengths read at the protocol's g = {} m/s^2 (give --g, e.g. 9.81 on Earth; a length scales with g)",
                self.g
            )
        }
    }
}

/// The length a recording's period gives.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PeriodLength {
    /// The rig the length is read for.
    pub rig: Rig,
    /// The rig's length, m: what the motion says for `rig`.
    pub length_m: f64,
    /// The equivalent simple length `g / w0^2`, m: all the motion fixes.
    pub simple_length_m: f64,
    /// The gravity it was read at.
    pub gravity: Gravity,
}

impl PeriodLength {
    /// The length of `rig` whose free small swing has `w0 = w` under
    /// `gravity`; `None` unless `w` is finite and positive.
    pub fn from_w(rig: Rig, w: f64, gravity: Gravity) -> Option<PeriodLength> {
        (w.is_finite() && w > 0.0).then(|| PeriodLength {
            rig,
            length_m: rig.length(gravity.g, w * w),
            simple_length_m: Rig::Simple.length(gravity.g, w * w),
            gravity,
        })
    }
}

/// The swing diagnosis of one recording.
#[derive(Debug, Clone, Serialize)]
pub struct RecordingSwings {
    /// Where it came from.
    pub source: String,
    /// What the swings say, when they could be measured.
    pub diagnosis: Option<energy::SwingDiagnosis>,
    /// The length its period gives, with the diagnosis.
    pub length: Option<PeriodLength>,
    /// The quality factor at the last swing, from the dissipation named
    /// ([`crate::physics::quality::q_of`]; `None` where none is named).
    pub q_factor: Option<f64>,
    /// Why there is no diagnosis, otherwise.
    pub error: Option<String>,
}

/// One effect over the recordings: how many named it, and the median of
/// their coefficients.
#[derive(Debug, Clone, Serialize)]
pub struct Named {
    /// Which.
    pub name: EffectKind,
    /// Recordings that named it.
    pub recordings: usize,
    /// The median of their coefficients, in the effect's unit.
    pub coefficient: f64,
    /// Its unit.
    pub unit: &'static str,
}

/// What `diagnose` found: the verdict over the recordings, then each.
#[derive(Debug, Clone, Serialize)]
pub struct Diagnosis {
    /// `none`, `explained` or `unexplained`: the recordings' verdicts
    /// combined, the strongest winning (`unexplained` over `explained`
    /// over `none`); a single recording's is its own.
    pub verdict: String,
    /// The effects named, each with how many recordings named it.
    pub effects: Vec<Named>,
    /// The rig the lengths are read for.
    pub rig: Rig,
    /// The gravity they are read at.
    pub gravity: Gravity,
    /// Recordings diagnosed, of those read.
    pub diagnosed: [usize; 2],
    /// Per recording.
    pub recordings: Vec<RecordingSwings>,
    /// How it was decided, in words.
    pub criterion: String,
    /// How to read the lengths, in words.
    pub length_note: String,
}

/// The swing diagnosis of a recording's angle at its own time stamps,
/// a tracker's single-frame spikes left out ([`without_glitches`]).
pub fn diagnose_recording(t: &[f64], theta: &[f64]) -> Result<energy::SwingDiagnosis> {
    let (t, theta) = without_glitches(t, theta);
    energy::diagnose_swings(&swings::swings(&t, &theta)?)
}

/// A recording's samples that are no glitch (the import's test,
/// [`crate::data::import::glitches`]): a spike of half a radian on a
/// swing of a tenth would set the swing's size the turning points are
/// looked for at.
pub fn without_glitches(t: &[f64], theta: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let glitch = crate::data::import::glitches(t, theta);
    t.iter()
        .zip(theta)
        .zip(&glitch)
        .filter(|(_, g)| !**g)
        .map(|((t, v), _)| (*t, *v))
        .unzip()
}

/// The swing diagnosis and period length of one `(source, recording)`.
pub fn diagnose_one(
    source: &str,
    rec: &crate::data::import::Recording,
    rig: Rig,
    gravity: Gravity,
) -> RecordingSwings {
    match diagnose_recording(&rec.t, &rec.theta) {
        Ok(d) => RecordingSwings {
            source: source.to_string(),
            length: PeriodLength::from_w(rig, d.w, gravity),
            q_factor: q_factor(&d),
            diagnosis: Some(d),
            error: None,
        },
        Err(e) => RecordingSwings {
            source: source.to_string(),
            diagnosis: None,
            length: None,
            q_factor: None,
            error: Some(format!("{e:#}")),
        },
    }
}

/// The quality factor at the diagnosis's last amplitude from the
/// dissipation it names; `None` where it names none.
pub fn q_factor(d: &energy::SwingDiagnosis) -> Option<f64> {
    let effects: Vec<crate::physics::Effect> = d
        .effects
        .iter()
        .filter(|t| {
            matches!(
                t.name,
                EffectKind::Viscous | EffectKind::Drag | EffectKind::Coulomb
            )
        })
        .map(|t| crate::physics::Effect::new(t.name, t.coefficient))
        .collect();
    let q = crate::physics::quality::q_of(&effects, d.w, d.amplitude[1]);
    (!effects.is_empty() && q.is_finite() && q > 0.0).then_some(q)
}

/// Diagnoses every recording and combines their verdicts; an error when
/// none of them could be diagnosed, naming each and why.
pub fn diagnose(
    recs: &[(String, crate::data::import::Recording)],
    rig: Rig,
    gravity: Gravity,
) -> Result<Diagnosis> {
    let recordings: Vec<RecordingSwings> = recs
        .iter()
        .map(|(source, rec)| diagnose_one(source, rec, rig, gravity))
        .collect();
    let done: Vec<&energy::SwingDiagnosis> = recordings
        .iter()
        .filter_map(|r| r.diagnosis.as_ref())
        .collect();
    if done.is_empty() {
        let why: Vec<String> = recordings
            .iter()
            .map(|r| format!("{}: {}", r.source, r.error.as_deref().unwrap_or("?")))
            .collect();
        anyhow::bail!(
            "no recording's swings could be diagnosed: {}",
            why.join("; ")
        );
    }
    let rank = |v: &str| match v {
        "unexplained" => 2,
        "explained" => 1,
        _ => 0,
    };
    let verdict = done
        .iter()
        .map(|d| d.verdict.as_str())
        .max_by_key(|v| rank(v))
        .unwrap_or("none")
        .to_string();
    let effects = EffectKind::ALL
        .iter()
        .filter_map(|&k| {
            let mut cs: Vec<f64> = done
                .iter()
                .flat_map(|d| d.effects.iter())
                .filter(|e| e.name == k)
                .map(|e| e.coefficient)
                .collect();
            (!cs.is_empty()).then(|| Named {
                name: k,
                recordings: cs.len(),
                coefficient: crate::metrics::median(&mut cs),
                unit: k.unit(),
            })
        })
        .collect();
    Ok(Diagnosis {
        verdict,
        effects,
        rig,
        gravity,
        diagnosed: [done.len(), recordings.len()],
        criterion: done
            .first()
            .map(|d| d.criterion.clone())
            .unwrap_or_default(),
        length_note: length_note(rig, gravity),
        recordings,
    })
}

/// How a printed length is to be read, in words.
pub fn length_note(rig: Rig, gravity: Gravity) -> String {
    format!(
        "The motion fixes only the equivalent simple length g / w0^2; the {} is that length converted for the declared rig ({rig}; --rig simple for a bob on a string, rod for a uniform rod); {}",
        rig.length_label(),
        gravity.note()
    )
}

/// The diagnosis as lines for the terminal: the verdict first, then each
/// recording.
pub fn summary(d: &Diagnosis) -> String {
    let mut s = format!("verdict: {}", d.verdict);
    if !d.effects.is_empty() {
        let named: Vec<String> = d
            .effects
            .iter()
            .map(|e| {
                format!(
                    "{} {:.5} {} ({} of {})",
                    e.name, e.coefficient, e.unit, e.recordings, d.diagnosed[0]
                )
            })
            .collect();
        s.push_str(&format!(" ({})", named.join(", ")));
    }
    s.push('\n');
    for r in &d.recordings {
        match (&r.diagnosis, &r.error) {
            (Some(x), _) => {
                s.push_str(&format!(
                    "{}: {} ({} turning points, amplitude {:.3} -> {:.3} rad, noise {:.4} rad, w0 {:.4} rad/s",
                    r.source, x.verdict, x.turns, x.amplitude[0], x.amplitude[1], x.noise, x.w
                ));
                if let Some(l) = &r.length {
                    s.push_str(&format!(
                        ", {} {:.4}, g / w0^2 {:.4} m",
                        l.rig.length_label(),
                        l.length_m,
                        l.simple_length_m
                    ));
                }
                if let Some(q) = r.q_factor {
                    s.push_str(&format!(", Q {q:.0} at {:.3} rad", x.amplitude[1]));
                }
                s.push_str(")\n");
                for e in &x.effects {
                    s.push_str(&format!(
                        "  {} {:.5} {} (95% CI {:.5} .. {:.5})\n",
                        e.name,
                        e.coefficient,
                        e.name.unit(),
                        e.ci[0],
                        e.ci[1]
                    ));
                }
            }
            (None, Some(e)) => s.push_str(&format!("{}: no swing diagnosis: {e}\n", r.source)),
            (None, None) => {}
        }
    }
    s.push_str(&format!("({})\n", d.length_note));
    s
}

/// Writes `diagnosis.json` into `dir`.
pub fn write(dir: &std::path::Path, d: &Diagnosis) -> Result<()> {
    std::fs::create_dir_all(dir)?;
    crate::io::write_atomic(
        &dir.join("diagnosis.json"),
        serde_json::to_string_pretty(d)?.as_bytes(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::Pendulum;

    /// Simulated free swings of each rig at 0.1 to 1.5 m, g = 9.81: the
    /// diagnosis reads the rig's length. Released at 0.3 rad, sampled at
    /// 50 Hz for 40 s, clean: the only errors are the window fits' and the
    /// amplitude correction of `free_w`, which `docs/diagnosis.md` puts
    /// well under 0.1%; the bar is the 0.5%.
    #[test]
    fn the_period_gives_the_rigs_length_within_half_a_percent() {
        let gravity = Gravity::declared_or_protocol(Some(9.81)).unwrap();
        let mut worst = 0.0f64;
        for rig in Rig::ALL {
            for l in [0.1, 0.2, 0.35, 0.5, 0.75, 1.0, 1.25, 1.5] {
                let mut p = Pendulum::of(rig, l);
                p.g = 9.81;
                let dt = 0.02;
                let xs = p.rollout([0.3, 0.0], 2000, dt);
                let rec = crate::data::import::Recording {
                    t: (0..xs.len()).map(|k| k as f64 * dt).collect(),
                    theta: xs.iter().map(|x| x[0]).collect(),
                    theta_dot: None,
                    torque: None,
                };
                let d = diagnose(&[("sim".into(), rec)], rig, gravity).unwrap();
                let got = d.recordings[0].length.unwrap();
                worst = worst.max((got.length_m - l).abs() / l);
                assert!(
                    (got.length_m - l).abs() < 0.005 * l,
                    "{rig} {l} m: read {}",
                    got.length_m
                );
                assert_eq!(got.rig, rig);
                // The equivalent simple length is the rig's converted.
                assert!((got.simple_length_m - rig.simple_per_length() * l).abs() < 0.005 * l);
            }
        }
        eprintln!("worst relative error of the period's length: {worst:.2e}");
    }

    /// A 0.6 m string swinging 0.15 rad at 30 Hz for 30 s, with three
    /// single-frame spikes of 0.5 rad (a tracker's): diagnosed as without
    /// them, `w` within 1e-3. Left in, they would set the swing's size
    /// the turning points are looked for at above the swing.
    #[test]
    fn a_trackers_spikes_are_left_out_of_the_diagnosis() {
        let mut p = Pendulum::of(Rig::Simple, 0.6);
        p.g = 9.81;
        let dt = 1.0 / 30.0;
        let xs = p.rollout([0.15, 0.0], 900, dt);
        let t: Vec<f64> = (0..xs.len()).map(|k| k as f64 * dt).collect();
        let clean: Vec<f64> = xs.iter().map(|x| x[0]).collect();
        let mut spiked = clean.clone();
        for k in [200, 451, 700] {
            spiked[k] += 0.5;
        }
        let a = diagnose_recording(&t, &clean).unwrap();
        let b = diagnose_recording(&t, &spiked).unwrap();
        assert!((a.w - b.w).abs() < 1e-3 * a.w, "{} {}", a.w, b.w);
        assert_eq!(without_glitches(&t, &spiked).0.len(), t.len() - 3);
    }

    #[test]
    fn an_undeclared_g_is_the_protocols_and_says_so() {
        let g = Gravity::declared_or_protocol(None).unwrap();
        assert!(!g.declared && g.g == G);
        assert!(g.note().contains("not declared"), "{}", g.note());
        assert!(Gravity::declared_or_protocol(Some(0.0)).is_err());
        assert!(Gravity::declared_or_protocol(Some(f64::NAN)).is_err());
    }
}
