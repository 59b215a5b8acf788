//! The angle of a rate-only recording (a phone's or an IMU's gyroscope):
//! the swing axis found, its rate integrated, the drift removed.
//!
//! Steps:
//! 1. The swing axis: of several axes, the principal direction of the
//!    rates (the eigenvector of their covariance with the largest
//!    eigenvalue), named after an axis where it lies within 10 degrees of
//!    one; a single rate column is its own axis.
//! 2. The rate along it, `w`, integrated by the trapezoid rule: `phi`.
//! 3. The drift removed: a gyroscope's bias `b` makes `phi` drift by
//!    `b t`. The trend is `phi` averaged twice over a window `W` of
//!    [`PERIODS`] swing periods (the mean period between the rate's
//!    crossings): a triangle of `2W`, which keeps a drift linear in time
//!    and lets through a swing at a period `W / n (1 + e)` only by
//!    `sinc^2`, about `e^2` (the period of a wide swing is longer than a
//!    small one's). The angle is `phi` less its trend, the rate `w` less
//!    its own. Each mean is over a window centred on the sample, shifted
//!    inside the recording at its ends, where the slope across the window
//!    carries it to the sample (exact for a line). The angle's zero is the
//!    swing's centre; an offset left in it is the estimator's to find.

use nalgebra::{DMatrix, SymmetricEigen};

use super::resample::interp;
use super::rough_period;

/// Swing periods the drift is averaged over.
pub const PERIODS: f64 = 2.0;
/// Degrees within which the principal direction is named after an axis.
const AXIS_DEGREES: f64 = 10.0;

/// An angle integrated from the rate.
#[derive(Debug, Clone, PartialEq)]
pub struct Integrated {
    /// The angle, rad, its zero the swing's centre.
    pub theta: Vec<f64>,
    /// The rate, rad/s, its bias removed.
    pub rate: Vec<f64>,
    /// The swing axis in words: a column's name or a direction.
    pub axis: String,
    /// The rate's rms about its mean along the axis, rad/s.
    pub rms: f64,
    /// The drift's window, s.
    pub window: f64,
}

/// The angle from the rates `axes` (rad/s, each at the stamps `t`, named
/// `names`), or why it cannot be had.
pub fn integrate(t: &[f64], axes: &[Vec<f64>], names: &[String]) -> Result<Integrated, String> {
    let (w, axis) = swing_axis(axes, names)?;
    let mean = w.iter().sum::<f64>() / w.len() as f64;
    let rms = (w.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / w.len() as f64).sqrt();
    let period = mean_period(t, &w).ok_or_else(|| {
        format!(
            "no swing in the rate on {axis} (rms {rms:.3} rad/s): under one full swing in {:.1} s to take its drift off (two upward crossings a period apart); record longer (several swings)",
            t.last().zip(t.first()).map_or(0.0, |(b, a)| b - a)
        )
    })?;
    let window = PERIODS * period;
    let (theta, rate) = detrend(t, &w, window);
    Ok(Integrated {
        theta,
        rate,
        axis,
        rms,
        window,
    })
}

/// The rate `w` at the stamps `t` integrated, and both the angle and the
/// rate less their trends over `window` s (shortened to the recording):
/// steps 2 and 3 of the module docs. A part of a recording cut from it
/// (a release) is detrended again on its own, away from the hand's motion
/// around it.
pub fn detrend(t: &[f64], w: &[f64], window: f64) -> (Vec<f64>, Vec<f64>) {
    let phi = cumulative(t, w);
    let span = t[t.len() - 1] - t[0];
    // Never wider than the recording (nor NaN: a clamp's bounds must be ordered).
    let window = if window > 0.0 && window < span {
        window
    } else {
        span
    };
    let trend = |v: &[f64]| boxcar(t, &boxcar(t, v, window), window);
    let theta = phi.iter().zip(trend(&phi)).map(|(p, d)| p - d).collect();
    let rate = w.iter().zip(trend(w)).map(|(v, d)| v - d).collect();
    (theta, rate)
}

/// The swing's mean period: the time between the first and the last
/// upward crossing of the median (interpolated, through a band of 30% of
/// the largest excursion, as [`rough_period`]) over their number less one;
/// `None` with fewer than two a period apart.
fn mean_period(t: &[f64], w: &[f64]) -> Option<f64> {
    let rough = rough_period(t, w)?;
    let mut sorted = w.to_vec();
    sorted.sort_by(f64::total_cmp);
    let centre = sorted[sorted.len() / 2];
    let band = 0.3 * w.iter().map(|v| (v - centre).abs()).fold(0.0, f64::max);
    let mut ups = Vec::new();
    let mut armed = false;
    for k in 1..w.len() {
        armed |= w[k] - centre < -band;
        if armed && w[k - 1] < centre && w[k] >= centre {
            let f = (centre - w[k - 1]) / (w[k] - w[k - 1]);
            ups.push(t[k - 1] + f * (t[k] - t[k - 1]));
            armed = false;
        }
    }
    // Between releases the swing stops: the crossings are counted only
    // where they follow within 1.5 rough periods.
    let (mut span, mut count) = (0.0, 0usize);
    for p in ups.windows(2).map(|u| u[1] - u[0]) {
        if p < 1.5 * rough {
            span += p;
            count += 1;
        }
    }
    (count >= 1).then(|| span / count as f64)
}

