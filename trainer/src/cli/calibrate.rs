//! `koopman calibrate`: sets a blob's trust verdict on held-out rollouts
//! (`trainer_core::calibrate`) and records how in the JSON beside it. A
//! blob of an earlier format is upgraded, its model, filter and schedule
//! kept byte for byte: format 9 (before the consistency check's law), 8
//! (before the consistency check), 7 (before
//! the rig was recorded: every blob made before format 8 is a rod's, the
//! protocol's) and 6 (before the unevenness check).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use estimator::blob::{
    Activation, Blob, Body, Envelope, F32s, FORMAT_VERSION, Family, FilterSpec, Header, ParamSpec,
    Rig, TrustSpec,
};
use estimator::{PARAM_DIM, STATE_DIM};
use serde::Deserialize;
use trainer_core::calibrate::{CalibrateConfig, blob_bytes};
use trainer_core::io::write_atomic;

/// Calibrates the trust verdict of a weights blob on held-out rollouts
/// from its declared operating range, and writes the blob with the
/// figures in the JSON beside it.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The blob (format 10, or 6 to 9 to upgrade).
    blob: PathBuf,
    /// Output path (default: over the input).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Seed of the held-out sets (map, calibration, check: seed, +1, +2).
    #[arg(long, default_value_t = CalibrateConfig::default().seed)]
    seed: u64,
}

/// The trust section of format 6: without `max_unevenness`.
#[derive(Deserialize)]
struct TrustSpecV6<'a> {
    #[serde(borrow)]
    envelope: Envelope<'a>,
    envelope_max_off: u16,
    range: [f32; 2],
    std_scale: [f32; PARAM_DIM],
    std_floor: [f32; PARAM_DIM],
    min_swing: f32,
}

/// The body of format 6: format 7's without `max_unevenness`.
#[derive(Deserialize)]
struct BodyV6<'a> {
    dt: f32,
    g: f32,
    activation: Activation,
    norm_mu: [f32; STATE_DIM],
    norm_s: [f32; STATE_DIM],
    #[serde(borrow)]
    params: [ParamSpec<'a>; PARAM_DIM],
    filter: FilterSpec,
    #[serde(borrow)]
    trust: TrustSpecV6<'a>,
    #[serde(borrow)]
    _pad: &'a [u8],
    #[serde(borrow)]
    weights: F32s<'a>,
}

#[derive(Deserialize)]
struct BlobV6<'a> {
    _header: Header,
    #[serde(borrow)]
    body: BodyV6<'a>,
}

/// The trust section of formats 7 and 8: without `max_nis`.
#[derive(Deserialize)]
#[cfg_attr(test, derive(serde::Serialize))]
struct TrustSpecV8<'a> {
    #[serde(borrow)]
    envelope: Envelope<'a>,
    envelope_max_off: u16,
    range: [f32; 2],
    std_scale: [f32; PARAM_DIM],
    std_floor: [f32; PARAM_DIM],
    min_swing: f32,
    max_unevenness: f32,
}

impl<'a> TrustSpecV8<'a> {
    /// The current section, every mean innovation trusted (until
    /// calibrated again).
    fn current(self) -> TrustSpec<'a> {
        TrustSpec {
            envelope: self.envelope,
            envelope_max_off: self.envelope_max_off,
            range: self.range,
            std_scale: self.std_scale,
            std_floor: self.std_floor,
            min_swing: self.min_swing,
            max_unevenness: self.max_unevenness,
            max_nis: f32::MAX,
            nis_law: [0.0; 2],
            max_rate_mismatch: f32::MAX,
        }
    }
}

/// The trust section of format 9: format 8's, then the two checks it
/// added, without `nis_law` (postcard writes a nested struct as its
/// fields in order, so this is format 9's layout).
#[derive(Deserialize)]
#[cfg_attr(test, derive(serde::Serialize))]
struct TrustSpecV9<'a> {
    #[serde(borrow)]
    v8: TrustSpecV8<'a>,
    max_nis: f32,
    max_rate_mismatch: f32,
}

impl<'a> TrustSpecV9<'a> {
    /// The current section: the plain mean innovation, as format 9 read
    /// it (until calibrated again).
    fn current(self) -> TrustSpec<'a> {
        TrustSpec {
            max_nis: self.max_nis,
            max_rate_mismatch: self.max_rate_mismatch,
            ..self.v8.current()
        }
    }
}

/// The body of formats 8 and 9: the current one with their trust section
/// `T`.
#[derive(Deserialize)]
#[cfg_attr(test, derive(serde::Serialize))]
struct BodyV8<'a, T> {
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
    trust: T,
    #[serde(borrow)]
    _pad: &'a [u8],
    #[serde(borrow)]
    weights: F32s<'a>,
}

