//! The rotary-encoder logger's format.

use crate::data::table::{CsvError, Table};

use super::super::Recording;

/// The rotary-encoder logger's format: line 1 names
/// `trigger_start_deg, sample_rate, duration_sec`, line 2 holds their
/// values, then one angle per line in degrees.
pub(super) fn parse_encoder(table: &Table) -> Result<Recording, CsvError> {
    if table.is_empty() {
        return Err(table.error(2, "missing the values line"));
    }
    let k = table
        .header
        .iter()
        .position(|n| n.to_lowercase() == "sample_rate")
        .ok_or_else(|| table.error(1, "no sample_rate field"))?;
    let rate = table.number(0, k, "sample_rate")?;
    if rate <= 0.0 {
        return Err(table.error(table.line(0), "sample_rate must be positive"));
    }
    let mut theta = Vec::with_capacity(table.len());
    for row in 1..table.len() {
        theta.push(table.number(row, 0, "angle")?.to_radians());
    }
    let t = (0..theta.len()).map(|k| k as f64 / rate).collect();
    Ok(Recording {
        t,
        theta,
        theta_dot: None,
        torque: None,
    })
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::super::super::ImportOptions;
    use super::super::parse;

    #[test]
    fn the_encoder_format_is_read_in_degrees_at_its_rate() {
        let text = "trigger_start_deg, sample_rate, duration_sec\n90, 1000, 5 \n-90.0\n-89.0\n-88.0\n\n-87.0\n";
        let r = parse(Path::new("x.txt"), text, &ImportOptions::default()).unwrap();
        assert_eq!(r.t, [0.0, 0.001, 0.002, 0.003]);
        assert!((r.theta[0] + std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!(r.theta_dot.is_none());
        let bad = "trigger_start_deg, sample_rate, duration_sec\n90, 1000, 5\n-90.0\nabc\n";
        let e = parse(Path::new("x.txt"), bad, &ImportOptions::default()).unwrap_err();
        assert!(e.to_string().contains("x.txt:4"), "{e}");
    }
}
