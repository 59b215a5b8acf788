//! The swing diagnosis on lab-like recordings (`trainer_core::data::lab`):
//! angle only, 12 to 100 Hz or one row per encoder count, tracking noise
//! and quantisation, strings and rods of 0.1 to 1 m at g = 9.81, 30 to 300
//! s, the effects at the sizes real pendulums show. Seeds 1 to 5, one
//! recording of every case each.

use std::collections::BTreeMap;

use trainer_core::data::lab::{Case, suite};
use trainer_core::diagnose::energy::diagnose_swings;
use trainer_core::diagnose::swings::swings;
use trainer_core::physics::EffectKind;

/// Whether a diagnosis names the case right: the effects expected and no
/// other, and the verdict (`none` when clean, `unexplained` for the
/// forcing, `explained` otherwise).
fn named_right(case: Case, verdict: &str, named: &[EffectKind]) -> bool {
    match case {
        Case::Clean => verdict == "none",
        Case::Forcing => verdict == "unexplained",
        _ => verdict == "explained" && named == case.expected().as_slice(),
    }
}

#[test]
fn the_swing_diagnosis_names_lab_recordings_right() {
    let mut table: BTreeMap<Case, (usize, usize)> = BTreeMap::new();
    let mut total = (0, 0);
    for seed in 1..=12u64 {
        for (spec, rec) in suite(seed) {
            let result = swings(&rec.t, &rec.theta).and_then(|sw| diagnose_swings(&sw));
            let (verdict, named, detail) = match &result {
                Ok(d) => {
                    let mut named: Vec<EffectKind> = d.effects.iter().map(|e| e.name).collect();
                    named.sort();
                    (
                        d.verdict.clone(),
                        named,
                        format!(
                            "turns {} A {:.3}->{:.3} noise {:.4} scatter e {:.2} c {:.2} terms {:?}",
                            d.turns,
                            d.amplitude[0],
                            d.amplitude[1],
                            d.noise,
                            d.energy_scatter,
                            d.centre_scatter,
                            d.effects
                                .iter()
                                .map(|e| format!("{} {:.4}+-{:.4}", e.name, e.coefficient, e.se))
                                .collect::<Vec<_>>()
                        ),
                    )
                }
                Err(e) => ("error".to_string(), vec![], e.to_string()),
            };
            let ok = named_right(spec.case, &verdict, &named);
            let row = table.entry(spec.case).or_default();
            row.0 += 1;
            row.1 += usize::from(ok);
            total.0 += 1;
            total.1 += usize::from(ok);
            eprintln!(
                "seed {seed} {:>16} {} L {:.2} {} {:.0} Hz {:?} {:.0} s noise {:.4} effects {:?} offset {:.3} -> {verdict} {named:?} {detail}",
                spec.case.name(),
                if ok { "ok  " } else { "MISS" },
                spec.length,
                spec.rig,
                spec.rate,
                spec.stamps,
                spec.duration,
                spec.noise,
                spec.effects
                    .iter()
                    .map(|e| format!("{} {:.3}", e.name(), e.coefficient))
                    .collect::<Vec<_>>(),
                spec.offset,
            );
        }
    }
    eprintln!("| case | recordings | named right |\n| --- | --- | --- |");
    for (case, (n, ok)) in &table {
        eprintln!("| {} | {n} | {ok} |", case.name());
    }
    eprintln!(
        "| all | {} | {} ({:.0}%) |",
        total.0,
        total.1,
        100.0 * total.1 as f64 / total.0 as f64
    );
    assert!(total.1 * 100 >= 95 * total.0, "{total:?}");
}
