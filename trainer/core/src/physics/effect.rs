//! The effects a declared model may lack: the one list, parsed in one
//! place, used by the simulator, the diagnosis and the closed loop.
//!
//! | name | kind | term | coefficient |
//! | --- | --- | --- | --- |
//! | viscous | dynamic | `-c theta_dot` added to `theta_ddot` | `c`, 1/s |
//! | coulomb | dynamic | `-c sign(theta_dot)` | `c`, rad/s^2 |
//! | drag | dynamic | `-c theta_dot abs(theta_dot)` | `c`, 1/rad |
//! | torque | dynamic | `+c` (a constant torque per unit inertia) | `c`, rad/s^2 |
//! | offset | sensor | measured angle = true + `c` | `c`, rad |
//! | gain | sensor | measured state = (1 + `c`) true | `c`, 1 |
//!
//! To add an effect: one variant in [`EffectKind`] and its row in each
//! `match` of this file (the compiler lists them), then its column in
//! `diagnose::library`.

use std::fmt;

use serde::{Deserialize, Serialize};

/// Which effect (without its coefficient).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum EffectKind {
    /// `-c theta_dot`.
    Viscous,
    /// `-c sign(theta_dot)`.
    Coulomb,
    /// `-c theta_dot |theta_dot|`.
    Drag,
    /// `+c`.
    Torque,
    /// The angle sensor reads `c` rad off.
    Offset,
    /// The sensor's scale is `1 + c`.
    Gain,
}

impl EffectKind {
    /// Every effect, in the order of the diagnosis's columns.
    pub const ALL: [EffectKind; 6] = [
        EffectKind::Viscous,
        EffectKind::Coulomb,
        EffectKind::Drag,
        EffectKind::Torque,
        EffectKind::Offset,
        EffectKind::Gain,
    ];

    /// Its name, as the command line and the files spell it.
    pub const fn name(self) -> &'static str {
        match self {
            EffectKind::Viscous => "viscous",
            EffectKind::Coulomb => "coulomb",
            EffectKind::Drag => "drag",
            EffectKind::Torque => "torque",
            EffectKind::Offset => "offset",
            EffectKind::Gain => "gain",
        }
    }

    /// Whether it changes the dynamics (else it is a sensor effect, which
    /// is corrected in the data rather than modelled).
    pub const fn is_dynamic(self) -> bool {
        !matches!(self, EffectKind::Offset | EffectKind::Gain)
    }

    /// The unit of its coefficient.
    pub const fn unit(self) -> &'static str {
        match self {
            EffectKind::Viscous => "1/s",
            EffectKind::Coulomb | EffectKind::Torque => "rad/s^2",
            EffectKind::Drag => "1/rad",
            EffectKind::Offset => "rad",
            EffectKind::Gain => "1",
        }
    }

    /// The kind named `name` (surrounding spaces ignored).
    pub fn parse(name: &str) -> Result<EffectKind, String> {
        let name = name.trim();
        EffectKind::ALL
            .into_iter()
            .find(|k| k.name() == name)
            .ok_or_else(|| {
                let known: Vec<&str> = EffectKind::ALL.iter().map(|k| k.name()).collect();
                format!("effect {name:?} unknown; known: {}", known.join(", "))
            })
    }
}

impl fmt::Display for EffectKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// An effect with its coefficient.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Effect {
    /// Which.
    pub kind: EffectKind,
    /// How strong (units in the module docs).
    pub coefficient: f64,
}

impl Effect {
    /// `kind` at `coefficient`.
    pub const fn new(kind: EffectKind, coefficient: f64) -> Effect {
        Effect { kind, coefficient }
    }

    /// Its name.
    pub const fn name(&self) -> &'static str {
        self.kind.name()
    }

    /// Its contribution to `theta_ddot` (0 for a sensor effect).
    pub fn accel(&self, _theta: f64, theta_dot: f64) -> f64 {
        let c = self.coefficient;
        match self.kind {
            EffectKind::Viscous => -c * theta_dot,
            EffectKind::Coulomb => -c * theta_dot.signum() * f64::from(u8::from(theta_dot != 0.0)),
            EffectKind::Drag => -c * theta_dot * theta_dot.abs(),
            EffectKind::Torque => c,
            EffectKind::Offset | EffectKind::Gain => 0.0,
        }
    }

    /// What a sensor with this effect reads for the true state `x` (the
    /// state itself for a dynamic effect).
    pub fn measure(&self, x: [f64; 2]) -> [f64; 2] {
        let c = self.coefficient;
        match self.kind {
            EffectKind::Offset => [x[0] + c, x[1]],
            EffectKind::Gain => [(1.0 + c) * x[0], (1.0 + c) * x[1]],
            _ => x,
        }
    }

    /// Parses `NAME:COEFFICIENT`, e.g. `viscous:0.1`.
    pub fn parse(s: &str) -> Result<Effect, String> {
        let (name, c) = s
            .split_once(':')
            .ok_or_else(|| format!("effect {s:?}: expected NAME:COEFFICIENT"))?;
        let kind = EffectKind::parse(name)?;
        let c: f64 = c
            .trim()
            .parse()
            .map_err(|_| format!("effect {s:?}: {c:?} is not a number"))?;
        if !c.is_finite() {
            return Err(format!("effect {s:?}: coefficient must be finite"));
        }
        Ok(Effect::new(kind, c))
    }
}

