//! The model read from a blob: normalisation, encoder `phi`, decoder
//! `phi^-1`, the augmented Koopman matrix `F`, and open-loop simulation.

use crate::blob::{Activation, Blob, Layer};
use crate::{AUG_DIM, Aug, Error, HIDDEN_DIM, LATENT_DIM, Latent, PARAM_DIM, STATE_DIM, State};

/// The latent rows of `F`, `C = [A B]` (row-major), decoded once: the
/// filter reads them every step. The parameter rows are the identity
/// (checked when the blob is read).
pub type KoopmanRows = [[f32; AUG_DIM]; LATENT_DIM];
/// `C^T`, the same numbers column by column (AUG rows of LATENT).
pub type KoopmanColumns = [[f32; LATENT_DIM]; AUG_DIM];

/// A validated model whose weights stay in the bytes it was read from.
///
/// Only the latent rows of `F` are copied out of the blob, by rows and by
/// columns ([`KoopmanRows`], [`KoopmanColumns`], 1152 bytes each), as
/// `f32` the filter can load directly; the MLP weights (the bulk of the
/// blob) are read in place.
#[derive(Debug, Clone, Copy)]
pub struct Model<'a> {
    blob: Blob<'a>,
    c: KoopmanRows,
    ct: KoopmanColumns,
}

#[inline(always)]
fn activate(v: f32, act: Option<Activation>) -> f32 {
    match act {
        None => v,
        Some(Activation::Relu) => v.max(0.0),
        Some(Activation::Tanh) => libm::tanhf(v),
    }
}

/// Lanes of the dot products in [`dense`].
const LANES: usize = 8;

/// `out = act(W input + b)`, with `W` output-major in the layer.
///
/// Each dot product runs in [`LANES`] interleaved partial sums (lane `l`
/// takes the inputs `j = l mod LANES`), added pairwise at the end, then
/// the bias. The order is fixed, so every target computes the same bits;
/// the lanes let a host CPU use its vector units and shorten the chain of
/// dependent additions.
#[inline]
fn dense<const I: usize, const O: usize>(
    layer: &Layer<'_>,
    input: &[f32; I],
    out: &mut [f32; O],
    act: Option<Activation>,
) {
    let (xs, x_rest) = input.as_chunks::<LANES>();
    let rows = layer.weight.0.chunks_exact(I * 4);
    for ((o, row), b) in out.iter_mut().zip(rows).zip(layer.bias.iter()) {
        let (w, _) = row.as_chunks::<4>();
        let (ws, w_rest) = w.as_chunks::<LANES>();
        let mut lanes = [0.0f32; LANES];
        for (x8, w8) in xs.iter().zip(ws) {
            for ((l, x), w) in lanes.iter_mut().zip(x8).zip(w8) {
                *l += x * f32::from_le_bytes(*w);
            }
        }
        let [l0, l1, l2, l3, l4, l5, l6, l7] = lanes;
        let mut acc = ((l0 + l4) + (l1 + l5)) + ((l2 + l6) + (l3 + l7));
        for (x, w) in x_rest.iter().zip(w_rest) {
            acc += x * f32::from_le_bytes(*w);
        }
        *o = activate(acc + b, act);
    }
}

impl<'a> Model<'a> {
    /// Reads a blob (see [`Blob::from_bytes`] for every check made); the
    /// weights are borrowed from `bytes`, not copied.
    pub fn from_bytes(bytes: &'a [u8]) -> Result<Self, Error> {
        let blob = Blob::from_bytes(bytes)?;
        let mut c = [[0.0; AUG_DIM]; LATENT_DIM];
        for (dst, src) in c.iter_mut().flatten().zip(blob.body.f.iter()) {
            *dst = src;
        }
        let mut ct = [[0.0; LATENT_DIM]; AUG_DIM];
        for (i, row) in c.iter().enumerate() {
            for (col, v) in ct.iter_mut().zip(row) {
                if let Some(d) = col.get_mut(i) {
                    *d = *v;
                }
            }
        }
        Ok(Model { blob, c, ct })
    }

    /// The latent rows of `F`.
    #[inline]
    pub fn koopman_rows(&self) -> &KoopmanRows {
        &self.c
    }

    /// The latent rows of `F`, transposed.
    #[inline]
    pub fn koopman_columns(&self) -> &KoopmanColumns {
        &self.ct
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
        let [l0, l1, l2] = &self.blob.body.encoder;
        let act = Some(self.blob.body.activation);
        let mut h0 = [0.0; HIDDEN_DIM];
        let mut h1 = [0.0; HIDDEN_DIM];
        let mut y = [0.0; LATENT_DIM];
        dense(l0, x_n, &mut h0, act);
        dense(l1, &h0, &mut h1, act);
        dense(l2, &h1, &mut y, None);
        y
    }

    /// Decoder to a normalised state.
    pub fn decode(&self, y: &Latent) -> State {
        let [l0, l1, l2] = &self.blob.body.decoder;
        let act = Some(self.blob.body.activation);
        let mut h0 = [0.0; HIDDEN_DIM];
        let mut h1 = [0.0; HIDDEN_DIM];
        let mut x = [0.0; STATE_DIM];
        dense(l0, y, &mut h0, act);
        dense(l1, &h0, &mut h1, act);
        dense(l2, &h1, &mut x, None);
        x
    }

    /// Element `(i, j)` of `F` (0 outside).
    #[inline]
    pub fn f(&self, i: usize, j: usize) -> f32 {
        self.blob.body.f.get(i * AUG_DIM + j).unwrap_or(0.0)
    }

    /// One step of the augmented linear model: `g' = F g`.
    pub fn advance(&self, g: &Aug) -> Aug {
        let mut out = [0.0; AUG_DIM];
        let rows = self.blob.body.f.0.chunks_exact(AUG_DIM * 4);
        for (o, row) in out.iter_mut().zip(rows) {
            let mut acc = 0.0;
            for (x, w) in g.iter().zip(row.chunks_exact(4)) {
                acc += x * w.first_chunk::<4>().map_or(0.0, |a| f32::from_le_bytes(*a));
            }
            *o = acc;
        }
        out
    }

    /// Rolls the model forward from the raw state `x0` with parameters
    /// `params`, writing the raw (denormalised) states `x_1 .. x_n` into
    /// `out` (`n = out.len()`).
    pub fn simulate(
        &self,
        x0: &State,
        params: &[f32; PARAM_DIM],
        out: &mut [State],
    ) -> Result<(), Error> {
        if !(x0.iter().chain(params).all(|v| v.is_finite())) {
            return Err(Error::NonFiniteInput);
        }
        let y0 = self.encode(&self.normalise(x0));
        let mut g = [0.0; AUG_DIM];
        for (d, s) in g.iter_mut().zip(y0.iter().chain(params)) {
            *d = *s;
        }
        for o in out.iter_mut() {
            g = self.advance(&g);
            let mut y = [0.0; LATENT_DIM];
            for (d, s) in y.iter_mut().zip(&g) {
                *d = *s;
            }
            *o = self.denormalise(&self.decode(&y));
        }
        Ok(())
    }
}
