//! The angle of a position-only recording (a video tracker's x, y of the
//! bob) about the pivot.
//!
//! The pivot is, in this order: the one given (`--pivot X,Y`); the origin,
//! where the bob keeps its distance from it within [`ORIGIN_SPREAD`] and
//! within [`ORIGIN_FIT_RATIO`] times its spread about the fitted arc (a
//! tracker's axes set on the pivot); else the centre of the circle fitted
//! to the track by least squares (Kasa's algebraic fit, `x^2 + y^2 + D x +
//! E y + F = 0` linear in `D, E, F`, refitted once without the points
//! over 5 spreads off the first circle: a tracker's glitches). The angle
//! is measured from straight down, down being the side of the pivot the
//! bob hangs on (a tracker's y up, an image's y down): a camera's tilt is
//! an angle offset, the estimator's to find.

use nalgebra::{Matrix3, Vector3};

/// The bob's largest spread of distance from the origin, as a fraction
/// of that distance, for the origin to be taken as the pivot.
pub const ORIGIN_SPREAD: f64 = 0.02;
/// The most the bob's spread of distance from the origin may be, as a
/// multiple of its spread about the arc fitted to the track, for the
/// origin to be taken as the pivot.
pub const ORIGIN_FIT_RATIO: f64 = 2.0;
/// The least arc, rad, a fitted pivot is trusted on.
pub const MIN_ARC: f64 = 0.1;

/// Where the pivot came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PivotFrom {
    /// `--pivot`.
    Given,
    /// The tracker's origin.
    Origin,
    /// The centre of the arc fitted to the track.
    Fitted,
}

/// The angle about the pivot.
#[derive(Debug, Clone, PartialEq)]
pub struct Pivoted {
    /// The angle from straight down, rad.
    pub theta: Vec<f64>,
    /// The pivot, in the file's units.
    pub pivot: [f64; 2],
    /// Where it came from.
    pub from: PivotFrom,
    /// The bob's mean distance from it, in the file's units.
    pub radius: f64,
    /// The rms of that distance about its mean.
    pub spread: f64,
}

/// The angle of the track `(x, y)` about the pivot (`given`, else the
/// origin or the fitted arc's centre), or why it cannot be had.
pub fn about_pivot(x: &[f64], y: &[f64], given: Option<[f64; 2]>) -> Result<Pivoted, String> {
    let (pivot, from) = match given {
        Some(p) => (p, PivotFrom::Given),
        None => {
            let (r, s) = distance(x, y, [0.0, 0.0], None);
            let origin = r > 0.0 && s <= ORIGIN_SPREAD * r;
            match fit_arc(x, y) {
                // The origin, where the bob keeps its distance from it
                // about as well as from the arc fitted to it: a bob far
                // from an origin elsewhere (an image's corner) on a small
                // arc keeps within 2% of that distance, but not within
                // the arc's own spread.
                Ok(c) if !origin || s > ORIGIN_FIT_RATIO * distance(x, y, c, None).1 => {
                    (c, PivotFrom::Fitted)
                }
                Ok(_) => ([0.0, 0.0], PivotFrom::Origin),
                Err(_) if origin => ([0.0, 0.0], PivotFrom::Origin),
                Err(e) => return Err(e),
            }
        }
    };
    let (radius, spread) = distance(x, y, pivot, None);
    let below = y.iter().map(|v| v - pivot[1]).sum::<f64>() < 0.0;
    let theta: Vec<f64> = x
        .iter()
        .zip(y)
        .map(|(&xi, &yi)| {
            let (dx, dy) = (xi - pivot[0], yi - pivot[1]);
            if below { dx.atan2(-dy) } else { dx.atan2(dy) }
        })
        .collect();
    if from == PivotFrom::Fitted {
        let (lo, hi) = theta
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        if hi - lo < MIN_ARC {
            return Err(format!(
                "the track spans {:.3} rad of the arc fitted to it (centre {:.4}, {:.4}): too little to find the pivot; give it (--pivot X,Y)",
                hi - lo,
                pivot[0],
                pivot[1]
            ));
        }
    }
    Ok(Pivoted {
        theta,
        pivot,
        from,
        radius,
        spread,
    })
}

