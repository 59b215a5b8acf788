//! The gain schedule: the filter's first updates' gains computed in f64
//! at export (the covariance recursion does not depend on the
//! measurements), checked against the full recursion in two forms, and
//! the constant-gain tail after them.

use anyhow::{Context, Result};
use estimator::blob::{FilterSpec, TAIL_LEN};
use estimator::{AUG_DIM, LATENT_DIM, PARAM_DIM};
use nalgebra::{SMatrix, SVector};
use serde::Serialize;

type Aug64 = SMatrix<f64, AUG_DIM, AUG_DIM>;
type Lat64 = SMatrix<f64, LATENT_DIM, LATENT_DIM>;
type Cols64 = SMatrix<f64, LATENT_DIM, PARAM_DIM>;
type Par64 = SMatrix<f64, PARAM_DIM, PARAM_DIM>;

/// The textbook filter's covariance recursion in f64 (the exporter's own,
/// independent of the estimator's and of `crate::reference`, which the
/// tests hold the scheduled estimator to): `P' = F P F^T + Q`,
/// `S = H P' H^T + R` (Cholesky), `K = P' H^T S^-1`, and Joseph's
/// `P = (I - K H) P' (I - K H)^T + K R K^T`, made exactly symmetric.
struct Full {
    f: Aug64,
    q: Aug64,
    r: Lat64,
    p: Aug64,
}

impl Full {
    /// One update; returns `K^T` (`LATENT x AUG`).
    fn update(&mut self, n: usize) -> Result<SMatrix<f64, LATENT_DIM, AUG_DIM>> {
        let h = SMatrix::<f64, LATENT_DIM, AUG_DIM>::from_fn(|i, j| f64::from(u8::from(i == j)));
        let pp = self.f * self.p * self.f.transpose() + self.q;
        let s = h * pp * h.transpose() + self.r;
        let chol = s
            .cholesky()
            .with_context(|| format!("gain schedule: S not positive definite at update {n}"))?;
        // K^T = S^-1 H P' (S and P' symmetric).
        let kt = chol.solve(&(h * pp));
        let ikh = Aug64::identity() - kt.transpose() * h;
        let joseph = ikh * pp * ikh.transpose() + kt.transpose() * self.r * kt;
        self.p = (joseph + joseph.transpose()) * 0.5;
        Ok(kt)
    }
}

/// Friedland's two-stage form of the same filter, exact when the
/// parameters are static (`Q_p = 0`) and the prior has no `y`-`p`
/// covariance: a bias-free filter over `y` alone (`P~`, gain `K~`,
/// innovation covariance `S~`), whose recursion does not involve `p`, and
/// the parameters' filter (`P_b`) with the sensitivity of `y` to `p`
/// (`U` predicted, `V` updated). The whole filter's gain is
/// `K_y = K~ + V K_b`, `K_p = K_b`, and its covariance
/// `P = [P~ + V P_b V^T, V P_b; P_b V^T, P_b]`.
struct TwoStage {
    a: Lat64,
    b: Cols64,
    qy: Lat64,
    r: Lat64,
    /// `P~` after the update.
    pt: Lat64,
    v: Cols64,
    pb: Par64,
}

impl TwoStage {
    /// The bias-free filter's next gain `K~` and `S~^-1`, from `P~`.
    fn bias_free_gain(&self) -> Result<(Lat64, Lat64, Lat64)> {
        let ptm = self.a * self.pt * self.a.transpose() + self.qy;
        let si = (ptm + self.r)
            .cholesky()
            .context("two-stage: S~ not positive definite")?
            .inverse();
        Ok((ptm * si, si, ptm))
    }

    /// One update with the bias-free gain `(k, si, ptm)` (the exact one,
    /// or a constant one in the tail).
    fn update(&mut self, (k, si, ptm): (Lat64, Lat64, Lat64)) -> Result<()> {
        let ik = Lat64::identity() - k;
        let joseph = ik * ptm * ik.transpose() + k * self.r * k.transpose();
        self.pt = (joseph + joseph.transpose()) * 0.5;
        let u = self.a * self.v + self.b;
        let w = si * u;
        let m2 = Par64::identity() + self.pb * (u.transpose() * w);
        let m2i = m2
            .try_inverse()
            .context("two-stage: I + P_b U^T S~^-1 U singular")?;
        let kb = m2i * self.pb * w.transpose();
        let e = kb * u;
        let j = Par64::identity() - e;
        let pb = j * self.pb * j.transpose() + m2i * self.pb * e.transpose();
        self.pb = (pb + pb.transpose()) * 0.5;
        self.v = u - k * u;
        Ok(())
    }

