//! The rig's geometry: which length a pendulum's motion is read as.
//!
//! The small swings of a pendulum have the squared angular frequency
//! `w0^2 = g / l_eq`, where `l_eq` is its *equivalent simple length*: the
//! motion fixes `l_eq` and nothing else. What a user measures with a tape
//! depends on the rig:
//!
//! | rig | what `L` is | `w0^2` | `l_eq` |
//! | --- | --- | --- | --- |
//! | [`Rig::Simple`] | a point mass on a massless string, pivot to bob | `g / L` | `L` |
//! | [`Rig::Rod`] | a uniform rod swinging about one end, its length | `3 g / (2 L)` | `2 L / 3` |
//!
//! The protocol's pendulum (and the shipped protocol blob) is a rod; a
//! bob on a string is a simple pendulum. Every length the project prints
//! names its rig, e.g. `length (simple, m)`.
//!
//! This is the one definition: the blob records it (format 8) and the
//! trainer's physics (`trainer_core::physics::Rig`) re-exports it.

use core::fmt;
use core::str::FromStr;

use serde::{Deserialize, Serialize};

/// Which physical length a pendulum's motion is read as (see the module).
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[serde(rename_all = "lowercase")]
pub enum Rig {
    /// A point mass on a massless string: `w0^2 = g / L`.
    Simple,
    /// A uniform rod about its end (the protocol's): `w0^2 = 3 g / (2 L)`.
    #[default]
    Rod,
}

impl Rig {
    /// Every rig, in the order the command line lists them.
    pub const ALL: [Rig; 2] = [Rig::Simple, Rig::Rod];

    /// Its name, as the command line and the files spell it.
    pub const fn name(self) -> &'static str {
        match self {
            Rig::Simple => "simple",
            Rig::Rod => "rod",
        }
    }

    /// `l_eq / L`: the equivalent simple length per unit of the rig's
    /// length (1 for a string, 2/3 for a rod).
    pub const fn simple_per_length(self) -> f64 {
        match self {
            Rig::Simple => 1.0,
            Rig::Rod => 2.0 / 3.0,
        }
    }

    /// `w0^2` of the rig of length `length` under gravity `g`. (The rod's
    /// is computed as `3 g / (2 L)`, the protocol's simulation to the bit.)
    pub fn w2(self, g: f64, length: f64) -> f64 {
        match self {
            Rig::Simple => g / length,
            Rig::Rod => 3.0 * g / (2.0 * length),
        }
    }

    /// The rig's length whose small swings have `w0^2 = w2` under `g`
    /// (the inverse of [`Rig::w2`]).
    pub fn length(self, g: f64, w2: f64) -> f64 {
        match self {
            Rig::Simple => g / w2,
            Rig::Rod => 3.0 * g / (2.0 * w2),
        }
    }

    /// The rig's length of a pendulum whose equivalent simple length is
    /// `simple`.
    pub fn from_simple(self, simple: f64) -> f64 {
        simple / self.simple_per_length()
    }

    /// The moment of inertia about the pivot per unit mass, `I / m`, of
    /// the rig of length `length` (`L^2` for a string, `L^2 / 3` for a
    /// rod): what a torque is divided by.
    pub fn inertia_per_mass(self, length: f64) -> f64 {
        match self {
            Rig::Simple => length * length,
            Rig::Rod => length * length / 3.0,
        }
    }

    /// The distance from the pivot to the centre of mass per unit of the
    /// rig's length (1 for a string, 1/2 for a rod): the potential energy
    /// is `m g (centre L) (1 - cos theta)`.
    pub const fn centre_per_length(self) -> f64 {
        match self {
            Rig::Simple => 1.0,
            Rig::Rod => 0.5,
        }
    }

    /// A label for a length of this rig, e.g. `length (simple, m)`.
    pub const fn length_label(self) -> &'static str {
        match self {
            Rig::Simple => "length (simple, m)",
            Rig::Rod => "length (rod, m)",
        }
    }
}

impl fmt::Display for Rig {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A name that is not a rig's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct UnknownRig;

impl fmt::Display for UnknownRig {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("unknown rig: expected simple (a bob on a string) or rod (a uniform rod)")
    }
}

impl core::error::Error for UnknownRig {}

impl FromStr for Rig {
    type Err = UnknownRig;

    /// `simple` (also `string`, `bob`) or `rod`, case ignored.
    fn from_str(s: &str) -> Result<Rig, UnknownRig> {
        let s = s.trim();
        let is = |name: &str| s.eq_ignore_ascii_case(name);
        if is("simple") || is("string") || is("bob") {
            Ok(Rig::Simple)
        } else if is("rod") {
            Ok(Rig::Rod)
        } else {
            Err(UnknownRig)
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
        assert!((Rig::Rod.from_simple(1.0) - 1.5).abs() < 1e-12);
        assert_eq!("String".parse::<Rig>(), Ok(Rig::Simple));
        assert_eq!(" rod ".parse::<Rig>(), Ok(Rig::Rod));
        assert_eq!("disc".parse::<Rig>(), Err(UnknownRig));
    }
}
