//! The estimator on a Cortex-M4F, in QEMU (`mps2-an386`, semihosting).
//!
//! Reads the shipped weights in place (`include_bytes!`), filters the test
//! rollouts of `rollouts.bin` (embedded by `build.rs`) step by step, each
//! twice (as shipped: the blob's gain schedule, then the two-stage tail;
//! and with `Estimator::without_schedule`), then the string of
//! `rig-rollouts.bin` with the rig blob (mode `rig`: the extended filter),
//! and
//! prints every step's outputs as the hex bits of each `f32`, so that
//! `host-tests/tests/firmware.rs` can compare them with the host's, then a
//! readable summary per rollout.
//!
//! No panic path: the panic handler calls a function that does not exist,
//! so the firmware links only if the optimiser removed every path to a
//! panic, in `Estimator::step`, `Model::from_bytes` and everything else
//! here. Nothing here uses `core::fmt` (its float formatting has panic
//! paths); numbers are written by hand.
//!
//! Instruction counts: QEMU runs with `-icount shift=0` (one nanosecond of
//! virtual time per executed instruction) and SysTick counts the 25 MHz
//! core clock, one tick per 40 instructions. A calibration loop of known
//! length (`cortex_m::asm::delay`, two instructions per turn) checks the
//! factor in every run.
#![no_std]
#![no_main]

use core::panic::PanicInfo;

use cortex_m::peripheral::SYST;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hio};
use estimator::blob::Aligned;
use estimator::control::{Phase, Pilot};
use estimator::{Estimator, Model, Trust};

mod rollouts {
    include!(concat!(env!("OUT_DIR"), "/rollouts.rs"));
}

/// The shipped weights, left in flash and read in place: each blob at a
/// 4-aligned address, so its weights are read as `f32` in place. The
/// protocol's blob ...
static BLOB: &Aligned<[u8]> = &Aligned(*include_bytes!("../../../weights/pendulum.kkf"));
/// ... and the rig blob (the bilinear family, the extended filter).
static RIG_BLOB: &Aligned<[u8]> = &Aligned(*include_bytes!("../../../weights/rig.kkf"));
/// The bilinear blob that learned the torque's `B(q)` (driven rollouts).
static DRIVEN_BLOB: &Aligned<[u8]> = &Aligned(*include_bytes!(
    "../../../weights/pendulum-bilinear-driven.kkf"
));

/// The blob the swing-up reads its length with (the control issue's).
static CONTROL_BLOB: &Aligned<[u8]> =
    &Aligned(*include_bytes!("../../../weights/pendulum-bilinear.kkf"));
/// The swing-up's gravity, m/s^2, and torque limit, N m: the control
/// environment's (the host's test records with the same).
const CONTROL_G: f32 = 10.0;
const CONTROL_MAX_TORQUE: f32 = 2.0;

/// Measurements in the protocol's estimation window: updates `1..WINDOW`
/// are timed apart from the later ones.
const WINDOW: u32 = estimator::WINDOW as u32;

/// Turns of `asm::delay` in the calibration: `2 (n + 1)` instructions.
const CALIBRATION_TURNS: u32 = 1_000_000;

#[panic_handler]
fn panic(_: &PanicInfo) -> ! {
    unsafe extern "Rust" {
        /// Deliberately undefined: referencing it fails the link.
        fn estimator_firmware_has_a_panic_path() -> !;
    }
    // SAFETY: never runs; the firmware links only if no panic is reachable.
    unsafe { estimator_firmware_has_a_panic_path() }
}

/// A line being written; full lines are sent over semihosting.
struct Line {
    buf: [u8; 384],
    len: usize,
}

impl Line {
    const fn new() -> Self {
        Line {
            buf: [0; 384],
            len: 0,
        }
    }

    fn byte(&mut self, b: u8) {
        if let Some(slot) = self.buf.get_mut(self.len) {
            *slot = b;
            self.len += 1;
        }
    }

    fn str(&mut self, s: &str) -> &mut Self {
        for b in s.bytes() {
            self.byte(b);
        }
        self
    }

    fn uint(&mut self, mut v: u64) -> &mut Self {
        let mut digits = [0u8; 20];
        let mut n = 0;
        loop {
            if let Some(d) = digits.get_mut(n) {
                *d = b'0' + (v % 10) as u8;
            }
            n += 1;
            v /= 10;
            if v == 0 || n >= digits.len() {
                break;
            }
        }
        for i in (0..n).rev() {
            if let Some(&d) = digits.get(i) {
                self.byte(d);
            }
        }
        self
    }

