//! The inputs the benchmarks and the instruction counts step through
//! (`koopman bench`, the criterion bench and the callgrind harness in
//! `host-tests`, the firmware's data): one test rollout in distribution,
//! its estimation window and the steps after it; and, for the rig blob, a
//! string swinging as a user's does ([`rig_window`]).

use estimator::{Estimator, Latent, Model, State};

use crate::data::{states_f32, test_set};
use crate::physics::{Effect, EffectKind, Pendulum, Rig};
use crate::protocol::{TEST_LENGTHS, WINDOW};

/// The string of [`rig_window`]: length, m; release angle, rad; viscous
/// damping, 1/s (inside the rig blob's trained ranges).
pub const RIG_STRING: (f64, f64, f64) = (0.6, 0.3, 0.05);

/// `n` raw states of a string of [`RIG_STRING`] at `g = 9.81`, sampled at
/// the blob's interval `dt`: what the rig blob's timings step through.
pub fn rig_window(n: usize, dt: f64) -> Vec<State> {
    let (length, theta0, viscous) = RIG_STRING;
    let p = Pendulum {
        g: 9.81,
        effects: vec![Effect::new(EffectKind::Viscous, viscous)],
        ..Pendulum::of(Rig::Simple, length)
    };
    states_f32(&p.rollout([theta0, 0.0], n, dt))
}

/// The test rollout [`window`] is taken from (L = 3.5, in distribution).
pub const WINDOW_ROLLOUT: usize = 34;

/// The first [`WINDOW`] raw states of test rollout [`WINDOW_ROLLOUT`]
/// (L = 3.5, theta_0 = pi/2 + 4 (0.4 pi) / 9): what the benchmarks and the
/// instruction counts step through.
pub fn window() -> Vec<State> {
    let mut xs = whole_rollout();
    xs.truncate(WINDOW);
    xs
}

/// All 128 raw states of test rollout [`WINDOW_ROLLOUT`]: the window, then
/// the steps after it (the filter's two-stage tail).
pub fn whole_rollout() -> Vec<State> {
    let ds = test_set(0, &TEST_LENGTHS, &[]);
    ds.rollouts
        .get(WINDOW_ROLLOUT)
        .map(|r| states_f32(&r.xs))
        .unwrap_or_default()
}

/// What the timings of the steps after the window start from: the raw
/// states of [`whole_rollout`] after [`window`], the same encoded, and the
/// filter (on the blob's gain schedule) after the window.
pub fn tail<'m>(model: &'m Model<'m>) -> (Vec<State>, Vec<Latent>, Estimator<'m>) {
    let all = whole_rollout();
    let (window, after) = all.split_at(WINDOW.min(all.len()));
    let zs = after
        .iter()
        .map(|x| model.encode(&model.normalise(x)))
        .collect();
    let mut warm = Estimator::new(model);
    for x in window {
        // A refused step leaves the filter as it was; the window is the
        // protocol's test data, which every step accepts.
        let _ = warm.step(x);
    }
    (after.to_vec(), zs, warm)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn window_is_the_protocols_estimation_window() {
        let xs = window();
        assert_eq!(xs.len(), WINDOW);
        let ds = test_set(0, &TEST_LENGTHS, &[]);
        let r = &ds.rollouts[WINDOW_ROLLOUT];
        assert_eq!(ds.sidecar.rollouts[WINDOW_ROLLOUT].length, 3.5);
        assert_eq!(xs[0], [r.xs[0][0] as f32, r.xs[0][1] as f32]);
        assert_eq!(xs[63], [r.xs[63][0] as f32, r.xs[63][1] as f32]);
    }
}
