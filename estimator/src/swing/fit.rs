//! The swing's equation fitted to the first measurements, before the
//! period reads: `theta'' = -w0^2 sin(theta - c) - gamma theta' + beta u`,
//! by least squares on the angle itself, twice integrated; `u` the torque
//! declared (N m, held from one measurement to the next), `beta` its
//! unknown gain (the rig's inverse inertia, 1/(kg m^2)).
//!
//! With `a = w0^2 cos c` and `b = w0^2 sin c`, `sin(theta - c) = (a sin
//! theta - b cos theta) / w0^2` exactly, so the measured angle is linear in
//! the unknowns:
//!
//! `theta(t) = theta_0 + v t + beta U(t) - a S(t) + b C(t) - gamma I(t)`,
//!
//! `S` and `C` the double integrals of `sin theta` and `cos theta` from the
//! first measurement, `I` the integral of `theta` (trapezoids at the
//! step), `U` the torque's double integral (exact: the torque is held
//! over each step), `v = theta'(0) + gamma theta_0`. Without a torque
//! `U` is zero, its column is skipped, and the fit is the free one bit
//! for bit. Each measurement is a row of the
//! regression, added by square-root-free Givens rotations (Gentleman's)
//! to its factor `R = D^(1/2) U`, `U` unit upper triangular (no matrix is
//! stored beyond it; a Cortex-M4F takes a square root in software);
//! `w0^2 = sqrt(a^2 + b^2)`. The offset
//! `c` needs no centre and the sine no small swing, and every
//! measurement, not a few crossings, times the swing: a string of 1.4 m
//! gives its length within a few percent from one period.
//!
//! Its standard deviation: the residuals' variance through `(R^T R)^-1 =
//! U^-1 D^-1 U^-T`,
//! times [`STD_SCALE`] (the residuals are not independent: a tracker's
//! noise interpolated to the steps, and the friction the equation lacks).
//! It fits for [`FIT_STEPS`] and on until the period gives its own
//! reading, then costs a comparison a step; a step without a measurement
//! starts it again, and a refused one is bridged at the last angle.
//!
//! A driven swing (a torque declared) is the one the other readers cannot
//! time: it goes where the drive takes it, past [`MAX_ANGLE`] and over
//! the top, and its period is the drive's as much as the rig's. The fit
//! follows it at any angle (sine and cosine by quadrant) and reads from
//! [`MIN_PERIODS_DRIVEN`] on. A free swing past [`MAX_ANGLE`] is read by
//! the model and the period, as before: the fit stops there, and a torque
//! that comes later starts it again.
//!
//! A driven fit does not stop when the period reads: it runs in segments of
//! [`FIT_STEPS`] (the double integrals' terms grow with the time fitted),
//! and the segments' readings, each from its own measurements, join by
//! inverse variance (no deviation below the floor, which is the fit's
//! error, not its noise). A step without a measurement closes its
//! segment where a free fit starts again.

