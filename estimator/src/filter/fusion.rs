//! The readers' evidence joined with the filter's, once: the filter's
//! coordinates read as the parameters with their calibrated standard
//! deviations, then the length joined with the swing's period, or before
//! it with the first swings' (the sharper of the half swings timed and
//! the equation fitted), each by inverse variance where they agree.
//!
//! Each piece of evidence enters once: the filter holds only the encoded
//! measurements (no reader writes into it), the first swings' two
//! readers read the same angles and so are not joined with each other,
//! and a coarse source's frames, which the filter takes several times
//! each once interpolated, count once in the reported deviation.
//!
//! The model's length carries, beside the filter's deviation scaled by
//! the blob's calibration, two terms of its own error: a coarse source's
//! interpolation ([`COARSE_SHARE`]) and the swing's width (the blob's
//! `TrustSpec::std_swing`, set by `koopman calibrate` on held-out rollouts).

use super::Estimator;
use crate::blob::ParamSpec;
use crate::swing::agm_of_cos_half;
use crate::trust;
use crate::PARAM_DIM;

/// The model's length's relative standard deviation from a source coarser
/// than the blob's interval, per `w0^2 (h^2 - dt^2)` (`h` the source's
/// interval, `dt` the blob's): the swing interpolated between frames is
/// flattened by about `(w0 h)^2`, a shape the model reads as a longer
/// length (at 5 Hz, strings of 0.1 to 0.2 m read 3 to 8% long after 64
/// measurements, their deviations 1%).
///
/// Unit: a share (dimensionless, per `(w0 h)^2`). Chosen on lab-check
/// seeds 12, 14 and 15 with `--recordings 200 --offsets -0.1,0.1 --rates
/// 5,240 --mixed` (tuning): the smallest of 0.01, 0.02 and 0.04 whose
/// 2-std band after 64 measurements covers the truth on at least 95% of
/// the sources under 12 Hz (89%, 94%, 96%; 87% without)
/// (docs/tuning.md#filterfusioncoarse_share).
pub(crate) const COARSE_SHARE: f32 = 0.04;

/// The parameters and their standard deviations as reported, the
/// period's length with its standard deviation, and how the model's
/// length stands to it ([`Estimator::with_period`]).
type Reported = ([f32; PARAM_DIM], [f32; PARAM_DIM], Option<(f32, f32)>, Agreement);

/// How the model's length stands to the period's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Agreement {
    /// No period, or the model's outside its calibrated range.
    Unknown,
    /// Within [`trust::PERIOD_AGREES`] standard deviations: joined.
    Agrees,
    /// Further apart: the period's is reported.
    Apart,
    /// Further apart and by more than [`trust::PERIOD_DISAGREES`] too: the
    /// consistency check fails unless the period is sure
    /// ([`trust::PERIOD_SURE`]).
    Disagrees,
}

/// One parameter as reported.
#[derive(Debug, Clone, Copy)]
pub(super) struct ParamRead {
    /// Its value at the blob's training gravity.
    pub(super) trained: f32,
    /// Its value at the declared gravity.
    value: f32,
    /// Its calibrated standard deviation there.
    std: f32,
}

impl ParamRead {
    /// No reading: every field NaN.
    ///
    /// No unit (a placeholder). Fixed by what it marks: NaN is the report's
    /// none for a parameter not read; not a tuning value.
    const NONE: ParamRead = ParamRead {
        trained: f32::NAN,
        value: f32::NAN,
        std: f32::NAN,
    };
}

