//! The smoothing differentiator (see the `import` module docs): on a
//! uniform grid, on uneven time stamps, and the window it takes from the
//! swing's period.

/// One part's angle, smoothed, and its rate, `t` holding no gap: over a
/// window of `smooth` seconds either side or, unset, a twentieth of the
/// part's own swing's period ([`rough_period`]; 0.01 s without one), by
/// [`differentiate`] on uniform stamps and by [`differentiate_uneven`] on
/// uneven ones, over the window of samples the grid's would hold.
pub(super) fn smooth_and_rate(
    t: &[f64],
    theta: &[f64],
    smooth: Option<f64>,
    step: f64,
) -> (Vec<f64>, Vec<f64>) {
    // Each part's own swing sets its window (a gap is no half period).
    let smooth = smooth
        .or_else(|| rough_period(t, theta).map(|p| p / 20.0))
        .unwrap_or(0.01);
    if uniform(t) {
        let h = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
        savitzky_golay(theta, samples_either_side(smooth, h) as usize, |k| t[k])
    } else {
        differentiate_uneven(t, theta, samples_either_side(smooth, step) as usize, step)
    }
}

/// Steps beyond the grid's `m` samples either side the window of
/// [`uneven_half`] reaches: frames each up to 30% of a step early or late
/// (the lab generator's jitter) keep samples `i - m` to `i + m` within
/// it, and `i +- (m + 1)` come in now and then.
pub const JITTER_ROOM: f64 = 0.6;

/// The half-window, s, of [`differentiate_uneven`] on stamps `step` apart
/// (their median) for the grid's `m` samples either side: `m` steps and
/// [`JITTER_ROOM`] more. A window of `m` steps alone holds fewer where
/// the stamps are jittered: on a 25 Hz video whose frames come up to 30%
/// of a step early or late, 0.076 s often holds `i - 1` to `i + 1` only,
/// where the grid's holds `i - 2` to `i + 2`, and the quadratic through
/// three samples is their interpolation. Its rate then carries 3.4 times
/// the noise of the same swing stamped evenly, and the filter's mean
/// innovation reads it (lab seed 83's viscous + drag rod: 4 times, its
/// right length flagged as inconsistent).
pub fn uneven_half(m: usize, step: f64) -> f64 {
    (m as f64 + JITTER_ROOM) * step
}

/// The span, s, of [`differentiate_uneven`]'s window at either end: the
/// grid's `2m + 1` samples, `2m` steps, and [`JITTER_ROOM`] more, so that
/// even stamps written to a few decimals (a 30 Hz file's 0.033333), which
/// take the uneven path, give the grid's rate at the ends too.
fn end_span(m: usize, step: f64) -> f64 {
    (2.0 * m as f64 + JITTER_ROOM) * step
}

/// Samples either side of each that a window of `smooth` s takes on
/// stamps `step` apart: `smooth / step` rounded, at least 1.
fn samples_either_side(smooth: f64, step: f64) -> f64 {
    (smooth / step).round().max(1.0)
}

/// The smoothing differentiator (the `import` module docs) with half-width
/// `m` samples on a uniform grid of step `h`: `(smoothed theta, theta_dot)`.
pub fn differentiate(theta: &[f64], h: f64, m: usize) -> (Vec<f64>, Vec<f64>) {
    savitzky_golay(theta, m, |k| k as f64 * h)
}

