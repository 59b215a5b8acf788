//! Data sets: generation per the protocol, the CSV layout
//! `rollout,t,theta,theta_dot` (the same for measured data), and each
//! rollout's true parameters in a JSON sidecar beside the CSV.

use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::fmt;
use std::path::{Path, PathBuf};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::io::write_atomic;
use crate::sim::{DT, Effect, Pendulum};

/// Observations per rollout (protocol: 128).
pub const ROLLOUT_LEN: usize = 128;
/// The protocol's test lengths.
pub const TEST_LENGTHS: [f64; 5] = [0.5, 1.0, 2.0, 3.5, 5.0];
/// Test rollouts per length.
pub const TEST_PER_LENGTH: usize = 10;
/// The CSV header line.
pub const CSV_HEADER: &str = "rollout,t,theta,theta_dot";

/// One rollout's ground truth, as the sidecar stores it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RolloutMeta {
    /// Id as in the CSV's `rollout` column.
    pub rollout: u32,
    /// Rod length, m.
    pub length: f64,
    /// Initial angle, rad.
    pub theta0: f64,
    /// Undeclared effects present, name -> coefficient.
    #[serde(default)]
    pub effects: BTreeMap<String, f64>,
}

/// The JSON sidecar of a CSV.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Sidecar {
    /// `"train"`, `"test"` or `"measured"`.
    pub set: String,
    /// Seed the set was drawn with (None for measured data).
    pub seed: Option<u64>,
    /// Observation interval, s.
    pub dt: f64,
    /// Truth per rollout.
    pub rollouts: Vec<RolloutMeta>,
}

/// A rollout's observations.
#[derive(Debug, Clone, PartialEq)]
pub struct Rollout {
    /// Id as in the CSV.
    pub id: u32,
    /// Times, s.
    pub t: Vec<f64>,
    /// `(theta, theta_dot)` per observation.
    pub xs: Vec<[f64; 2]>,
}

/// Rollouts with their truth (when known).
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    /// The observations.
    pub rollouts: Vec<Rollout>,
    /// Truth and provenance.
    pub sidecar: Sidecar,
}

impl Dataset {
    /// The truth of rollout `id`, if the sidecar has it.
    pub fn meta(&self, id: u32) -> Option<&RolloutMeta> {
        self.sidecar.rollouts.iter().find(|m| m.rollout == id)
    }
}

/// The physical constants a data set is simulated with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Physics {
    /// Gravity, m/s^2.
    pub g: f64,
    /// Observation interval, s.
    pub dt: f64,
}

impl Physics {
    /// The protocol's: `g = 10`, `dt = 0.05`.
    pub const PROTOCOL: Physics = Physics {
        g: crate::sim::G,
        dt: DT,
    };
}

/// One rollout to simulate: length, initial angle, its effects.
type Spec = (f64, f64, Vec<Effect>);

fn make(set: &str, seed: u64, specs: Vec<Spec>, physics: Physics) -> Dataset {
    let mut rollouts = Vec::new();
    let mut metas = Vec::new();
    let dt = physics.dt;
    for (id, (length, theta0, effects)) in specs.into_iter().enumerate() {
        let mut p = Pendulum::new(length);
        p.g = physics.g;
        p.effects = effects.clone();
        let xs = p.rollout([theta0, 0.0], ROLLOUT_LEN, dt);
        let t = (0..ROLLOUT_LEN).map(|k| k as f64 * dt).collect();
        rollouts.push(Rollout {
            id: id as u32,
            t,
            xs,
        });
        metas.push(RolloutMeta {
            rollout: id as u32,
            length,
            theta0,
            effects: effects
                .iter()
                .map(|e| (e.name().to_string(), e.coefficient()))
                .collect(),
        });
    }
    Dataset {
        rollouts,
        sidecar: Sidecar {
            set: set.into(),
            seed: Some(seed),
            dt,
            rollouts: metas,
        },
    }
}

/// The training set: `per_length` rollouts at each length, `theta_0`
/// uniform in `[pi/2, 0.9 pi]`, drawn from ChaCha8 seeded with `seed`.
pub fn training_set(seed: u64, lengths: &[f64], per_length: usize, effects: &[Effect]) -> Dataset {
    training_set_with(
        seed,
        lengths,
        per_length,
        effects,
        Physics::PROTOCOL,
        [PI / 2.0, 0.9 * PI],
        None,
    )
}

/// A training set with other constants: `theta_0` uniform in `theta0`, and,
/// with `varied`, one more effect whose coefficient is drawn per rollout
/// (after its `theta_0`, from the same generator) uniformly in its range.
pub fn training_set_with(
    seed: u64,
    lengths: &[f64],
    per_length: usize,
    effects: &[Effect],
    physics: Physics,
    theta0: [f64; 2],
    varied: Option<&crate::config::EffectRange>,
) -> Dataset {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut specs = Vec::new();
    for &l in lengths {
        for _ in 0..per_length {
            let th = rng.random_range(theta0[0]..=theta0[1]);
            let mut e = effects.to_vec();
            if let Some(v) = varied {
                e.push(v.at(rng.random_range(v.range[0]..=v.range[1])));
            }
            specs.push((l, th, e));
        }
    }
    make("train", seed, specs, physics)
}

