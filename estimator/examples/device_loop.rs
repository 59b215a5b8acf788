//! The device's loop, as the firmware (`estimator/firmware`) runs it: a
//! blob in flash, one estimator on the stack, a measurement in and an
//! estimate out every interval, no allocation.
//!
//! ```text
//! cargo run -p estimator --example device_loop
//! ```
//!
//! Here the sensor is a simulated string of 0.5 m with a little drag and
//! an angle offset of 0.03 rad; on a board, `read_sensor` reads the
//! encoder or the IMU, and `report` writes to the UART or a display.

use estimator::blob::Aligned;
use estimator::{Estimator, Model, StepOutput};

/// The blob, in flash, aligned as the model reads it in place.
static RIG: &Aligned<[u8]> = &Aligned(*include_bytes!("../../weights/rig.kkf"));

/// The rig's gravity, m/s^2.
const G: f32 = 9.81;

/// The simulated rig: its length (m), drag (1/rad), the sensor's offset
/// (rad), and its state.
struct Sensor {
    length: f32,
    drag: f32,
    offset: f32,
    theta: f32,
    rate: f32,
}

impl Sensor {
    /// The next measurement, `dt` s after the last: `[theta, theta_dot]`.
    fn read_sensor(&mut self, dt: f32) -> [f32; 2] {
        for _ in 0..100 {
            let h = dt / 100.0;
            let acc = -G / self.length * self.theta.sin() - self.drag * self.rate * self.rate.abs();
            self.rate += acc * h;
            self.theta += self.rate * h;
        }
        [self.theta + self.offset, self.rate]
    }
}

fn main() -> Result<(), estimator::Error> {
    // Once, at boot: the blob checked (magic, version, sizes, CRC).
    let model = Model::from_bytes(&RIG.0)?;
    let dt = model.blob().body.dt;
    let mut est = Estimator::new(&model).with_gravity(G)?;
    let mut sensor = Sensor {
        length: 0.5,
        drag: 0.02,
        offset: 0.03,
        theta: 0.5,
        rate: 0.0,
    };
    // Every `dt`: measure, step, report. A refused measurement (a NaN, a
    // glitch the filter calls an outlier) changes nothing and the loop
    // goes on.
    for k in 0..(90.0 / dt) as u32 {
        let x = sensor.read_sensor(dt);
        match est.step(&x) {
            Ok(out) if k % 250 == 249 => report(k as f32 * dt, &out),
            Ok(_) => {}
            Err(e) => println!("step {k}: refused: {e}"),
        }
    }
    Ok(())
}

/// What a display shows: the length, its 2-std band, the offset found and
/// the verdict's first reason.
fn report(t: f32, out: &StepOutput) {
    let reason = out
        .trust
        .reasons()
        .first()
        .map_or(String::new(), |r| format!(" ({r})"));
    println!(
        "{t:5.0} s  L = {:.3} m +- {:.3}  offset {}  {}{reason}",
        out.params[0],
        2.0 * out.param_std[0],
        out.readers
            .offset
            .map_or("-".into(), |o| format!("{o:+.3} rad")),
        if out.trust.is_trusted() {
            "trusted"
        } else if out.trust.is_untrusted() {
            "untrusted"
        } else {
            "pending"
        },
    );
}
