//! `koopman calibrate`: sets a blob's trust verdict on held-out rollouts
//! (`trainer_core::calibrate`) and records how in the JSON beside it. A
//! blob of the previous format (4, without a trust section) is upgraded:
//! its model, filter and schedule are kept byte for byte.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use estimator::blob::{
    Activation, Blob, Body, F32s, FORMAT_VERSION, FilterSpec, Header, ParamSpec,
};
use estimator::{PARAM_DIM, STATE_DIM};
use serde::Deserialize;
use trainer_core::calibrate::{CalibrateConfig, blob_bytes, map_bytes, permissive};
use trainer_core::io::write_atomic;

/// Calibrates the trust verdict of a weights blob on held-out rollouts
/// from its declared operating range, and writes the blob with the
/// figures in the JSON beside it.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The blob (format 5, or 4 to upgrade).
    blob: PathBuf,
    /// Output path (default: over the input).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Seed of the held-out sets (map, calibration, check: seed, +1, +2).
    #[arg(long, default_value_t = CalibrateConfig::default().seed)]
    seed: u64,
}

/// The body of format 4: format 5's without the trust section.
#[derive(Deserialize)]
struct BodyV4<'a> {
    dt: f32,
    activation: Activation,
    norm_mu: [f32; STATE_DIM],
    norm_s: [f32; STATE_DIM],
    #[serde(borrow)]
    params: [ParamSpec<'a>; PARAM_DIM],
    filter: FilterSpec,
    #[serde(borrow)]
    _pad: &'a [u8],
    #[serde(borrow)]
    weights: F32s<'a>,
}

#[derive(Deserialize)]
struct BlobV4<'a> {
    _header: Header,
    #[serde(borrow)]
    body: BodyV4<'a>,
}

static CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISCSI);

/// The blob's bytes in the current format: as they are, or a format-4
/// blob with a trust section that passes everything (to be calibrated).
fn current_format(bytes: &[u8], path: &Path) -> Result<Vec<u8>> {
    let version = postcard::from_bytes::<Header>(bytes)
        .ok()
        .map(|h| h.version);
    if Blob::from_bytes(bytes).is_ok() || version != Some(4) {
        // Current, or broken in a way the reader names below.
        Blob::from_bytes(bytes).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        return Ok(bytes.to_vec());
    }
    let (old, rest) = postcard::take_from_bytes_crc32::<BlobV4>(bytes, CRC.digest())
        .map_err(|e| anyhow::anyhow!("{}: not a readable format-4 blob: {e}", path.display()))?;
    anyhow::ensure!(rest.is_empty(), "{}: trailing bytes", path.display());
    let cfg = CalibrateConfig::default();
    let full = vec![0xffu8; map_bytes(&cfg)];
    let p = old.body.params[0];
    let q = [
        p.coordinate(p.train_range[0]),
        p.coordinate(p.train_range[1]),
    ];
    let b = old.body;
    let blob = Blob {
        header: Header::CURRENT,
        body: Body {
            dt: b.dt,
            activation: b.activation,
            norm_mu: b.norm_mu,
            norm_s: b.norm_s,
            params: b.params,
            filter: b.filter,
            trust: permissive(&cfg, q, &full),
            pad: &[],
            weights: b.weights,
        },
    };
    eprintln!(
        "{}: format 4, upgraded to {FORMAT_VERSION} (model, filter and schedule unchanged)",
        path.display()
    );
    blob_bytes(&blob)
}

/// Runs it.
pub fn run(a: Args) -> Result<()> {
    let bytes = std::fs::read(&a.blob).with_context(|| a.blob.display().to_string())?;
    let bytes = current_format(&bytes, &a.blob)?;
    let cfg = CalibrateConfig {
        seed: a.seed,
        ..CalibrateConfig::default()
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
    println!(
        "wrote {} ({} bytes): envelope allows {} of {} measurements off, range [{:.3}, {:.3}], std x{:.2} + {:.3e}",
        out.display(),
        out_bytes.len(),
        report.envelope_max_off,
        trainer_core::protocol::WINDOW,
        report.range[0],
        report.range[1],
        report.std_scale,
        report.std_floor
    );
    for c in &report.check {
        println!(
            "check set after {} steps: {} of {} flagged, {} within 2 std, {} within 20%",
            c.steps, c.flagged, c.rollouts, c.covered, c.within_20_percent
        );
    }
    Ok(())
}
