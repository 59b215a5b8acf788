//! The model read from a blob: normalisation, encoder `phi`, decoder
//! `phi^-1`, the augmented Koopman matrix `F`, and open-loop simulation.

use crate::blob::{
    BILINEAR_BLOCK_LEN, BILINEAR_BLOCKS, Blob, Family, Layout, Net,
    SCHEDULE_STEP_LEN,
};
use crate::{
    AUG_DIM, Aug, Error, HIDDEN_DIM, HIDDEN_NARROW, LATENT_DIM, Latent, PARAM_DIM,
    STATE_DIM, State,
};

mod mlp;

use mlp::{Mlp, rows};

#[cfg(target_endian = "big")]
compile_error!(
    "the blob's weights are little-endian f32 read in place: little-endian targets only"
);

internal! {
    /// The latent rows of `F`, `C = [A B]`, stored column by column: `C^T`
    /// (AUG rows of LATENT), decoded once. The filter reads them every step,
    /// summing scaled columns. The parameter rows of `F` are the identity
    /// (checked when the blob is read).
    pub type KoopmanColumns = [[f32; LATENT_DIM]; AUG_DIM];
}

internal! {
    /// The gain schedule's tail (see the blob's "gain schedule"), read in
    /// place: what the filter needs after update `T` in two-stage form.
    #[derive(Debug, Clone, Copy)]
    pub struct Tail<'a> {
        /// `S~^-1`, the inverse of the bias-free innovation covariance (the
        /// held gain is `K~ = I - R S~^-1`).
        pub si: &'a [[f32; LATENT_DIM]; LATENT_DIM],
        /// `P~`, the bias-free covariance after an update.
        pub pt: &'a [[f32; LATENT_DIM]; LATENT_DIM],
        /// `V_T`, the sensitivity of `y` to `p` after update `T`, column by
        /// column.
        pub v: &'a [[f32; LATENT_DIM]; PARAM_DIM],
        /// `P_b,T`, the parameters' covariance after update `T`.
        pub pb: &'a [[f32; PARAM_DIM]; PARAM_DIM],
    }
}

impl<'a> Tail<'a> {
    fn from_arena(a: &'a [f32], at: usize) -> Result<Self, Error> {
        let l2 = LATENT_DIM * LATENT_DIM;
        Ok(Tail {
            si: rows(a, at)?,
            pt: rows(a, at + l2)?,
            v: rows(a, at + 2 * l2)?,
            pb: rows(a, at + 2 * l2 + PARAM_DIM * LATENT_DIM)?,
        })
    }
}

/// `C^T` of a linear blob's `F` (row-major, [`AUG_DIM`] square, at `at`
/// of the arena): its latent rows, column by column.
fn columns(a: &[f32], at: usize) -> Result<KoopmanColumns, Error> {
    let f = rows::<LATENT_DIM, AUG_DIM>(a, at)?;
    let mut ct = [[0.0f32; LATENT_DIM]; AUG_DIM];
    for (i, row) in f.iter().enumerate() {
        for (col, v) in ct.iter_mut().zip(row) {
            if let Some(d) = col.get_mut(i) {
                *d = *v;
            }
        }
    }
    Ok(ct)
}

/// The encoder and the decoder at one of the [`HIDDEN_WIDTHS`], each
/// with its sizes fixed at compile time.
#[derive(Debug, Clone, Copy)]
enum Nets<'a> {
    /// 64-wide hidden layers.
    Narrow(
        Mlp<'a, STATE_DIM, HIDDEN_NARROW, LATENT_DIM>,
        Mlp<'a, LATENT_DIM, HIDDEN_NARROW, STATE_DIM>,
    ),
    /// [`HIDDEN_DIM`]-wide hidden layers.
    Wide(
        Mlp<'a, STATE_DIM, HIDDEN_DIM, LATENT_DIM>,
        Mlp<'a, LATENT_DIM, HIDDEN_DIM, STATE_DIM>,
    ),
}

