//! A rig blob's forecast is of the angle as measured: about the sensor's
//! offset, which the estimator takes off before the encoder
//! (`weights/rig.kkf`, a lab-like string imported at the blob's 0.04 s).

use estimator::{Estimator, Model};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use trainer_core::data::import::{self, ImportOptions};
use trainer_core::data::lab::{Artefacts, Case, LAB_G, LabSpec, Stamps};
use trainer_core::physics::{Effect, EffectKind, Rig};

#[test]
fn a_forecast_swings_about_the_measured_offset() {
    let bytes = host_tests::rig_blob();
    let m = Model::from_bytes(&bytes).unwrap();
    let dt = f64::from(m.blob().body.dt);
    // 0.5 m (1.42 s a period, 35.5 steps), 0.15 rad about a 0.08 rad
    // offset, a little drag, 30 Hz, 30 s.
    let spec = LabSpec {
        case: Case::Drag,
        length: 0.5,
        rig: Rig::Simple,
        theta0: 0.15,
        duration: 30.0,
        rate: 30.0,
        stamps: Stamps::Even,
        noise: 0.003,
        quantum: 0.1f64.to_radians(),
        effects: vec![Effect::new(EffectKind::Drag, 0.02)],
        offset: 0.08,
        forcing: None,
        artefacts: Artefacts::NONE,
    };
    let rec = spec.record(&mut ChaCha8Rng::seed_from_u64(5));
    let opts = ImportOptions {
        dt,
        ..ImportOptions::default()
    };
    let r = import::to_rollout(&rec, 0, &opts).unwrap();
    let (seen, next) = r.xs.split_at(400);
    let mut est = Estimator::new(&m).with_gravity(LAB_G as f32).unwrap();
    let mut offset = None;
    for x in seen {
        offset = est
            .step(&[x[0] as f32, x[1] as f32])
            .unwrap()
            .readers
            .offset;
    }
    assert!(
        offset.is_some_and(|o| (o - 0.08).abs() < 0.01),
        "offset read {offset:?}"
    );
    // Two periods forecast: their mean angle is the offset (0 without it
    // added back), and each angle follows the measured one.
    let mut out = [[0.0f32; 2]; 71];
    est.forecast(&mut out).unwrap();
    let mean = out.iter().map(|x| f64::from(x[0])).sum::<f64>() / out.len() as f64;
    assert!((mean - 0.08).abs() < 0.01, "mean forecast angle {mean:.4}");
    let rms = (out
        .iter()
        .zip(next)
        .map(|(f, x)| (f64::from(f[0]) - x[0]).powi(2))
        .sum::<f64>()
        / out.len() as f64)
        .sqrt();
    // The swing there is about 0.13 rad; the noise 0.003.
    assert!(rms < 0.02, "forecast rms {rms:.4} rad");
}
