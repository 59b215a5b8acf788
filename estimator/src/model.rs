//! The model read from a blob: normalisation, encoder `phi`, decoder
//! `phi^-1`, the augmented Koopman matrix `F`, and open-loop simulation.

use crate::blob::{Activation, Blob, Layer};
use crate::{AUG_DIM, Aug, Error, HIDDEN_DIM, LATENT_DIM, Latent, PARAM_DIM, STATE_DIM, State};

/// A validated model whose weights stay in the bytes it was read from.
#[derive(Debug, Clone, Copy)]
pub struct Model<'a> {
    blob: Blob<'a>,
}

/// `out = act(W input + b)`, with `W` output-major in the layer.
#[inline]
fn dense<const I: usize, const O: usize>(
    layer: &Layer<'_>,
    input: &[f32; I],
    out: &mut [f32; O],
    act: Option<Activation>,
) {
    let rows = layer.weight.0.chunks_exact(I * 4);
    for ((o, row), b) in out.iter_mut().zip(rows).zip(layer.bias.iter()) {
        let mut acc = b;
        for (x, w) in input.iter().zip(row.chunks_exact(4)) {
            let w = w.first_chunk::<4>().map_or(0.0, |a| f32::from_le_bytes(*a));
            acc += x * w;
        }
        *o = match act {
            None => acc,
            Some(Activation::Relu) => acc.max(0.0),
            Some(Activation::Tanh) => libm::tanhf(acc),
        };
    }
}

impl<'a> Model<'a> {
    /// Reads a blob (see [`Blob::from_bytes`] for every check made); the
    /// weights are borrowed from `bytes`, not copied.
    pub fn from_bytes(bytes: &'a [u8]) -> Result<Self, Error> {
        Ok(Model {
            blob: Blob::from_bytes(bytes)?,
        })
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
