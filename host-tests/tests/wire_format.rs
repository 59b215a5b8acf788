//! The blob's bytes, pinned: a small blob written by `Blob::to_slice` is
//! compared byte for byte with the layout `docs/blob-format.md` specifies,
//! and every shipped blob reads and writes back to its own bytes.
//!
//! Origin of the golden values: the header and the body's first bytes are
//! worked by hand from the spec below (postcard: `u16` as a varint, `f32`
//! as 4 little-endian bytes, an enum as its variant's index, a string or
//! byte slice as a varint length then its bytes). The CRC was computed
//! independently of the crate, by a bitwise CRC-32/ISCSI (reflected,
//! polynomial 0x82F63B78, initial and final XOR 0xFFFFFFFF) in Python
//! over the bytes before it; its check value for `"123456789"` is
//! 0xE3069283.

use estimator::blob::{
    Activation, Blob, Body, Envelope, F32s, Family, FilterSpec, Header, Layout, TrustSpec,
};
use estimator::{AUG_DIM, HIDDEN_NARROW, LATENT_DIM, Model, Rig};
use host_tests::root;
use host_tests::synthetic::bilinear_params;

/// The arena's values: multiples of 1/8 in `[-0.375, 0.375]`, exact in
/// `f32`, so the bytes do not depend on any arithmetic.
fn arena(len: usize) -> Vec<u8> {
    (0..len)
        .flat_map(|k| (((k % 7) as f32 - 3.0) * 0.125).to_le_bytes())
        .collect()
}

/// The smallest blob there is: bilinear (no gain schedule), hidden layers
/// 64 wide, a one-byte envelope; the synthetic blob's parameters.
fn small_blob_bytes() -> Vec<u8> {
    let layout = Layout {
        hidden: HIDDEN_NARROW,
    };
    let weights = arena(layout.bilinear_arena_len(true));
    let bits = [0b1010_0101u8];
    let blob = Blob {
        header: Header::with_hidden(HIDDEN_NARROW as u16),
        body: Body {
            dt: 0.04,
            g: 9.81,
            rig: Rig::Simple,
            family: Family::Bilinear,
            activation: Activation::Tanh,
            norm_mu: [0.0, -0.5],
            norm_s: [1.0, 2.0],
            params: bilinear_params(),
            filter: FilterSpec {
                q: [0.0; AUG_DIM],
                r: [1.0; LATENT_DIM],
                prior_mean: [0.0; 2],
                prior_var: [1.0; AUG_DIM],
                burn_in: 32,
                sigma_threshold: 0.5,
                schedule_steps: 0,
            },
            trust: TrustSpec {
                envelope: Envelope {
                    extent: 4.0,
                    theta_cells: 2,
                    rate_cells: 2,
                    q_lo: -1.0,
                    q_width: 1.0,
                    q_bins: 2,
                    bits: &bits,
                },
                envelope_max_off: 0,
                range: [-1.0, 1.0],
                std_scale: [1.0, 1.0],
                std_floor: [0.0, 0.0],
                min_swing: 0.0,
                max_unevenness: 1.0,
                max_nis: 100.0,
                nis_law: [0.0, 0.0],
                max_rate_mismatch: 0.5,
                max_step_nis: 0.0,
                min_samples_per_period: 0.0,
            },
            pad: &[],
            weights: F32s(&weights),
        },
    };
    let mut buf = vec![0u8; 1 << 16];
    let n = blob.to_slice(&mut buf).unwrap().len();
    buf.truncate(n);
    buf
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[test]
fn a_small_blob_is_written_as_the_spec_says() {
    let bytes = small_blob_bytes();
    // Header: "KKF1", version 12, state 2, latent 16, params 2, hidden 64,
    // inputs 1 (each u16 one varint byte).
    assert_eq!(hex(&bytes[..10]), "4b4b46310c0210024001");
    // Body: dt 0.04 (0x3d23d70a), g 9.81 (0x411cf5c3), rig Simple (0),
    // family Bilinear (1), activation Tanh (1), norm_mu [0, -0.5],
    // norm_s [1, 2], then the first parameter: name "length" (6 bytes),
    // declared (1), train_range [0.1, 1.5], reading ReciprocalUnit (3),
    // scales_with_g (1).
    assert_eq!(
        hex(&bytes[10..55]),
        concat!(
            "0ad7233d",
            "c3f51c41",
            "00",
            "01",
            "01",
            "00000000",
            "000000bf",
            "0000803f",
            "00000040",
            "06",
            "6c656e677468",
            "01",
            "cdcccc3d",
            "0000c03f",
            "03",
            "01",
        )
    );
    // The arena starts at a multiple of 4 bytes, after 0-3 pad bytes, and
    // runs to the CRC: 11,858 values at hidden width 64 (the MLPs'
    // 10,770, four 16 x 16 matrices, four torque columns of 16).
    let arena_len = 11_858 * 4;
    let arena_at = bytes.len() - 4 - arena_len;
    assert_eq!(arena_at % 4, 0);
    assert_eq!(&bytes[arena_at..bytes.len() - 4], arena(11_858).as_slice());
    assert_eq!(bytes.len(), 47_812);
    // The CRC-32/ISCSI of everything before it, little-endian.
    assert_eq!(hex(&bytes[bytes.len() - 4..]), "9b248a08");
    // And it reads back as what was written.
    let back = Blob::from_bytes(&bytes).unwrap();
    assert_eq!(back.body.params[1].name, "damping");
    assert_eq!(back.body.trust.envelope.bits, &[0b1010_0101]);
}

/// Every shipped blob reads, runs, and writes back to its own bytes: the
/// format is read and written by one definition.
#[test]
fn every_shipped_blob_writes_back_byte_for_byte() {
    for name in ["rig.kkf", "pendulum.kkf", "pendulum-bilinear.kkf"] {
        let path = root().join("weights").join(name);
        let bytes = std::fs::read(&path).unwrap();
        Model::from_bytes(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
        let blob = Blob::from_bytes(&bytes).unwrap();
        let mut buf = vec![0u8; bytes.len() + 16];
        let out = blob.to_slice(&mut buf).unwrap();
        assert!(out == bytes.as_slice(), "{name} does not write back");
    }
}

/// A bilinear blob of format 11, whose arena ends after `F_11` (no torque
/// columns), reads as a free model (`B = 0`): the same small blob with its
/// version set to 11 and its arena 64 values shorter.
#[test]
fn a_format_11_bilinear_blob_reads_as_free() {
    let layout = Layout {
        hidden: HIDDEN_NARROW,
    };
    let bytes = small_blob_bytes();
    let blob = Blob::from_bytes(&bytes).unwrap();
    let short = arena(layout.bilinear_arena_len(false));
    let mut old = blob;
    old.header.version = 11;
    old.body.weights = F32s(&short);
    let mut buf = vec![0u8; bytes.len() + 16];
    let written = old.to_slice(&mut buf).unwrap().to_vec();
    let model = Model::from_bytes(&written).unwrap();
    assert!(!model.is_driven(), "format 11 carries no B");
    assert!(
        Model::from_bytes(&bytes).unwrap().is_driven(),
        "format 12 carries B"
    );
    // Format 12 without the torque columns is refused: a truncated arena.
    let mut cut = blob;
    cut.body.weights = F32s(&short);
    let n = cut.to_slice(&mut buf).unwrap().len();
    assert_eq!(
        Model::from_bytes(&buf[..n]).unwrap_err(),
        estimator::Error::BlobShapeMismatch
    );
}