impl<'a> Nets<'a> {
    fn from_arena(a: &'a [f32], layout: Layout) -> Result<Self, Error> {
        match layout.hidden {
            HIDDEN_NARROW => Ok(Nets::Narrow(
                Mlp::from_arena(a, layout, Net::Encoder)?,
                Mlp::from_arena(a, layout, Net::Decoder)?,
            )),
            HIDDEN_DIM => Ok(Nets::Wide(
                Mlp::from_arena(a, layout, Net::Encoder)?,
                Mlp::from_arena(a, layout, Net::Decoder)?,
            )),
            _ => Err(Error::BlobShapeMismatch),
        }
    }
}

internal! {
    /// A [`LATENT_DIM`] square matrix, row-major, read in place.
    pub type LatentRows = [[f32; LATENT_DIM]; LATENT_DIM];
}

/// A validated model whose weights stay in the bytes it was read from.
///
/// Only the latent rows of a linear `F` are copied out of the blob, by
/// columns (1152 bytes), as `f32` the filter can load
/// directly; the MLP weights (the bulk of the blob) and the bilinear
/// matrices are read in place as `&[f32]`.
#[derive(Debug, Clone, Copy)]
pub struct Model<'a> {
    blob: Blob<'a>,
    arena: &'a [f32],
    tail: Option<Tail<'a>>,
    nets: Nets<'a>,
    /// Where the gain schedule starts in the arena (read every scheduled
    /// step; set once from the blob's layout).
    schedule_at: usize,
    ct: KoopmanColumns,
    /// `F_0, F_1, F_2, F_11` of a bilinear blob, in place.
    bilinear: Option<[&'a LatentRows; BILINEAR_BLOCKS]>,
    /// The latent rows of `B` (the torque's column; its parameter rows are
    /// zero): a linear blob's, or a bilinear blob's `B_0, B_1, B_2, B_11`
    /// (format 12 on). `None`: a free model (`B = 0`).
    drive: Option<Drive<'a>>,
    /// `drive` is there and not all zero ([`Model::is_driven`]).
    driven: bool,
}

