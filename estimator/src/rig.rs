//! The rig's geometry: which length a pendulum's motion is read as. The
//! one definition: the blob records it and the trainer's physics
//! (`trainer_core::physics`, where its f64 formulas live) re-exports it.

use core::fmt;
use core::str::FromStr;

use serde::{Deserialize, Serialize};

/// Which physical length a pendulum's motion is read as.
///
/// The small swings of a pendulum have the squared angular frequency
/// `w0^2 = g / l_eq`, where `l_eq` is its *equivalent simple length*: the
/// motion fixes `l_eq` and nothing else. What a user measures with a tape
/// depends on the rig:
///
/// | rig | what `L` is | `w0^2` | `l_eq` |
/// | --- | --- | --- | --- |
/// | [`Rig::Simple`] | a point mass on a massless string, pivot to bob | `g / L` | `L` |
/// | [`Rig::Rod`] | a uniform rod swinging about one end, its length | `3 g / (2 L)` | `2 L / 3` |
///
/// A bob on a string is a simple pendulum (the rig blob's); the
/// protocol's pendulum is a rod. Every length the project prints names
/// its rig, e.g. `length (simple, m)`.
///
/// # Examples
///
/// ```
/// use estimator::Rig;
///
/// let rig: Rig = " Simple ".parse()?;
/// assert_eq!(rig, Rig::Simple);
/// assert_eq!(rig.length_label(), "length (simple, m)");
/// assert!("pendulum".parse::<Rig>().is_err());
/// # Ok::<(), estimator::UnknownRig>(())
/// ```
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
    ///
    /// No unit (a list). Fixed by [`Rig`]'s variants.
    pub const ALL: [Rig; 2] = [Rig::Simple, Rig::Rod];

    /// `l_eq / L`: the equivalent simple length per unit of the rig's
    /// length (1 for a string, 2/3 for a rod).
    pub const fn equivalent_fraction(self) -> f32 {
        match self {
            Rig::Simple => 1.0,
            Rig::Rod => 2.0 / 3.0,
        }
    }

    /// The rig's length whose swing at gravity `g` has `w0^2`:
    /// `g / (w0^2 f)`, `f` the [`Rig::equivalent_fraction`].
    pub(crate) fn length_at(self, g: f32, w0_squared: f32) -> f32 {
        g / (w0_squared * self.equivalent_fraction())
    }

    /// `w0^2` of the rig's swing at gravity `g` and length `length`: the
    /// same relation the other way, `g / (length f)`.
    pub(crate) fn omega_squared_at(self, g: f32, length: f32) -> f32 {
        g / (length * self.equivalent_fraction())
    }

    /// Its name, as the command line and the files spell it.
    pub const fn name(self) -> &'static str {
        match self {
            Rig::Simple => "simple",
            Rig::Rod => "rod",
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
    fn names_parse_case_and_space_ignored() {
        assert_eq!("String".parse::<Rig>(), Ok(Rig::Simple));
        assert_eq!(" rod ".parse::<Rig>(), Ok(Rig::Rod));
        assert_eq!("disc".parse::<Rig>(), Err(UnknownRig));
    }
}
