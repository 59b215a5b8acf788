//! Export: a trained run becomes one weights blob (see `estimator::blob`).
//!
//! `K` is refitted once over every training transition with the trained
//! encoder (the global matrix the batches converged to). `R` and the latent
//! part of `Q` scale the per-dimension variance of the one-step latent
//! residual `phi(x_{t+1}) - K g_t`. The trust threshold is calibrated by
//! running the estimator crate's own filter on the training rollouts.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use burn::nn::Linear;
use burn::tensor::{Tensor, TensorData};
use estimator::blob::{
    Blob, Body, F32s, FilterSpec, Header, ParamSpec, Reading, SCHEDULE_AT, TAIL_LEN,
};
use estimator::{AUG_DIM, INPUT_DIM, LATENT_DIM, Model, PARAM_DIM};
use nalgebra::{SMatrix, SVector};
use serde::{Deserialize, Serialize};

use crate::config::{ModelKind, TrainConfig};
use crate::data::Dataset;
use crate::io::write_atomic;
use crate::model::{Klm, Mlp, Regressor, fit_koopman};
use crate::train::{self, Norm, RunPaths, RunState};

/// Protocol: the filter sees `x_0 .. x_63`.
pub const ESTIMATION_STEPS: usize = 64;
/// Protocol: corrections at `t >= 32` count towards sigma.
pub const BURN_IN: u16 = 32;

/// Little-endian bytes of `f32` values.
pub fn le_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// A burn `Linear` (weight `[d_in, d_out]`, `y = x W + b`) as the blob
/// stores it: `(d_in, d_out, W, b)` with `W` input-major, `d_in` rows of
/// `d_out` (burn's own layout, copied as it is).
pub fn linear_to_blob(l: &Linear) -> (usize, usize, Vec<f32>, Vec<f32>) {
    let w = l.weight.val();
    let [d_in, d_out] = w.dims();
    let w: Vec<f32> = w
        .into_data()
        .convert::<f32>()
        .try_to_vec::<f32>()
        .unwrap_or_default();
    let b: Vec<f32> = match &l.bias {
        Some(b) => b
            .val()
            .into_data()
            .convert::<f32>()
            .try_to_vec::<f32>()
            .unwrap_or_default(),
        None => vec![0.0; d_out],
    };
    (d_in, d_out, w, b)
}

/// The weight arena a [`Blob`] borrows from, as little-endian bytes.
pub struct BlobParts {
    arena: Vec<u8>,
}

impl BlobParts {
    /// From the MLPs and `F` (row-major AUG x AUG), in the arena's order
    /// (see `estimator::blob`): encoder layers, decoder layers (weight then
    /// bias each), `F`, `B` (zero: no input is modelled yet). No gain
    /// schedule: see [`BlobParts::set_schedule`].
    pub fn new(enc: &Mlp, dec: &Mlp, f: &[f32]) -> Self {
        let mut arena: Vec<f32> = Vec::with_capacity(SCHEDULE_AT);
        for l in [&enc.l0, &enc.l1, &enc.l2, &dec.l0, &dec.l1, &dec.l2] {
            let (_, _, w, b) = linear_to_blob(l);
            arena.extend(w);
            arena.extend(b);
        }
        arena.extend_from_slice(f);
        arena.extend([0.0; AUG_DIM * INPUT_DIM]);
        BlobParts {
            arena: le_bytes(&arena),
        }
    }

    /// `F` (row-major) as stored in the arena.
    fn f(&self) -> Vec<f32> {
        F32s(&self.arena)
            .iter()
            .skip(estimator::blob::F_AT)
            .take(AUG_DIM * AUG_DIM)
            .collect()
    }

    /// Replaces the arena's gain schedule with the one of `filter` (its
    /// `schedule_steps` updates, from [`gain_schedule`]); a blob must be
    /// made with the same `filter`.
    pub fn set_schedule(&mut self, filter: &FilterSpec) -> Result<ScheduleCheck> {
        let (schedule, check) = gain_schedule(&self.f(), filter)?;
        self.arena.truncate(SCHEDULE_AT * 4);
        self.arena.extend(le_bytes(&schedule));
        Ok(check)
    }

    /// The blob, borrowing from `self`.
    pub fn blob<'a>(
        &'a self,
        norm: &Norm,
        cfg: &TrainConfig,
        filter: FilterSpec,
        params: [ParamSpec<'a>; PARAM_DIM],
    ) -> Blob<'a> {
        Blob {
            header: Header::CURRENT,
            body: Body {
                dt: cfg.dt as f32,
                activation: cfg.activation,
                norm_mu: norm.mu.map(|v| v as f32),
                norm_s: norm.s.map(|v| v as f32),
                params,
                filter,
                pad: &[],
                weights: F32s(&self.arena),
            },
        }
    }
}