/// Steps the fit runs at least (two windows), and on until the period
/// reads.
///
/// Unit: a count (steps). Set by hand at two windows (ff272a2); not swept.
pub(crate) const FIT_STEPS: u32 = 2 * crate::WINDOW as u32;
/// Unknowns: `theta_0`, `v`, `beta`, `a`, `b`, `gamma`.
///
/// Unit: a count. Fixed by the equation fitted (module docs).
const N: usize = 6;
/// Fewest measurements fitted before a reading.
///
/// Unit: a count (measurements). Set by hand (ff272a2); not swept.
const MIN_ROWS: u16 = 24;
/// The residuals' standard deviation scale: the reported relative standard
/// deviation of `w0^2` over the least-squares one (the residuals are not
/// independent: module docs).
///
/// Unit: dimensionless (a ratio). Set by hand (ff272a2); not swept.
const STD_SCALE: f32 = 2.0;
/// The widest relative standard deviation of `w0^2` read: a looser fit
/// (less than a period seen, or the swing lost in the noise) is none.
///
/// Unit: relative (dimensionless). Set by hand with 8cbaba4, whose figures
/// are the change's as a whole (off distribution, 3 of 120 long and 3 of
/// 120 short strings wrong after 64 rather than 21 and 44); not swept.
const MAX_REL: f32 = 0.1;
/// The fewest periods seen before a reading.
///
/// Unit: dimensionless (periods seen: the time fitted over the period, a
/// float). Set by hand with 8cbaba4 (less than a period fits the noise as
/// readily as the swing); not swept.
const MIN_PERIODS: f32 = 1.0;
/// The fewest periods seen before a driven fit reads: the torque's column
/// times the swing as well as its turns do.
///
/// Unit: dimensionless (periods seen, a float). Set by hand at half a
/// period, below the 0.87 that 64 measurements of the protocol's longest
/// rod (5 m) show; on tuning seed 5 (ours and gymnasium's,
/// `docs/driven`) every in-range rollout then reads within 5%.
const MIN_PERIODS_DRIVEN: f32 = 0.5;
/// The least relative standard deviation of `w0^2`.
///
/// Unit: relative (dimensionless). Set by hand (ff272a2); not swept.
const REL_FLOOR: f32 = 0.01;
/// The least relative standard deviation of a driven fit's `w0^2`: a
/// drive takes the swing wide and fast, where how the source integrates
/// it (a simulator's step) biases the continuous equation's fit.
///
/// Unit: relative (dimensionless). Set by hand on tuning seed 5
/// (`docs/driven`): gymnasium's driven rollouts (semi-implicit Euler at
/// 0.05 s) read up to 2.9% short, ours (RK4) at most 0.8% off; at 1.5%
/// the 2-std band covers all 120 of gymnasium's in range and all 90 of
/// ours.
const REL_FLOOR_DRIVEN: f32 = 0.015;
/// The largest half phase `w0 dt / 2` a step may span (8 steps a
/// period).
///
/// Unit: rad (a phase). Set by hand at about 8 steps a period (`pi / 0.4` =
/// 7.9), where the trapezoids' factor `x / tan x` is 0.95; not swept.
const MAX_STEP_PHASE: f32 = 0.4;
/// The widest free angle fitted, rad: real rigs swing to 1.5 rad about an
/// offset of a few hundredths. Beyond it a free fit stops (a wider
/// release is read by the model and the period, as the protocol's blob
/// was calibrated); a driven one reads on (module docs).
///
/// Unit: rad. Set by hand above real rigs' widest swing (1.5 rad); the sine
/// and cosine series is tested up to it; not swept.
const MAX_ANGLE: f32 = 1.6;

/// The regression's factor and the integrals it runs on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Fit {
    /// `D`, the strict upper triangle of `U` row by row, and the rotated
    /// targets (`U beta = z` at the solution).
    d: [f32; N],
    u: [[f32; N]; N],
    z: [f32; N],
    /// Residual sum of squares.
    rss: f32,
    /// Rows fitted.
    rows: u16,
    /// Time since the first measurement, s.
    t: f32,
    /// The last angle, its sine and cosine; the integrals `I`, `S' = int
    /// sin`, `S`, `C' = int cos`, `C`, `U' = int u` (`tq1`), `U` (`tq`).
    last: Option<[f32; 3]>,
    i: f32,
    s1: f32,
    s: f32,
    c1: f32,
    c: f32,
    tq1: f32,
    tq: f32,
    /// A torque was declared (not zero) since the fit began.
    driven: bool,
    /// The period gives its own reading.
    done: bool,
    /// A driven fit's closed segments joined: `w0^2` and its relative
    /// standard deviation (floor included).
    past: Option<(f32, f32)>,
}

impl Default for Fit {
    fn default() -> Self {
        Fit {
            d: [0.0; N],
            u: [[0.0; N]; N],
            z: [0.0; N],
            rss: 0.0,
            rows: 0,
            t: 0.0,
            last: None,
            i: 0.0,
            s1: 0.0,
            s: 0.0,
            c1: 0.0,
            c: 0.0,
            tq1: 0.0,
            tq: 0.0,
            driven: false,
            done: false,
            past: None,
        }
    }
}