/// [`differentiate`] with sample `k` at `time(k)` (even stamps): each
/// window's step is its own span over its width, so that a stretch of a
/// recording gives the same as the whole (`estimate --follow`).
fn savitzky_golay(theta: &[f64], m: usize, time: impl Fn(usize) -> f64) -> (Vec<f64>, Vec<f64>) {
    let n = theta.len();
    let mut smooth = Vec::with_capacity(n);
    let mut rate = Vec::with_capacity(n);
    for i in 0..n {
        let w = m.min(i).min(n - 1 - i);
        let window = &theta[i - w..=i + w];
        // The angle: the window's least-squares quadratic at its centre
        // (Savitzky-Golay), exact on a parabola; a window's mean would
        // shave the swing's peaks.
        let (mut s0, mut s2) = (0.0, 0.0);
        for (k, v) in window.iter().enumerate() {
            let k = k as f64 - w as f64;
            s0 += v;
            s2 += k * k * v;
        }
        let nn = (2 * w + 1) as f64;
        let (k2, k4): (f64, f64) = (-(w as i64)..=w as i64)
            .map(|k| ((k * k) as f64, (k * k * k * k) as f64))
            .fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
        let den = nn * k4 - k2 * k2;
        smooth.push(if den > 0.0 {
            (k4 * s0 - k2 * s2) / den
        } else {
            s0 / nn
        });
        if w < m && n >= 3 {
            // Near the ends, where the centred window is cut: the same
            // quadratic over a full window that stops at the end, read at
            // the sample (a difference of the end samples alone would be
            // the noise over one step: at 100 Hz, a hundred times it).
            let width = (2 * m + 1).min(n);
            let a = i.saturating_sub(m).min(n - width);
            let (c0, c1) = quadratic_at(|k| time(k) - time(i), theta, a, a + width - 1, i);
            // The smoothed angle here too, in place of the centred one.
            if let Some(v) = smooth.last_mut() {
                *v = c0;
            }
            rate.push(c1);
            continue;
        }
        if w == 0 {
            // Fewer than three samples: a one-sided difference.
            let (d, h) = match i {
                _ if n < 2 => (0.0, 0.0),
                0 => (theta[1] - theta[0], time(1) - time(0)),
                _ => (theta[i] - theta[i - 1], time(i) - time(i - 1)),
            };
            rate.push(if h > 0.0 { d / h } else { 0.0 });
            continue;
        }
        let num: f64 = (1..=w)
            .map(|k| k as f64 * (theta[i + k] - theta[i - k]))
            .sum();
        let den: f64 = (1..=w).map(|k| 2.0 * (k * k) as f64).sum();
        let h = (time(i + w) - time(i - w)) / (2 * w) as f64;
        rate.push(num / (den * h));
    }
    (smooth, rate)
}

/// The same differentiator on uneven time stamps `t` (an encoder logged
/// on every count) `step` apart at the median, for the grid's `m`
/// samples either side: over the samples within [`uneven_half`] seconds
/// either side of each (within it of either end, over the first or last
/// [`end_span`] seconds, as on a grid), the least-squares quadratic
/// through `(t_k - t_i, theta_k)`, its value at `t_i` the smoothed angle
/// and its slope there the rate. The window is one of time, not of
/// samples: an encoder logged per count writes a row every millisecond
/// mid-swing and one every tens of milliseconds at the turning points,
/// where a window of a fixed number of samples would span half a swing
/// and cut its amplitude. On a uniform grid of step `step` this is
/// [`differentiate`] with `m`, the ends included.
pub fn differentiate_uneven(t: &[f64], theta: &[f64], m: usize, step: f64) -> (Vec<f64>, Vec<f64>) {
    let n = theta.len().min(t.len());
    let (half, span) = (uneven_half(m, step), end_span(m, step));
    let mut smooth = Vec::with_capacity(n);
    let mut rate = Vec::with_capacity(n);
    // The window's edges move forward with i.
    let (mut lo, mut hi) = (0usize, 0usize);
    for i in 0..n {
        if n >= 3 && (t[i] - t[0] < half || t[n - 1] - t[i] < half) {
            // Near the ends, as on a grid: the quadratic over a full
            // window of time that stops at the end (at least three
            // samples), read at the sample.
            let (lo_t, hi_t) = if t[i] - t[0] < half {
                (t[0], t[0] + span)
            } else {
                (t[n - 1] - span, t[n - 1])
            };
            let a = t.partition_point(|&v| v < lo_t).min(n - 3);
            let b = t
                .partition_point(|&v| v <= hi_t)
                .saturating_sub(1)
                .clamp(a + 2, n - 1);
            let (c0, c1) = quadratic_at(|k| t[k], theta, a, b, i);
            smooth.push(c0);
            rate.push(c1);
            continue;
        }
        if i == 0 || i == n - 1 {
            // Fewer than three samples: a one-sided difference.
            let (a, b) = if i == 0 {
                (0, 1.min(n - 1))
            } else {
                (i - 1, i)
            };
            let dt = t[b] - t[a];
            rate.push(if dt > 0.0 {
                (theta[b] - theta[a]) / dt
            } else {
                0.0
            });
            smooth.push(theta[i]);
            continue;
        }
        // Symmetric in time: no further than the nearer end allows.
        let h = half.min(t[i] - t[0]).min(t[n - 1] - t[i]) * (1.0 + 1e-9);
        while t[lo] < t[i] - h {
            lo += 1;
        }
        hi = hi.max(i);
        while hi + 1 < n && t[hi + 1] <= t[i] + h {
            hi += 1;
        }
        let (a, b) = (lo.min(i - 1), hi.max(i + 1));
        let (c0, c1) = quadratic_at(|k| t[k], theta, a, b, i);
        smooth.push(c0);
        rate.push(c1);
    }
    (smooth, rate)
}