/// How the torque `u` enters the latent step: `y' = ... + u b`.
#[derive(Debug, Clone, Copy)]
enum Drive<'a> {
    /// A linear blob's `b`, the same at every parameter.
    Linear(&'a [f32; LATENT_DIM]),
    /// A bilinear blob's `b(q) = B_0 + q_1 B_1 + q_2 B_2 + q_1^2 B_11`.
    Bilinear([&'a [f32; LATENT_DIM]; BILINEAR_BLOCKS]),
}

impl<'a> Model<'a> {
    /// Reads a blob; the weights are borrowed from `bytes`, not copied.
    ///
    /// # Errors
    ///
    /// Every check of [`Blob::from_bytes`] (magic, version, sizes, CRC,
    /// lengths, finiteness); [`Error::BlobMisaligned`] unless the weights
    /// lie at a 4-byte aligned address (any heap buffer, or
    /// [`crate::blob::Aligned`] for `include_bytes!`).
    ///
    /// # Examples
    ///
    /// ```
    /// use estimator::{Error, Model};
    ///
    /// let mut bytes = std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/../weights/rig.kkf"))?;
    /// let model = Model::from_bytes(&bytes)?;
    /// assert_eq!(model.blob().body.rig.name(), "simple");
    ///
    /// // One flipped bit in the weights: the CRC refuses the blob.
    /// let last = bytes.len() - 5;
    /// bytes[last] ^= 1;
    /// assert_eq!(Model::from_bytes(&bytes).unwrap_err(), Error::BlobBadCrc);
    /// // Not a blob at all; the start of one.
    /// assert_eq!(Model::from_bytes(b"GIF89a, a picture").unwrap_err(), Error::BlobBadMagic);
    /// assert_eq!(Model::from_bytes(&bytes[..6]).unwrap_err(), Error::BlobTruncated);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn from_bytes(bytes: &'a [u8]) -> Result<Self, Error> {
        let blob = Blob::from_bytes(bytes)?;
        let arena: &'a [f32] =
            bytemuck::try_cast_slice(blob.body.weights.0).map_err(|_| Error::BlobMisaligned)?;
        let layout = blob.layout();
        let nets = Nets::from_arena(arena, layout)?;
        let bilinear = match blob.body.family {
            Family::Linear => None,
            Family::Bilinear => {
                let block = |k: usize| {
                    rows::<LATENT_DIM, LATENT_DIM>(arena, layout.f_at() + k * BILINEAR_BLOCK_LEN)
                };
                Some([block(0)?, block(1)?, block(2)?, block(3)?])
            }
        };
        let ct = match bilinear {
            None => columns(arena, layout.f_at())?,
            Some(_) => [[0.0; LATENT_DIM]; AUG_DIM],
        };
        let column = |at: usize| rows::<1, LATENT_DIM>(arena, at).map(|[r]| r);
        let drive = match blob.body.family {
            Family::Linear => Some(Drive::Linear(column(layout.b_at())?)),
            Family::Bilinear if blob.bilinear_driven() => {
                let at = |k: usize| column(layout.bilinear_b_at() + k * LATENT_DIM);
                Some(Drive::Bilinear([at(0)?, at(1)?, at(2)?, at(3)?]))
            }
            Family::Bilinear => None,
        };
        let steps = usize::from(blob.body.filter.schedule_steps);
        let tail = if steps > 0 {
            Some(Tail::from_arena(
                arena,
                layout.schedule_at() + steps * SCHEDULE_STEP_LEN,
            )?)
        } else {
            None
        };
        Ok(Model {
            blob,
            arena,
            tail,
            nets,
            schedule_at: layout.schedule_at(),
            ct,
            bilinear,
            drive,
            driven: match drive {
                Some(Drive::Linear(b)) => b.iter().any(|v| *v != 0.0),
                Some(Drive::Bilinear(bs)) => bs.iter().any(|b| b.iter().any(|v| *v != 0.0)),
                None => false,
            },
        })
    }

    /// The model's family.
    #[inline]
    pub fn family(&self) -> Family {
        self.blob.body.family
    }

    internal! {
        /// The bilinear family's latent step at `m = [y; q]` and its Jacobian:
        /// `y' = F(q) y` with `F(q) = F_0 + q_1 F_1 + q_2 F_2 + q_1^2 F_11`,
        /// and the latent rows of `d y' / d g`, `[F(q), (F_1 + 2 q_1 F_11) y,
        /// F_2 y]`, by columns (entry `[j][i]` is `d y'_i / d g_j`: the filter
        /// sums along columns). `None` for a linear model (whose columns are
        /// [`Model::koopman_columns`], the same at every `g`).
        pub fn bilinear_step(&self, m: &Aug, u: f32) -> Option<(Latent, KoopmanColumns)> {
            let mut jac = [[0.0f32; LATENT_DIM]; AUG_DIM];
            let next = self.bilinear_step_into(m, u, &mut jac)?;
            Some((next, jac))
        }
    }

    internal! {
        /// [`Model::bilinear_step`] with the Jacobian's columns written into
        /// `jac` (every entry), the caller's buffer: the filter's step
        /// neither zeroes nor copies them. On `None`, `jac` is partly
        /// written.
        #[inline(never)]
        pub fn bilinear_step_into(&self, m: &Aug, u: f32, jac: &mut KoopmanColumns) -> Option<Latent> {
            let [f0, f1, f2, f11] = self.bilinear?;
            let (y, q) = m.split_first_chunk::<LATENT_DIM>()?;
            let (q1, q2) = (q.first().copied()?, q.get(1).copied()?);
            let q11 = q1 * q1;
            let mut next = [0.0f32; LATENT_DIM];
            let (latent, q_cols) = jac.split_first_chunk_mut::<LATENT_DIM>()?;
            let [dq1, dq2] = q_cols.first_chunk_mut::<PARAM_DIM>()?;
            for (i, ((((n, r0), r1), r2), r11)) in next.iter_mut().zip(f0).zip(f1).zip(f2).zip(f11).enumerate() {
                // The four sums side by side, each in the order of `k`.
                let (mut u0, mut u1, mut u2, mut u11) = (0.0f32, 0.0f32, 0.0f32, 0.0f32);
                for ((((a, b), c), e), v) in r0.iter().zip(r1).zip(r2).zip(r11).zip(y) {
                    u0 += a * v;
                    u1 += b * v;
                    u2 += c * v;
                    u11 += e * v;
                }
                *n = ((u0 + q1 * u1) + q2 * u2) + q11 * u11;
                if let (Some(d1), Some(d2)) = (dq1.get_mut(i), dq2.get_mut(i)) {
                    *d1 = u1 + 2.0 * q1 * u11;
                    *d2 = u2;
                }
            }
            // The torque: `y' += u b(q)`, and `b(q)`'s slopes in `q` on the
            // parameters' columns of the Jacobian.
            if let (Some(Drive::Bilinear([b0, b1, b2, b11])), true) = (self.drive, u != 0.0) {
                let b = b0.iter().zip(b1).zip(b2.iter().zip(b11));
                for (((n, d1), d2), ((c0, c1), (c2, c11))) in next.iter_mut().zip(dq1.iter_mut()).zip(dq2.iter_mut()).zip(b) {
                    *n += u * (((c0 + q1 * c1) + q2 * c2) + q11 * c11);
                    *d1 += u * (c1 + 2.0 * q1 * c11);
                    *d2 += u * c2;
                }
            }
            // The latent columns, one at a time: column `j` of `F(q)`.
            for (j, col) in latent.iter_mut().enumerate() {
                for ((((d, r0), r1), r2), r11) in col.iter_mut().zip(f0).zip(f1).zip(f2).zip(f11) {
                    if let (Some(a), Some(b), Some(c), Some(e)) = (r0.get(j), r1.get(j), r2.get(j), r11.get(j)) {
                        *d = ((a + q1 * b) + q2 * c) + q11 * e;
                    }
                }
            }
            Some(next)
        }
    }

    internal! {
        /// The latent rows of `F`, transposed: `C^T`, column `i` of row `j`
        /// is `F_ij`.
        #[inline]
        pub fn koopman_columns(&self) -> &KoopmanColumns {
            &self.ct
        }
    }

    internal! {
        /// Updates whose gains the blob precomputes (`T`, see the blob's
        /// "gain schedule").
        #[inline]
        pub fn schedule_steps(&self) -> u32 {
            u32::from(self.blob.body.filter.schedule_steps)
        }
    }

    internal! {
        /// Scheduled update `n` (`1..=T`): `K_n^T` (row `k`: how innovation `k`
        /// moves `[y; p]`) and the parameters' standard deviations after it,
        /// read in place. `None` outside the schedule.
        #[inline]
        pub fn scheduled_gain(
            &self,
            n: u32,
        ) -> Option<(&'a [[f32; AUG_DIM]; LATENT_DIM], &'a [f32; PARAM_DIM])> {
            if n == 0 || n > self.schedule_steps() {
                return None;
            }
            let at = self.schedule_at + (n as usize - 1) * SCHEDULE_STEP_LEN;
            let kt = rows::<LATENT_DIM, AUG_DIM>(self.arena, at).ok()?;
            let std = rows::<1, PARAM_DIM>(self.arena, at + LATENT_DIM * AUG_DIM)
                .ok()
                .map(|[r]| r)?;
            Some((kt, std))
        }
    }

    internal! {
        /// The schedule's tail, the filter after update `T` in two-stage form;
        /// `None` without a schedule.
        #[inline]
        pub fn schedule_tail(&self) -> Option<&Tail<'a>> {
            self.tail.as_ref()
        }
    }

    /// The decoded blob.
    pub fn blob(&self) -> &Blob<'a> {
        &self.blob
    }

    /// `x_n = (x - mu) / s`.
    pub fn normalise(&self, x: &State) -> State {
        let b = &self.blob.body;
        let mut out = [0.0; STATE_DIM];
        for (((o, x), mu), s) in out.iter_mut().zip(x).zip(&b.norm_mu).zip(&b.norm_s) {
            *o = (x - mu) / s;
        }
        out
    }

    /// `x = x_n s + mu`.
    pub fn denormalise(&self, x_n: &State) -> State {
        let b = &self.blob.body;
        let mut out = [0.0; STATE_DIM];
        for (((o, x), mu), s) in out.iter_mut().zip(x_n).zip(&b.norm_mu).zip(&b.norm_s) {
            *o = x * s + mu;
        }
        out
    }

    /// Encoder on a normalised state.
    pub fn encode(&self, x_n: &State) -> Latent {
        let act = self.blob.body.activation;
        match &self.nets {
            Nets::Narrow(e, _) => e.forward::<LATENT_DIM>(x_n, act),
            Nets::Wide(e, _) => e.forward::<LATENT_DIM>(x_n, act),
        }
    }

    /// Decoder to a normalised state.
    pub fn decode(&self, y: &Latent) -> State {
        let act = self.blob.body.activation;
        match &self.nets {
            Nets::Narrow(_, d) => d.forward::<STATE_DIM>(y, act),
            Nets::Wide(_, d) => d.forward::<STATE_DIM>(y, act),
        }
    }

    internal! {
        /// Element `(i, j)` of `F` (0 outside).
        #[inline]
        pub fn f(&self, i: usize, j: usize) -> f32 {
            if j >= AUG_DIM {
                return 0.0;
            }
            self.blob.f().get(i * AUG_DIM + j).unwrap_or(0.0)
        }
    }

    internal! {
        /// One step of the augmented model under the torque `u` (N m, held
        /// over the step), `p' = p`: for the linear family `g' = F g + B u`,
        /// that is `y' = C g + b u` (the parameter rows of `F` are the
        /// identity, those of `B` zero); for the bilinear
        /// `y' = F(q) y + b(q) u` ([`Model::bilinear_step`]).
        pub fn advance(&self, m: &Aug, u: f32) -> Aug {
            let mut out = *m;
            if self.bilinear.is_some() {
                if let Some((y, _)) = self.bilinear_step(m, u) {
                    for (o, v) in out.iter_mut().zip(&y) {
                        *o = *v;
                    }
                }
                return out;
            }
            let mut y = [0.0f32; LATENT_DIM];
            for (i, o) in y.iter_mut().enumerate() {
                *o = self.ct.iter().zip(m).fold(0.0, |acc, (col, x)| {
                    acc + col.get(i).copied().unwrap_or(0.0) * x
                });
            }
            self.drive_linear(u, &mut y);
            for (o, v) in out.iter_mut().zip(&y) {
                *o = *v;
            }
            out
        }
    }

    internal! {
        /// `y += u b` for a linear blob (nothing for `u = 0`, a free step,
        /// or a bilinear blob, whose `b(q)` [`Model::bilinear_step_into`]
        /// adds).
        #[inline(always)]
        pub fn drive_linear(&self, u: f32, y: &mut Latent) {
            if let (Some(Drive::Linear(b)), true) = (self.drive, u != 0.0) {
                for (yi, bi) in y.iter_mut().zip(b) {
                    *yi += u * bi;
                }
            }
        }
    }

    /// Whether the blob carries a torque's column `B` (a linear blob's
    /// slot, or a bilinear blob of format 12 on) that is not all zero: a
    /// model of the driven pendulum. Without one, torques are ignored.
    pub fn is_driven(&self) -> bool {
        self.driven
    }

    /// Rolls the model forward from the raw state `x0` with parameters
    /// `params` (values, as [`crate::StepOutput::params`] reports them;
    /// the model runs on their coordinates), writing the raw
    /// (denormalised) states `x_1 .. x_n` into `out` (`n = out.len()`).
    ///
    /// # Errors
    ///
    /// [`Error::NonFiniteInput`] for a state or a parameter without a
    /// finite coordinate (a length of 0).
    ///
    /// # Examples
    ///
    /// ```
    /// use estimator::blob::Aligned;
    /// use estimator::Model;
    ///
    /// static RIG: &Aligned<[u8]> = &Aligned(*include_bytes!("../../../weights/rig.kkf"));
    /// let model = Model::from_bytes(&RIG.0)?;
    ///
    /// // A 1 m string released at 0.2 rad, undamped, for 2 s (50 steps of 0.04 s):
    /// let mut xs = [[0.0f32; 2]; 50];
    /// model.simulate(&[0.2, 0.0], &[1.0, 0.0], &mut xs)?;
    /// // Its period is 2 s: a full swing later it is back near 0.2 rad.
    /// assert!((xs[49][0] - 0.2).abs() < 0.02, "{:?}", xs[49]);
    /// # Ok::<(), estimator::Error>(())
    /// ```
    pub fn simulate(
        &self,
        x0: &State,
        params: &[f32; PARAM_DIM],
        out: &mut [State],
    ) -> Result<(), Error> {
        self.simulate_coordinates(x0, &self.coordinates(params), &[], out)
    }

    /// [`Model::simulate`] under torques: `us[k]` (N m) is held from the
    /// state before `out[k]` to it (the protocol CSV's `u` of the row
    /// before); steps past the end of `us` are free.
    ///
    /// # Errors
    ///
    /// As [`Model::simulate`]; [`Error::NonFiniteInput`] for a torque that
    /// is not finite.
    pub fn simulate_driven(
        &self,
        x0: &State,
        params: &[f32; PARAM_DIM],
        us: &[f32],
        out: &mut [State],
    ) -> Result<(), Error> {
        self.simulate_coordinates(x0, &self.coordinates(params), us, out)
    }

    internal! {
        /// The filter's coordinates of the parameter values `params` (see
        /// [`crate::blob::Reading`]).
        pub fn coordinates(&self, params: &[f32; PARAM_DIM]) -> [f32; PARAM_DIM] {
            let mut q = [0.0; PARAM_DIM];
            for ((q, p), spec) in q.iter_mut().zip(params).zip(&self.blob.body.params) {
                *q = spec.coordinate(*p);
            }
            q
        }
    }

    internal! {
        /// [`Model::simulate_driven`] from the parameters' filter coordinates
        /// `q` ([`crate::FilterReport::coordinate`]).
        pub fn simulate_coordinates(
            &self,
            x0: &State,
            q: &[f32; PARAM_DIM],
            us: &[f32],
            out: &mut [State],
        ) -> Result<(), Error> {
            if !(x0.iter().chain(q).all(|v| v.is_finite())) {
                return Err(Error::NonFiniteInput);
            }
            let y0 = self.encode(&self.normalise(x0));
            let mut m = [0.0; AUG_DIM];
            for (d, s) in m.iter_mut().zip(y0.iter().chain(q)) {
                *d = *s;
            }
            self.rollout_from(&m, us, out)
        }
    }

    internal! {
        /// Rolls the augmented model forward from `[y; p]` = `g0` (a filter's
        /// mean, [`crate::Estimator::forecast`]) under the torques `us`
        /// (`us[k]` before `out[k]`; free past its end), writing the
        /// decoded raw states `x_1 .. x_n` into `out`. A non-finite `g0` or
        /// torque is refused with [`Error::NonFiniteInput`].
        pub fn rollout_from(&self, g0: &Aug, us: &[f32], out: &mut [State]) -> Result<(), Error> {
            if !g0.iter().chain(us).all(|v| v.is_finite()) {
                return Err(Error::NonFiniteInput);
            }
            let mut m = *g0;
            for (k, o) in out.iter_mut().enumerate() {
                m = self.advance(&m, us.get(k).copied().unwrap_or(0.0));
                let mut y = [0.0; LATENT_DIM];
                for (d, s) in y.iter_mut().zip(&m) {
                    *d = *s;
                }
                *o = self.denormalise(&self.decode(&y));
            }
            Ok(())
        }
    }
}