impl Fit {
    /// One step's measured angle, `dt` after the last, the torque `u`
    /// held between them.
    #[inline(always)]
    pub(crate) fn push(&mut self, theta: f32, dt: f32, u: f32) {
        if self.done {
            if u == 0.0 {
                return;
            }
            // A drive after the fit stopped: it starts again, driven.
            *self = Fit {
                driven: true,
                ..Fit::default()
            };
        }
        if self.driven && u32::from(self.rows) >= FIT_STEPS {
            self.close_segment(dt);
        }
        self.push_row(theta, dt, u);
    }

    /// A driven segment's reading joined with those before it, and the
    /// fit started afresh (still driven) from the next measurement.
    #[cold]
    #[inline(never)]
    fn close_segment(&mut self, dt: f32) {
        *self = Fit {
            driven: true,
            past: self.with_segment(dt),
            ..Fit::default()
        };
    }

    /// The closed segments' reading joined with this one's.
    fn with_segment(&self, dt: f32) -> Option<(f32, f32)> {
        match (self.segment(dt, 0.0), self.past) {
            (Some(now), Some(before)) => Some(join_segments(now, before)),
            (now, before) => now.or(before),
        }
    }

    /// The integrals to `theta`, and its row rotated in.
    #[cold]
    #[inline(never)]
    fn push_row(&mut self, theta: f32, dt: f32, u: f32) {
        if libm::fabsf(theta) > MAX_ANGLE && !self.driven && u == 0.0 {
            // Free and too wide: the fit stops (a torque starts it again).
            self.done = true;
            return;
        }
        let (sn, cs) = sin_cos_any(theta);
        self.integrate(theta, sn, cs, dt, u);
        let row = [1.0, self.t, self.tq, -self.s, self.c, -self.i];
        self.add(row, theta);
    }

    /// One step whose measurement was refused: the integrals run on at
    /// the last angle (and the torque held); no row is fitted.
    pub(crate) fn hold(&mut self, dt: f32, u: f32) {
        if self.done {
            return;
        }
        if let Some([theta, sn, cs]) = self.last {
            self.integrate(theta, sn, cs, dt, u);
        }
    }

    /// A step without a measurement (`dt` the step): the fit starts
    /// again; a driven one keeps what it read so far as a closed segment.
    pub(crate) fn gap(&mut self, dt: f32) {
        if !self.done {
            let (driven, past) = if self.driven {
                (true, self.with_segment(dt))
            } else {
                (false, self.past)
            };
            *self = Fit {
                driven,
                past,
                ..Fit::default()
            };
        }
    }

    /// The period gives its own reading from now on; a driven fit reads
    /// on (the period under a drive is the drive's as much as the rig's).
    pub(crate) fn finish(&mut self) {
        self.done = !self.driven;
    }

    /// The integrals to the angle `theta` (its sine and cosine), `dt` on,
    /// the torque `u` held over the step.
    fn integrate(&mut self, theta: f32, sn: f32, cs: f32, dt: f32, u: f32) {
        if let Some([t0, s0, c0]) = self.last {
            let h = 0.5 * dt;
            if u != 0.0 {
                // A held torque's double integral is exact.
                self.driven = true;
                self.tq += dt * (self.tq1 + h * u);
                self.tq1 += dt * u;
            } else {
                self.tq += dt * self.tq1;
            }
            self.t += dt;
            self.i += h * (t0 + theta);
            let (s1, c1) = (self.s1 + h * (s0 + sn), self.c1 + h * (c0 + cs));
            self.s += h * (self.s1 + s1);
            self.c += h * (self.c1 + c1);
            (self.s1, self.c1) = (s1, c1);
        }
        self.last = Some([theta, sn, cs]);
    }