impl fmt::Display for Effect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}", self.name(), self.coefficient)
    }
}

/// A dynamic effect trained as the second physical parameter: its
/// coefficient is drawn per training rollout, uniformly in `range`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EffectRange {
    /// Which effect.
    pub name: EffectKind,
    /// Coefficients drawn from `[lo, hi]`.
    pub range: [f64; 2],
}

impl EffectRange {
    /// Parses `NAME:LO..HI`, e.g. `viscous:0..0.5`. A sensor effect is
    /// refused: it is corrected in the data, not trained.
    pub fn parse(s: &str) -> Result<EffectRange, String> {
        let (name, r) = s
            .split_once(':')
            .ok_or_else(|| format!("effect {s:?}: expected NAME:LO..HI"))?;
        let (lo, hi) = r
            .split_once("..")
            .ok_or_else(|| format!("effect {s:?}: expected a range LO..HI"))?;
        let num = |v: &str| -> Result<f64, String> {
            v.trim()
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| format!("effect {s:?}: {v:?} is not a finite number"))
        };
        let (lo, hi) = (num(lo)?, num(hi)?);
        if lo > hi {
            return Err(format!("effect {s:?}: empty range"));
        }
        let kind = EffectKind::parse(name)?;
        if !kind.is_dynamic() {
            return Err(format!(
                "effect {s:?}: {kind} is a sensor effect, corrected in the data rather than trained"
            ));
        }
        Ok(EffectRange {
            name: kind,
            range: [lo, hi],
        })
    }

    /// The effect at coefficient `c`.
    pub fn at(&self, c: f64) -> Effect {
        Effect::new(self.name, c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn effects_parse_and_refuse() {
        assert_eq!(
            Effect::parse("viscous:0.25").unwrap(),
            Effect::new(EffectKind::Viscous, 0.25)
        );
        assert_eq!(
            Effect::parse(" offset :-0.1").unwrap(),
            Effect::new(EffectKind::Offset, -0.1)
        );
        for bad in ["viscous", "magic:1", "drag:x", "drag:inf"] {
            assert!(Effect::parse(bad).is_err(), "{bad} was accepted");
        }
        // Every name parses back to its kind: the list is the parser's.
        for k in EffectKind::ALL {
            assert_eq!(EffectKind::parse(k.name()), Ok(k));
        }
    }

    #[test]
    fn effect_ranges_parse_and_refuse() {
        let e = EffectRange::parse("viscous:0..0.5").unwrap();
        assert_eq!(e.name, EffectKind::Viscous);
        assert_eq!(e.range, [0.0, 0.5]);
        assert_eq!(e.at(0.25), Effect::new(EffectKind::Viscous, 0.25));
        assert_eq!(
            EffectRange::parse("torque:-2..0").unwrap().range,
            [-2.0, 0.0]
        );
        for bad in [
            "viscous",
            "viscous:0.5",
            "viscous:1..0",
            "wind:0..1",
            "drag:0..x",
            "offset:0..0.1",
        ] {
            assert!(EffectRange::parse(bad).is_err(), "{bad} was accepted");
        }
        // The config file spells the kind as the command line does.
        let json = serde_json::to_string(&e).unwrap();
        assert_eq!(json, r#"{"name":"viscous","range":[0.0,0.5]}"#);
    }

    #[test]
    fn sensor_effects_change_the_reading_not_the_dynamics() {
        let off = Effect::new(EffectKind::Offset, 0.1);
        let gain = Effect::new(EffectKind::Gain, 0.5);
        assert_eq!(off.accel(1.0, 2.0), 0.0);
        assert_eq!(off.measure([1.0, 2.0]), [1.1, 2.0]);
        assert_eq!(gain.measure([1.0, 2.0]), [1.5, 3.0]);
        let visc = Effect::new(EffectKind::Viscous, 0.2);
        assert_eq!(visc.measure([1.0, 2.0]), [1.0, 2.0]);
        assert_eq!(visc.accel(1.0, 2.0), -0.4);
    }
}
