//! Time stamps that step back or repeat: the samples put in time order.
//!
//! A phone's sensor events can arrive out of order (a phyphox gyroscope
//! export held a sample 10 ms before the one above it, 12 times in 45 s):
//! each sample is a measurement at its own stamp, so it is put at its
//! time (a stable sort), not dropped; the samples out of order are
//! counted. A time that repeats the one before (a logger that wrote a
//! sample twice) is skipped and counted. Refused, with the reason: a step
//! back of over [`BACK_MAX_S`] (a clock reset, two recordings joined: an
//! order would interleave them), and stamps out of order in over
//! [`SCRAMBLED_SHARE`] of the steps (wholly scrambled), or back at
//! [`BACKWARDS_SHARE`] of them (running backwards throughout).

/// Longest step back put in order, s: a sensor's event delivered late is
/// a step or a few behind (10 ms in the phyphox export); a step back of
/// a second or more is a clock reset or two recordings in one file.
pub const BACK_MAX_S: f64 = 1.0;

/// Share of steps that go back from which a recording runs backwards
/// throughout (written in reverse, a few of its own stamps out of order
/// as a phone's are).
pub const BACKWARDS_SHARE: f64 = 0.9;

/// Largest share of steps that go back put in order: 12 in 2,250 (0.5%)
/// in the phyphox export; a random order has about half its steps go
/// back, a recording written backwards all of them. Two steps back or
/// fewer are never called scrambled (a short file's one late sample).
pub const SCRAMBLED_SHARE: f64 = 0.25;

/// What putting rows in time order did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Order {
    /// Rows whose time was before a row's above them, moved to their time.
    pub reordered: usize,
    /// Rows skipped whose time repeats the one before.
    pub repeated: usize,
}

/// Puts `t` and each of `values` (the same length) in time order and
/// skips the rows whose time repeats the one before (see the module
/// docs); `line` gives a row's line for errors, which are
/// `(line, problem)`.
pub fn in_time_order(
    t: &mut Vec<f64>,
    values: &mut [Vec<f64>],
    line: impl Fn(usize) -> usize,
) -> Result<Order, (usize, String)> {
    let steps_back = t.windows(2).filter(|w| w[1] < w[0]).count();
    if t.len() > 2 && steps_back as f64 >= BACKWARDS_SHARE * (t.len() - 1) as f64 {
        return Err((
            0,
            "the time stamps run backwards throughout: not a recording in time order".into(),
        ));
    }
    if steps_back > 2 && steps_back as f64 > SCRAMBLED_SHARE * t.len() as f64 {
        return Err((
            0,
            format!(
                "the time stamps are scrambled: {steps_back} of {} steps go back",
                t.len() - 1
            ),
        ));
    }
    let mut latest = f64::NEG_INFINITY;
    let mut behind = 0;
    for (k, &time) in t.iter().enumerate() {
        if time < latest {
            if latest - time > BACK_MAX_S {
                return Err((
                    line(k),
                    format!(
                        "time {time} is {:.3} s before the row above's {latest}: a clock reset or two recordings in one file? Import each part (--start, --duration) or split the file there",
                        latest - time
                    ),
                ));
            }
            behind += 1;
        }
        latest = latest.max(time);
    }
    if behind > 0 {
        let mut at: Vec<usize> = (0..t.len()).collect();
        at.sort_by(|&a, &b| t[a].total_cmp(&t[b]));
        let pick = |v: &mut Vec<f64>| *v = at.iter().map(|&k| v[k]).collect();
        pick(t);
        values.iter_mut().for_each(pick);
    }
    // Repeats skipped, in place.
    let mut kept = 0;
    for k in 0..t.len() {
        if kept > 0 && t[k] == t[kept - 1] {
            continue;
        }
        t[kept] = t[k];
        for v in values.iter_mut() {
            v[kept] = v[k];
        }
        kept += 1;
    }
    let repeated = t.len() - kept;
    t.truncate(kept);
    values.iter_mut().for_each(|v| v.truncate(kept));
    Ok(Order {
        reordered: behind,
        repeated,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two rows 10 ms behind (as the phyphox export's) are moved to their
    /// time with their values; a repeat skipped; a reset, a scrambled and
    /// a backwards recording refused with what they are.
    #[test]
    fn rows_out_of_order_are_put_in_order_and_the_rest_refused() {
        let mut t = vec![0.0, 0.02, 0.04, 0.03, 0.06, 0.06, 0.08, 0.07, 0.1];
        let mut v = vec![(0..9).map(f64::from).collect::<Vec<_>>()];
        let lines: Vec<usize> = (2..11).collect();
        let order = in_time_order(&mut t, &mut v, |k| lines[k]).unwrap();
        assert_eq!(
            order,
            Order {
                reordered: 2,
                repeated: 1
            }
        );
        assert_eq!(t, [0.0, 0.02, 0.03, 0.04, 0.06, 0.07, 0.08, 0.1]);
        assert_eq!(v[0], [0.0, 1.0, 3.0, 2.0, 4.0, 7.0, 6.0, 8.0]);
        let mut t = vec![30.0, 30.02, 0.0, 0.02];
        let e = in_time_order(&mut t, &mut [], |k| k + 2).unwrap_err();
        assert_eq!(e.0, 4);
        assert!(e.1.contains("clock reset"), "{}", e.1);
        let mut t: Vec<f64> = (0..100).rev().map(|k| f64::from(k) * 0.01).collect();
        let e = in_time_order(&mut t, &mut [], |_| 0).unwrap_err();
        assert!(e.1.contains("backwards throughout"), "{}", e.1);
        let mut t: Vec<f64> = (0..100)
            .map(|k| f64::from((k * 37) % 100) * 0.005)
            .collect();
        let e = in_time_order(&mut t, &mut [], |_| 0).unwrap_err();
        assert!(e.1.contains("scrambled"), "{}", e.1);
    }
}