type Aug64 = SMatrix<f64, AUG_DIM, AUG_DIM>;
type Lat64 = SMatrix<f64, LATENT_DIM, LATENT_DIM>;
type Cols64 = SMatrix<f64, LATENT_DIM, PARAM_DIM>;
type Par64 = SMatrix<f64, PARAM_DIM, PARAM_DIM>;

/// The textbook filter's covariance recursion in f64 (the exporter's own,
/// independent of the estimator's and of `crate::reference`, which the
/// tests hold the scheduled estimator to): `P' = F P F^T + Q`,
/// `S = H P' H^T + R` (Cholesky), `K = P' H^T S^-1`, and Joseph's
/// `P = (I - K H) P' (I - K H)^T + K R K^T`, made exactly symmetric.
struct Full {
    f: Aug64,
    q: Aug64,
    r: Lat64,
    p: Aug64,
}

impl Full {
    /// One update; returns `K^T` (`LATENT x AUG`).
    fn update(&mut self, n: usize) -> Result<SMatrix<f64, LATENT_DIM, AUG_DIM>> {
        let h = SMatrix::<f64, LATENT_DIM, AUG_DIM>::from_fn(|i, j| f64::from(u8::from(i == j)));
        let pp = self.f * self.p * self.f.transpose() + self.q;
        let s = h * pp * h.transpose() + self.r;
        let chol = s
            .cholesky()
            .with_context(|| format!("gain schedule: S not positive definite at update {n}"))?;
        // K^T = S^-1 H P' (S and P' symmetric).
        let kt = chol.solve(&(h * pp));
        let ikh = Aug64::identity() - kt.transpose() * h;
        let joseph = ikh * pp * ikh.transpose() + kt.transpose() * self.r * kt;
        self.p = (joseph + joseph.transpose()) * 0.5;
        Ok(kt)
    }
}

/// Friedland's two-stage form of the same filter, exact when the
/// parameters are static (`Q_p = 0`) and the prior has no `y`-`p`
/// covariance: a bias-free filter over `y` alone (`P~`, gain `K~`,
/// innovation covariance `S~`), whose recursion does not involve `p`, and
/// the parameters' filter (`P_b`) with the sensitivity of `y` to `p`
/// (`U` predicted, `V` updated). The whole filter's gain is
/// `K_y = K~ + V K_b`, `K_p = K_b`, and its covariance
/// `P = [P~ + V P_b V^T, V P_b; P_b V^T, P_b]`.
struct TwoStage {
    a: Lat64,
    b: Cols64,
    qy: Lat64,
    r: Lat64,
    /// `P~` after the update.
    pt: Lat64,
    v: Cols64,
    pb: Par64,
}

impl TwoStage {
    /// The bias-free filter's next gain `K~` and `S~^-1`, from `P~`.
    fn bias_free_gain(&self) -> Result<(Lat64, Lat64, Lat64)> {
        let ptm = self.a * self.pt * self.a.transpose() + self.qy;
        let si = (ptm + self.r)
            .cholesky()
            .context("two-stage: S~ not positive definite")?
            .inverse();
        Ok((ptm * si, si, ptm))
    }

    /// One update with the bias-free gain `(k, si, ptm)` (the exact one,
    /// or a constant one in the tail).
    fn update(&mut self, (k, si, ptm): (Lat64, Lat64, Lat64)) -> Result<()> {
        let ik = Lat64::identity() - k;
        let joseph = ik * ptm * ik.transpose() + k * self.r * k.transpose();
        self.pt = (joseph + joseph.transpose()) * 0.5;
        let u = self.a * self.v + self.b;
        let w = si * u;
        let m2 = Par64::identity() + self.pb * (u.transpose() * w);
        let m2i = m2
            .try_inverse()
            .context("two-stage: I + P_b U^T S~^-1 U singular")?;
        let kb = m2i * self.pb * w.transpose();
        let e = kb * u;
        let j = Par64::identity() - e;
        let pb = j * self.pb * j.transpose() + m2i * self.pb * e.transpose();
        self.pb = (pb + pb.transpose()) * 0.5;
        self.v = u - k * u;
        Ok(())
    }

