//! The blob for real rigs (`weights/rig.kkf`) held to the bars on
//! lab-like recordings it has not seen: `trainer_core::labcheck` (what
//! `koopman lab-check` runs) with its defaults, 120 recordings, seed 11:
//! strings of 0.1 to 1.5 m at g = 9.81, released at 0.05 to 1.4 rad,
//! tracked at 12 to 100 Hz with noise and 0.1-degree steps, viscous
//! damping, drag or Coulomb friction in turn.
//!
//! The bars: the length within 2% at the end in at least 90%; within 5%
//! after the first 64 measurements in at least 95%; more than 5% off and
//! trusted (after 64 or at the end) in at most 2%; trusted at the end in
//! at least 80% of those within 5% there. The blob reaches 95%, 97%, 0%
//! and 85%, with a median error of 0.35% at the end (the README's table):
//! a retrained or recalibrated blob that falls below a bar fails here.
//!
//! On real rigs' draws (offsets within 0.1 rad, sources at 5 to 240 Hz, a
//! mixed dissipation in turn; 200 recordings, seed 12, a seed the
//! estimator was tuned on, not the one reported): within 2% at the end
//! in at least 92% (192, 96%, since the filter starts again, latent
//! included, once an offset of a fifth of the swing or more is
//! subtracted; 174 without), within 5% after 64 in at least 85% (176,
//! 88%, with the half swings timed after the parameters are reopened
//! taken as measurements of the length; 165 without), at most 1% wrong
//! and trusted (0), trusted at the end
//! in at least 88% of those within 5% there (92%, since a swing never as
//! wide as the blob's smallest trusted is read once 12 half swings of at
//! least 0.03 rad are; 82% without).

use estimator::Model;
use host_tests::rig_blob;
use trainer_core::labcheck::{self, LabCheckConfig};

#[test]
fn the_rig_blob_meets_the_lab_bars() {
    let bytes = rig_blob();
    let m = Model::from_bytes(&bytes).unwrap();
    let cfg = LabCheckConfig::default();
    assert_eq!((cfg.seed, cfg.recordings), (11, 120));
    let f = labcheck::figures(&labcheck::run(&m, &cfg).unwrap());
    eprint!("{}", labcheck::markdown(&f));
    let c = &f.all;
    let share = |k: usize, n: usize| k as f64 / n as f64;
    assert!(share(c.end_within_2, c.n) >= 0.90, "{c:?}");
    assert!(share(c.first_within_5, c.n) >= 0.95, "{c:?}");
    assert!(share(c.wrong_trusted, c.n) <= 0.02, "{c:?}");
    let [trusted, right] = c.trusted_of_right;
    assert!(share(trusted, right) >= 0.80, "{c:?}");
}

#[test]
fn the_rig_blob_reads_real_rigs_draws() {
    let bytes = rig_blob();
    let m = Model::from_bytes(&bytes).unwrap();
    let cfg = LabCheckConfig {
        seed: 12,
        recordings: 200,
        offsets: [-0.1, 0.1],
        rates: Some([5.0, 240.0]),
        mixed: true,
        ..LabCheckConfig::default()
    };
    let f = labcheck::figures(&labcheck::run(&m, &cfg).unwrap());
    eprint!("{}", labcheck::markdown(&f));
    let c = &f.all;
    let share = |k: usize, n: usize| k as f64 / n as f64;
    assert!(share(c.end_within_2, c.n) >= 0.92, "{c:?}");
    assert!(share(c.first_within_5, c.n) >= 0.85, "{c:?}");
    assert!(share(c.wrong_trusted, c.n) <= 0.01, "{c:?}");
    // With a sharp period that agrees waiving the checks of the model's
    // fit, and a coarse source's rate read as one, 180 of the 195 right
    // are trusted.
    let [trusted, right] = c.trusted_of_right;
    assert!(share(trusted, right) >= 0.91, "{c:?}");
    // Joined with the swing's period, the median error at the end is
    // within 1.5 times the physics peer's (0.105% against 0.085%; the
    // model alone read 0.46%).
    assert!(
        c.median_end_error <= 1.5 * f.peer.median_end_error,
        "{c:?} against the peer's {:?}",
        f.peer
    );
}