    /// The row `x` with target `y` (weight 1) rotated into `D` and `U`.
    fn add(&mut self, mut x: [f32; N], mut y: f32) {
        let mut w = 1.0f32;
        let rows = self
            .d
            .iter_mut()
            .zip(self.u.iter_mut())
            .zip(self.z.iter_mut());
        for (k, ((dk, uk), zk)) in rows.enumerate() {
            // The row is taken up whole (the first rows fill `D`).
            if w == 0.0 {
                break;
            }
            let (Some(ut), Some(xt)) = (uk.get_mut(k + 1..), x.get_mut(k..)) else {
                return;
            };
            let Some((&mut xk, xt)) = xt.split_first_mut() else {
                return;
            };
            if xk == 0.0 {
                continue;
            }
            let dp = *dk + w * xk * xk;
            let inv = 1.0 / dp;
            let (cbar, sbar) = (*dk * inv, w * xk * inv);
            w *= cbar;
            *dk = dp;
            for (uj, xj) in ut.iter_mut().zip(xt.iter_mut()) {
                let v = *xj;
                *xj = v - xk * *uj;
                *uj = cbar * *uj + sbar * v;
            }
            let v = y;
            y = v - xk * *zk;
            *zk = cbar * *zk + sbar * v;
        }
        self.rss += w * y * y;
        self.rows = self.rows.saturating_add(1);
    }

    /// `w0^2` (1/s^2) and its relative standard deviation, once
    /// [`MIN_ROWS`] measurements are fitted; the angles interpolated
    /// between a source's frames `source_dt` apart where that is more than
    /// the step `dt`.
    pub(crate) fn reading(&self, dt: f32, source_dt: f32) -> Option<(f32, f32)> {
        let Some(before) = self.past else {
            return self.segment(dt, source_dt);
        };
        let scale = if source_dt > dt {
            libm::sqrtf(source_dt / dt)
        } else {
            1.0
        };
        let before = (before.0, before.1 * scale);
        Some(match self.segment(dt, source_dt) {
            Some(now) => join_segments(now, before),
            None => before,
        })
    }

    /// [`Fit::reading`] of the measurements since the fit (or its
    /// segment) began.
    fn segment(&self, dt: f32, source_dt: f32) -> Option<(f32, f32)> {
        if self.done || self.rows < MIN_ROWS {
            return None;
        }
        let (fitted, rel) = self.solved()?;
        // The trapezoids take a swing's integral as the true one's times
        // `x / tan x`, `x = w0 dt / 2`, and `S` is two of them: `w0^2`
        // is the fitted `a` times its square, found by fixed point.
        let mut w2 = fitted;
        for _ in 0..3 {
            let x = 0.5 * libm::sqrtf(w2) * dt;
            if x >= MAX_STEP_PHASE {
                return None;
            }
            let (sn, cs) = sin_cos(x);
            let k = x * cs / sn;
            w2 = fitted * k * k;
        }
        // The rows between a source's frames are interpolations: the
        // independent ones are fewer by `h / dt`.
        let rel = if source_dt > dt {
            rel * libm::sqrtf(source_dt / dt)
        } else {
            rel
        };
        // Less than [`MIN_PERIODS`] seen fits the noise as readily as the swing.
        let seen = self.t * libm::sqrtf(w2) / core::f32::consts::TAU;
        let least = if self.driven {
            MIN_PERIODS_DRIVEN
        } else {
            MIN_PERIODS
        };
        (rel <= MAX_REL && seen >= least).then_some((w2, rel))
    }