    /// `P` of the whole filter.
    fn covariance(&self) -> Aug64 {
        let mut p = Aug64::zeros();
        let vpb = self.v * self.pb;
        p.fixed_view_mut::<LATENT_DIM, LATENT_DIM>(0, 0)
            .copy_from(&(self.pt + vpb * self.v.transpose()));
        p.fixed_view_mut::<LATENT_DIM, PARAM_DIM>(0, LATENT_DIM)
            .copy_from(&vpb);
        p.fixed_view_mut::<PARAM_DIM, LATENT_DIM>(LATENT_DIM, 0)
            .copy_from(&vpb.transpose());
        p.fixed_view_mut::<PARAM_DIM, PARAM_DIM>(LATENT_DIM, LATENT_DIM)
            .copy_from(&self.pb);
        p
    }
}

/// How the gain schedule was checked at export.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct ScheduleCheck {
    /// Largest `|P - P_two-stage|` over the schedule's updates, relative to
    /// `max |P|`: the two forms of the filter agree (f64).
    pub two_stage_gap: f64,
    /// Largest change of the bias-free gain `K~` at the schedule's last
    /// update, relative to `max |K~|`: how far it had converged.
    pub bias_free_change: f64,
    /// Largest relative difference of the parameters' standard deviation
    /// between the exact recursion and the tail's constant `K~`, over
    /// [`TAIL_CHECK_STEPS`] updates after the schedule.
    pub tail_std_gap: f64,
}

/// Updates after the schedule over which the constant-gain tail is
/// checked against the exact recursion.
pub const TAIL_CHECK_STEPS: usize = 2000;

/// The gain schedule of `filter.schedule_steps` updates for `F`
/// (row-major), as the blob stores it (see `estimator::blob`): per update
/// `K^T` and the parameters' standard deviations, then the tail: `S~^-1`
/// and `P~` of the converged bias-free filter, `V_T` and `P_b,T`.
///
/// Both forms of the filter run side by side in f64 and must agree at
/// every update; the bias-free gain must have converged by the last
/// update (its change below 1e-9 of its size), and the tail, run with that
/// gain held constant, must give the parameters' standard deviations of
/// the exact recursion within 1e-6 relative for [`TAIL_CHECK_STEPS`]
/// updates. Otherwise an error says which check failed.
pub fn gain_schedule(f: &[f32], filter: &FilterSpec) -> Result<(Vec<f32>, ScheduleCheck)> {
    anyhow::ensure!(f.len() == AUG_DIM * AUG_DIM, "F has {} values", f.len());
    let f = Aug64::from_row_iterator(f.iter().map(|&v| f64::from(v)));
    let q = Aug64::from_diagonal(&SVector::from_iterator(
        filter.q.iter().map(|&x| f64::from(x)),
    ));
    let r = Lat64::from_diagonal(&SVector::from_iterator(
        filter.r.iter().map(|&x| f64::from(x)),
    ));
    let prior = Aug64::from_diagonal(&SVector::from_iterator(
        filter.prior_var.iter().map(|&x| f64::from(x)),
    ));
    let steps = usize::from(filter.schedule_steps);
    let mut check = ScheduleCheck {
        two_stage_gap: 0.0,
        bias_free_change: 0.0,
        tail_std_gap: 0.0,
    };
    if steps == 0 {
        return Ok((Vec::new(), check));
    }
    anyhow::ensure!(
        filter.q[LATENT_DIM..].iter().all(|&v| v == 0.0),
        "gain schedule: the parameters have process noise, so they are not static"
    );
    let mut full = Full { f, q, r, p: prior };
    let mut two = TwoStage {
        a: f.fixed_view::<LATENT_DIM, LATENT_DIM>(0, 0).into_owned(),
        b: f.fixed_view::<LATENT_DIM, PARAM_DIM>(0, LATENT_DIM)
            .into_owned(),
        qy: q.fixed_view::<LATENT_DIM, LATENT_DIM>(0, 0).into_owned(),
        r,
        pt: prior
            .fixed_view::<LATENT_DIM, LATENT_DIM>(0, 0)
            .into_owned(),
        v: Cols64::zeros(),
        pb: prior
            .fixed_view::<PARAM_DIM, PARAM_DIM>(LATENT_DIM, LATENT_DIM)
            .into_owned(),
    };
    let mut out = Vec::with_capacity(steps * estimator::blob::SCHEDULE_STEP_LEN + TAIL_LEN);
    let mut last_k = Lat64::zeros();
    for n in 1..=steps {
        let kt = full.update(n)?;
        let gain = two.bias_free_gain()?;
        last_k = gain.0;
        two.update(gain)?;
        let scale = full.p.amax().max(f64::MIN_POSITIVE);
        check.two_stage_gap = check
            .two_stage_gap
            .max((full.p - two.covariance()).amax() / scale);
        for k in 0..LATENT_DIM {
            out.extend((0..AUG_DIM).map(|i| kt[(k, i)] as f32));
        }
        out.extend((0..PARAM_DIM).map(|a| {
            let v = full.p[(LATENT_DIM + a, LATENT_DIM + a)];
            v.max(0.0).sqrt() as f32
        }));
    }
    anyhow::ensure!(
        check.two_stage_gap < 1e-9,
        "gain schedule: the two-stage filter departs from the full one by {:.1e}",
        check.two_stage_gap
    );
    // The tail: the next bias-free gain, held from here on.
    let tail = two.bias_free_gain()?;
    check.bias_free_change = (tail.0 - last_k).amax() / tail.0.amax().max(f64::MIN_POSITIVE);
    anyhow::ensure!(
        check.bias_free_change < 1e-9,
        "gain schedule: the bias-free gain still changes by {:.1e} (relative) at update {steps}; \
         a longer schedule is needed",
        check.bias_free_change
    );
    // K~ = P~' S~^-1 = I - R S~^-1: the device needs S~^-1 only.
    let si = (tail.1 + tail.1.transpose()) * 0.5;
    out.extend(si.iter().map(|&v| v as f32)); // exactly symmetric
    out.extend(two.pt.iter().map(|&v| v as f32)); // symmetric
    out.extend(two.v.iter().map(|&v| v as f32)); // column by column
    out.extend(two.pb.iter().map(|&v| v as f32)); // symmetric
    // The tail against the exact recursion.
    let mut held = two;
    for n in steps + 1..=steps + TAIL_CHECK_STEPS {
        full.update(n)?;
        held.update(tail)?;
        for a in 0..PARAM_DIM {
            let exact = full.p[(LATENT_DIM + a, LATENT_DIM + a)].max(0.0).sqrt();
            let ours = held.pb[(a, a)].max(0.0).sqrt();
            if exact > 0.0 {
                check.tail_std_gap = check.tail_std_gap.max((exact - ours).abs() / exact);
            }
        }
    }
    anyhow::ensure!(
        check.tail_std_gap < 1e-6,
        "gain schedule: with the bias-free gain held, the parameters' std departs by {:.1e}",
        check.tail_std_gap
    );
    anyhow::ensure!(
        out.iter().all(|v| v.is_finite()),
        "gain schedule: not finite"
    );
    Ok((out, check))
}

