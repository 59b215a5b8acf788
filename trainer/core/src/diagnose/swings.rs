//! The swings of a recording: its turning points, each measured by a
//! least-squares fit of one period of samples around it, so that no rate or
//! acceleration is ever differentiated from the data.
//!
//! Around each turning point `t_k` the angle is fitted over one period
//! `T` (`tau = t - t_k`, `w = 2 pi / T`) by
//!
//! `m(tau) = c + a cos(w tau) + b sin(w tau) + tau (a' cos(w tau) + b' sin(w tau)) + a3 cos(3 w tau) + b3 sin(3 w tau)`:
//!
//! the centre `c`, the swing, its change across the window (damping, and a
//! period slightly off), and the third harmonic of a large swing. The
//! turning point is the fitted curve's extremum next to `tau = 0`; its
//! amplitude is `|m(tau*) - c|`. Each window's residual gives the noise
//! level, and from it the standard deviation of the amplitude and the
//! centre (the fit's covariance). Windows are one period wide and half a
//! period apart, so neighbours share half their samples.
//!
//! Works on any time stamps (even, jittered, one row per encoder count).

use anyhow::{Result, bail};
use nalgebra::{DMatrix, DVector};

use crate::metrics::{correlation_inflation, lag1_autocorrelation, median};

/// Basis functions of the window fit.
const BASIS: usize = 7;

/// One turning point.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Turn {
    /// Time, s.
    pub t: f64,
    /// Amplitude from the window's centre, rad.
    pub amplitude: f64,
    /// Its standard deviation.
    pub amplitude_sd: f64,
    /// `+1` at a maximum, `-1` at a minimum.
    pub sign: f64,
    /// The window's centre, rad.
    pub centre: f64,
    /// Its standard deviation.
    pub centre_sd: f64,
    /// RMS residual of the window's fit, rad.
    pub residual_rms: f64,
}

/// The swings found.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Swings {
    /// Turning points, alternately maxima and minima, in time order.
    pub turns: Vec<Turn>,
    /// The period the windows started from (from the first crossings), s.
    pub period: f64,
    /// Median residual RMS of the window fits: the noise level, rad.
    pub noise: f64,
}

fn basis(tau: f64, w: f64) -> [f64; BASIS] {
    let (s, c) = (w * tau).sin_cos();
    let (s3, c3) = (3.0 * w * tau).sin_cos();
    [1.0, c, s, tau * c, tau * s, c3, s3]
}

fn basis_deriv(tau: f64, w: f64) -> [f64; BASIS] {
    let (s, c) = (w * tau).sin_cos();
    let (s3, c3) = (3.0 * w * tau).sin_cos();
    [
        0.0,
        -w * s,
        w * c,
        c - tau * w * s,
        s + tau * w * c,
        -3.0 * w * s3,
        3.0 * w * c3,
    ]
}

/// A window's fit: coefficients, their unscaled covariance
/// `(X^T X)^-1` and the residual RMS.
struct WindowFit {
    beta: [f64; BASIS],
    cov: DMatrix<f64>,
    rms: f64,
}

fn fit_window(t: &[f64], m: &[f64], centre: f64, w: f64) -> Option<WindowFit> {
    let n = t.len();
    if n < BASIS + 4 {
        return None;
    }
    let mut x = DMatrix::<f64>::zeros(n, BASIS);
    for (i, &ti) in t.iter().enumerate() {
        for (j, v) in basis(ti - centre, w).into_iter().enumerate() {
            x[(i, j)] = v;
        }
    }
    let y = DVector::from_column_slice(m);
    let xtx = x.transpose() * &x;
    let cov = xtx.try_inverse()?;
    let b = &cov * (x.transpose() * &y);
    let resid = &y - &x * &b;
    // Neighbouring residuals that move together (quantisation, a tracker's
    // lag) carry less information than as many independent ones: the
    // noise level is inflated by (1 + rho) / (1 - rho), rho their lag-1
    // correlation.
    let inflate = correlation_inflation(lag1_autocorrelation(resid.as_slice()), 0.95);
    let rms = (resid.norm_squared() / (n - BASIS) as f64 * inflate).sqrt();
    let mut beta = [0.0; BASIS];
    for (j, v) in beta.iter_mut().enumerate() {
        *v = b[j];
    }
    Some(WindowFit { beta, cov, rms })
}