    /// The bits of `x` as 8 hex digits, exact.
    fn hex(&mut self, x: f32) -> &mut Self {
        let bits = x.to_bits();
        for k in (0..8).rev() {
            let nib = ((bits >> (4 * k)) & 0xf) as u8;
            self.byte(if nib < 10 {
                b'0' + nib
            } else {
                b'a' + nib - 10
            });
        }
        self.byte(b' ');
        self
    }

    /// `x` with four decimals, for people.
    fn dec(&mut self, x: f32) -> &mut Self {
        if x.is_nan() {
            return self.str("nan");
        }
        if x < 0.0 {
            self.byte(b'-');
        }
        let scaled = x.abs() * 10_000.0 + 0.5;
        if !(scaled < 1.0e18) {
            return self.str("inf");
        }
        let v = scaled as u64;
        self.uint(v / 10_000);
        self.byte(b'.');
        let frac = v % 10_000;
        for div in [1000, 100, 10, 1] {
            self.byte(b'0' + ((frac / div) % 10) as u8);
        }
        self
    }

    fn send(&mut self) {
        self.byte(b'\n');
        if let Ok(mut out) = hio::hstdout() {
            let _ = out.write_all(self.buf.get(..self.len).unwrap_or(&[]));
        }
        self.len = 0;
    }
}

/// SysTick ticks elapsed between two readings of the down-counter.
fn ticks(before: u32, after: u32) -> u32 {
    before.wrapping_sub(after) & 0x00ff_ffff
}

/// Writes `reasons=` and the verdict's reasons as codes joined by commas
/// (`-` for none).
fn reasons(line: &mut Line, t: &Trust) {
    line.str("reasons=");
    if t.reasons().is_empty() {
        line.str("-");
    }
    for (k, r) in t.reasons().iter().enumerate() {
        if k > 0 {
            line.str(",");
        }
        line.str(r.code());
    }
}

/// Bytes below the stack pointer painted at start to find the stack's
/// high-water mark (RAM is 4 MiB; the firmware needs far less).
const PAINT: usize = 64 * 1024;
const PAINT_WORD: u32 = 0xdead_beef;

/// Fills `bytes` below the current stack pointer with a pattern.
#[inline(never)]
fn paint_stack(bytes: usize) -> usize {
    let sp = cortex_m::register::msp::read() as usize - 256;
    let bottom = sp - bytes;
    let mut a = bottom;
    while a < sp {
        // SAFETY: RAM below the stack pointer, unused so far (the stack
        // grows down into it; nothing else is placed there).
        unsafe { core::ptr::write_volatile(a as *mut u32, PAINT_WORD) };
        a += 4;
    }
    sp
}

/// Stack bytes used below `top` since [`paint_stack`] painted `bytes`.
fn stack_used(top: usize, bytes: usize) -> usize {
    let bottom = top - bytes;
    let mut a = bottom;
    // SAFETY: the same painted RAM, read back.
    while a < top && unsafe { core::ptr::read_volatile(a as *const u32) } == PAINT_WORD {
        a += 4;
    }
    top - a
}

/// Bytes painted below the caller of each step: more than a step uses.
const STEP_PAINT: usize = 24 * 1024;