/// Serialises a blob with its CRC.
pub fn blob_bytes(blob: &Blob<'_>) -> Result<Vec<u8>> {
    let mut buf = vec![0u8; 1 << 20];
    let n = blob
        .to_slice(&mut buf)
        .map_err(|e| anyhow::anyhow!("{e}"))?
        .len();
    buf.truncate(n);
    Ok(buf)
}

/// What an export measured, saved beside the blob.
#[derive(Debug, Serialize)]
pub struct ExportInfo {
    /// The run's config.
    pub config: TrainConfig,
    /// The run's state at export.
    pub iteration: usize,
    /// Training wall time, s.
    pub train_seconds: f64,
    /// One-step latent residual variance per dimension.
    pub residual_var: Vec<f32>,
    /// Sigma per training rollout's estimation window: max and median.
    pub train_sigma_max: f32,
    /// Median of the same.
    pub train_sigma_median: f32,
    /// The calibrated threshold.
    pub sigma_threshold: f32,
    /// Blob size, bytes.
    pub blob_bytes: usize,
    /// Updates in the blob's gain schedule.
    pub schedule_steps: u16,
    /// How the schedule and its tail were checked.
    pub schedule_check: ScheduleCheck,
}

/// Sigma of the length corrections over the protocol's estimation window.
pub fn window_sigma(model: &Model<'_>, xs: &[[f64; 2]]) -> Result<f32> {
    let n = ESTIMATION_STEPS.min(xs.len());
    let out = crate::eval::estimate(model, &xs[..n]).map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(out.sigma[0])
}

/// A baseline's weights as exported: the burnpack beside this sidecar, and
/// what is needed to run it (the config names the model and its sizes).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct BaselineInfo {
    /// The run's config.
    pub config: TrainConfig,
    /// The run's normalisation.
    pub norm: Norm,
    /// Iterations trained.
    pub iteration: usize,
    /// Training wall time, s.
    pub train_seconds: f64,
    /// Size of the burnpack, bytes.
    pub bytes: usize,
}

/// The sidecar of a baseline's burnpack (`cbm.bpk` -> `cbm.json`).
pub fn baseline_sidecar(weights: &Path) -> PathBuf {
    weights.with_extension("json")
}

