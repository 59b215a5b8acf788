//! The KLM on burn: encoder `phi` and decoder `phi^-1` MLPs, and the
//! Koopman matrix fitted by ridge least squares inside every batch.

use burn::module::Module;
use burn::nn::{Linear, LinearConfig};
use burn::tensor::activation::{relu, tanh};
use burn::tensor::{Device, Tensor};
use estimator::blob::Activation;

use super::config::{ModelKind, TrainConfig};
use super::lstsq;

/// A 3-layer MLP `d_in -> h -> h -> d_out`.
#[derive(Module, Debug)]
pub struct Mlp {
    /// Input layer.
    pub l0: Linear,
    /// Hidden layer.
    pub l1: Linear,
    /// Output layer (no activation).
    pub l2: Linear,
}

impl Mlp {
    /// New MLP with burn's default initialisation.
    pub fn new(d_in: usize, hidden: usize, d_out: usize, device: &Device) -> Self {
        Mlp {
            l0: LinearConfig::new(d_in, hidden).init(device),
            l1: LinearConfig::new(hidden, hidden).init(device),
            l2: LinearConfig::new(hidden, d_out).init(device),
        }
    }

    /// Forward pass over the last dimension.
    pub fn forward<const D: usize>(&self, x: Tensor<D>, act: Activation) -> Tensor<D> {
        let a = |t: Tensor<D>| match act {
            Activation::Relu => relu(t),
            Activation::Tanh => tanh(t),
        };
        let h = a(self.l0.forward(x));
        let h = a(self.l1.forward(h));
        self.l2.forward(h)
    }
}

/// Encoder and decoder.
#[derive(Module, Debug)]
pub struct Klm {
    /// `phi`: state -> latent.
    pub enc: Mlp,
    /// `phi^-1`: latent -> state.
    pub dec: Mlp,
}

impl Klm {
    /// New model.
    pub fn new(state: usize, hidden: usize, latent: usize, device: &Device) -> Self {
        Klm {
            enc: Mlp::new(state, hidden, latent, device),
            dec: Mlp::new(latent, hidden, state, device),
        }
    }
}

/// The losses of one batch.
pub struct Losses {
    /// Total, to minimise.
    pub total: Tensor<1>,
    /// Its parts, named by [`Trainable::PARTS`]. For the Koopman models:
    /// reconstruction `|phi^-1(phi(x)) - x|^2`, multi-step prediction in state
    /// space, multi-step prediction in latent space.
    pub parts: [Tensor<1>; 3],
}