/// The test set: 10 rollouts per test length, `theta_0 = pi/2 + k 0.4 pi / 9`.
pub fn test_set(seed: u64, lengths: &[f64], effects: &[Effect]) -> Dataset {
    let mut specs = Vec::new();
    for &l in lengths {
        for k in 0..TEST_PER_LENGTH {
            specs.push((l, PI / 2.0 + k as f64 * 0.4 * PI / 9.0, effects.to_vec()));
        }
    }
    make("test", seed, specs, Physics::PROTOCOL)
}

/// The CSV text of a data set.
pub fn to_csv(ds: &Dataset) -> String {
    let mut s = String::with_capacity(ds.rollouts.len() * ROLLOUT_LEN * 48);
    s.push_str(CSV_HEADER);
    s.push('\n');
    for r in &ds.rollouts {
        for (t, x) in r.t.iter().zip(&r.xs) {
            s.push_str(&format!("{},{:.6},{},{}\n", r.id, t, x[0], x[1]));
        }
    }
    s
}

/// Sidecar path of a CSV: the same stem with `.json`.
pub fn sidecar_path(csv: &Path) -> PathBuf {
    csv.with_extension("json")
}

/// Writes `NAME.csv` and `NAME.json` in `dir`, atomically each.
pub fn write(ds: &Dataset, dir: &Path, name: &str) -> anyhow::Result<PathBuf> {
    std::fs::create_dir_all(dir)?;
    let csv = dir.join(format!("{name}.csv"));
    write_atomic(&csv, to_csv(ds).as_bytes())?;
    write_atomic(
        &sidecar_path(&csv),
        serde_json::to_string_pretty(&ds.sidecar)?.as_bytes(),
    )?;
    Ok(csv)
}

/// A CSV problem, naming the file and line (1-based).
#[derive(Debug, Clone, PartialEq)]
pub struct CsvError {
    /// The file.
    pub path: PathBuf,
    /// 1-based line, 0 when the problem is the whole file.
    pub line: usize,
    /// What is wrong.
    pub problem: String,
}

impl fmt::Display for CsvError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line == 0 {
            write!(f, "{}: {}", self.path.display(), self.problem)
        } else {
            write!(f, "{}:{}: {}", self.path.display(), self.line, self.problem)
        }
    }
}

impl std::error::Error for CsvError {}

/// Parses the project's CSV. Rows of one rollout must be contiguous with
/// increasing `t`; every value finite; each rollout at least `min_rows`.
pub fn parse_csv(path: &Path, text: &str, min_rows: usize) -> Result<Vec<Rollout>, CsvError> {
    let err = |line: usize, problem: String| CsvError {
        path: path.to_path_buf(),
        line,
        problem,
    };
    let mut lines = text.lines().enumerate();
    let Some((_, header)) = lines.next() else {
        return Err(err(
            0,
            "empty file (expected header `rollout,t,theta,theta_dot`)".into(),
        ));
    };
    let cols: Vec<&str> = header.split(',').map(str::trim).collect();
    if cols != ["rollout", "t", "theta", "theta_dot"] {
        return Err(err(
            1,
            format!("header is {header:?}, expected {CSV_HEADER:?}"),
        ));
    }
    let mut out: Vec<Rollout> = Vec::new();
    for (i, line) in lines {
        let n = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if f.len() != 4 {
            return Err(err(n, format!("expected 4 columns, found {}", f.len())));
        }
        let id: u32 = f[0]
            .parse()
            .map_err(|_| err(n, format!("rollout {:?} is not an id", f[0])))?;
        let mut v = [0.0f64; 3];
        for (k, name) in ["t", "theta", "theta_dot"].iter().enumerate() {
            let x: f64 = f[k + 1]
                .parse()
                .map_err(|_| err(n, format!("{name} {:?} is not a number", f[k + 1])))?;
            if !x.is_finite() {
                return Err(err(n, format!("{name} is {x}, not a finite number")));
            }
            v[k] = x;
        }
        match out.last_mut() {
            Some(r) if r.id == id => {
                if let Some(&last) = r.t.last()
                    && v[0] <= last
                {
                    return Err(err(
                        n,
                        format!("t {} does not increase (previous {last})", v[0]),
                    ));
                }
                r.t.push(v[0]);
                r.xs.push([v[1], v[2]]);
            }
            _ => {
                if out.iter().any(|r| r.id == id) {
                    return Err(err(
                        n,
                        format!("rollout {id} appears again after another rollout"),
                    ));
                }
                out.push(Rollout {
                    id,
                    t: vec![v[0]],
                    xs: vec![[v[1], v[2]]],
                });
            }
        }
    }
    if out.is_empty() {
        return Err(err(0, "no data rows".into()));
    }
    if let Some(r) = out.iter().find(|r| r.xs.len() < min_rows) {
        return Err(err(
            0,
            format!(
                "rollout {} has {} rows, at least {min_rows} needed",
                r.id,
                r.xs.len()
            ),
        ));
    }
    Ok(out)
}

