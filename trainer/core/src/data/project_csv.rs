//! The project's CSV, `rollout,t,theta,theta_dot` (simulated and imported
//! data alike), with a fifth column `u` for a driven pendulum (the torque,
//! N m, held from the row to the next, as the protocol writes it), and its
//! JSON sidecar of each rollout's truth (and, for an import, of how each
//! recording was sampled: `sources`).

use std::path::{Path, PathBuf};

use super::table::{CsvError, Table};
use super::{Dataset, Rollout, Sidecar, SourceMeta};
use crate::io::write_atomic;
use crate::protocol::{DT, ROLLOUT_LEN};

/// The CSV header line.
pub const CSV_HEADER: &str = "rollout,t,theta,theta_dot";
/// The CSV header line of a driven set.
pub const CSV_HEADER_DRIVEN: &str = "rollout,t,theta,theta_dot,u";

/// The CSV text of a data set: with the `u` column where any rollout has
/// torques.
pub fn to_csv(ds: &Dataset) -> String {
    let driven = ds.rollouts.iter().any(|r| !r.us.is_empty());
    let mut s = String::with_capacity(ds.rollouts.len() * ROLLOUT_LEN * 48);
    s.push_str(if driven {
        CSV_HEADER_DRIVEN
    } else {
        CSV_HEADER
    });
    s.push('\n');
    for r in &ds.rollouts {
        for (k, (t, x)) in r.t.iter().zip(&r.xs).enumerate() {
            s.push_str(&format!("{},{:.6},{},{}", r.id, t, x[0], x[1]));
            if driven {
                s.push_str(&format!(",{}", r.u(k)));
            }
            s.push('\n');
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
    write_imported(ds, &[], dir, name)
}

/// A sidecar with how each imported recording was sampled (none: the
/// sidecar as it is).
#[derive(serde::Serialize)]
struct WithSources<'a> {
    #[serde(flatten)]
    sidecar: &'a Sidecar,
    #[serde(skip_serializing_if = "<[SourceMeta]>::is_empty")]
    sources: &'a [SourceMeta],
}

/// [`write`], the sidecar holding `sources` too (as [`read_sources`]
/// reads them).
pub fn write_imported(
    ds: &Dataset,
    sources: &[SourceMeta],
    dir: &Path,
    name: &str,
) -> anyhow::Result<PathBuf> {
    std::fs::create_dir_all(dir)?;
    let csv = dir.join(format!("{name}.csv"));
    write_atomic(&csv, to_csv(ds).as_bytes())?;
    let sidecar = WithSources {
        sidecar: &ds.sidecar,
        sources,
    };
    write_atomic(
        &sidecar_path(&csv),
        serde_json::to_string_pretty(&sidecar)?.as_bytes(),
    )?;
    Ok(csv)
}

/// What [`read_sources`] reads of a sidecar.
#[derive(serde::Deserialize)]
struct SourcesOnly {
    #[serde(default)]
    sources: Vec<SourceMeta>,
}

/// How each rollout of the CSV at `path` was sampled before its import,
/// as its sidecar records (none without a sidecar, or from a sidecar
/// written before the import recorded it).
pub fn read_sources(path: &Path) -> anyhow::Result<Vec<SourceMeta>> {
    let sc = sidecar_path(path);
    if !sc.exists() {
        return Ok(Vec::new());
    }
    let s = std::fs::read_to_string(&sc)?;
    let only: SourcesOnly =
        serde_json::from_str(&s).map_err(|e| anyhow::anyhow!("{}: {e}", sc.display()))?;
    Ok(only.sources)
}

/// Parses the project's CSV from its [`Table`]. Rows of one rollout must be
/// contiguous with increasing `t`; every value finite; each rollout at
/// least `min_rows`.
pub fn parse_csv(table: &Table, min_rows: usize) -> Result<Vec<Rollout>, CsvError> {
    let driven = match table.header.as_slice() {
        [a, b, c, d] if [a, b, c, d] == ["rollout", "t", "theta", "theta_dot"] => false,
        [a, b, c, d, e] if [a, b, c, d, e] == ["rollout", "t", "theta", "theta_dot", "u"] => true,
        _ => {
            return Err(table.error(
                1,
                format!(
                    "header is {:?}, expected {CSV_HEADER:?} or {CSV_HEADER_DRIVEN:?}",
                    table.header.join(",")
                ),
            ));
        }
    };
    let columns = if driven { 5 } else { 4 };
    let mut out: Vec<Rollout> = Vec::new();
    if let Some((row, n)) = table.ragged() {
        return Err(table.error(
            table.line(row),
            format!("expected {columns} columns, found {n}"),
        ));
    }
    for row in 0..table.len() {
        let n = table.line(row);
        let id = table.value(row, 0, "rollout")?;
        let id: u32 = id
            .filter(|v| v.fract() == 0.0 && (0.0..=f64::from(u32::MAX)).contains(v))
            .map(|v| v as u32)
            .ok_or_else(|| table.error(n, format!("rollout {id:?} is not an id")))?;
        let v = [
            table.number(row, 1, "t")?,
            table.number(row, 2, "theta")?,
            table.number(row, 3, "theta_dot")?,
        ];
        match out.last_mut() {
            Some(r) if r.id == id => {
                if let Some(&last) = r.t.last()
                    && v[0] <= last
                {
                    return Err(
                        table.error(n, format!("t {} does not increase (previous {last})", v[0]))
                    );
                }
                r.t.push(v[0]);
                r.xs.push([v[1], v[2]]);
                if driven {
                    r.us.push(table.number(row, 4, "u")?);
                }
            }
            _ => {
                if out.iter().any(|r| r.id == id) {
                    return Err(table.error(
                        n,
                        format!("rollout {id} appears again after another rollout"),
                    ));
                }
                let us = if driven {
                    vec![table.number(row, 4, "u")?]
                } else {
                    Vec::new()
                };
                out.push(Rollout {
                    id,
                    t: vec![v[0]],
                    xs: vec![[v[1], v[2]]],
                    us,
                });
            }
        }
    }
    if out.is_empty() {
        return Err(table.error(0, "no data rows"));
    }
    if let Some(r) = out.iter().find(|r| r.xs.len() < min_rows) {
        return Err(table.error(
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
    let rollouts = parse_csv(&Table::read(path)?, min_rows)?;
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
            rig: None,
            rollouts: Vec::new(),
        }
    };
    Ok(Dataset { rollouts, sidecar })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::test_set;

    #[test]
    fn csv_round_trips() {
        let ds = test_set(1, &[2.0], &[]);
        let text = to_csv(&ds);
        let back = parse_csv(&Table::parse(Path::new("x.csv"), &text).unwrap(), 2).unwrap();
        assert_eq!(back.len(), 10);
        // f64 Display is the shortest string that parses back to the same bits.
        assert_eq!(back[3].xs, ds.rollouts[3].xs);
    }

    #[test]
    fn an_imports_sources_round_trip_and_other_sidecars_stay_as_they_were() {
        let dir = std::env::temp_dir().join(format!("sources-{}", std::process::id()));
        let ds = test_set(1, &[2.0], &[]);
        // Without sources, the sidecar as it is, byte for byte.
        let csv = write(&ds, &dir, "plain").unwrap();
        let text = std::fs::read_to_string(sidecar_path(&csv)).unwrap();
        assert_eq!(text, serde_json::to_string_pretty(&ds.sidecar).unwrap());
        // A sidecar without them (as written before) reads none.
        assert!(read_sources(&csv).unwrap().is_empty());
        assert!(read_sources(&dir.join("absent.csv")).unwrap().is_empty());
        let sources = [SourceMeta {
            rollout: 3,
            median_interval: 0.083,
            largest_gap: 0.25,
            interpolated: true,
            glitches: 2,
            reordered: 12,
            angle_from: "integrated from the rate".into(),
        }];
        let csv = write_imported(&ds, &sources, &dir, "imported").unwrap();
        assert_eq!(read_sources(&csv).unwrap(), sources);
        assert_eq!(read(&csv, 2).unwrap().sidecar.set, ds.sidecar.set);
        std::fs::remove_dir_all(&dir).unwrap();
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
            let e = Table::parse(p, text)
                .and_then(|t| parse_csv(&t, 2))
                .unwrap_err();
            assert_eq!(e.line, line, "{text:?}: {e}");
            assert!(e.to_string().contains(word), "{e}");
            assert!(e.to_string().starts_with("d.csv"), "{e}");
        }
    }
}