/// Reads a run's config and state.
fn run_files(dir: &Path) -> Result<(TrainConfig, RunState)> {
    let paths = RunPaths::new(dir);
    let cfg: TrainConfig = serde_json::from_str(
        &std::fs::read_to_string(&paths.config)
            .with_context(|| format!("{}: cannot read", paths.config.display()))?,
    )
    .with_context(|| format!("{}", paths.config.display()))?;
    let state: RunState = serde_json::from_str(
        &std::fs::read_to_string(&paths.state)
            .with_context(|| format!("{}: cannot read", paths.state.display()))?,
    )
    .with_context(|| format!("{}", paths.state.display()))?;
    Ok((cfg, state))
}

/// The model kind of run `dir`.
pub fn run_kind(dir: &Path) -> Result<ModelKind> {
    Ok(run_files(dir)?.0.model)
}

/// Exports a baseline run (CBM or MLP): its burnpack to `out` and a
/// [`BaselineInfo`] beside it. The weights are checked to load first.
pub fn export_baseline(dir: &Path, out: &Path) -> Result<BaselineInfo> {
    let (cfg, state) = run_files(dir)?;
    let paths = RunPaths::new(dir);
    let device = train::device();
    match cfg.model {
        ModelKind::Cbm => drop(train::load_model::<Klm>(&paths, &cfg, &device)?),
        ModelKind::Mlp => drop(train::load_model::<Regressor>(&paths, &cfg, &device)?),
        ModelKind::Klm => anyhow::bail!("{}: a KLM run exports to a blob", dir.display()),
    }
    let bytes = std::fs::read(&paths.model)?;
    write_atomic(out, &bytes)?;
    let info = BaselineInfo {
        config: cfg,
        norm: state.norm,
        iteration: state.iteration,
        train_seconds: state.train_seconds,
        bytes: bytes.len(),
    };
    write_atomic(
        &baseline_sidecar(out),
        serde_json::to_string_pretty(&info)?.as_bytes(),
    )?;
    Ok(info)
}

/// Exports KLM run `dir` to the blob `out`, with a gain schedule over the
/// protocol's estimation window ([`ESTIMATION_STEPS`] measurements, so
/// `ESTIMATION_STEPS - 1` updates).
pub fn export(dir: &Path, out: &Path) -> Result<ExportInfo> {
    export_with(dir, out, &ExportOptions::default())
}

/// How [`export_with`] departs from the run's own settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExportOptions {
    /// Updates of the gain schedule (0: none).
    pub schedule_steps: u16,
    /// The filter's latent `Q` and `R` scales in place of the run's
    /// `q_latent` and `r_latent` (the filter is fitted at export, so it is
    /// tuned without retraining; the config saved beside the blob says
    /// which were used).
    pub q_latent: Option<f64>,
    /// See `q_latent`.
    pub r_latent: Option<f64>,
}

impl Default for ExportOptions {
    fn default() -> Self {
        ExportOptions {
            schedule_steps: (ESTIMATION_STEPS - 1) as u16,
            q_latent: None,
            r_latent: None,
        }
    }
}