/// The least-squares quadratic through `(time(k) - time(i), theta[k])`
/// for `k` in `a..=b`: its value and slope (per second) at `time(i)`; the
/// line where fewer than three distinct times, `(theta[i], 0)` where not
/// even that.
pub(super) fn quadratic_at(
    time: impl Fn(usize) -> f64,
    theta: &[f64],
    a: usize,
    b: usize,
    i: usize,
) -> (f64, f64) {
    // Normal equations of theta ~ c0 + c1 u + c2 u^2 in u = (t - t_i) / scale.
    let scale = (time(b) - time(a)).max(f64::MIN_POSITIVE);
    let mut m = [[0.0f64; 3]; 3];
    let mut r = [0.0f64; 3];
    for (k, v) in theta.iter().enumerate().take(b + 1).skip(a) {
        let u = (time(k) - time(i)) / scale;
        let p = [1.0, u, u * u];
        for (row, pr) in m.iter_mut().zip(p) {
            for (cell, pc) in row.iter_mut().zip(p) {
                *cell += pr * pc;
            }
        }
        for (rr, pr) in r.iter_mut().zip(p) {
            *rr += pr * v;
        }
    }
    let (c0, c1) = match solve3(m, r) {
        Some(c) => (c[0], c[1]),
        // Fewer than three distinct times: the line.
        None => {
            let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
            if det.abs() > 1e-12 * m[0][0] * m[1][1].max(1e-300) {
                (
                    (r[0] * m[1][1] - r[1] * m[0][1]) / det,
                    (m[0][0] * r[1] - m[1][0] * r[0]) / det,
                )
            } else {
                (theta[i], 0.0)
            }
        }
    };
    (c0, c1 / scale)
}

/// Solves the symmetric 3 x 3 system `m c = r` by Cramer's rule; `None`
/// when `m` is (nearly) singular.
fn solve3(m: [[f64; 3]; 3], r: [f64; 3]) -> Option<[f64; 3]> {
    let det = |a: [[f64; 3]; 3]| {
        a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
            - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
    };
    let d = det(m);
    let size = m[0][0] * m[1][1] * m[2][2];
    // Not greater, or not comparable (a NaN): no solution.
    if d.abs().partial_cmp(&(1e-10 * size)) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    let mut c = [0.0; 3];
    for (j, cj) in c.iter_mut().enumerate() {
        let mut a = m;
        for (row, rv) in a.iter_mut().zip(r) {
            row[j] = rv;
        }
        *cj = det(a) / d;
    }
    Some(c)
}

/// Whether the time stamps are uniform: every step within 1e-6 of the mean.
fn uniform(t: &[f64]) -> bool {
    let h = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
    t.windows(2).all(|w| ((w[1] - w[0]) - h).abs() <= 1e-6 * h)
}

/// The swing's period, roughly: twice the median time between the first
/// crossings of the median angle through a band of 30% of the largest
/// excursion (so noise does not cross it). `None` with fewer than three
/// crossings.
pub fn rough_period(t: &[f64], theta: &[f64]) -> Option<f64> {
    let mut sorted = theta.to_vec();
    if sorted.is_empty() {
        return None;
    }
    let mid = sorted.len() / 2;
    let centre = *sorted.select_nth_unstable_by(mid, f64::total_cmp).1;
    drop(sorted);
    let band = 0.3 * theta.iter().map(|v| (v - centre).abs()).fold(0.0, f64::max);
    let mut flips = Vec::new();
    let mut side = 0i8;
    for (&ti, &v) in t.iter().zip(theta) {
        let s = if v - centre > band {
            1
        } else if v - centre < -band {
            -1
        } else {
            0
        };
        if s != 0 && s != side {
            if side != 0 {
                flips.push(ti);
            }
            side = s;
        }
    }
    // From the first swings (the largest, before friction stops them).
    let mut halves: Vec<f64> = flips.windows(2).take(8).map(|w| w[1] - w[0]).collect();
    if halves.len() < 2 {
        return None;
    }
    halves.sort_by(f64::total_cmp);
    Some(2.0 * halves[halves.len() / 2])
}