    /// `P` of the whole filter.
    fn covariance(&self) -> Aug64 {
        let mut p = Aug64::zeros();
        let vpb = self.v * self.pb;
        p.fixed_view_mut::<LATENT_DIM, LATENT_DIM>(0, 0)
            .copy_from(&(self.pt + vpb * self.v.transpose()));
        p.fixed_view_mut::<LATENT_DIM, PARAM_DIM>(0, LATENT_DIM)
            .copy_from(&vpb);
        p.fixed_view_mut::<PARAM_DIM, LATENT_DIM>(LATENT_DIM, 0)
            .copy_from(&vpb.transpose());
        p.fixed_view_mut::<PARAM_DIM, PARAM_DIM>(LATENT_DIM, LATENT_DIM)
            .copy_from(&self.pb);
        p
    }
}

/// How the gain schedule was checked at export.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct ScheduleCheck {
    /// Largest `|P - P_two-stage|` over the schedule's updates, relative to
    /// `max |P|`: the two forms of the filter agree (f64).
    pub two_stage_gap: f64,
    /// Largest change of the bias-free gain `K~` at the schedule's last
    /// update, relative to `max |K~|`: how far it had converged.
    pub bias_free_change: f64,
    /// Largest relative difference of the parameters' standard deviation
    /// between the exact recursion and the tail's constant `K~`, over
    /// [`TAIL_CHECK_STEPS`] updates after the schedule.
    pub tail_std_gap: f64,
}

/// Updates after the schedule over which the constant-gain tail is
/// checked against the exact recursion.
pub const TAIL_CHECK_STEPS: usize = 2000;