/// The mean of `v` over a window of `window` s centred on each stamp,
/// shifted inside the recording at its ends, where the slope across the
/// window carries it to the stamp (exact for a line).
fn boxcar(t: &[f64], v: &[f64], window: f64) -> Vec<f64> {
    let integral = cumulative(t, v);
    let (first, last) = (t[0], t[t.len() - 1]);
    t.iter()
        .map(|&ti| {
            let a = (ti - window / 2.0).clamp(first, last - window);
            let b = a + window;
            let mean = (interp(t, &integral, b) - interp(t, &integral, a)) / window;
            let slope = (interp(t, v, b) - interp(t, v, a)) / window;
            mean + slope * (ti - (a + b) / 2.0)
        })
        .collect()
}

/// The rate along the swing axis and the axis in words.
fn swing_axis(axes: &[Vec<f64>], names: &[String]) -> Result<(Vec<f64>, String), String> {
    match axes {
        [] => Err("no rate column".into()),
        [one] => Ok((one.clone(), names.first().cloned().unwrap_or_default())),
        _ => {
            let n = axes[0].len();
            let means: Vec<f64> = axes
                .iter()
                .map(|a| a.iter().sum::<f64>() / n as f64)
                .collect();
            let cov = DMatrix::from_fn(axes.len(), axes.len(), |i, j| {
                (0..n)
                    .map(|k| (axes[i][k] - means[i]) * (axes[j][k] - means[j]))
                    .sum::<f64>()
                    / n as f64
            });
            let eig = SymmetricEigen::new(cov);
            let top = eig.eigenvalues.imax();
            let mut v: Vec<f64> = eig.eigenvectors.column(top).iter().copied().collect();
            // The sign of the largest component positive, so that a swing
            // on one axis reads as that axis.
            let big = (0..v.len())
                .max_by(|&i, &j| v[i].abs().total_cmp(&v[j].abs()))
                .unwrap_or(0);
            if v[big] < 0.0 {
                v.iter_mut().for_each(|x| *x = -*x);
            }
            let w = (0..n)
                .map(|k| v.iter().zip(axes).map(|(c, a)| c * a[k]).sum())
                .collect();
            let axis = if v[big] >= AXIS_DEGREES.to_radians().cos() {
                names[big].clone()
            } else {
                let parts: Vec<String> = v.iter().map(|c| format!("{c:.2}")).collect();
                format!(
                    "the principal direction ({}) of {}",
                    parts.join(", "),
                    names.join(", ")
                )
            };
            Ok((w, axis))
        }
    }
}

/// The running trapezoid integral of `v` over `t`, from 0.
fn cumulative(t: &[f64], v: &[f64]) -> Vec<f64> {
    let mut out = Vec::with_capacity(v.len());
    let mut sum = 0.0;
    out.push(0.0);
    for k in 1..v.len() {
        sum += 0.5 * (v[k] + v[k - 1]) * (t[k] - t[k - 1]);
        out.push(sum);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A swing of 0.4 rad at 1.5 Hz on a phone's z axis, tilted 5 degrees
    /// into y, with biases of 0.01 rad/s and a little of x's noise: the
    /// axis named z, the angle back within 2e-3 rad of the truth (the
    /// trapezoid's error at 100 Hz and the swing's change over the window),
    /// the rate within 2e-3 rad/s after the bias.
    #[test]
    fn a_biased_gyroscope_gives_the_swing_back() {
        let w = 2.0 * std::f64::consts::PI * 1.5;
        let t: Vec<f64> = (0..6000).map(|k| k as f64 * 0.01).collect();
        let truth: Vec<f64> = t.iter().map(|&s| 0.4 * (w * s).sin()).collect();
        let rate: Vec<f64> = t.iter().map(|&s| 0.4 * w * (w * s).cos()).collect();
        let tilt = 5f64.to_radians();
        let axes = vec![
            rate.iter()
                .enumerate()
                .map(|(k, _)| 0.01 + 0.001 * ((k * 7919) % 13) as f64 / 13.0)
                .collect(),
            rate.iter().map(|r| r * tilt.sin() - 0.01).collect(),
            rate.iter().map(|r| r * tilt.cos() + 0.01).collect(),
        ];
        let names: Vec<String> = ["x", "y", "z"].map(String::from).to_vec();
        let got = integrate(&t, &axes, &names).unwrap();
        assert_eq!(got.axis, "z");
        assert!((got.window - 2.0 / 1.5).abs() < 0.05, "{}", got.window);
        for k in 0..t.len() {
            assert!(
                (got.theta[k] - truth[k]).abs() < 2e-3,
                "{k}: {} vs {}",
                got.theta[k],
                truth[k]
            );
            assert!((got.rate[k] - rate[k]).abs() < 2e-3, "{k}");
        }
        // Swung on a diagonal: named as a direction.
        let diagonal = vec![
            rate.iter().map(|r| r * 0.6).collect(),
            rate.iter().map(|r| r * 0.8).collect(),
        ];
        let got = integrate(&t, &diagonal, &names[..2]).unwrap();
        assert!(
            got.axis.starts_with("the principal direction (0.60, 0.80)"),
            "{}",
            got.axis
        );
        // No swing at all: said so.
        let still = vec![vec![0.01; t.len()]];
        assert!(
            integrate(&t, &still, &names[..1])
                .unwrap_err()
                .contains("no swing")
        );
    }
}