#[cfg(test)]
mod tests {
    use super::super::{ImportOptions, Recording, to_rollout};
    use super::*;

    #[test]
    fn the_differentiator_is_exact_on_a_parabola_and_close_on_a_sine() {
        // A quadratic's derivative is linear: the least-squares slope over a
        // symmetric window is exact (up to rounding) away from the ends.
        let h = 0.001;
        let th: Vec<f64> = (0..200)
            .map(|k| {
                let t = k as f64 * h;
                3.0 * t * t - t
            })
            .collect();
        let (_, d) = differentiate(&th, h, 10);
        for (k, v) in d.iter().enumerate().skip(10).take(180) {
            let want = 6.0 * k as f64 * h - 1.0;
            assert!((v - want).abs() < 1e-9, "{k}: {v} vs {want}");
        }
        // sin(10 t) sampled at 1 kHz, window +-10 ms: the attenuation is
        // sinc-like, 1 - (w m h)^2 / 6 ... about 0.17%; 0.5% is asserted.
        let th: Vec<f64> = (0..1000).map(|k| (10.0 * k as f64 * h).sin()).collect();
        let (s, d) = differentiate(&th, h, 10);
        for k in (20..980).step_by(37) {
            let t = k as f64 * h;
            assert!((d[k] - 10.0 * (10.0 * t).cos()).abs() < 0.05, "rate at {k}");
            assert!((s[k] - (10.0 * t).sin()).abs() < 0.005, "angle at {k}");
        }
    }

    /// Near the ends the rate is the full window's quadratic read at the
    /// sample, not a difference of the end samples: a swing of 0.1 rad at
    /// 5 rad/s tracked at 100 Hz with noise of +-5 mrad alternating (the
    /// worst case for a difference: it reads 1 rad/s of noise), a window
    /// of +-10 samples. The quadratic read at its end misses the sine's
    /// cubic term by about 0.1 x 5^3 x (0.2 s)^2 / 20 = 0.025 rad/s and
    /// the alternating noise by less than 0.01: 0.05 rad/s is asserted,
    /// against a true rate of up to 0.5. The same on uneven stamps.
    #[test]
    fn the_ends_are_read_from_a_full_window() {
        let h = 0.01;
        let t: Vec<f64> = (0..400).map(|k| k as f64 * h).collect();
        let th: Vec<f64> = t
            .iter()
            .enumerate()
            .map(|(k, &x)| 0.1 * (5.0 * x).sin() + if k % 2 == 0 { 0.005 } else { -0.005 })
            .collect();
        let truth = |x: f64| 0.5 * (5.0 * x).cos();
        let (_, d) = differentiate(&th, h, 10);
        let (_, e) = differentiate_uneven(&t, &th, 10, h);
        for k in (0..12).chain(388..400) {
            assert!(
                (d[k] - truth(t[k])).abs() < 0.05,
                "grid, rate at {k}: {}",
                d[k]
            );
            assert!(
                (e[k] - truth(t[k])).abs() < 0.05,
                "uneven, rate at {k}: {}",
                e[k]
            );
        }
    }

