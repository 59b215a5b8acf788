//! One MLP read in place from the arena, and its dense layers.

use crate::blob::{Activation, Layout, Net};
use crate::{Error, HIDDEN_WIDTHS};

/// Hidden outputs computed per block by [`dense`]: as many accumulators as
/// the target's vector registers hold beside the weights being loaded.
/// x86-64 (16 SSE registers of 4): 32 outputs in 8 registers. Elsewhere
/// (a Cortex-M4F has 32 single-precision registers): 16. The block size
/// changes no bit of the result, only the loads and loop turns.
///
/// Unit: a count (outputs). Derived from the targets' register counts
/// above; not swept.
#[cfg(target_arch = "x86_64")]
const HIDDEN_BLOCK: usize = 32;
#[cfg(not(target_arch = "x86_64"))]
const HIDDEN_BLOCK: usize = 16;
// `dense` needs the block to divide each width [`Nets`] runs.
const _: () = {
    let [narrow, wide] = HIDDEN_WIDTHS;
    assert!(narrow.is_multiple_of(HIDDEN_BLOCK) && wide.is_multiple_of(HIDDEN_BLOCK));
};

/// One MLP, `I -> H -> H -> O`, its weights borrowed from the blob as
/// typed arrays (input-major: `w[j]` is input `j`'s weights).
#[derive(Debug, Clone, Copy)]
pub(super) struct Mlp<'a, const I: usize, const H: usize, const O: usize> {
    w0: &'a [[f32; H]; I],
    b0: &'a [f32; H],
    w1: &'a [[f32; H]; H],
    b1: &'a [f32; H],
    w2: &'a [[f32; O]; H],
    b2: &'a [f32; O],
}

/// `R x C` values at `at` of the arena, as rows.
pub(super) fn rows<const R: usize, const C: usize>(a: &[f32], at: usize) -> Result<&[[f32; C]; R], Error> {
    let s = a.get(at..).ok_or(Error::BlobShapeMismatch)?;
    let (chunks, _) = s.as_chunks::<C>();
    chunks.first_chunk::<R>().ok_or(Error::BlobShapeMismatch)
}

impl<'a, const I: usize, const H: usize, const O: usize> Mlp<'a, I, H, O> {
    pub(super) fn from_arena(a: &'a [f32], layout: Layout, net: Net) -> Result<Self, Error> {
        let at = |k| {
            layout
                .layer_span(net, k)
                .map(|(at, i, o)| (at, at + i * o))
                .ok_or(Error::BlobShapeMismatch)
        };
        let ((w0, b0), (w1, b1), (w2, b2)) = (at(0)?, at(1)?, at(2)?);
        let one = |at| rows::<1, H>(a, at).map(|[r]| r);
        Ok(Mlp {
            w0: rows(a, w0)?,
            b0: one(b0)?,
            w1: rows(a, w1)?,
            b1: one(b1)?,
            w2: rows(a, w2)?,
            b2: rows::<1, O>(a, b2).map(|[r]| r)?,
        })
    }

    /// `act(act(x W0 + b0) W1 + b1) W2 + b2`.
    #[inline]
    pub(super) fn forward<const B: usize>(&self, x: &[f32; I], act: Activation) -> [f32; O] {
        let mut h0 = [0.0; H];
        let mut h1 = [0.0; H];
        let mut out = [0.0; O];
        dense::<I, H, HIDDEN_BLOCK>(self.w0, self.b0, x, &mut h0, Some(act));
        dense::<H, H, HIDDEN_BLOCK>(self.w1, self.b1, &h0, &mut h1, Some(act));
        dense::<H, O, B>(self.w2, self.b2, &h1, &mut out, None);
        out
    }
}

#[inline(always)]
fn activate(v: f32, act: Option<Activation>) -> f32 {
    match act {
        None => v,
        // A comparison, not `f32::max` (a library call on the Cortex-M4F);
        // NaN goes to 0 as with `max`.
        Some(Activation::Relu) => {
            if v > 0.0 {
                v
            } else {
                0.0
            }
        }
        Some(Activation::Tanh) => libm::tanhf(v),
    }
}