/// Exports KLM run `dir` to the blob `out` with `opts`.
pub fn export_with(dir: &Path, out: &Path, opts: &ExportOptions) -> Result<ExportInfo> {
    let paths = RunPaths::new(dir);
    let (mut cfg, state) = run_files(dir)?;
    cfg.q_latent = opts.q_latent.unwrap_or(cfg.q_latent);
    cfg.r_latent = opts.r_latent.unwrap_or(cfg.r_latent);
    let schedule_steps = opts.schedule_steps;
    anyhow::ensure!(
        cfg.model == ModelKind::Klm,
        "{}: a {:?} run exports with export_baseline",
        dir.display(),
        cfg.model
    );
    let device = train::device();
    let model: Klm = train::load_model(&paths, &cfg, &device)?;
    let ds = train::training_data(&cfg);
    let (f, residual_var) = global_koopman(&model, &ds, &state.norm, &cfg)?;
    let mut parts = BlobParts::new(&model.enc, &model.dec, &f);
    let params = [
        cfg.length_spec(),
        match &cfg.effect {
            Some(e) => ParamSpec {
                name: e.name.as_str(),
                declared: true,
                train_range: [e.range[0] as f32, e.range[1] as f32],
                reading: Reading::Direct,
            },
            None => ParamSpec {
                name: "none",
                declared: false,
                train_range: [0.0, 0.0],
                reading: Reading::Direct,
            },
        },
    ];
    let mut q = [0.0f32; AUG_DIM];
    let mut r = [0.0f32; LATENT_DIM];
    let mut prior_var = [0.0f32; AUG_DIM];
    for k in 0..LATENT_DIM {
        q[k] = (cfg.q_latent as f32) * residual_var[k];
        r[k] = (cfg.r_latent as f32) * residual_var[k];
        prior_var[k] = residual_var[k];
    }
    prior_var[LATENT_DIM] = (cfg.prior_std_length * cfg.prior_std_length) as f32;
    if let Some(e) = &cfg.effect {
        let std = if cfg.prior_std_effect > 0.0 {
            cfg.prior_std_effect
        } else {
            e.range[0]
                .abs()
                .max(e.range[1].abs())
                .max(f64::MIN_POSITIVE)
        };
        prior_var[LATENT_DIM + 1] = (std * std) as f32;
    }
    let mut filter = FilterSpec {
        q,
        r,
        prior_mean: [0.0; PARAM_DIM],
        prior_var,
        burn_in: BURN_IN,
        sigma_threshold: 1.0,
        schedule_steps,
    };
    let schedule_check = parts.set_schedule(&filter)?;
    // Calibrate: sigma over every training rollout's estimation window.
    let draft = blob_bytes(&parts.blob(&state.norm, &cfg, filter, params))?;
    let m = Model::from_bytes(&draft).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut sigmas = ds
        .rollouts
        .iter()
        .map(|r| window_sigma(&m, &r.xs))
        .collect::<Result<Vec<_>>>()?;
    sigmas.sort_by(f32::total_cmp);
    let max = *sigmas.last().context("no training rollouts")?;
    filter.sigma_threshold = (cfg.trust_factor as f32 * max).max(f32::MIN_POSITIVE);
    let bytes = blob_bytes(&parts.blob(&state.norm, &cfg, filter, params))?;
    Model::from_bytes(&bytes)
        .map_err(|e| anyhow::anyhow!("exported blob does not read back: {e}"))?;
    write_atomic(out, &bytes)?;
    let info = ExportInfo {
        config: cfg,
        iteration: state.iteration,
        train_seconds: state.train_seconds,
        residual_var: residual_var.to_vec(),
        train_sigma_max: max,
        train_sigma_median: sigmas[sigmas.len() / 2],
        sigma_threshold: filter.sigma_threshold,
        blob_bytes: bytes.len(),
        schedule_steps,
        schedule_check,
    };
    write_atomic(
        &out.with_extension("json"),
        serde_json::to_string_pretty(&info)?.as_bytes(),
    )?;
    Ok(info)
}