#[entry]
fn main() -> ! {
    let top = paint_stack(PAINT);
    let mut line = Line::new();
    let mut ok = run(&mut line);
    line.str("stack used=")
        .uint(stack_used(top, PAINT) as u64)
        .str(" (high-water below main: model, estimator, step)")
        .send();
    if ok {
        let top = paint_stack(PAINT);
        ok = run_rig(&mut line);
        line.str("rig stack used=")
            .uint(stack_used(top, PAINT) as u64)
            .str(" (the same for the rig blob)")
            .send();
    }
    if ok {
        ok = run_driven(&mut line);
    }
    if ok {
        ok = run_control(&mut line);
    }
    line.str(if ok { "done" } else { "failed" }).send();
    debug::exit(if ok {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    loop {
        cortex_m::asm::wfi();
    }
}

#[inline(never)]
fn run(line: &mut Line) -> bool {
    // Proves that the link-time check can fail: with this feature the
    // firmware holds one reachable panic (an out-of-bounds index) and must
    // not link (host-tests/tests/firmware.rs checks that it does not).
    #[cfg(feature = "deliberate-panic")]
    {
        let a = [0u8; 2];
        line.uint(u64::from(a[core::hint::black_box(2usize)]));
    }
    let Some(mut cp) = cortex_m::Peripherals::take() else {
        line.str("error: core peripherals taken").send();
        return false;
    };
    cp.SYST.set_clock_source(SystClkSource::Core);
    cp.SYST.set_reload(0x00ff_ffff);
    cp.SYST.clear_current();
    cp.SYST.enable_counter();

    let before = SYST::get_current();
    cortex_m::asm::delay(CALIBRATION_TURNS);
    let after = SYST::get_current();
    line.str("calibration instructions=")
        .uint(2 * (u64::from(CALIBRATION_TURNS) + 1))
        .str(" ticks=")
        .uint(u64::from(ticks(before, after)))
        .send();

    let model = match Model::from_bytes(&BLOB.0) {
        Ok(m) => m,
        Err(e) => {
            line.str("error: blob refused: ").str(e.message()).send();
            return false;
        }
    };
    line.str("sizes blob=")
        .uint(BLOB.0.len() as u64)
        .str(" model=")
        .uint(core::mem::size_of::<Model>() as u64)
        .str(" estimator=")
        .uint(core::mem::size_of::<Estimator>() as u64)
        .send();

    // Each rollout twice: on the blob's gain schedule (as shipped), and
    // with the covariance recursion at every update (what runs after the
    // schedule's last update).
    let modes = [
        ("scheduled", Estimator::new(&model).at_trained_gravity()),
        (
            "recursive",
            Estimator::without_schedule(&model).at_trained_gravity(),
        ),
    ];
    for (id, xs) in &rollouts::ROLLOUTS {
        for (mode, est) in &modes {
            if !filter(line, &model, *id, mode, est.clone(), xs) {
                return false;
            }
        }
    }
    true
}

/// The rig blob over the string of `rig-rollouts.bin`, at its trained
/// gravity (9.81).
#[inline(never)]
fn run_rig(line: &mut Line) -> bool {
    let model = match Model::from_bytes(&RIG_BLOB.0) {
        Ok(m) => m,
        Err(e) => {
            line.str("error: rig blob refused: ")
                .str(e.message())
                .send();
            return false;
        }
    };
    line.str("rig sizes blob=")
        .uint(RIG_BLOB.0.len() as u64)
        .str(" model=")
        .uint(core::mem::size_of::<Model>() as u64)
        .send();
    let est = Estimator::new(&model).at_trained_gravity();
    rollouts::RIG_ROLLOUTS
        .iter()
        .all(|(id, xs)| filter(line, &model, *id, "rig", est.clone(), xs))
}

/// The driven rollouts through the blob with `B(q)`: each told its
/// torques (`driven`), then the same measurements without them
/// (`undriven`), so that the two steps' costs compare.
#[inline(never)]
fn run_driven(line: &mut Line) -> bool {
    let model = match Model::from_bytes(&DRIVEN_BLOB.0) {
        Ok(m) => m,
        Err(e) => {
            line.str("error: driven blob refused: ")
                .str(e.message())
                .send();
            return false;
        }
    };
    let est = Estimator::new(&model).at_trained_gravity();
    for (id, rows) in &rollouts::DRIVEN_ROLLOUTS {
        let mut xs = [[0.0f32; 2]; rollouts::DRIVEN_ROLLOUTS_STEPS];
        let mut us = [0.0f32; rollouts::DRIVEN_ROLLOUTS_STEPS];
        for ((x, u), r) in xs.iter_mut().zip(us.iter_mut()).zip(rows) {
            *x = [r[0], r[1]];
            *u = r[2];
        }
        if !filter_driven(line, &model, *id, "driven", est.clone(), &xs, Some(&us)) {
            return false;
        }
        if !filter_driven(line, &model, *id, "undriven", est.clone(), &xs, None) {
            return false;
        }
    }
    true
}

/// A recorded swing-up (`swing-up.bin`: the states and the torques the
/// host's [`Pilot`] applied) stepped again here through a `Pilot` of the
/// same blob: each step's torque and length printed (`ctl`), its
/// instructions summed apart for the coast's reading steps (an estimator
/// step each) and the others (the controller alone).
#[inline(never)]
fn run_control(line: &mut Line) -> bool {
    let model = match Model::from_bytes(&CONTROL_BLOB.0) {
        Ok(m) => m,
        Err(e) => {
            line.str("error: control blob refused: ")
                .str(e.message())
                .send();
            return false;
        }
    };
    let mut pilot = match Pilot::new(&model, CONTROL_G, CONTROL_MAX_TORQUE) {
        Ok(p) => p,
        Err(e) => {
            line.str("error: pilot refused: ").str(e.message()).send();
            return false;
        }
    };
    // (steps, ticks) of the controller alone and of the reading steps.
    let (mut ctl, mut read) = ((0u64, 0u64), (0u64, 0u64));
    for (id, rows) in &rollouts::SWING_UP {
        for (k, r) in rows.iter().enumerate() {
            let x = [r[0], r[1]];
            let before = SYST::get_current();
            let out = pilot.step(&x);
            let after = SYST::get_current();
            let c = match out {
                Ok(c) => c,
                Err(e) => {
                    line.str("error: step refused: ").str(e.message()).send();
                    return false;
                }
            };
            let sum = if matches!(c.phase, Phase::Read(_)) {
                &mut read
            } else {
                &mut ctl
            };
            sum.0 += 1;
            sum.1 += u64::from(ticks(before, after));
            line.str("ctl ")
                .uint(u64::from(*id))
                .str(" ")
                .uint(k as u64)
                .str(" ");
            line.hex(c.torque);
            line.hex(c.length);
            line.send();
        }
    }
    line.str("control steps=")
        .uint(ctl.0)
        .str(" ticks=")
        .uint(ctl.1)
        .str(" read_steps=")
        .uint(read.0)
        .str(" read_ticks=")
        .uint(read.1)
        .send();
    true
}

/// Filters one rollout from `est` reset, printing every step's outputs
/// and a summary with the instructions spent; `false` if a step was
/// refused.
#[inline(never)]
fn filter(
    line: &mut Line,
    model: &Model,
    id: u32,
    mode: &str,
    est: Estimator,
    xs: &[[f32; 2]],
) -> bool {
    filter_driven(line, model, id, mode, est, xs, None)
}

/// [`filter`] with the torque held before each measurement (`us[k - 1]`
/// before `xs[k]`; none: free steps).
#[inline(never)]
fn filter_driven(
    line: &mut Line,
    model: &Model,
    id: u32,
    mode: &str,
    mut est: Estimator,
    xs: &[[f32; 2]],
    us: Option<&[f32]>,
) -> bool {
    est.reset();
    // Ticks of the updates in the protocol's window (t = 1..=63, the gain
    // schedule's when it is used) and of those after it.
    let (mut window_ticks, mut window_steps) = (0u64, 0u64);
    let (mut after_ticks, mut after_steps) = (0u64, 0u64);
    let mut last = None;
    // The most stack one step used, below this frame.
    let mut step_stack = 0usize;
    for (k, x) in xs.iter().enumerate() {
        let u = match (us, k.checked_sub(1)) {
            (Some(us), Some(j)) => us.get(j).copied().unwrap_or(0.0),
            _ => 0.0,
        };
        let top = paint_stack(STEP_PAINT);
        let before = SYST::get_current();
        let out = est.step_driven(x, u);
        let after = SYST::get_current();
        step_stack = step_stack.max(stack_used(top, STEP_PAINT));
        let out = match out {
            Ok(o) => o,
            Err(e) => {
                line.str("error: step refused: ").str(e.message()).send();
                return false;
            }
        };
        // The first step only encodes and sets the prior.
        let spent = u64::from(ticks(before, after));
        if (1..WINDOW).contains(&out.t) {
            window_ticks += spent;
            window_steps += 1;
        } else if out.t >= WINDOW {
            after_ticks += spent;
            after_steps += 1;
        }
        line.str("step ")
            .uint(u64::from(id))
            .str(" ")
            .str(mode)
            .str(" ");
        line.uint(u64::from(out.t)).str(" ");
        for v in out
            .params
            .iter()
            .chain(&out.param_std)
            .chain(&out.filter.sigma)
        {
            line.hex(*v);
        }
        // The quality factor and its std, NaN where there is none yet.
        line.hex(out.readers.q_factor.unwrap_or(f32::NAN));
        line.hex(out.readers.q_factor_std.unwrap_or(f32::NAN));
        line.str(out.trust.as_str()).str(" ");
        reasons(line, &out.trust);
        line.send();
        last = Some(out);
    }
    let before = SYST::get_current();
    let z = model.encode(&model.normalise(&[0.5, -0.25]));
    let after = SYST::get_current();
    core::hint::black_box(z);
    if let Some(out) = last {
        let p = out.params;
        line.str("rollout ").uint(u64::from(id));
        line.str(" mode=").str(mode);
        line.str(" length=").dec(p[0]);
        line.str(" std=").dec(out.param_std[0]);
        line.str(" sigma=").dec(out.filter.sigma[0]);
        line.str(" q=")
            .dec(out.readers.q_factor.unwrap_or(f32::NAN));
        line.str(" trust=").str(out.trust.as_str()).str(" ");
        reasons(line, &out.trust);
        line.str(" window_steps=").uint(window_steps);
        line.str(" window_ticks=").uint(window_ticks);
        line.str(" after_steps=").uint(after_steps);
        line.str(" after_ticks=").uint(after_ticks);
        line.str(" encode_ticks=")
            .uint(u64::from(ticks(before, after)));
        line.str(" step_stack=").uint(step_stack as u64);
        line.send();
    }
    true
}