/// Whether [`dense`] gathers the inputs that are not zero before it sums,
/// for a layer of `blocks` output blocks. The gather costs about as much as
/// one block's sum over the inputs it drops, so it pays for several
/// blocks. On x86-64 a single block (the encoder's last layer) sums every
/// input; on the Cortex-M4F, whose loads and stores are cheaper against its
/// one multiply-add per instruction, gathering pays even then.
#[inline(always)]
const fn gathers(blocks: usize) -> bool {
    blocks > 1 || !cfg!(target_arch = "x86_64")
}

/// The `B` outputs from `at` of `sum_j x_j W_j` over `terms`, in their
/// order: one block load per term (a `vldm` on a Cortex-M4F), then `B`
/// multiply-accumulates.
#[inline(always)]
fn block<'w, const O: usize, const B: usize>(
    terms: impl Iterator<Item = (&'w f32, &'w [f32; O])>,
    at: usize,
) -> [f32; B] {
    let mut acc = [0.0f32; B];
    for (xj, wj) in terms {
        if let Some(wb) = wj.get(at..).and_then(|r| r.first_chunk::<B>()) {
            let wv = *wb;
            for (a, wv) in acc.iter_mut().zip(wv) {
                *a += xj * wv;
            }
        }
    }
    acc
}

/// `out = act(x W + b)` with `W` input-major (`w[j]`: input `j`'s
/// weights), computed `B` outputs at a time as a sum of scaled rows:
/// `out = sum_j x_j W_j + b` over the inputs that are not zero (after a
/// ReLU about half are; see [`gathers`]), in the order of `j`, then the
/// bias. Skipping a zero input changes no bit of the result (the sums
/// start at `+0`, so adding `+-0` leaves them as they are); the order is
/// fixed, so every target computes the same bits. `B` divides `O`.
#[inline]
fn dense<const I: usize, const O: usize, const B: usize>(
    w: &[[f32; O]; I],
    b: &[f32; O],
    x: &[f32; I],
    out: &mut [f32; O],
    act: Option<Activation>,
) {
    let (outs, _) = out.as_chunks_mut::<B>();
    let (bias, _) = b.as_chunks::<B>();
    if !gathers(O / B) {
        for (k, (ob, bb)) in outs.iter_mut().zip(bias).enumerate() {
            let acc = block::<O, B>(x.iter().zip(w), k * B);
            for ((o, a), bv) in ob.iter_mut().zip(&acc).zip(bb) {
                *o = activate(a + bv, act);
            }
        }
        return;
    }
    // The inputs that are not zero, with their weight rows.
    let mut xs = [0.0f32; I];
    let mut ws: [&[f32; O]; I] = [&[0.0; O]; I];
    let mut n = 0;
    // Without a branch on the value: which inputs a ReLU zeroed is data,
    // and a mispredicted branch per input would cost more than the copy.
    for (xj, wj) in x.iter().zip(w) {
        // `n` counts the inputs before this one, so `n % I == n`; the
        // remainder shows the compiler that the index is in bounds.
        if let (Some(xd), Some(wd)) = (xs.get_mut(n % I), ws.get_mut(n % I)) {
            *xd = *xj;
            *wd = wj;
        }
        n += usize::from(*xj != 0.0);
    }
    let xs = xs.get(..n).unwrap_or(&[]);
    let ws = ws.get(..n).unwrap_or(&[]);
    for (k, (ob, bb)) in outs.iter_mut().zip(bias).enumerate() {
        let acc = block::<O, B>(xs.iter().zip(ws.iter().copied()), k * B);
        for ((o, a), bv) in ob.iter_mut().zip(&acc).zip(bb) {
            *o = activate(a + bv, act);
        }
    }
}