/// What the training loop needs of a model.
pub trait Trainable: Module + Sized {
    /// Names of [`Losses::parts`], for the log.
    const PARTS: [&'static str; 3];
    /// A freshly initialised model for a config.
    fn init(cfg: &TrainConfig, device: &Device) -> Self;
    /// The model made of a trained encoder and decoder (`None`: a model
    /// that has none, the MLP regressor).
    fn from_mlps(_enc: Mlp, _dec: Mlp) -> Option<Self> {
        None
    }
    /// The losses of one batch: windows `x` `[B, T, 2]`, parameters `p`
    /// `[B, 2]`, and the torques `u` `[B, T]` held from each state to the
    /// next (`None`: a free set).
    fn batch_losses(
        &self,
        x: Tensor<3>,
        p: Tensor<2>,
        u: Option<Tensor<2>>,
        cfg: &TrainConfig,
    ) -> Losses;
}

impl Trainable for Klm {
    const PARTS: [&'static str; 3] = ["rec", "pred", "lin"];
    fn init(cfg: &TrainConfig, device: &Device) -> Self {
        Klm::new(2, cfg.hidden, estimator::LATENT_DIM, device)
    }
    fn from_mlps(enc: Mlp, dec: Mlp) -> Option<Self> {
        Some(Klm { enc, dec })
    }
    fn batch_losses(
        &self,
        x: Tensor<3>,
        p: Tensor<2>,
        u: Option<Tensor<2>>,
        cfg: &TrainConfig,
    ) -> Losses {
        let p = (cfg.model == ModelKind::Klm).then_some(p);
        self.losses(x, p, u, cfg.activation, cfg.ridge, cfg.w_lin)
    }
}

impl Trainable for Regressor {
    const PARTS: [&'static str; 3] = ["mse", "mae", "unused"];
    fn init(cfg: &TrainConfig, device: &Device) -> Self {
        Regressor::new(cfg.window, cfg.hidden, device)
    }
    fn batch_losses(
        &self,
        x: Tensor<3>,
        p: Tensor<2>,
        _u: Option<Tensor<2>>,
        cfg: &TrainConfig,
    ) -> Losses {
        self.losses(x, p, cfg.activation)
    }
}

/// `[K^T]` split into its parts: `y_{t+1} = y_t A^T + p C^T + u_t B^T`.
pub struct Koopman {
    /// `A^T`, `[latent, latent]`.
    pub at: Tensor<2>,
    /// `C^T`, `[params, latent]`; `None` for the CBM, whose state has no `p`.
    pub ct: Option<Tensor<2>>,
    /// `B^T`, `[1, latent]`, the torque's row; `None` for a free set.
    pub bt: Option<Tensor<2>>,
}

/// The torques of the batch's transitions as a column: `u` `[B, T]`, its
/// first `T - 1` (the last is held beyond the window), `[B (T - 1), 1]`.
pub fn torque_column(u: Tensor<2>) -> Tensor<2> {
    let [b, t] = u.dims();
    u.slice([0..b, 0..t - 1]).reshape([b * (t - 1), 1])
}

/// Fits `y_{t+1} = [y_t, p, u_t] K^T` (or without `p`, or without `u`) by
/// ridge least squares over every transition of the batch, `K` and `B`
/// together as the paper does. `y` is `[B, T, latent]`, `p` `[B, P]`, `u`
/// `[B, T]`.
pub fn fit_koopman(
    y: Tensor<3>,
    p: Option<Tensor<2>>,
    u: Option<Tensor<2>>,
    ridge: f64,
) -> Koopman {
    let [b, t, l] = y.dims();
    let g_y = y
        .clone()
        .slice([0..b, 0..t - 1, 0..l])
        .reshape([b * (t - 1), l]);
    let target = y.slice([0..b, 1..t, 0..l]).reshape([b * (t - 1), l]);
    let np = p.as_ref().map_or(0, |p| p.dims()[1]);
    let mut columns = vec![g_y];
    if let Some(p) = p {
        columns.push(
            p.unsqueeze_dim::<3>(1)
                .expand([b, t - 1, np])
                .reshape([b * (t - 1), np]),
        );
    }
    let driven = u.is_some();
    if let Some(u) = u {
        columns.push(torque_column(u));
    }
    let g = if columns.len() == 1 {
        columns.remove(0)
    } else {
        Tensor::cat(columns, 1)
    };
    let kt = lstsq::ridge(g, target, ridge); // [l + np (+ 1), l]
    Koopman {
        at: kt.clone().slice([0..l, 0..l]),
        ct: (np > 0).then(|| kt.clone().slice([l..l + np, 0..l])),
        bt: driven.then(|| kt.slice([l + np..l + np + 1, 0..l])),
    }
}

/// Rolls `y_0` (`[B, latent]`) forward `steps` times under the torques `u`
/// (`[B, T]`, `T > steps`); returns `[B, steps, latent]`.
pub fn rollout(
    k: &Koopman,
    y0: Tensor<2>,
    p: Option<Tensor<2>>,
    u: Option<Tensor<2>>,
    steps: usize,
) -> Tensor<3> {
    let c = match (&k.ct, p) {
        (Some(ct), Some(p)) => Some(p.matmul(ct.clone())),
        _ => None,
    };
    let mut y = y0;
    let mut out = Vec::with_capacity(steps);
    for s in 0..steps {
        y = y.matmul(k.at.clone());
        if let Some(c) = &c {
            y = y + c.clone();
        }
        if let (Some(bt), Some(u)) = (&k.bt, &u) {
            let [b, _] = u.dims();
            y = y + u.clone().slice([0..b, s..s + 1]).matmul(bt.clone());
        }
        out.push(y.clone());
    }
    Tensor::stack(out, 1)
}

impl Klm {
    /// Losses of one batch: `x` `[B, T, state]` normalised, `p` `[B, P]`
    /// (`None` for the CBM: `K` over the latent alone), `u` `[B, T]`
    /// (`None`: free).
    pub fn losses(
        &self,
        x: Tensor<3>,
        p: Option<Tensor<2>>,
        u: Option<Tensor<2>>,
        act: Activation,
        ridge: f64,
        w_lin: f64,
    ) -> Losses {
        koopman_losses(&self.enc, &self.dec, x, act, w_lin, |y, y0, steps| {
            rollout(
                &fit_koopman(y, p.clone(), u.clone(), ridge),
                y0,
                p,
                u,
                steps,
            )
        })
    }
}

/// A Koopman model's losses of one batch `x` (`[B, T, state]`,
/// normalised), its family's only in `predict`: reconstruction, and the
/// `T - 1`-step prediction in state and in latent space (weighted
/// `w_lin`) of the latent rollout `predict(y, y_0, T - 1)` makes from the
/// encoded batch `y` (`[B, T, latent]`, which it fits its matrices on)
/// and its first states `y_0` (`[B, latent]`).
pub fn koopman_losses(
    enc: &Mlp,
    dec: &Mlp,
    x: Tensor<3>,
    act: Activation,
    w_lin: f64,
    predict: impl FnOnce(Tensor<3>, Tensor<2>, usize) -> Tensor<3>,
) -> Losses {
    let [b, t, s] = x.dims();
    let y = enc.forward(x.clone(), act);
    let [_, _, l] = y.dims();
    let x_rec = dec.forward(y.clone(), act);
    let rec = (x_rec - x.clone()).powi_scalar(2).mean();
    let y0 = y.clone().slice([0..b, 0..1, 0..l]).reshape([b, l]);
    let y_pred = predict(y.clone(), y0, t - 1);
    let x_pred = dec.forward(y_pred.clone(), act);
    let x_next = x.slice([0..b, 1..t, 0..s]);
    let pred = (x_pred - x_next).powi_scalar(2).mean();
    let lin = (y_pred - y.slice([0..b, 1..t, 0..l])).powi_scalar(2).mean();
    let total = rec.clone() + pred.clone() + lin.clone().mul_scalar(w_lin);
    Losses {
        total,
        parts: [rec, pred, lin],
    }
}

/// The MLP baseline: regresses the length from a window of normalised
/// states, flattened `[theta_0, theta_dot_0, theta_1, ...]`.
#[derive(Module, Debug)]
pub struct Regressor {
    /// `2 window -> hidden -> hidden -> 1`.
    pub net: Mlp,
}

impl Regressor {
    /// New regressor for windows of `window` states.
    pub fn new(window: usize, hidden: usize, device: &Device) -> Self {
        Regressor {
            net: Mlp::new(2 * window, hidden, 1, device),
        }
    }

    /// Predicted lengths `[B]` of windows `x` `[B, T, 2]`.
    pub fn forward(&self, x: Tensor<3>, act: Activation) -> Tensor<1> {
        let [b, t, s] = x.dims();
        self.net.forward(x.reshape([b, t * s]), act).reshape([b])
    }

    /// Mean squared error against the true lengths, and the mean absolute
    /// error (reported, not trained on).
    pub fn losses(&self, x: Tensor<3>, p: Tensor<2>, act: Activation) -> Losses {
        let [b, _] = p.dims();
        let truth = p.slice([0..b, 0..1]).reshape([b]);
        let err = self.forward(x, act) - truth;
        let mse = err.clone().powi_scalar(2).mean();
        let mae = err.abs().mean().detach();
        Losses {
            total: mse.clone(),
            parts: [mse, mae.clone(), mae.zeros_like()],
        }
    }
}
