//! Where each weight lies in the arena, at the header's hidden width.

use super::{Blob, F32s, Family, Header};
use crate::{AUG_DIM, HIDDEN_DIM, HIDDEN_WIDTHS, INPUT_DIM, LATENT_DIM, PARAM_DIM, STATE_DIM};

internal! {
    /// Number of dense layers in the encoder and in the decoder.
    ///
    /// Unit: a count. Fixed by the trained MLPs' architecture (`I -> H -> H ->
    /// O`, `model::mlp`).
    pub const N_LAYERS: usize = 3;
}

internal! {
    /// Which MLP a layer belongs to.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum Net {
        /// The encoder `phi`.
        Encoder,
        /// The decoder `phi^-1`.
        Decoder,
    }
}

/// Length of one layer in the arena: weight then bias.
const fn layer_len((d_in, d_out): (usize, usize)) -> usize {
    d_in * d_out + d_out
}

const fn mlp_len(shapes: &[(usize, usize); N_LAYERS]) -> usize {
    let [l0, l1, l2] = *shapes;
    layer_len(l0) + layer_len(l1) + layer_len(l2)
}

internal! {
    /// Where everything lies in a weight arena whose MLPs have hidden layers
    /// `hidden` wide (the header's `hidden_dim`, one of
    /// [`HIDDEN_WIDTHS`](crate::HIDDEN_WIDTHS)). Offsets are in `f32`s.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub struct Layout {
        /// Width of the encoder's and the decoder's hidden layers.
        pub hidden: usize,
    }
}

impl Layout {
    /// The layout of a blob with this header; `None` for a hidden width
    /// this build does not run.
    pub const fn of(header: &Header) -> Option<Layout> {
        let hidden = header.hidden_dim as usize;
        let [narrow, wide] = HIDDEN_WIDTHS;
        if hidden == narrow || hidden == wide {
            Some(Layout { hidden })
        } else {
            None
        }
    }

    /// `(d_in, d_out)` of the encoder's layers: STATE -> HIDDEN -> HIDDEN
    /// -> LATENT.
    pub const fn encoder_shapes(self) -> [(usize, usize); N_LAYERS] {
        let h = self.hidden;
        [(STATE_DIM, h), (h, h), (h, LATENT_DIM)]
    }

    /// `(d_in, d_out)` of the decoder's layers: LATENT -> HIDDEN -> HIDDEN
    /// -> STATE.
    pub const fn decoder_shapes(self) -> [(usize, usize); N_LAYERS] {
        let h = self.hidden;
        [(LATENT_DIM, h), (h, h), (h, STATE_DIM)]
    }

    /// Where layer `k` of `net` lies: `(weight offset, d_in, d_out)`; its
    /// bias follows the weight at `offset + d_in * d_out`. `None` for
    /// `k >= N_LAYERS`.
    pub const fn layer_span(self, net: Net, k: usize) -> Option<(usize, usize, usize)> {
        let (shapes, at) = match net {
            Net::Encoder => (self.encoder_shapes(), 0),
            Net::Decoder => (self.decoder_shapes(), mlp_len(&self.encoder_shapes())),
        };
        let [l0, l1, l2] = shapes;
        match k {
            0 => Some((at, l0.0, l0.1)),
            1 => Some((at + layer_len(l0), l1.0, l1.1)),
            2 => Some((at + layer_len(l0) + layer_len(l1), l2.0, l2.1)),
            _ => None,
        }
    }

    /// Offset of `F` (or of the bilinear matrices): after both MLPs.
    pub const fn f_at(self) -> usize {
        mlp_len(&self.encoder_shapes()) + mlp_len(&self.decoder_shapes())
    }

    /// Offset of `B`.
    pub const fn b_at(self) -> usize {
        self.f_at() + AUG_DIM * AUG_DIM
    }

    /// Offset of the gain schedule: the length of a linear arena without
    /// one.
    pub const fn schedule_at(self) -> usize {
        self.b_at() + AUG_DIM * INPUT_DIM
    }

    /// Length of a linear arena with a schedule of `steps` updates: the
    /// weights, `steps` scheduled updates and, when `steps > 0`, the tail.
    pub const fn arena_len(self, steps: u16) -> usize {
        let steps = steps as usize;
        let tail = if steps > 0 { TAIL_LEN } else { 0 };
        self.schedule_at() + steps * SCHEDULE_STEP_LEN + tail
    }

    /// Offset of a bilinear arena's `B_0, B_1, B_2, B_11` (format 12 on):
    /// after its four matrices.
    pub const fn bilinear_b_at(self) -> usize {
        self.f_at() + BILINEAR_BLOCKS * BILINEAR_BLOCK_LEN
    }

    /// Length of a bilinear arena: with its `B(q)` (`driven`, format 12
    /// on) or without (format 11).
    pub const fn bilinear_arena_len(self, driven: bool) -> usize {
        self.bilinear_b_at()
            + if driven {
                BILINEAR_BLOCKS * LATENT_DIM
            } else {
                0
            }
    }
}

internal! {
    /// Values of one scheduled update: `K^T` then the parameters' standard
    /// deviations.
    ///
    /// Unit: a count (f32 values). Derived from the sizes.
    pub const SCHEDULE_STEP_LEN: usize = LATENT_DIM * AUG_DIM + PARAM_DIM;
}