impl Estimator<'_> {
    /// The parameters at the coordinates `q` with the filter's standard
    /// deviations `q_std`, read with the blob's calibration.
    /// The parameters the filter's coordinate `q` reads as at the declared
    /// gravity ([`FilterReport::coordinate`](crate::FilterReport::coordinate) gives it): the learned model's
    /// own estimate, before the swing's period is joined with it.
    pub fn model_params(&self, q: &[f32; PARAM_DIM]) -> [f32; PARAM_DIM] {
        self.read_params(q, &[0.0; PARAM_DIM]).map(|r| r.value)
    }

    pub(super) fn read_params(
        &self,
        q: &[f32; PARAM_DIM],
        q_std: &[f32; PARAM_DIM],
    ) -> [ParamRead; PARAM_DIM] {
        let body = &self.model.blob().body;
        let calib = &body.trust;
        core::array::from_fn(|k| {
            let at = |a: &[f32; PARAM_DIM]| a.get(k).copied().unwrap_or(f32::NAN);
            let std_calibration = [at(&calib.std_scale), at(&calib.std_floor)];
            body.params.get(k).map_or(ParamRead::NONE, |spec| {
                self.read_param(spec, at(q), at(q_std), std_calibration)
            })
        })
    }

    /// The parameters and standard deviations reported from the filter's
    /// `read`, the length joined with the period's (`w0_squared`, `w0^2`
    /// and its relative standard deviation) where there is one, each
    /// weighted by its inverse variance, and the period's length with its
    /// standard deviation. Where the filter's deviations are not
    /// `calibrated` (outside the range), or the two lie further apart
    /// than [`trust::PERIOD_AGREES`] deviations, the period's alone
    /// ([`Agreement`]).
    pub(super) fn with_period(
        &self,
        read: &[ParamRead; PARAM_DIM],
        calibrated: bool,
        w0_squared: Option<(f32, f32)>,
    ) -> Reported {
        let mut params = read.map(|r| r.value);
        let mut agreement = Agreement::Unknown;
        let mut param_std = read.map(|r| r.std);
        let body = &self.model.blob().body;
        let is_length = body
            .params
            .first()
            .is_some_and(|spec| spec.declared && spec.scales_with_g);
        let period = w0_squared
            .filter(|_| is_length)
            .map(|(w2, rel)| {
                let length = body.rig.length_at(self.g_ratio * body.g, w2);
                (length, rel * length)
            });
        if let (Some((lp, sp)), Some(l), Some(s)) = (period, params.first_mut(), param_std.first_mut())
        {
            // Two readings further apart than their deviations allow: one
            // is wrong, and the model's deviation is the one calibrated on
            // the training's draws alone.
            let known = calibrated && (*s * *s).is_finite();
            let join = if known { joined((*l, *s), (lp, sp)) } else { None };
            agreement = match join {
                Some(_) => Agreement::Agrees,
                None if !known => Agreement::Unknown,
                None if libm::fabsf(*l - lp) > trust::PERIOD_DISAGREES * lp => Agreement::Disagrees,
                None => Agreement::Apart,
            };
            (*l, *s) = join.unwrap_or((lp, sp));
        }
        (params, param_std, period, agreement)
    }

    /// The length joined with the first swings' ([`Self::first_swings`]:
    /// the half swings timed and the swing's equation fitted) before the
    /// period gives its own and for two windows, each weighted by its
    /// inverse variance, where the two agree within
    /// [`trust::PERIOD_AGREES`] deviations. Further apart, the first
    /// swings' is reported where the model is `suspect`
    /// (in the first two windows, its measurements inconsistent with it,
    /// or its swing uneven: an offset not yet subtracted), else the model's (few half swings can
    /// be wrong together); outside the `calibrated` range, the half
    /// swings' alone, as the period's. Within 5% after 64 on lab-check
    /// seeds 12, 14, 15 and 16: 708 of 800, 695 without (the half swings'
    /// wherever apart: 710); with the later timing rules, 744, 745 with
    /// the half swings' where suspect (746 with `early`'s span gate).
    ///
    /// Returns whether the first swings confirm the length: from two
    /// windows of measurements on, joined with a `calibrated` model's, at
    /// a relative standard deviation of at most [`trust::VERDICT_REL_STD`]
    /// and at most the model's. Such a length does not rest on the model's
    /// accuracy at this swing, so the swing check passes (the smallest
    /// trusted swing is where the model's own reading fails after one
    /// window: on the protocol's in-distribution rollouts of two,
    /// `docs/protocol-check/README.md`, it flagged 11 of 120 right ones;
    /// with this, 1). Before two windows, or sharper only than 5%, the
    /// rig blob's heavily damped swings (`rig_off_distribution`, viscous
    /// 0.3 to 1 1/s) were trusted wrong 3 times in 120 rather than 2.
    #[cold]
    #[inline(never)]
    pub(super) fn join_early(
        &self,
        params: &mut [f32; PARAM_DIM],
        std: &mut [f32; PARAM_DIM],
        calibrated: bool,
        suspect: bool,
    ) -> bool {
        let Some((w2, rel)) = self.first_swings() else {
            return false;
        };
        let body = &self.model.blob().body;
        if !body.params.first().is_some_and(|spec| spec.declared && spec.scales_with_g) {
            return false;
        }
        let (Some(l), Some(s)) = (params.first_mut(), std.first_mut()) else {
            return false;
        };
        let lp = body.rig.length_at(self.g_ratio * body.g, w2);
        if !(lp.is_finite() && lp > 0.0) {
            return false;
        }
        let reading = (lp, rel * lp);
        let join = joined((*l, *s), reading);
        // Sharper than the model's own calibrated reading: the length no
        // longer rests on the model's accuracy at this swing.
        let sharper = reading.1 <= *s;
        let confirms = calibrated && join.is_some() && sharper && rel <= trust::VERDICT_REL_STD && self.kalman.t.saturating_add(1) >= 2 * crate::WINDOW as u32;
        (*l, *s) = match (calibrated, join) {
            (false, _) => reading,
            (true, Some(join)) => join,
            (true, None) if suspect => reading,
            (true, None) => (*l, *s),
        };
        confirms
    }

    /// `w0^2` and its relative standard deviation from the first swings:
    /// their half swings timed ([`super::early`]) and their equation
    /// fitted ([`super::fit`]), the sharper of the two; a driven swing's
    /// half swings are the drive's, and the fit alone reads it.
    fn first_swings(&self) -> Option<(f32, f32)> {
        let dt = self.model.blob().body.dt;
        let fit = self.fit.reading(dt, self.source_dt);
        if self.driven {
            return fit;
        }
        match (self.early.reading(), fit) {
            (Some((w_e, r_e)), Some((w_f, r_f))) => {
                if r_f < r_e { Some((w_f, r_f)) } else { Some((w_e, r_e)) }
            }
            (early, fit) => early.or(fit),
        }
    }

    /// The parameter `spec` at the coordinate `q` with the filter's
    /// standard deviation `q_std`, reported with the blob's calibration
    /// `[scale, floor]`: `sqrt((scale q_std)^2 + floor^2)`, through the
    /// reading's slope.
    fn read_param(&self, spec: &ParamSpec, q: f32, q_std: f32, [a, b]: [f32; 2]) -> ParamRead {
        let scale = if spec.scales_with_g {
            self.g_ratio
        } else {
            1.0
        };
        let trained = spec.read(q);
        // A source coarser than the steps is interpolated to them: the
        // filter takes `source_dt / dt` measurements for each frame, and
        // its `P` counts each frame that many times.
        let dt = self.model.blob().body.dt;
        let q_std = if self.source_dt > dt {
            q_std * libm::sqrtf(self.source_dt / dt)
        } else {
            q_std
        };
        let calibrated = libm::sqrtf((a * q_std) * (a * q_std) + b * b);
        let std = scale * libm::fabsf(spec.slope(q)) * calibrated;
        let value = scale * trained;
        // Interpolated, a coarse source's swing is flattened between its
        // frames, by about `(w0 h)^2`, and the model reads it long.
        let coarse = if spec.scales_with_g && self.source_dt > dt {
            let body = &self.model.blob().body;
            let w2 = body.rig.omega_squared_at(body.g, trained);
            let h2 = self.source_dt * self.source_dt - dt * dt;
            COARSE_SHARE * w2 * h2 * libm::fabsf(value)
        } else {
            0.0
        };
        // The model's own error grows with the swing, by the blob's
        // calibration (`TrustSpec::std_swing`, per `c(a) - 1`).
        let per_swing = self.model.blob().body.trust.std_swing;
        let wide = match self.swing.widest() {
            Some(a) if spec.scales_with_g && per_swing > 0.0 => {
                per_swing * (1.0 / agm_of_cos_half(a) - 1.0) * libm::fabsf(value)
            }
            _ => 0.0,
        };
        let std = if (coarse + wide).is_finite() {
            libm::sqrtf(std * std + coarse * coarse + wide * wide)
        } else {
            std
        };
        ParamRead {
            trained,
            value,
            std,
        }
    }
}

/// Two readings of the length with their standard deviations, `(l, s)`
/// and `(lp, sp)`, joined by inverse variance where they agree within
/// [`trust::PERIOD_AGREES`] deviations; `None` further apart.
fn joined((l, s): (f32, f32), (lp, sp): (f32, f32)) -> Option<(f32, f32)> {
    let (vk, vp) = (s * s, sp * sp);
    let apart = l - lp;
    if apart * apart > trust::PERIOD_AGREES * trust::PERIOD_AGREES * (vk + vp) {
        return None;
    }
    if vk + vp > 0.0 {
        Some((l + vk / (vk + vp) * (lp - l), libm::sqrtf(vk * vp / (vk + vp))))
    } else {
        Some((l, s))
    }
}