#[derive(Deserialize)]
#[cfg_attr(test, derive(serde::Serialize))]
struct BlobV8<'a, T> {
    _header: Header,
    #[serde(borrow)]
    body: BodyV8<'a, T>,
}

/// The body of format 7: format 8's without `rig` and `family`.
#[derive(Deserialize)]
#[cfg_attr(test, derive(serde::Serialize))]
struct BodyV7<'a> {
    dt: f32,
    g: f32,
    activation: Activation,
    norm_mu: [f32; STATE_DIM],
    norm_s: [f32; STATE_DIM],
    #[serde(borrow)]
    params: [ParamSpec<'a>; PARAM_DIM],
    filter: FilterSpec,
    #[serde(borrow)]
    trust: TrustSpecV8<'a>,
    #[serde(borrow)]
    _pad: &'a [u8],
    #[serde(borrow)]
    weights: F32s<'a>,
}

#[derive(Deserialize)]
#[cfg_attr(test, derive(serde::Serialize))]
struct BlobV7<'a> {
    _header: Header,
    #[serde(borrow)]
    body: BodyV7<'a>,
}

static CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISCSI);

/// The blob's bytes in the current format: as they are, or a blob of
/// format 6 to 9 upgraded (before 8 a rod's; format 6 with every
/// unevenness trusted, every one before 9 with every mean innovation,
/// format 9 with the plain mean innovation, law `[0, 0]`), to
/// be calibrated again by the caller.
fn current_format(bytes: &[u8], path: &Path) -> Result<Vec<u8>> {
    let header = postcard::from_bytes::<Header>(bytes).ok();
    let version = header.map(|h| h.version);
    let unreadable = |e: postcard::Error| {
        anyhow::anyhow!(
            "{}: not a readable format-{} blob: {e}",
            path.display(),
            version.unwrap_or(0)
        )
    };
    let body = match version {
        Some(6) => {
            let (old, rest) = postcard::take_from_bytes_crc32::<BlobV6>(bytes, CRC.digest())
                .map_err(unreadable)?;
            anyhow::ensure!(rest.is_empty(), "{}: trailing bytes", path.display());
            let b = old.body;
            let t = b.trust;
            let trust = TrustSpec {
                envelope: t.envelope,
                envelope_max_off: t.envelope_max_off,
                range: t.range,
                std_scale: t.std_scale,
                std_floor: t.std_floor,
                min_swing: t.min_swing,
                max_unevenness: f32::MAX,
                max_nis: f32::MAX,
                nis_law: [0.0; 2],
                max_rate_mismatch: f32::MAX,
            };
            body(
                b.dt,
                b.g,
                b.activation,
                [b.norm_mu, b.norm_s],
                b.params,
                b.filter,
                trust,
                b.weights,
            )
        }
        Some(7) => {
            let (old, rest) = postcard::take_from_bytes_crc32::<BlobV7>(bytes, CRC.digest())
                .map_err(unreadable)?;
            anyhow::ensure!(rest.is_empty(), "{}: trailing bytes", path.display());
            let b = old.body;
            body(
                b.dt,
                b.g,
                b.activation,
                [b.norm_mu, b.norm_s],
                b.params,
                b.filter,
                b.trust.current(),
                b.weights,
            )
        }
        Some(8) => {
            let (old, rest) =
                postcard::take_from_bytes_crc32::<BlobV8<TrustSpecV8>>(bytes, CRC.digest())
                    .map_err(unreadable)?;
            anyhow::ensure!(rest.is_empty(), "{}: trailing bytes", path.display());
            old.body.current(TrustSpecV8::current)
        }
        Some(9) => {
            let (old, rest) =
                postcard::take_from_bytes_crc32::<BlobV8<TrustSpecV9>>(bytes, CRC.digest())
                    .map_err(unreadable)?;
            anyhow::ensure!(rest.is_empty(), "{}: trailing bytes", path.display());
            old.body.current(TrustSpecV9::current)
        }
        // Current, or broken in a way the reader names.
        _ => {
            Blob::from_bytes(bytes).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
            return Ok(bytes.to_vec());
        }
    };
    eprintln!(
        "{}: format {}, upgraded to {FORMAT_VERSION} (model, filter and schedule unchanged; before format 8, a rod's)",
        path.display(),
        version.unwrap_or(0)
    );
    // The old header's widths (a narrow blob stays narrow), this format.
    let header = Header {
        version: FORMAT_VERSION,
        ..header.unwrap_or(Header::CURRENT)
    };
    blob_bytes(&Blob { header, body })
}

