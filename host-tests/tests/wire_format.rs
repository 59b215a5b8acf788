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
    Activation, Blob, Body, Envelope, F32s, FORMAT_VERSION, Family, FilterSpec, Header, Layout,
    TrustSpec,
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
                std_swing: 0.25,
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
    // Header: "KKF1", version 13, state 2, latent 16, params 2, hidden 64,
    // inputs 1 (each u16 one varint byte).
    assert_eq!(hex(&bytes[..10]), "4b4b46310d0210024001");
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
    // Before it: the trust section's last two fields, min_samples_per_period
    // 0 and std_swing 0.25 (0x3e800000), the pad (its length 2, then two
    // zero bytes) and the arena's length, 47,432 bytes as a varint.
    assert_eq!(
        hex(&bytes[arena_at - 14..arena_at]),
        concat!("00000000", "0000803e", "02", "0000", "c8f202")
    );
    assert_eq!(&bytes[arena_at..bytes.len() - 4], arena(11_858).as_slice());
    assert_eq!(bytes.len(), 47_816);
    // The CRC-32/ISCSI of everything before it, little-endian.
    assert_eq!(hex(&bytes[bytes.len() - 4..]), "02de6728");
    // And it reads back as what was written.
    let back = Blob::from_bytes(&bytes).unwrap();
    assert_eq!(back.body.params[1].name, "damping");
    assert_eq!(back.body.trust.envelope.bits, &[0b1010_0101]);
}

/// Every shipped blob reads, runs, and writes back to its own bytes (one
/// of an older format, read with the fields it lacks at their defaults,
/// writes the current format, which then writes back to itself): the
/// format is read and written by one definition.
#[test]
fn every_shipped_blob_writes_back_byte_for_byte() {
    for name in [
        "rig.kkf",
        "pendulum.kkf",
        "pendulum-bilinear.kkf",
        "pendulum-bilinear-driven.kkf",
    ] {
        let path = root().join("weights").join(name);
        let bytes = std::fs::read(&path).unwrap();
        Model::from_bytes(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
        let blob = Blob::from_bytes(&bytes).unwrap();
        let mut buf = vec![0u8; bytes.len() + 16];
        let out = blob.to_slice(&mut buf).unwrap().to_vec();
        if blob.header.version == FORMAT_VERSION {
            assert!(out == bytes, "{name} does not write back");
        } else {
            let current = Blob::from_bytes(&out).unwrap();
            assert_eq!(current.header.version, FORMAT_VERSION, "{name}");
            assert_eq!(current.body.trust.std_swing, 0.0, "{name}");
            assert_eq!(current.body, blob.body, "{name}: the body moved");
            let mut again = vec![0u8; out.len() + 16];
            assert!(
                current.to_slice(&mut again).unwrap() == out.as_slice(),
                "{name}"
            );
        }
    }
}

/// The small blob as format `version` (11 or 12) writes it: its trust
/// section without `std_swing` (the 4 bytes before the pad, whose length
/// byte is the `pad_at`-th) and the CRC made again.
fn as_older(bytes: &[u8], version: u8, pad_at: usize) -> Vec<u8> {
    let mut old = bytes[..bytes.len() - 4].to_vec();
    old[4] = version;
    old.drain(pad_at - 4..pad_at);
    let crc = estimator::blob::CRC.checksum(&old);
    old.extend_from_slice(&crc.to_le_bytes());
    old
}

/// Formats 11 and 12 read as format 13 with `std_swing` 0; a bilinear
/// arena of format 11 ends after `F_11` (no torque columns) and reads as
/// a free model (`B = 0`), one of 12 carries them; from 13 on, either
/// length reads, and says which.
#[test]
fn older_formats_read_as_the_current_one() {
    let layout = Layout {
        hidden: HIDDEN_NARROW,
    };
    let bytes = small_blob_bytes();
    let blob = Blob::from_bytes(&bytes).unwrap();
    let arena_at = bytes.len() - 4 - layout.bilinear_arena_len(true) * 4;
    // The pad's length byte: 2, before two zero bytes and the arena's
    // 3-byte length.
    let pad_at = arena_at - 3 - 2 - 1;
    assert_eq!(bytes[pad_at], 2);
    let twelve = as_older(&bytes, 12, pad_at);
    let read = Blob::from_bytes(&twelve).unwrap();
    assert_eq!(read.header.version, 12);
    assert_eq!(read.body.trust.std_swing, 0.0);
    let mut expected = blob.body;
    expected.trust.std_swing = 0.0;
    assert_eq!(read.body, expected);
    assert!(
        Model::from_bytes(&twelve).unwrap().is_driven(),
        "format 12 carries B"
    );
    // Format 12's header over format 13's bytes: refused, not misread.
    let mut wrong = bytes.clone();
    wrong[4] = 12;
    assert!(Blob::from_bytes(&wrong).is_err());

    // A short arena: free in format 13 and, written as 11, in format 11.
    let short = arena(layout.bilinear_arena_len(false));
    let mut free = blob;
    free.body.weights = F32s(&short);
    let mut buf = vec![0u8; bytes.len() + 16];
    let written = free.to_slice(&mut buf).unwrap().to_vec();
    assert!(
        !Model::from_bytes(&written).unwrap().is_driven(),
        "a short arena carries no B"
    );
    assert!(
        Model::from_bytes(&bytes).unwrap().is_driven(),
        "a long one carries B"
    );
    let short_at = written.len() - 4 - short.len();
    let eleven = as_older(&written, 11, short_at - 3 - 2 - 1);
    assert!(
        !Model::from_bytes(&eleven).unwrap().is_driven(),
        "format 11 carries no B"
    );
    // Format 12 with a short arena, or 11 with a long one: a truncated or
    // overlong arena.
    for (v, b) in [(12u8, &written), (11u8, &bytes)] {
        let at = b.len()
            - 4
            - if v == 12 {
                short.len()
            } else {
                layout.bilinear_arena_len(true) * 4
            };
        let old = as_older(b, v, at - 3 - 2 - 1);
        assert_eq!(
            Model::from_bytes(&old).unwrap_err(),
            estimator::Error::BlobShapeMismatch,
            "format {v}"
        );
    }
}
