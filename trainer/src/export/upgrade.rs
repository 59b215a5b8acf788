//! Blobs of earlier formats read and upgraded to the current one, their
//! model, filter and schedule kept byte for byte: format 10 (before the
//! outlier gate and the source's samples a period), 9 (before the
//! consistency check's law), 8 (before the consistency check), 7 (before
//! the rig was recorded: every blob made before format 8 is a rod's, the
//! protocol's) and 6 (before the unevenness check). `koopman calibrate`
//! upgrades a blob so, then calibrates it again.

use std::path::Path;

use anyhow::Result;
use estimator::blob::{
    Activation, Blob, Body, CRC, Envelope, F32s, FORMAT_VERSION, Family, FilterSpec, Header,
    ParamSpec, TrustSpec,
};
use estimator::{PARAM_DIM, Rig, STATE_DIM};
use serde::Deserialize;
use trainer_core::calibrate::{OPEN, blob_bytes};

/// The trust section of format 6: without `max_unevenness`.
#[derive(Deserialize)]
#[cfg_attr(test, derive(serde::Serialize))]
struct TrustSpecV6<'a> {
    #[serde(borrow)]
    envelope: Envelope<'a>,
    envelope_max_off: u16,
    range: [f32; 2],
    std_scale: [f32; PARAM_DIM],
    std_floor: [f32; PARAM_DIM],
    min_swing: f32,
}

impl<'a> TrustSpecV6<'a> {
    /// The current section, every unevenness, mean innovation and rate
    /// ratio trusted (until calibrated again).
    fn current(self) -> TrustSpec<'a> {
        TrustSpec {
            envelope: self.envelope,
            envelope_max_off: self.envelope_max_off,
            range: self.range,
            std_scale: self.std_scale,
            std_floor: self.std_floor,
            min_swing: self.min_swing,
            ..OPEN
        }
    }
}

/// The trust section of formats 7 and 8: format 6's, then
/// `max_unevenness` (postcard writes a nested struct as its fields in
/// order, as for [`TrustSpecV9`]).
#[derive(Deserialize)]
#[cfg_attr(test, derive(serde::Serialize))]
struct TrustSpecV8<'a> {
    #[serde(borrow)]
    v6: TrustSpecV6<'a>,
    max_unevenness: f32,
}

impl<'a> TrustSpecV8<'a> {
    /// The current section, every mean innovation and rate ratio trusted
    /// (until calibrated again).
    fn current(self) -> TrustSpec<'a> {
        TrustSpec {
            max_unevenness: self.max_unevenness,
            ..self.v6.current()
        }
    }
}

/// The trust section of format 9: format 8's, then the two checks it
/// added, without `nis_law`.
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

/// The trust section of format 10: format 8's, then the consistency
/// check with its law and the rate check, without the outlier gate and
/// the source's samples a period.
#[derive(Deserialize)]
#[cfg_attr(test, derive(serde::Serialize))]
struct TrustSpecV10<'a> {
    #[serde(borrow)]
    v8: TrustSpecV8<'a>,
    max_nis: f32,
    nis_law: [f32; 2],
    max_rate_mismatch: f32,
}

impl<'a> TrustSpecV10<'a> {
    /// The current section, no measurement refused and every source
    /// passing (until calibrated again).
    fn current(self) -> TrustSpec<'a> {
        TrustSpec {
            max_nis: self.max_nis,
            nis_law: self.nis_law,
            max_rate_mismatch: self.max_rate_mismatch,
            ..self.v8.current()
        }
    }
}

/// What follows the rig and family in the body of formats 6 to 10 (the
/// gravity in 6 and 7, which record neither), with their trust section
/// `T`.
#[derive(Deserialize)]
#[cfg_attr(test, derive(serde::Serialize))]
struct Rest<'a, T> {
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

/// The body of formats 6 and 7: no rig and family (every blob before
/// format 8 is a rod's, and linear).
#[derive(Deserialize)]
#[cfg_attr(test, derive(serde::Serialize))]
struct BodyV7<'a, T> {
    dt: f32,
    g: f32,
    #[serde(borrow)]
    rest: Rest<'a, T>,
}