    /// The least-squares solution's `w0^2` and relative standard deviation.
    ///
    /// `a`, `b` and `gamma` are the last three unknowns, so the lower-right
    /// 3 x 3 blocks of `D` and `U` alone give them and their covariance.
    #[cold]
    #[inline(never)]
    fn solved(&self) -> Option<(f32, f32)> {
        let [_, _, _, ua, ub, _] = self.u;
        let [_, _, _, za, zb, zg] = self.z;
        let [_, _, _, da, db, dg] = self.d;
        if da <= 0.0 || db <= 0.0 || dg <= 0.0 {
            return None;
        }
        let (uab, uag, ubg) = (ua[4], ua[5], ub[5]);
        // Back substitution, U beta = z.
        let b = zb - ubg * zg;
        let a = za - uab * b - uag * zg;
        let w2 = libm::sqrtf(a * a + b * b);
        if !(w2.is_finite() && w2 > 0.0) {
            return None;
        }
        // Rows a and b of U^-1 (unit upper triangular) over a, b, gamma.
        let (iab, ibg) = (-uab, -ubg);
        let iag = uab * ubg - uag;
        // var(w0^2) = u^T Cov(a, b) u, u = (a, b) / w0^2;
        // Cov = s^2 U^-1 D^-1 U^-T.
        let (pa, pb) = (a / w2, b / w2);
        let (g1, g2, g3) = (pa, pa * iab + pb, pa * iag + pb * ibg);
        let g = g1 * g1 / da + g2 * g2 / db + g3 * g3 / dg;
        // The torque's gain is an unknown only where a torque was declared.
        let unknowns = N as u16 - u16::from(!self.driven);
        let s2 = self.rss / f32::from(self.rows.saturating_sub(unknowns).max(1));
        let rel2 = STD_SCALE * STD_SCALE * s2 * g / (w2 * w2);
        let floor = if self.driven {
            REL_FLOOR_DRIVEN
        } else {
            REL_FLOOR
        };
        Some((w2, libm::sqrtf(rel2 + floor * floor)))
    }
}

/// Two readings of `w0^2` with their relative standard deviations joined
/// by inverse variance; the deviation no smaller than the driven floor
/// (the fit's error repeats from segment to segment).
fn join_segments((w_a, r_a): (f32, f32), (w_b, r_b): (f32, f32)) -> (f32, f32) {
    let (v_a, v_b) = ((r_a * w_a) * (r_a * w_a), (r_b * w_b) * (r_b * w_b));
    if v_a + v_b <= 0.0 || (v_a + v_b).is_nan() {
        return (w_a, r_a);
    }
    let w = (w_a * v_b + w_b * v_a) / (v_a + v_b);
    let rel = libm::sqrtf(v_a * v_b / (v_a + v_b)) / w;
    (w, rel.max(REL_FLOOR_DRIVEN))
}

/// `sin x` and `cos x` at any angle: [`sin_cos`] within [`MAX_ANGLE`],
/// beyond it at `x - k pi` (within `pi / 2`), the signs turned for odd
/// `k`.
fn sin_cos_any(x: f32) -> (f32, f32) {
    if libm::fabsf(x) <= MAX_ANGLE {
        return sin_cos(x);
    }
    let k = libm::roundf(x / core::f32::consts::PI);
    let (s, c) = sin_cos(x - k * core::f32::consts::PI);
    if libm::fmodf(k, 2.0) == 0.0 {
        (s, c)
    } else {
        (-s, -c)
    }
}

/// `sin x` and `cos x` for `|x| <= MAX_ANGLE`, by their series to `x^10`
/// (within 5e-6 there; the `libm` functions run in double precision,
/// which a Cortex-M4F emulates).
fn sin_cos(x: f32) -> (f32, f32) {
    let x2 = x * x;
    let s = x * (1.0 - x2 / 6.0 * (1.0 - x2 / 20.0 * (1.0 - x2 / 42.0 * (1.0 - x2 / 72.0))));
    let c = 1.0
        - x2 / 2.0 * (1.0 - x2 / 12.0 * (1.0 - x2 / 30.0 * (1.0 - x2 / 56.0 * (1.0 - x2 / 90.0))));
    (s, c)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing)]
mod tests {
    use super::*;

    /// The series against `libm`'s sine and cosine up to [`MAX_ANGLE`].
    #[test]
    fn the_series_is_within_5e_6() {
        for k in 0..=160 {
            let x = -MAX_ANGLE + 0.02 * k as f32;
            let (s, c) = sin_cos(x);
            assert!((s - libm::sinf(x)).abs() < 5e-6, "{x}");
            assert!((c - libm::cosf(x)).abs() < 5e-6, "{x}");
        }
    }

