//! The physics of a rig's geometry ([`Rig`]): its frequency, length,
//! inertia and centre of mass in f64, what the trainer simulates and reads
//! lengths with. The estimator records the rig and never computes these.

use super::Rig;

/// A rig's f64 physics: `w0^2` and its inverse, the equivalent simple
/// length, the inertia and the centre of mass (see [`estimator::Rig`]).
pub trait RigPhysics {
    /// `l_eq / L`: the equivalent simple length per unit of the rig's
    /// length (1 for a string, 2/3 for a rod).
    fn simple_per_length(self) -> f64;

    /// `w0^2` of the rig of length `length` under gravity `g`. (The rod's
    /// is computed as `3 g / (2 L)`, the protocol's simulation to the bit.)
    fn w2(self, g: f64, length: f64) -> f64;

    /// The rig's length whose small swings have `w0^2 = w2` under `g`
    /// (the inverse of [`RigPhysics::w2`]).
    fn length(self, g: f64, w2: f64) -> f64;

    /// The rig's length of a pendulum whose equivalent simple length is
    /// `simple`.
    fn length_from_simple(self, simple: f64) -> f64;

    /// The moment of inertia about the pivot per unit mass, `I / m`, of
    /// the rig of length `length` (`L^2` for a string, `L^2 / 3` for a
    /// rod): what a torque is divided by.
    fn inertia_per_mass(self, length: f64) -> f64;

    /// The distance from the pivot to the centre of mass per unit of the
    /// rig's length (1 for a string, 1/2 for a rod): the potential energy
    /// is `m g (centre L) (1 - cos theta)`.
    fn centre_per_length(self) -> f64;
}

impl RigPhysics for Rig {
    fn simple_per_length(self) -> f64 {
        match self {
            Rig::Simple => 1.0,
            Rig::Rod => 2.0 / 3.0,
        }
    }

    fn w2(self, g: f64, length: f64) -> f64 {
        match self {
            Rig::Simple => g / length,
            Rig::Rod => 3.0 * g / (2.0 * length),
        }
    }

    fn length(self, g: f64, w2: f64) -> f64 {
        match self {
            Rig::Simple => g / w2,
            Rig::Rod => 3.0 * g / (2.0 * w2),
        }
    }

    fn length_from_simple(self, simple: f64) -> f64 {
        simple / self.simple_per_length()
    }

    fn inertia_per_mass(self, length: f64) -> f64 {
        match self {
            Rig::Simple => length * length,
            Rig::Rod => length * length / 3.0,
        }
    }

    fn centre_per_length(self) -> f64 {
        match self {
            Rig::Simple => 1.0,
            Rig::Rod => 0.5,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn length_and_frequency_are_inverses_and_the_rod_reads_one_and_a_half_strings() {
        for rig in Rig::ALL {
            for l in [0.1, 0.65, 1.5, 5.0] {
                let w2 = rig.w2(9.81, l);
                // Two divisions in f64: within a few ulps.
                assert!((rig.length(9.81, w2) - l).abs() < 1e-12 * l);
            }
        }
        // A rod of 1.5 m swings as a string of 1 m: both w0^2 = g.
        assert!((Rig::Rod.w2(9.81, 1.5) - Rig::Simple.w2(9.81, 1.0)).abs() < 1e-12);
        assert!((Rig::Rod.length_from_simple(1.0) - 1.5).abs() < 1e-12);
    }
}