impl<'a, T> BodyV7<'a, T> {
    /// This body in format 8's layout: a linear rod's.
    fn with_rod(self) -> BodyV8<'a, T> {
        BodyV8 {
            dt: self.dt,
            g: self.g,
            rig: Rig::Rod,
            family: Family::Linear,
            rest: self.rest,
        }
    }
}

/// The body of formats 8 to 10.
#[derive(Deserialize)]
#[cfg_attr(test, derive(serde::Serialize))]
struct BodyV8<'a, T> {
    dt: f32,
    g: f32,
    rig: Rig,
    family: Family,
    #[serde(borrow)]
    rest: Rest<'a, T>,
}

impl<'a, T> BodyV8<'a, T> {
    /// The current body, its trust section made current by `trust`.
    fn current(self, trust: impl FnOnce(T) -> TrustSpec<'a>) -> Body<'a> {
        let rest = self.rest;
        Body {
            dt: self.dt,
            g: self.g,
            rig: self.rig,
            family: self.family,
            activation: rest.activation,
            norm_mu: rest.norm_mu,
            norm_s: rest.norm_s,
            params: rest.params,
            filter: rest.filter,
            trust: trust(rest.trust),
            pad: &[],
            weights: rest.weights,
        }
    }
}

/// A blob of an earlier format: its header, then its body `B`.
#[derive(Deserialize)]
#[cfg_attr(test, derive(serde::Serialize))]
struct Old<B> {
    _header: Header,
    body: B,
}

/// A blob in the current format.
pub struct Current {
    /// Its bytes.
    pub bytes: Vec<u8>,
    /// The format it was upgraded from (`None`: it was current).
    pub upgraded_from: Option<u16>,
}

/// The blob's bytes in the current format: as they are, or a blob of
/// format 6 to 10 upgraded (before 8 a rod's; format 6 with every
/// unevenness trusted, every one before 9 with every mean innovation,
/// format 9 with the plain mean innovation, law `[0, 0]`; none with an
/// outlier gate or a source check), to
/// be calibrated again by the caller. `path` names the blob in errors.
pub fn current_format(bytes: &[u8], path: &Path) -> Result<Current> {
    let header = postcard::from_bytes::<Header>(bytes).ok();
    let version = header.map(|h| h.version);
    let body = match version {
        Some(6) => read::<BodyV7<TrustSpecV6>>(bytes, path, 6)?
            .with_rod()
            .current(TrustSpecV6::current),
        Some(7) => read::<BodyV7<TrustSpecV8>>(bytes, path, 7)?
            .with_rod()
            .current(TrustSpecV8::current),
        Some(8) => read::<BodyV8<TrustSpecV8>>(bytes, path, 8)?.current(TrustSpecV8::current),
        Some(9) => read::<BodyV8<TrustSpecV9>>(bytes, path, 9)?.current(TrustSpecV9::current),
        Some(10) => read::<BodyV8<TrustSpecV10>>(bytes, path, 10)?.current(TrustSpecV10::current),
        // Read by the estimator (11 and 12 without the swing's term, which
        // reads as 0; written again in the current layout), or broken in a
        // way the reader names.
        _ => {
            let blob =
                Blob::from_bytes(bytes).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
            let old = version.filter(|v| *v < FORMAT_VERSION);
            return Ok(Current {
                bytes: if old.is_some() {
                    blob_bytes(&blob)?
                } else {
                    bytes.to_vec()
                },
                upgraded_from: old,
            });
        }
    };
    // The old header's widths (a narrow blob stays narrow), this format (a
    // bilinear arena without torque columns keeps none: its length says
    // so, B = 0).
    let header = Header {
        version: FORMAT_VERSION,
        ..header.unwrap_or(Header::CURRENT)
    };
    Ok(Current {
        bytes: blob_bytes(&Blob { header, body })?,
        upgraded_from: version,
    })
}

/// The body `B` of the blob of format `version` at `path`, whose bytes
/// are `bytes` (its CRC checked, no byte after it).
fn read<'a, B: Deserialize<'a>>(bytes: &'a [u8], path: &Path, version: u16) -> Result<B> {
    let (old, rest) =
        postcard::take_from_bytes_crc32::<Old<B>>(bytes, CRC.digest()).map_err(|e| {
            anyhow::anyhow!(
                "{}: not a readable format-{version} blob: {e}",
                path.display()
            )
        })?;
    anyhow::ensure!(rest.is_empty(), "{}: trailing bytes", path.display());
    Ok(old.body)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The trust section of `t` as formats 7 and 8 wrote it.
    fn v8_trust<'a>(t: &TrustSpec<'a>) -> TrustSpecV8<'a> {
        TrustSpecV8 {
            v6: TrustSpecV6 {
                envelope: t.envelope,
                envelope_max_off: t.envelope_max_off,
                range: t.range,
                std_scale: t.std_scale,
                std_floor: t.std_floor,
                min_swing: t.min_swing,
            },
            max_unevenness: t.max_unevenness,
        }
    }

    /// The parts of `b` after its rig, with the trust section `trust`.
    fn rest<'a, T>(b: &Body<'a>, trust: T) -> Rest<'a, T> {
        Rest {
            activation: b.activation,
            norm_mu: b.norm_mu,
            norm_s: b.norm_s,
            params: b.params,
            filter: b.filter,
            trust,
            _pad: &[],
            weights: b.weights,
        }
    }

    /// `body` written as a blob whose header is `header` but for its
    /// `version`.
    fn written<B: serde::Serialize>(header: Header, version: u16, body: B) -> Vec<u8> {
        let old = Old {
            _header: Header { version, ..header },
            body,
        };
        postcard::to_allocvec_crc32(&old, CRC.digest()).unwrap()
    }

    /// `blob` written back in the layout of formats 8 and 9 with the
    /// header's `version` and the trust section `trust`.
    fn written_back<T: serde::Serialize>(blob: &Blob<'_>, version: u16, trust: T) -> Vec<u8> {
        let b = blob.body;
        let body = BodyV8 {
            dt: b.dt,
            g: b.g,
            rig: b.rig,
            family: b.family,
            rest: rest(&b, trust),
        };
        written(blob.header, version, body)
    }

    /// `blob`, a rod's, written back in the layout of formats 6 and 7
    /// (no rig) with the header's `version` and the trust section `trust`.
    fn written_back_as_rod<T: serde::Serialize>(
        blob: &Blob<'_>,
        version: u16,
        trust: T,
    ) -> Vec<u8> {
        let b = blob.body;
        assert_eq!(b.rig, Rig::Rod);
        let body = BodyV7 {
            dt: b.dt,
            g: b.g,
            rest: rest(&b, trust),
        };
        written(Header::CURRENT, version, body)
    }

    /// The path and bytes of the shipped blob `name`.
    fn read_shipped(name: &str) -> (std::path::PathBuf, Vec<u8>) {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../weights")
            .join(name);
        let bytes = std::fs::read(&path).unwrap();
        (path, bytes)
    }

    /// `old`, a blob of format `version` that the current reader refuses,
    /// upgraded.
    fn upgraded(old: &[u8], path: &Path, version: u16) -> Vec<u8> {
        assert!(
            Blob::from_bytes(old).is_err(),
            "format {version} read as current"
        );
        let current = current_format(old, path).unwrap();
        assert_eq!(current.upgraded_from, Some(version));
        current.bytes
    }

    /// `bytes` with format 9's two checks open (every mean innovation and
    /// rate ratio passing) and format 10's law `[0, 0]`: what an upgrade
    /// writes before it is calibrated again.
    fn unchecked(bytes: &[u8]) -> Vec<u8> {
        let mut b = Blob::from_bytes(bytes).unwrap();
        b.body.trust.std_swing = 0.0;
        b.body.trust.max_nis = f32::MAX;
        b.body.trust.nis_law = [0.0; 2];
        b.body.trust.max_rate_mismatch = f32::MAX;
        b.body.trust.max_step_nis = 0.0;
        b.body.trust.min_samples_per_period = 0.0;
        blob_bytes(&b).unwrap()
    }

    /// The rig blob written back as format 10 (its trust section without
    /// the outlier gate and the source check) upgrades to the rig blob
    /// with neither, every other threshold kept, byte for byte.
    #[test]
    fn a_format_10_blob_upgrades_without_gate_or_source_check() {
        let (path, shipped) = read_shipped("rig.kkf");
        let blob = Blob::from_bytes(&shipped).unwrap();
        let t = blob.body.trust;
        let v10 = written_back(
            &blob,
            10,
            TrustSpecV10 {
                v8: v8_trust(&t),
                max_nis: t.max_nis,
                nis_law: t.nis_law,
                max_rate_mismatch: t.max_rate_mismatch,
            },
        );
        let mut want = Blob::from_bytes(&shipped).unwrap();
        want.body.trust.max_step_nis = 0.0;
        want.body.trust.min_samples_per_period = 0.0;
        want.body.trust.std_swing = 0.0;
        assert!(upgraded(&v10, &path, 10) == blob_bytes(&want).unwrap());
    }

    /// The rig blob written back as format 9 (its trust section without
    /// the consistency law) upgrades to the rig blob with the law `[0, 0]`
    /// and every other threshold kept, byte for byte.
    #[test]
    fn a_format_9_blob_upgrades_with_the_plain_mean() {
        let (path, shipped) = read_shipped("rig.kkf");
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
        let mut want = Blob::from_bytes(&shipped).unwrap();
        want.body.trust.nis_law = [0.0; 2];
        want.body.trust.max_step_nis = 0.0;
        want.body.trust.min_samples_per_period = 0.0;
        want.body.trust.std_swing = 0.0;
        let (got, want) = (upgraded(&v9, &path, 9), blob_bytes(&want).unwrap());
        let first = got.iter().zip(&want).position(|(a, b)| a != b);
        assert!(
            got == want,
            "{} against {} bytes, first difference at {first:?}",
            got.len(),
            want.len()
        );
    }

    /// The shipped blob written back as format 8 (its trust section
    /// without `max_nis` and `max_rate_mismatch`), and as format 7 (its
    /// body without the rig too), upgrades to the shipped blob with those
    /// two checks open and the law `[0, 0]`, byte for byte: the upgrade
    /// adds the rod and changes nothing else; `koopman calibrate` then
    /// sets them.
    #[test]
    fn a_format_7_or_8_blob_upgrades_to_the_same_blob() {
        let (path, shipped) = read_shipped("pendulum.kkf");
        let blob = Blob::from_bytes(&shipped).unwrap();
        let v8 = written_back(&blob, 8, v8_trust(&blob.body.trust));
        assert_eq!(upgraded(&v8, &path, 8), unchecked(&shipped));
        let v7 = written_back_as_rod(&blob, 7, v8_trust(&blob.body.trust));
        assert_eq!(upgraded(&v7, &path, 7), unchecked(&shipped));
        // Format 11 (the shipped protocol blob) is written again in the
        // current format, unchanged but for `std_swing` 0; a current blob
        // passes through; a truncated one is refused.
        let eleven = current_format(&shipped, &path).unwrap();
        assert_eq!(eleven.upgraded_from, Some(11));
        assert_eq!(eleven.bytes, blob_bytes(&blob).unwrap());
        let current = current_format(&eleven.bytes, &path).unwrap();
        assert_eq!((current.bytes, current.upgraded_from), (eleven.bytes, None));
        assert!(current_format(&v7[..v7.len() - 9], &path).is_err());
    }

    /// The shipped blob written back as format 6 (format 7's without
    /// `max_unevenness`) upgrades to the shipped blob with every
    /// unevenness trusted besides format 9's checks open, byte for byte.
    #[test]
    fn a_format_6_blob_upgrades_with_every_unevenness_trusted() {
        let (path, shipped) = read_shipped("pendulum.kkf");
        let blob = Blob::from_bytes(&shipped).unwrap();
        let v6 = written_back_as_rod(&blob, 6, v8_trust(&blob.body.trust).v6);
        let open = unchecked(&shipped);
        let mut want = Blob::from_bytes(&open).unwrap();
        want.body.trust.max_unevenness = f32::MAX;
        assert_eq!(upgraded(&v6, &path, 6), blob_bytes(&want).unwrap());
    }
}