/// `F` (row-major, AUG x AUG) fitted over every transition of `ds`, and
/// the one-step latent residual variance per dimension.
pub fn global_koopman(
    model: &Klm,
    ds: &Dataset,
    norm: &Norm,
    cfg: &TrainConfig,
) -> Result<(Vec<f32>, [f32; LATENT_DIM])> {
    let device = train::device();
    let t = ds.rollouts.first().context("empty data set")?.xs.len();
    let mut x = Vec::new();
    let mut p = Vec::new();
    for r in &ds.rollouts {
        anyhow::ensure!(r.xs.len() == t, "rollouts of unequal length");
        x.extend(r.xs.iter().flat_map(|&v| norm.apply(v)));
        let m = ds.meta(r.id).context("rollout without truth")?;
        let second = match &cfg.effect {
            Some(e) => *m
                .effects
                .get(&e.name)
                .context("rollout without its effect's coefficient")?,
            None => 0.0,
        };
        p.extend([m.length as f32, second as f32]);
    }
    let b = ds.rollouts.len();
    let x = Tensor::<3>::from_data(TensorData::new(x, [b, t, 2]), &device);
    let p = Tensor::<2>::from_data(TensorData::new(p, [b, 2]), &device);
    let y = model.enc.forward(x, cfg.activation).detach();
    let k = fit_koopman(y.clone(), Some(p.clone()), cfg.ridge);
    let kct = k.ct.context("the KLM's K has a parameter block")?;
    let at: Vec<f32> =
        k.at.clone()
            .into_data()
            .try_to_vec::<f32>()
            .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let ct: Vec<f32> = kct
        .clone()
        .into_data()
        .try_to_vec::<f32>()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let l = LATENT_DIM;
    // One-step residual.
    let g_y = y.clone().slice([0..b, 0..t - 1, 0..l]);
    let pred = g_y.matmul(k.at.unsqueeze_dim::<3>(0)) + p.matmul(kct).unsqueeze_dim::<3>(1);
    let res = (y.slice([0..b, 1..t, 0..l]) - pred)
        .powi_scalar(2)
        .reshape([b * (t - 1), l])
        .mean_dim(0);
    let res: Vec<f32> = res
        .into_data()
        .try_to_vec::<f32>()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let mut residual_var = [0.0f32; LATENT_DIM];
    for (d, s) in residual_var.iter_mut().zip(&res) {
        *d = s.max(1e-10);
    }
    let mut f = vec![0.0f32; AUG_DIM * AUG_DIM];
    for i in 0..l {
        for j in 0..l {
            f[i * AUG_DIM + j] = at[j * l + i];
        }
        f[i * AUG_DIM + l] = ct[i]; // length column
        if cfg.effect.is_some() {
            f[i * AUG_DIM + l + 1] = ct[l + i]; // the effect's column (else it stays 0)
        }
    }
    for k in l..AUG_DIM {
        f[k * AUG_DIM + k] = 1.0;
    }
    Ok((f, residual_var))
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::module::Param;
    use burn::tensor::Device;

    /// A 2 -> 3 layer with every weight distinct: `W[i][o] = 10 (i + 1) + (o + 1)`,
    /// `b[o] = -(o + 1)`. burn stores it `[d_in, d_out]`; `y = x W + b`.
    fn asymmetric_linear(d_in: usize, d_out: usize) -> Linear {
        let device = Device::flex();
        let w: Vec<f32> = (0..d_in)
            .flat_map(|i| (0..d_out).map(move |o| (10 * (i + 1) + o + 1) as f32))
            .collect();
        let b: Vec<f32> = (0..d_out).map(|o| -((o + 1) as f32)).collect();
        Linear {
            weight: Param::from_tensor(Tensor::from_data(
                TensorData::new(w, [d_in, d_out]),
                &device,
            )),
            bias: Some(Param::from_tensor(Tensor::from_data(
                TensorData::new(b, [d_out]),
                &device,
            ))),
        }
    }

    /// A small stable system: the latent block 0.9 I plus a small
    /// asymmetric coupling, the parameters' columns arbitrary.
    fn toy_f() -> Vec<f32> {
        let mut f = vec![0.0f32; AUG_DIM * AUG_DIM];
        for i in 0..LATENT_DIM {
            for j in 0..LATENT_DIM {
                f[i * AUG_DIM + j] = if i == j {
                    0.9
                } else {
                    0.02 * ((i * 7 + j * 3) as f32).sin()
                };
            }
            f[i * AUG_DIM + LATENT_DIM] = 0.1 * (i as f32).cos();
            f[i * AUG_DIM + LATENT_DIM + 1] = 0.05;
        }
        for k in LATENT_DIM..AUG_DIM {
            f[k * AUG_DIM + k] = 1.0;
        }
        f
    }

    fn toy_filter(steps: u16) -> FilterSpec {
        let mut q = [0.01; AUG_DIM];
        q[LATENT_DIM..].fill(0.0);
        let mut prior_var = [0.01; AUG_DIM];
        prior_var[LATENT_DIM] = 25.0;
        prior_var[LATENT_DIM + 1] = 0.0;
        FilterSpec {
            q,
            r: [0.02; LATENT_DIM],
            prior_mean: [0.0; PARAM_DIM],
            prior_var,
            burn_in: 32,
            sigma_threshold: 1.0,
            schedule_steps: steps,
        }
    }

    #[test]
    fn gain_schedule_checks_its_two_stage_tail() {
        let f = toy_f();
        let (values, check) = gain_schedule(&f, &toy_filter(63)).unwrap();
        assert_eq!(
            values.len(),
            63 * estimator::blob::SCHEDULE_STEP_LEN + TAIL_LEN
        );
        // Both forms in f64: agreement to rounding (1e-12 leaves 4 digits
        // of room above f64's 2e-16 for 100 products).
        assert!(check.two_stage_gap < 1e-12, "{check:?}");
        assert!(check.bias_free_change < 1e-9, "{check:?}");
        assert!(check.tail_std_gap < 1e-6, "{check:?}");
        // Update 1's gain: with P' = F P0 F^T + Q, the length's gain
        // row is (P'_py S^-1); its first entry must not be zero here.
        assert!(values[LATENT_DIM] != 0.0);
        // Two updates are too few for the bias-free gain to settle.
        let err = gain_schedule(&f, &toy_filter(2)).unwrap_err().to_string();
        assert!(err.contains("still changes"), "{err}");
        // Parameters with process noise are not static.
        let mut noisy = toy_filter(63);
        noisy.q[LATENT_DIM] = 1e-4;
        let err = gain_schedule(&f, &noisy).unwrap_err().to_string();
        assert!(err.contains("process noise"), "{err}");
        // No schedule: nothing to store.
        assert!(gain_schedule(&f, &toy_filter(0)).unwrap().0.is_empty());
    }

    #[test]
    fn linear_lands_input_major() {
        let (d_in, d_out, w, b) = linear_to_blob(&asymmetric_linear(2, 3));
        assert_eq!((d_in, d_out), (2, 3));
        // Golden, from the formula above: row i holds W[i][0..3].
        assert_eq!(w, [11.0, 12.0, 13.0, 21.0, 22.0, 23.0]);
        assert_eq!(b, [-1.0, -2.0, -3.0]);
    }

    #[test]
    fn blob_round_trips_and_computes_what_burn_computes() {
        let device = Device::flex();
        device.seed(3);
        let mut enc = Mlp::new(2, estimator::HIDDEN_DIM, LATENT_DIM, &device);
        enc.l0 = asymmetric_linear(2, estimator::HIDDEN_DIM); // large but exact
        enc.l0.weight = enc.l0.weight.map(|w| w.mul_scalar(0.01));
        let dec = Mlp::new(LATENT_DIM, estimator::HIDDEN_DIM, 2, &device);
        // Latent rows arbitrary; parameter rows the identity, as the filter
        // requires (a blob without it is refused, checked at the end).
        let f: Vec<f32> = (0..AUG_DIM * AUG_DIM)
            .map(|k| match (k / AUG_DIM, k % AUG_DIM) {
                (i, j) if i >= LATENT_DIM => f32::from(u8::from(i == j)),
                _ => (k as f32 * 0.37).sin(),
            })
            .collect();
        let parts = BlobParts::new(&enc, &dec, &f);
        let cfg = TrainConfig::default();
        let norm = Norm {
            mu: [0.5, -0.25],
            s: [2.0, 4.0],
        };
        let filter = FilterSpec {
            q: [0.1; AUG_DIM],
            r: [0.2; LATENT_DIM],
            prior_mean: [0.0; PARAM_DIM],
            prior_var: [1.0; AUG_DIM],
            burn_in: 32,
            sigma_threshold: 0.05,
            schedule_steps: 0,
        };
        let params = [
            ParamSpec {
                name: "length",
                declared: true,
                train_range: [2.0, 5.0],
                reading: Reading::Reciprocal,
            },
            ParamSpec {
                name: "none",
                declared: false,
                train_range: [0.0, 0.0],
                reading: Reading::Direct,
            },
        ];
        let blob = parts.blob(&norm, &cfg, filter, params);
        let bytes = blob_bytes(&blob).unwrap();
        let back = Model::from_bytes(&bytes).unwrap();
        // Exactly the same numbers come back (the blob stores f32 bits),
        // with the 0-3 padding bytes the writer chose, which put the arena
        // at a multiple of 4 bytes from the blob's start.
        let pad = back.blob().body.pad;
        assert!(pad.len() <= 3 && pad.iter().all(|b| *b == 0));
        let offset = back.blob().body.weights.0.as_ptr() as usize - bytes.as_ptr() as usize;
        assert_eq!(offset % 4, 0, "arena at byte {offset}");
        let mut want = blob;
        want.body.pad = pad;
        assert_eq!(*back.blob(), want);
        for (i, j) in [(0, 0), (3, 17), (17, 2), (17, 17)] {
            assert_eq!(back.f(i, j), f[i * AUG_DIM + j]);
        }
        // And the estimator's encoder computes burn's forward pass.
        let x = [0.3f32, -1.2];
        let burn_y: Vec<f32> = enc
            .forward(
                Tensor::<2>::from_data(TensorData::new(x.to_vec(), [1, 2]), &device),
                cfg.activation,
            )
            .into_data()
            .try_to_vec::<f32>()
            .unwrap();
        let y = back.encode(&x);
        for (a, b) in y.iter().zip(&burn_y) {
            // Same f32 sums in another order: relative 1e-5 of the magnitude.
            assert!((a - b).abs() <= 1e-5 * b.abs().max(1.0), "{a} vs {b}");
        }
        // A length that would drift (F[16][16] != 1) is refused.
        let mut drifting = f.clone();
        drifting[LATENT_DIM * AUG_DIM + LATENT_DIM] = 0.99;
        let parts = BlobParts::new(&enc, &dec, &drifting);
        let blob = parts.blob(&norm, &cfg, filter, params);
        let bytes = blob_bytes(&blob).unwrap();
        assert_eq!(
            Model::from_bytes(&bytes).unwrap_err(),
            estimator::Error::BlobParamsNotStatic
        );
    }
}