/// The gain schedule of `filter.schedule_steps` updates for `F`
/// (row-major), as the blob stores it (see `estimator::blob`): per update
/// `K^T` and the parameters' standard deviations, then the tail: `S~^-1`
/// and `P~` of the converged bias-free filter, `V_T` and `P_b,T`.
///
/// Both forms of the filter run side by side in f64 and must agree at
/// every update; the bias-free gain must have converged by the last
/// update (its change below 1e-9 of its size), and the tail, run with that
/// gain held constant, must give the parameters' standard deviations of
/// the exact recursion within 1e-6 relative for [`TAIL_CHECK_STEPS`]
/// updates. Otherwise an error says which check failed.
pub fn gain_schedule(f: &[f32], filter: &FilterSpec) -> Result<(Vec<f32>, ScheduleCheck)> {
    anyhow::ensure!(f.len() == AUG_DIM * AUG_DIM, "F has {} values", f.len());
    let f = Aug64::from_row_iterator(f.iter().map(|&v| f64::from(v)));
    let q = Aug64::from_diagonal(&SVector::from_iterator(
        filter.q.iter().map(|&x| f64::from(x)),
    ));
    let r = Lat64::from_diagonal(&SVector::from_iterator(
        filter.r.iter().map(|&x| f64::from(x)),
    ));
    let prior = Aug64::from_diagonal(&SVector::from_iterator(
        filter.prior_var.iter().map(|&x| f64::from(x)),
    ));
    let steps = usize::from(filter.schedule_steps);
    let mut check = ScheduleCheck {
        two_stage_gap: 0.0,
        bias_free_change: 0.0,
        tail_std_gap: 0.0,
    };
    if steps == 0 {
        return Ok((Vec::new(), check));
    }
    anyhow::ensure!(
        filter.q[LATENT_DIM..].iter().all(|&v| v == 0.0),
        "gain schedule: the parameters have process noise, so they are not static"
    );
    let mut full = Full { f, q, r, p: prior };
    let mut two = TwoStage {
        a: f.fixed_view::<LATENT_DIM, LATENT_DIM>(0, 0).into_owned(),
        b: f.fixed_view::<LATENT_DIM, PARAM_DIM>(0, LATENT_DIM)
            .into_owned(),
        qy: q.fixed_view::<LATENT_DIM, LATENT_DIM>(0, 0).into_owned(),
        r,
        pt: prior
            .fixed_view::<LATENT_DIM, LATENT_DIM>(0, 0)
            .into_owned(),
        v: Cols64::zeros(),
        pb: prior
            .fixed_view::<PARAM_DIM, PARAM_DIM>(LATENT_DIM, LATENT_DIM)
            .into_owned(),
    };
    let mut out = Vec::with_capacity(steps * estimator::blob::SCHEDULE_STEP_LEN + TAIL_LEN);
    let mut last_k = Lat64::zeros();
    for n in 1..=steps {
        let kt = full.update(n)?;
        let gain = two.bias_free_gain()?;
        last_k = gain.0;
        two.update(gain)?;
        let scale = full.p.amax().max(f64::MIN_POSITIVE);
        check.two_stage_gap = check
            .two_stage_gap
            .max((full.p - two.covariance()).amax() / scale);
        for k in 0..LATENT_DIM {
            out.extend((0..AUG_DIM).map(|i| kt[(k, i)] as f32));
        }
        out.extend((0..PARAM_DIM).map(|a| {
            let v = full.p[(LATENT_DIM + a, LATENT_DIM + a)];
            v.max(0.0).sqrt() as f32
        }));
    }
    anyhow::ensure!(
        check.two_stage_gap < 1e-9,
        "gain schedule: the two-stage filter departs from the full one by {:.1e}",
        check.two_stage_gap
    );
    // The tail: the next bias-free gain, held from here on.
    let tail = two.bias_free_gain()?;
    check.bias_free_change = (tail.0 - last_k).amax() / tail.0.amax().max(f64::MIN_POSITIVE);
    anyhow::ensure!(
        check.bias_free_change < 1e-9,
        "gain schedule: the bias-free gain still changes by {:.1e} (relative) at update {steps}; \
         a longer schedule is needed",
        check.bias_free_change
    );
    // K~ = P~' S~^-1 = I - R S~^-1: the device needs S~^-1 only.
    let si = (tail.1 + tail.1.transpose()) * 0.5;
    out.extend(si.iter().map(|&v| v as f32)); // exactly symmetric
    out.extend(two.pt.iter().map(|&v| v as f32)); // symmetric
    out.extend(two.v.iter().map(|&v| v as f32)); // column by column
    out.extend(two.pb.iter().map(|&v| v as f32)); // symmetric
    // The tail against the exact recursion.
    let mut held = two;
    for n in steps + 1..=steps + TAIL_CHECK_STEPS {
        full.update(n)?;
        held.update(tail)?;
        for a in 0..PARAM_DIM {
            let exact = full.p[(LATENT_DIM + a, LATENT_DIM + a)].max(0.0).sqrt();
            let ours = held.pb[(a, a)].max(0.0).sqrt();
            if exact > 0.0 {
                check.tail_std_gap = check.tail_std_gap.max((exact - ours).abs() / exact);
            }
        }
    }
    anyhow::ensure!(
        check.tail_std_gap < 1e-6,
        "gain schedule: with the bias-free gain held, the parameters' std departs by {:.1e}",
        check.tail_std_gap
    );
    anyhow::ensure!(
        out.iter().all(|v| v.is_finite()),
        "gain schedule: not finite"
    );
    Ok((out, check))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small stable system: the latent block 0.9 I plus a small
    /// asymmetric coupling, the parameters' columns arbitrary.
    fn toy_f() -> Vec<f32> {
        let mut f = vec![0.0f32; AUG_DIM * AUG_DIM];
        for i in 0..LATENT_DIM {
            for j in 0..LATENT_DIM {
                f[i * AUG_DIM + j] = if i == j {
                    0.9
                } else {
                    0.02 * ((i * 7 + j * 3) as f32).sin()
                };
            }
            f[i * AUG_DIM + LATENT_DIM] = 0.1 * (i as f32).cos();
            f[i * AUG_DIM + LATENT_DIM + 1] = 0.05;
        }
        for k in LATENT_DIM..AUG_DIM {
            f[k * AUG_DIM + k] = 1.0;
        }
        f
    }

    fn toy_filter(steps: u16) -> FilterSpec {
        let mut q = [0.01; AUG_DIM];
        q[LATENT_DIM..].fill(0.0);
        let mut prior_var = [0.01; AUG_DIM];
        prior_var[LATENT_DIM] = 25.0;
        prior_var[LATENT_DIM + 1] = 0.0;
        FilterSpec {
            q,
            r: [0.02; LATENT_DIM],
            prior_mean: [0.0; PARAM_DIM],
            prior_var,
            burn_in: 32,
            sigma_threshold: 1.0,
            schedule_steps: steps,
        }
    }

    #[test]
    fn gain_schedule_checks_its_two_stage_tail() {
        let f = toy_f();
        let (values, check) = gain_schedule(&f, &toy_filter(63)).unwrap();
        assert_eq!(
            values.len(),
            63 * estimator::blob::SCHEDULE_STEP_LEN + TAIL_LEN
        );
        // Both forms in f64: agreement to rounding (1e-12 leaves 4 digits
        // of room above f64's 2e-16 for 100 products).
        assert!(check.two_stage_gap < 1e-12, "{check:?}");
        assert!(check.bias_free_change < 1e-9, "{check:?}");
        assert!(check.tail_std_gap < 1e-6, "{check:?}");
        // Update 1's gain: with P' = F P0 F^T + Q, the length's gain
        // row is (P'_py S^-1); its first entry must not be zero here.
        assert!(values[LATENT_DIM] != 0.0);
        // Two updates are too few for the bias-free gain to settle.
        let err = gain_schedule(&f, &toy_filter(2)).unwrap_err().to_string();
        assert!(err.contains("still changes"), "{err}");
        // Parameters with process noise are not static.
        let mut noisy = toy_filter(63);
        noisy.q[LATENT_DIM] = 1e-4;
        let err = gain_schedule(&f, &noisy).unwrap_err().to_string();
        assert!(err.contains("process noise"), "{err}");
        // No schedule: nothing to store.
        assert!(gain_schedule(&f, &toy_filter(0)).unwrap().0.is_empty());
    }
}