internal! {
    /// Values of the schedule's tail: `S~^-1`, `P~`, `V_T`, `P_b,T`.
    ///
    /// Unit: a count (f32 values). Derived from the sizes.
    pub const TAIL_LEN: usize =
        2 * LATENT_DIM * LATENT_DIM + PARAM_DIM * LATENT_DIM + PARAM_DIM * PARAM_DIM;
}

internal! {
    /// Matrices of a bilinear arena: `F_0`, `F_1`, `F_2`, `F_11`.
    ///
    /// Unit: a count (matrices). Fixed by the bilinear model's form
    /// (docs/bilinear.md).
    pub const BILINEAR_BLOCKS: usize = 4;
}
internal! {
    /// The first format whose bilinear arena carries `B(q)`.
    ///
    /// Unit: a count (a version number). Set by hand: the format that
    /// added it.
    pub const DRIVEN_VERSION: u16 = 12;
}
internal! {
    /// Values of one bilinear matrix.
    ///
    /// Unit: a count (f32 values). Derived: `LATENT_DIM` squared.
    pub const BILINEAR_BLOCK_LEN: usize = LATENT_DIM * LATENT_DIM;
}

impl<'a> Blob<'a> {
    internal! {
        /// The layout of the arena (its hidden width from the header; the
        /// widest for a width this build does not run, which
        /// [`Blob::from_bytes`] refuses).
        pub fn layout(&self) -> Layout {
            Layout::of(&self.header).unwrap_or(Layout { hidden: HIDDEN_DIM })
        }
    }

    internal! {
        /// `F`, row-major (empty for a bilinear blob).
        pub fn f(&self) -> F32s<'a> {
            match self.body.family {
                Family::Linear => self.body.span(self.layout().f_at(), AUG_DIM * AUG_DIM),
                Family::Bilinear => F32s(&[]),
            }
        }
    }

    internal! {
        /// Bilinear matrix `k` (`F_0`, `F_1`, `F_2`, `F_11` for `k = 0..4`),
        /// row-major; empty for a linear blob or `k` out of range.
        pub fn bilinear(&self, k: usize) -> F32s<'a> {
            match self.body.family {
                Family::Bilinear if k < BILINEAR_BLOCKS => self.body.span(
                    self.layout().f_at() + k * BILINEAR_BLOCK_LEN,
                    BILINEAR_BLOCK_LEN,
                ),
                _ => F32s(&[]),
            }
        }
    }

    internal! {
        /// `B`, row-major (empty for a bilinear blob).
        pub fn b(&self) -> F32s<'a> {
            match self.body.family {
                Family::Linear => self.body.span(self.layout().b_at(), AUG_DIM * INPUT_DIM),
                Family::Bilinear => F32s(&[]),
            }
        }
    }

    internal! {
        /// Whether a bilinear arena carries `B(q)`: one of format 11 never,
        /// of 12 always, from 13 on as its length says.
        pub fn bilinear_driven(&self) -> bool {
            match self.header.version {
                v if v < DRIVEN_VERSION => false,
                DRIVEN_VERSION => true,
                _ => self.body.weights.len() == self.layout().bilinear_arena_len(true),
            }
        }
    }

    internal! {
        /// A bilinear blob's `B_k` (`B_0`, `B_1`, `B_2`, `B_11` for
        /// `k = 0..4`: `B(q) = B_0 + q_1 B_1 + q_2 B_2 + q_1^2 B_11`, a
        /// column over the latent); empty for a linear blob, one of format
        /// 11 (`B = 0`) or `k` out of range.
        pub fn bilinear_b(&self, k: usize) -> F32s<'a> {
            match self.body.family {
                Family::Bilinear if k < BILINEAR_BLOCKS && self.bilinear_driven() => {
                    self.body.span(self.layout().bilinear_b_at() + k * LATENT_DIM, LATENT_DIM)
                }
                _ => F32s(&[]),
            }
        }
    }

    internal! {
        /// Scheduled update `n` (`1..=schedule_steps`): `K_n^T` ([`LATENT_DIM`]
        /// rows of [`AUG_DIM`]) and the parameters' standard deviations after
        /// it. Empty runs for an `n` outside the schedule.
        pub fn schedule_step(&self, n: usize) -> (F32s<'a>, F32s<'a>) {
            let steps = usize::from(self.body.filter.schedule_steps);
            if n == 0 || n > steps {
                return (F32s(&[]), F32s(&[]));
            }
            let at = self.layout().schedule_at() + (n - 1) * SCHEDULE_STEP_LEN;
            let gain = LATENT_DIM * AUG_DIM;
            (
                self.body.span(at, gain),
                self.body.span(at + gain, PARAM_DIM),
            )
        }
    }

    internal! {
        /// The schedule's tail (see the module docs), empty without a schedule.
        pub fn schedule_tail(&self) -> F32s<'a> {
            let steps = usize::from(self.body.filter.schedule_steps);
            if steps == 0 {
                return F32s(&[]);
            }
            self.body.span(
                self.layout().schedule_at() + steps * SCHEDULE_STEP_LEN,
                TAIL_LEN,
            )
        }
    }

    internal! {
        /// Layer `k` of `net`: its input-major weight and its bias.
        pub fn layer(&self, net: Net, k: usize) -> (F32s<'a>, F32s<'a>) {
            match self.layout().layer_span(net, k) {
                Some((at, i, o)) => (self.body.span(at, i * o), self.body.span(at + i * o, o)),
                None => (F32s(&[]), F32s(&[])),
            }
        }
    }
}