/// Reads a CSV and its sidecar (a sidecar is optional for measured data).
pub fn read(path: &Path, min_rows: usize) -> anyhow::Result<Dataset> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| anyhow::anyhow!("{}: cannot read: {e}", path.display()))?;
    let rollouts = parse_csv(path, &text, min_rows)?;
    let sc = sidecar_path(path);
    let sidecar = if sc.exists() {
        let s = std::fs::read_to_string(&sc)?;
        serde_json::from_str(&s).map_err(|e| anyhow::anyhow!("{}: {e}", sc.display()))?
    } else {
        let dt = rollouts
            .first()
            .and_then(|r| r.t.get(1).zip(r.t.first()).map(|(b, a)| b - a))
            .unwrap_or(DT);
        Sidecar {
            set: "measured".into(),
            seed: None,
            dt,
            rollouts: Vec::new(),
        }
    };
    Ok(Dataset { rollouts, sidecar })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_round_trips() {
        let ds = test_set(1, &[2.0], &[]);
        let text = to_csv(&ds);
        let back = parse_csv(Path::new("x.csv"), &text, 2).unwrap();
        assert_eq!(back.len(), 10);
        // f64 Display is the shortest string that parses back to the same bits.
        assert_eq!(back[3].xs, ds.rollouts[3].xs);
    }

    #[test]
    fn broken_lines_are_named() {
        let p = Path::new("d.csv");
        let cases = [
            ("", 0, "empty"),
            ("rollout,t,theta\n", 1, "header"),
            ("rollout,t,theta,theta_dot\n0,0,1\n", 2, "columns"),
            (
                "rollout,t,theta,theta_dot\n0,0,1,2\n0,0.05,abc,2\n",
                3,
                "not a number",
            ),
            (
                "rollout,t,theta,theta_dot\n0,0,1,2\n0,0.05,NaN,2\n",
                3,
                "finite",
            ),
            (
                "rollout,t,theta,theta_dot\n0,0,1,2\n0,0.1,1,2\n0,0.05,1,2\n",
                4,
                "increase",
            ),
            ("rollout,t,theta,theta_dot\n0,0,1,2\n", 0, "rows"),
        ];
        for (text, line, word) in cases {
            let e = parse_csv(p, text, 2).unwrap_err();
            assert_eq!(e.line, line, "{text:?}: {e}");
            assert!(e.to_string().contains(word), "{e}");
            assert!(e.to_string().starts_with("d.csv"), "{e}");
        }
    }

    #[test]
    fn training_set_is_seeded() {
        let a = training_set(7, &[2.0, 5.0], 3, &[]);
        let b = training_set(7, &[2.0, 5.0], 3, &[]);
        let c = training_set(8, &[2.0, 5.0], 3, &[]);
        assert_eq!(to_csv(&a), to_csv(&b));
        assert_ne!(to_csv(&a), to_csv(&c));
        for m in &a.sidecar.rollouts {
            assert!((PI / 2.0..=0.9 * PI).contains(&m.theta0));
        }
    }

    #[test]
    fn constants_and_a_varied_effect_reach_the_data() {
        let varied = crate::config::EffectRange::parse("viscous:0.1..0.3").unwrap();
        let physics = Physics { g: 9.81, dt: 0.02 };
        let ds = training_set_with(3, &[0.13], 6, &[], physics, [0.5, 1.0], Some(&varied));
        assert_eq!(ds.sidecar.dt, 0.02);
        assert!((ds.rollouts[0].t[1] - 0.02).abs() < 1e-12);
        let mut cs = Vec::new();
        for (r, m) in ds.rollouts.iter().zip(&ds.sidecar.rollouts) {
            assert!((0.5..=1.0).contains(&m.theta0));
            let c = m.effects["viscous"];
            assert!((0.1..=0.3).contains(&c), "{c}");
            cs.push(c);
            // Damped: the energy falls over the rollout.
            let e = |x: [f64; 2]| 0.5 * x[1] * x[1] + 1.5 * 9.81 / 0.13 * (1.0 - x[0].cos());
            assert!(e(r.xs[127]) < 0.9 * e(r.xs[0]));
        }
        assert!(
            cs.windows(2).any(|w| w[0] != w[1]),
            "one coefficient for all: {cs:?}"
        );
        // Without the varied effect the protocol's stream is unchanged.
        let a = training_set(7, &[2.0, 5.0], 3, &[]);
        let b = training_set_with(
            7,
            &[2.0, 5.0],
            3,
            &[],
            Physics::PROTOCOL,
            [PI / 2.0, 0.9 * PI],
            None,
        );
        assert_eq!(a, b);
    }
}