    /// Two segments' readings join between them, nearer the sharper, the
    /// same either way round, never below the driven floor.
    #[test]
    fn segments_join_by_inverse_variance_above_the_floor() {
        let pairs = [
            ((5.0f32, 0.02f32), (5.2f32, 0.04f32)),
            ((3.0, 0.015), (3.0, 0.015)),
            ((7.5, 0.1), (7.0, 0.016)),
        ];
        for (a, b) in pairs {
            let (w, rel) = join_segments(a, b);
            assert_eq!((w, rel), join_segments(b, a));
            assert!(w >= a.0.min(b.0) && w <= a.0.max(b.0), "{w}");
            let sharper = if a.1 * a.0 <= b.1 * b.0 { a.0 } else { b.0 };
            assert!((w - sharper).abs() <= 0.5 * (a.0 - b.0).abs() + 1e-6, "{w}");
            assert!(rel >= REL_FLOOR_DRIVEN, "{rel}");
        }
    }

    /// Beyond the series' range, the sine and cosine by quadrant against
    /// `libm`'s, over two turns either way.
    #[test]
    fn any_angle_is_within_1e_5() {
        for k in 0..=1300 {
            let x = -13.0 + 0.02 * k as f32;
            let (s, c) = sin_cos_any(x);
            assert!((s - libm::sinf(x)).abs() < 1e-5, "{x}");
            assert!((c - libm::cosf(x)).abs() < 1e-5, "{x}");
        }
    }

    /// A rod of 3 m (`w0^2 = 5`) released at 2.5 rad and pushed by a
    /// held sine, integrated finely, sampled at 0.05 s: told the torque,
    /// 64 measurements give `w0^2` within 0.5%; not told, no reading
    /// (the swing is past [`MAX_ANGLE`]).
    #[test]
    fn a_driven_swing_past_the_free_range_gives_w0_squared_only_with_its_torque() {
        let (w2, beta, dt) = (5.0f32, 1.0 / 3.0f32, 0.05f32);
        let drive = |k: usize| 1.5 * libm::sinf(1.7 * k as f32 * dt);
        let read = |declared: bool| {
            let (mut th, mut om) = (2.5f32, 0.0f32);
            let mut fit = Fit::default();
            let sub = 50;
            let h = dt / sub as f32;
            for k in 0..64 {
                let u = if k == 0 { 0.0 } else { drive(k - 1) };
                fit.push(th, dt, if declared { u } else { 0.0 });
                for _ in 0..sub {
                    om += h * (-w2 * libm::sinf(th) + beta * drive(k));
                    th += h * om;
                }
            }
            fit.reading(dt, 0.0)
        };
        let (got, rel) = read(true).unwrap();
        assert!((got / w2 - 1.0).abs() < 0.005, "{got} vs {w2}");
        assert!((REL_FLOOR_DRIVEN..0.05).contains(&rel), "{rel}");
        assert!(read(false).is_none());
    }

    /// A wide swing about an offset, damped, integrated finely: one period
    /// of it sampled at 0.04 s gives `w0^2` within 0.5%, a sharp std.
    #[test]
    fn a_damped_swing_about_an_offset_gives_w0_squared() {
        let (w2, c, gamma, dt) = (9.81f32 / 1.2, 0.08f32, 0.05f32, 0.04f32);
        let (mut th, mut om) = (c + 1.4f32, 0.0f32);
        let mut fit = Fit::default();
        let sub = 40;
        let h = dt / sub as f32;
        for _ in 0..60 {
            fit.push(th, dt, 0.0);
            for _ in 0..sub {
                // Semi-implicit Euler on the fine grid.
                om += h * (-w2 * libm::sinf(th - c) - gamma * om);
                th += h * om;
            }
        }
        let (got, rel) = fit.reading(dt, 0.0).unwrap();
        assert!((got / w2 - 1.0).abs() < 0.005, "{got} vs {w2}");
        assert!(rel < 0.05, "{rel}");
    }
}
