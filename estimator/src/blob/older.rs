//! Formats 11 and 12, read as the current one: their trust section ends
//! before [`TrustSpec::std_swing`], which reads as 0 (no term for the
//! swing added to the reported deviation). Everything else is laid out as
//! now.

use serde::Deserialize;

use super::{Activation, Body, Envelope, F32s, Family, FilterSpec, Header, ParamSpec, TrustSpec};
use crate::{PARAM_DIM, Rig, STATE_DIM};

/// A blob of format 11 or 12.
#[derive(Deserialize)]
pub(super) struct BlobV12<'a> {
    pub(super) header: Header,
    #[serde(borrow)]
    body: BodyV12<'a>,
}

/// [`Body`] of formats 11 and 12 (postcard writes a struct as its fields in
/// order: only the trust section differs).
#[derive(Deserialize, Clone, Copy)]
struct BodyV12<'a> {
    dt: f32,
    g: f32,
    rig: Rig,
    family: Family,
    activation: Activation,
    norm_mu: [f32; STATE_DIM],
    norm_s: [f32; STATE_DIM],
    #[serde(borrow)]
    params: [ParamSpec<'a>; PARAM_DIM],
    filter: FilterSpec,
    #[serde(borrow)]
    trust: TrustSpecV12<'a>,
    #[serde(borrow)]
    pad: &'a [u8],
    #[serde(borrow)]
    weights: F32s<'a>,
}

/// [`TrustSpec`] of formats 11 and 12: without `std_swing`.
#[derive(Deserialize, Clone, Copy)]
struct TrustSpecV12<'a> {
    #[serde(borrow)]
    envelope: Envelope<'a>,
    envelope_max_off: u16,
    range: [f32; 2],
    std_scale: [f32; PARAM_DIM],
    std_floor: [f32; PARAM_DIM],
    min_swing: f32,
    max_unevenness: f32,
    max_nis: f32,
    nis_law: [f32; 2],
    max_rate_mismatch: f32,
    max_step_nis: f32,
    min_samples_per_period: f32,
}

impl<'a> BlobV12<'a> {
    /// The current body, `std_swing` 0; the header as read.
    pub(super) fn body(self) -> Body<'a> {
        let b = self.body;
        let t = b.trust;
        Body {
            dt: b.dt,
            g: b.g,
            rig: b.rig,
            family: b.family,
            activation: b.activation,
            norm_mu: b.norm_mu,
            norm_s: b.norm_s,
            params: b.params,
            filter: b.filter,
            trust: TrustSpec {
                envelope: t.envelope,
                envelope_max_off: t.envelope_max_off,
                range: t.range,
                std_scale: t.std_scale,
                std_floor: t.std_floor,
                min_swing: t.min_swing,
                max_unevenness: t.max_unevenness,
                max_nis: t.max_nis,
                nis_law: t.nis_law,
                max_rate_mismatch: t.max_rate_mismatch,
                max_step_nis: t.max_step_nis,
                min_samples_per_period: t.min_samples_per_period,
                std_swing: 0.0,
            },
            pad: b.pad,
            weights: b.weights,
        }
    }
}