    /// A 25 Hz video's frames jittered as the lab generator's (up to 30%
    /// of a step early or late, the angle at each stamp), a swing of
    /// 0.09 rad at 4.15 rad/s with 0.0073 rad of noise (lab seed 83's
    /// viscous + drag rod in its last third), a window of 0.076 s (a
    /// twentieth of its period): the rate's error is within 1.2 times that
    /// of the same swing stamped evenly (1.09 here; with the window of
    /// 0.076 s alone, 3.4 times). Over 2000 samples the ratio of two RMS
    /// errors moves by about 3% with the draw.
    #[test]
    fn jittered_stamps_are_differentiated_over_the_grids_samples() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(83);
        let mut gauss = || {
            let (u1, u2): (f64, f64) = (rng.random_range(1e-12..1.0), rng.random());
            (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
        };
        let (step, w, noise) = (0.04, 4.15, 0.0073);
        let rms_error = |t: &[f64], theta: &[f64]| {
            let (_, rate) = smooth_and_rate(t, theta, Some(0.076), step);
            let n = t.len();
            let sq: f64 = (10..n - 10)
                .map(|k| (rate[k] - 0.09 * w * (w * t[k]).cos()).powi(2))
                .sum();
            (sq / (n - 20) as f64).sqrt()
        };
        let mut even = (vec![], vec![]);
        let mut jittered = (vec![], vec![]);
        for k in 0..2000 {
            let j = (0.3 * step * 2.0 * gauss().tanh()).clamp(-0.3 * step, 0.3 * step);
            for ((t, theta), s) in [(&mut even, 0.0), (&mut jittered, j)] {
                let s = k as f64 * step + s;
                t.push(s);
                theta.push(0.09 * (w * s).sin() + noise * gauss());
            }
        }
        let (a, b) = (
            rms_error(&even.0, &even.1),
            rms_error(&jittered.0, &jittered.1),
        );
        assert!(b < 1.2 * a, "jittered {b:.4} rad/s against even {a:.4}");
    }

    #[test]
    fn uneven_stamps_are_differentiated_at_their_times() {
        // Stamps jittered by up to 20% of the 1 ms step either way, a sine
        // of amplitude 1 at 6 rad/s, a window of +-10 ms. Tolerances: the
        // quadratic misses the sine's cubic term, which biases the slope
        // by about 6^3 x (10 ms)^2 x 3/5 / 6 = 2.2e-3 (the window's mean
        // u^4 over its mean u^2): 5e-3 leaves room for the jitter's
        // asymmetry. Its value at t_i misses the quartic term, 6^4 x
        // (10 ms)^4 / 24 = 5e-7 at most: 1e-5.
        let t: Vec<f64> = (0..300)
            .map(|k| 0.001 * (k as f64 + 0.4 * ((k * 7919 % 13) as f64 / 13.0 - 0.5)))
            .collect();
        let th: Vec<f64> = t.iter().map(|&x| (6.0 * x).sin()).collect();
        let (s, d) = differentiate_uneven(&t, &th, 10, 0.001);
        for k in (15..285).step_by(17) {
            assert!(
                (d[k] - 6.0 * (6.0 * t[k]).cos()).abs() < 5e-3,
                "rate at {k}: {}",
                d[k]
            );
            assert!((s[k] - (6.0 * t[k]).sin()).abs() < 1e-5, "angle at {k}");
        }
        // On a uniform grid it is the uniform differentiator, the ends
        // included, and so are stamps rounded to six decimals (a 30 Hz
        // file's 0.033333), which fail the grid's test: a cubic with
        // noise, so that a window one sample wider or narrower shows.
        // Tolerance: the rounding's 5e-7 s moves a sample by under 1e-6
        // of the rate's scale, 1e-9 on exact stamps.
        let tu: Vec<f64> = (0..50).map(|k| k as f64 / 30.0).collect();
        let thu: Vec<f64> = tu
            .iter()
            .enumerate()
            .map(|(k, &x)| x * x * x - x + 1e-3 * ((k * 7919 % 13) as f64 - 6.0))
            .collect();
        let t6: Vec<f64> = tu.iter().map(|&x| (x * 1e6).round() / 1e6).collect();
        assert!(!uniform(&t6), "six decimals fail the grid's test");
        let (sa, a) = differentiate(&thu, 1.0 / 30.0, 3);
        for (stamps, tol) in [(&tu, 1e-9), (&t6, 1e-4)] {
            let (sb, b) = differentiate_uneven(stamps, &thu, 3, 1.0 / 30.0);
            for k in 0..50 {
                assert!(
                    (a[k] - b[k]).abs() < tol,
                    "rate at {k}: {} vs {}",
                    a[k],
                    b[k]
                );
                assert!((sa[k] - sb[k]).abs() < tol, "angle at {k}");
            }
        }
        // And import takes them without a panic.
        let rec = Recording {
            t: t.clone(),
            theta: th,
            theta_dot: None,
            torque: None,
        };
        let r = to_rollout(&rec, 1, &ImportOptions::default()).unwrap();
        assert!(r.xs.iter().all(|x| x[0].is_finite() && x[1].is_finite()));
    }
}
