//! The quality factor `Q` of a pendulum's swing for a set of dissipations.
//!
//! `Q = omega A / (2 |dA/dt|)` at the swing `A`: the amplitude's decay
//! rate from the energy each dissipation takes a period (for
//! `theta = A cos(omega t)`): viscous `c` gives `dA/dt = -c A / 2`
//! (`Q = omega / c` at every swing), drag `c` gives `-(4 / 3 pi) c omega
//! A^2`, Coulomb friction `c` gives `-(2 / pi) c / omega`; together their
//! sum.

use super::{Effect, EffectKind};

/// `Q` at the swing `a`, rad, of a pendulum at `omega`, rad/s, with
/// `effects` (the module docs); infinite without dissipation.
pub fn q_of(effects: &[Effect], omega: f64, a: f64) -> f64 {
    let rate: f64 = effects
        .iter()
        .map(|e| {
            let c = e.coefficient.abs();
            match e.kind {
                EffectKind::Viscous => c * a / 2.0,
                EffectKind::Drag => 4.0 / (3.0 * std::f64::consts::PI) * c * omega * a * a,
                EffectKind::Coulomb => 2.0 / std::f64::consts::PI * c / omega,
                _ => 0.0,
            }
        })
        .sum();
    omega * a / (2.0 * rate)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Viscous `Q = omega / c` at any swing; drag's halves as the swing
    /// doubles; Coulomb's doubles.
    #[test]
    fn q_follows_each_dissipation() {
        let v = [Effect::new(EffectKind::Viscous, 0.02)];
        assert!((q_of(&v, 4.0, 0.3) - 200.0).abs() < 1e-9);
        let d = [Effect::new(EffectKind::Drag, 0.02)];
        assert!((q_of(&d, 4.0, 0.2) / q_of(&d, 4.0, 0.4) - 2.0).abs() < 1e-9);
        let c = [Effect::new(EffectKind::Coulomb, 0.02)];
        assert!((q_of(&c, 4.0, 0.4) / q_of(&c, 4.0, 0.2) - 2.0).abs() < 1e-9);
    }
}