/// The mean distance of the points from `c` and its rms spread, over the
/// points `keep` allows (all where `None`).
fn distance(x: &[f64], y: &[f64], c: [f64; 2], keep: Option<&[bool]>) -> (f64, f64) {
    let d: Vec<f64> = x
        .iter()
        .zip(y)
        .enumerate()
        .filter(|(k, _)| keep.is_none_or(|m| m[*k]))
        .map(|(_, (xi, yi))| (xi - c[0]).hypot(yi - c[1]))
        .collect();
    let n = d.len().max(1) as f64;
    let mean = d.iter().sum::<f64>() / n;
    let spread = (d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
    (mean, spread)
}

/// The centre of the circle fitted to the track (see the module docs).
fn fit_arc(x: &[f64], y: &[f64]) -> Result<[f64; 2], String> {
    let mut keep = vec![true; x.len()];
    let mut c = kasa(x, y, &keep)?;
    let (r, s) = distance(x, y, c, None);
    for (k, (xi, yi)) in x.iter().zip(y).enumerate() {
        keep[k] = ((xi - c[0]).hypot(yi - c[1]) - r).abs() <= 5.0 * s + 1e-12 * r;
    }
    if keep.iter().any(|k| !k) {
        c = kasa(x, y, &keep)?;
    }
    Ok(c)
}

/// Why a track gives no pivot.
const ON_A_LINE: &str = "the bob's x, y lie on a line, not an arc: give the pivot (--pivot X,Y)";

/// Kasa's fit over the points `keep` allows.
fn kasa(x: &[f64], y: &[f64], keep: &[bool]) -> Result<[f64; 2], String> {
    // Centred and scaled for the normal equations' conditioning.
    let n = keep.iter().filter(|k| **k).count() as f64;
    let mean_kept = |v: &[f64]| -> f64 {
        v.iter()
            .zip(keep)
            .filter(|(_, k)| **k)
            .map(|(v, _)| v)
            .sum::<f64>()
            / n
    };
    let (mx, my) = (mean_kept(x), mean_kept(y));
    let scale = x
        .iter()
        .zip(y)
        .map(|(a, b)| (a - mx).hypot(b - my))
        .fold(0.0, f64::max)
        .max(1e-300);
    let (mut ata, mut atb) = (Matrix3::<f64>::zeros(), Vector3::<f64>::zeros());
    for ((xi, yi), _) in x.iter().zip(y).zip(keep).filter(|(_, k)| **k) {
        let (u, v) = ((xi - mx) / scale, (yi - my) / scale);
        let row = Vector3::new(u, v, 1.0);
        ata += row * row.transpose();
        atb -= row * (u * u + v * v);
    }
    let sol = ata
        .try_inverse()
        .map(|inv| inv * atb)
        .filter(|s| s.iter().all(|v| v.is_finite()))
        .ok_or(ON_A_LINE)?;
    let (cx, cy) = (-sol[0] / 2.0, -sol[1] / 2.0);
    if cx.hypot(cy) > 1e3 {
        return Err(
            "the bob's x, y lie on a line, not an arc: give the pivot (--pivot X,Y)".into(),
        );
    }
    Ok([mx + cx * scale, my + cy * scale])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A bob 0.5 m below a pivot at (0.3, 1.2), swinging 0.6 rad, tracked
    /// with 1 mm of noise and one glitch: the fitted pivot within 5 mm, the
    /// angle within 0.01 rad; the same track about the origin (a tracker's
    /// axes on the pivot) and in an image's y-down pixels.
    #[test]
    fn the_pivot_is_found() {
        let (px, py, l) = (0.3, 1.2, 0.5);
        let truth: Vec<f64> = (0..500).map(|k| 0.6 * (k as f64 * 0.05).cos()).collect();
        let noise = |k: usize| 1e-3 * (((k * 7919) % 17) as f64 / 8.0 - 1.0);
        let mut x: Vec<f64> = truth
            .iter()
            .enumerate()
            .map(|(k, a)| px + l * a.sin() + noise(k))
            .collect();
        let y: Vec<f64> = truth
            .iter()
            .enumerate()
            .map(|(k, a)| py - l * a.cos() + noise(k + 3))
            .collect();
        x[200] += 0.3;
        let got = about_pivot(&x, &y, None).unwrap();
        assert_eq!(got.from, PivotFrom::Fitted);
        assert!(
            (got.pivot[0] - px).abs() < 5e-3 && (got.pivot[1] - py).abs() < 5e-3,
            "{:?}",
            got.pivot
        );
        assert!((got.radius - l).abs() < 0.01, "{}", got.radius);
        for (k, (a, b)) in got.theta.iter().zip(&truth).enumerate() {
            if k != 200 {
                assert!((a - b).abs() < 0.01, "{k}: {a} vs {b}");
            }
        }
        let (xo, yo): (Vec<f64>, Vec<f64>) =
            x.iter().zip(&y).map(|(a, b)| (a - px, b - py)).unzip();
        let mut xo = xo;
        xo[200] -= 0.3;
        let got = about_pivot(&xo, &yo, None).unwrap();
        assert_eq!(got.from, PivotFrom::Origin);
        assert!((got.theta[10] - truth[10]).abs() < 0.01);
        // Pixels, y down: the same swing, mirrored.
        let (xp, yp): (Vec<f64>, Vec<f64>) = xo
            .iter()
            .zip(&yo)
            .map(|(a, b)| (500.0 + 400.0 * a, 100.0 - 400.0 * b))
            .unzip();
        let got = about_pivot(&xp, &yp, None).unwrap();
        assert!(
            (got.pivot[0] - 500.0).abs() < 2.0 && (got.pivot[1] - 100.0).abs() < 2.0,
            "{:?}",
            got.pivot
        );
        assert!((got.theta[10] - truth[10]).abs() < 0.01);
        // A short string in pixels, its pivot at (640, 900), an image's
        // corner the origin: the bob 1,000 px from it keeps within 2% of
        // that distance, but far outside the arc's own spread.
        let (xs, ys): (Vec<f64>, Vec<f64>) = truth
            .iter()
            .enumerate()
            .map(|(k, a)| {
                (
                    640.0 + 62.0 * (1.1 * a).sin() + 400.0 * noise(k),
                    900.0 + 62.0 * (1.1 * a).cos() + 400.0 * noise(k + 3),
                )
            })
            .unzip();
        let got = about_pivot(&xs, &ys, None).unwrap();
        assert_eq!(got.from, PivotFrom::Fitted);
        assert!(
            (got.pivot[0] - 640.0).abs() < 2.0 && (got.pivot[1] - 900.0).abs() < 2.0,
            "{:?}",
            got.pivot
        );
        // Given: taken as it is.
        let got = about_pivot(&x, &y, Some([px, py])).unwrap();
        assert_eq!(got.from, PivotFrom::Given);
        // A bob that slides along a line: no arc to fit.
        let line: Vec<f64> = (0..100).map(|k| 0.01 * k as f64 - 0.5).collect();
        let e = about_pivot(&line, &vec![0.2; 100], None).unwrap_err();
        assert!(e.contains("--pivot"), "{e}");
    }
}