impl<'a, T> BodyV8<'a, T> {
    /// The current body, its trust section made current by `trust`.
    fn current(self, trust: impl FnOnce(T) -> TrustSpec<'a>) -> Body<'a> {
        Body {
            dt: self.dt,
            g: self.g,
            rig: self.rig,
            family: self.family,
            activation: self.activation,
            norm_mu: self.norm_mu,
            norm_s: self.norm_s,
            params: self.params,
            filter: self.filter,
            trust: trust(self.trust),
            pad: &[],
            weights: self.weights,
        }
    }
}

/// A current body from an older blob's parts; every blob before format 8
/// is a rod's, and linear.
#[allow(clippy::too_many_arguments)]
fn body<'a>(
    dt: f32,
    g: f32,
    activation: Activation,
    [norm_mu, norm_s]: [[f32; STATE_DIM]; 2],
    params: [ParamSpec<'a>; PARAM_DIM],
    filter: FilterSpec,
    trust: TrustSpec<'a>,
    weights: F32s<'a>,
) -> Body<'a> {
    Body {
        dt,
        g,
        rig: Rig::Rod,
        family: Family::Linear,
        activation,
        norm_mu,
        norm_s,
        params,
        filter,
        trust,
        pad: &[],
        weights,
    }
}

/// Runs it.
pub fn run(a: Args) -> Result<()> {
    let bytes = std::fs::read(&a.blob).with_context(|| a.blob.display().to_string())?;
    let bytes = current_format(&bytes, &a.blob)?;
    // Held-out rollouts as the blob's training set was drawn (its
    // sidecar's config; the protocol's without one).
    let cfg = CalibrateConfig {
        seed: a.seed,
        ..trainer::export::calibration_for(&trainer::export::config_of(&a.blob))
    };
    let (out_bytes, report) = trainer::export::calibrate_with_progress(&bytes, &cfg)?;
    let out = a.out.unwrap_or(a.blob.clone());
    write_atomic(&out, &out_bytes)?;
    let sidecar = a.blob.with_extension("json");
    let mut info = std::fs::read_to_string(&sidecar)
        .ok()
        .and_then(|s| serde_json::from_str::<serde_json::Value>(&s).ok())
        .unwrap_or_else(|| serde_json::json!({}));
    info["trust"] = serde_json::to_value(&report)?;
    info["blob_bytes"] = serde_json::json!(out_bytes.len());
    write_atomic(
        &out.with_extension("json"),
        serde_json::to_string_pretty(&info)?.as_bytes(),
    )?;
    super::say(&format!(
        "wrote {} ({} bytes): envelope allows {} of {} measurements off, range [{:.3}, {:.3}], std x{:.2} + {:.3e}, swing at least {:.3} rad, unevenness at most {:.3}, mean innovation x L^{:.3} / s^{:.3} at most {:.4e}, rate ratio within {:.3} of 1",
        out.display(),
        out_bytes.len(),
        report.envelope_max_off,
        trainer_core::protocol::WINDOW,
        report.range[0],
        report.range[1],
        report.std_scale,
        report.std_floor,
        report.min_swing,
        report.max_unevenness,
        report.nis_law[0],
        report.nis_law[1],
        report.max_nis,
        report.max_rate_mismatch
    ))?;
    for c in &report.check {
        super::say(&format!(
            "check set after {} steps: {} of {} flagged ({} of them within 20%), {} within 2 std, {} within 20%, {} more than 20% off and trusted",
            c.steps,
            c.flagged,
            c.rollouts,
            c.false_flags,
            c.covered,
            c.within_20_percent,
            c.wrong_trusted
        ))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The trust section of `t` as formats 7 and 8 wrote it.
    fn v8_trust<'a>(t: &TrustSpec<'a>) -> TrustSpecV8<'a> {
        TrustSpecV8 {
            envelope: t.envelope,
            envelope_max_off: t.envelope_max_off,
            range: t.range,
            std_scale: t.std_scale,
            std_floor: t.std_floor,
            min_swing: t.min_swing,
            max_unevenness: t.max_unevenness,
        }
    }

    /// `blob` written back in the layout of formats 8 and 9 with the
    /// header's `version` and the trust section `trust`.
    fn written_back<T: serde::Serialize>(blob: &Blob<'_>, version: u16, trust: T) -> Vec<u8> {
        let b = blob.body;
        let old = BlobV8 {
            _header: Header {
                version,
                ..blob.header
            },
            body: BodyV8 {
                dt: b.dt,
                g: b.g,
                rig: b.rig,
                family: b.family,
                activation: b.activation,
                norm_mu: b.norm_mu,
                norm_s: b.norm_s,
                params: b.params,
                filter: b.filter,
                trust,
                _pad: &[],
                weights: b.weights,
            },
        };
        postcard::to_allocvec_crc32(&old, CRC.digest()).unwrap()
    }

    /// The shipped blob written back as format 8 (its trust section
    /// without `max_nis` and `max_rate_mismatch`) upgrades to the shipped
    /// blob with those two checks open and the law `[0, 0]`, byte for byte; `koopman
    /// calibrate` then sets them.
    #[test]
    fn a_format_8_blob_upgrades_to_the_same_blob() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../weights/pendulum.kkf");
        let shipped = std::fs::read(&path).unwrap();
        let blob = Blob::from_bytes(&shipped).unwrap();
        let v8 = written_back(&blob, 8, v8_trust(&blob.body.trust));
        assert!(Blob::from_bytes(&v8).is_err(), "format 8 read as current");
        assert_eq!(current_format(&v8, &path).unwrap(), unchecked(&shipped));
    }

    /// `bytes` with format 9's two checks open (every mean innovation and
    /// rate ratio passing) and format 10's law `[0, 0]`: what an upgrade
    /// writes before it is calibrated again.
    fn unchecked(bytes: &[u8]) -> Vec<u8> {
        let mut b = Blob::from_bytes(bytes).unwrap();
        b.body.trust.max_nis = f32::MAX;
        b.body.trust.nis_law = [0.0; 2];
        b.body.trust.max_rate_mismatch = f32::MAX;
        blob_bytes(&b).unwrap()
    }

    /// The rig blob written back as format 9 (its trust section without
    /// the consistency law) upgrades to the rig blob with the law `[0, 0]`
    /// and every other threshold kept, byte for byte.
    #[test]
    fn a_format_9_blob_upgrades_with_the_plain_mean() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../weights/rig.kkf");
        let shipped = std::fs::read(&path).unwrap();
        let blob = Blob::from_bytes(&shipped).unwrap();
        let t = blob.body.trust;
        assert_ne!(t.nis_law, [0.0; 2], "the rig blob's law is fitted");
        // The rig blob's own widths (64): the upgrade keeps them.
        let v9 = written_back(
            &blob,
            9,
            TrustSpecV9 {
                v8: v8_trust(&t),
                max_nis: t.max_nis,
                max_rate_mismatch: t.max_rate_mismatch,
            },
        );
        assert!(Blob::from_bytes(&v9).is_err(), "format 9 read as current");
        let mut want = Blob::from_bytes(&shipped).unwrap();
        want.body.trust.nis_law = [0.0; 2];
        let (got, want) = (
            current_format(&v9, &path).unwrap(),
            blob_bytes(&want).unwrap(),
        );
        let first = got.iter().zip(&want).position(|(a, b)| a != b);
        assert!(
            got == want,
            "{} against {} bytes, first difference at {first:?}",
            got.len(),
            want.len()
        );
    }

    /// The shipped blob written back as format 7 (its body without the
    /// rig, the header's version 7) upgrades to the shipped blob (format
    /// 9's checks open, format 10's law `[0, 0]`), byte for byte: the upgrade adds the rod and
    /// changes nothing else.
    #[test]
    fn a_format_7_blob_upgrades_to_the_same_blob_with_the_rod() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../weights/pendulum.kkf");
        let shipped = std::fs::read(&path).unwrap();
        let b = Blob::from_bytes(&shipped).unwrap().body;
        assert_eq!(b.rig, Rig::Rod);
        let old = BlobV7 {
            _header: Header {
                version: 7,
                ..Header::CURRENT
            },
            body: BodyV7 {
                dt: b.dt,
                g: b.g,
                activation: b.activation,
                norm_mu: b.norm_mu,
                norm_s: b.norm_s,
                params: b.params,
                filter: b.filter,
                trust: v8_trust(&b.trust),
                _pad: &[],
                weights: b.weights,
            },
        };
        let v7 = postcard::to_allocvec_crc32(&old, CRC.digest()).unwrap();
        assert!(Blob::from_bytes(&v7).is_err(), "format 7 read as current");
        assert_eq!(current_format(&v7, &path).unwrap(), unchecked(&shipped));
        // A current blob passes through; a truncated one is refused.
        assert_eq!(current_format(&shipped, &path).unwrap(), shipped);
        assert!(current_format(&v7[..v7.len() - 9], &path).is_err());
    }
}