fn eval(beta: &[f64; BASIS], f: [f64; BASIS]) -> f64 {
    beta.iter().zip(f).map(|(b, v)| b * v).sum()
}

/// Finds the turning points of the angle `m` at times `t` (increasing).
/// An error says why there are none: fewer than two swings, or too few
/// samples a period.
pub fn swings(t: &[f64], m: &[f64]) -> Result<Swings> {
    let n = t.len().min(m.len());
    if n < 4 * BASIS {
        bail!("{n} samples: too few to find swings in");
    }
    let (t, m) = (&t[..n], &m[..n]);
    let centre0 = median(&mut m.to_vec());
    // The reading's resolution: its smallest step (a count, a pixel).
    let quantum = m
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .filter(|d| *d > 0.0)
        .fold(f64::INFINITY, f64::min);
    let Some(period) = crate::data::import::rough_period(t, m) else {
        bail!("fewer than two swings through the centre: nothing to measure a period on");
    };
    let mut half = 0.5 * period;
    // The first turning point whose window fits in the recording: the
    // largest deviation in the half period after the first half period.
    let first_seed = {
        let lo = t.partition_point(|&x| x < t[0] + half);
        let hi = t
            .partition_point(|&x| x < t[0] + 2.0 * half)
            .max(lo + 1)
            .min(n);
        let k = (lo..hi)
            .max_by(|&a, &b| (m[a] - centre0).abs().total_cmp(&(m[b] - centre0).abs()))
            .unwrap_or(lo);
        t[k.min(n - 1)]
    };
    let mut turns: Vec<Turn> = Vec::new();
    let mut seed = first_seed;
    let mut sign = 0.0;
    loop {
        let (lo_t, hi_t) = (seed - half, seed + half);
        if hi_t > t[n - 1] {
            break;
        }
        let lo = t.partition_point(|&x| x < lo_t);
        let hi = t.partition_point(|&x| x <= hi_t);
        let w = std::f64::consts::PI / half;
        let Some(fit) = fit_window(&t[lo..hi], &m[lo..hi], seed, w) else {
            if turns.is_empty() {
                bail!(
                    "fewer than {} samples in a period of {:.2} s: record faster",
                    BASIS + 4,
                    2.0 * half
                );
            }
            break;
        };
        // The extremum next to tau = 0: Newton on m'(tau) = 0.
        let mut tau = 0.0;
        for _ in 0..8 {
            let d1 = eval(&fit.beta, basis_deriv(tau, w));
            let h = 1e-4 * half;
            let d2 = (eval(&fit.beta, basis_deriv(tau + h, w))
                - eval(&fit.beta, basis_deriv(tau - h, w)))
                / (2.0 * h);
            if d2 == 0.0 {
                break;
            }
            tau = (tau - d1 / d2).clamp(-0.5 * half, 0.5 * half);
        }
        let f = basis(tau, w);
        let peak = eval(&fit.beta, f) - fit.beta[0];
        // Var(m(tau*) - c) = s^2 g^T (X^T X)^-1 g, g = f - e_0.
        let mut g = DVector::from_column_slice(&f);
        g[0] -= 1.0;
        let var_a = (g.transpose() * &fit.cov * &g)[(0, 0)].max(0.0);
        let amplitude_sd = fit.rms * var_a.sqrt();
        let s = peak.signum();
        if peak.abs() < (4.0 * amplitude_sd).max(3.0 * quantum) || (sign != 0.0 && s == sign) {
            // Below the noise, or not the alternation of a swing: the
            // swinging is over.
            break;
        }
        turns.push(Turn {
            t: seed + tau,
            amplitude: peak.abs(),
            amplitude_sd,
            sign: s,
            centre: fit.beta[0],
            centre_sd: fit.rms * fit.cov[(0, 0)].max(0.0).sqrt(),
            residual_rms: fit.rms,
        });
        sign = s;
        // The half period from the turning points found, smoothed.
        if let [.., a, b] = turns.as_slice() {
            half = 0.8 * half + 0.2 * (b.t - a.t).clamp(0.5 * half, 1.5 * half);
        }
        seed = seed + tau + half;
    }
    if turns.len() < 4 {
        bail!(
            "only {} turning points above the noise: fewer than two swings to measure",
            turns.len()
        );
    }
    let mut r: Vec<f64> = turns.iter().map(|k| k.residual_rms).collect();
    Ok(Swings {
        noise: median(&mut r),
        turns,
        period,
    })
}
