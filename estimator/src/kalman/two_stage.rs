//! Updates after the schedule, in Friedland's two-stage form.

use super::Kalman;
use super::kernels::{ParamSquare, Sensitivity, all_finite, combo, inverse2, mul2, transpose2};
use crate::model::Tail;
use crate::{Aug, Error, LATENT_DIM, Latent, PARAM_DIM};

impl Kalman<'_> {
    /// One update in two-stage form (after the schedule), leaving `self`
    /// alone; returns the new mean, `V` and `P_b`. With `S~^-1` from the
    /// tail and the held bias-free gain `K~ = I - R S~^-1` (never formed):
    /// `U = A V + B` (the sensitivity predicted), `W = S~^-1 U`,
    /// `K_b = (I + P_b U^T W)^-1 P_b W^T` (the parameters' gain, the
    /// push-through form of `P_b U^T (U P_b U^T + S~)^-1`),
    /// `V = U - K~ U = R W`; the mean moves by
    /// `K_y nu = K~ nu + V K_b nu = nu - R S~^-1 nu + V K_b nu` and `p` by
    /// `K_b nu`; `P_b = J P_b J^T + K_b S~ K_b^T` with
    /// `J = I - K_b U` (Joseph's form). `K_b` is never formed either: with
    /// `X = U^T W` and `N = (I + P_b X)^-1 P_b`, `K_b = N W^T`, so
    /// `K_b nu = N (W^T nu)`, `K_b U = N X^T` and `K_b S~ K_b^T = N X N^T`;
    /// past `U` and `W` the update is six sums over the latent and 2x2
    /// algebra.
    pub(crate) fn two_stage_update(
        &self,
        z: &Latent,
        tail: &Tail<'_>,
    ) -> Result<(Aug, Sensitivity, ParamSquare), Error> {
        let spec = &self.model.blob().body.filter;
        let ct = self.model.koopman_columns();
        let (_, nu) = self.predict_latent(z);
        // U_a = sum_k V_a[k] A^T_k + B^T_a (rows of C^T: A's columns, then B's).
        let mut u: Sensitivity = [[0.0; LATENT_DIM]; PARAM_DIM];
        for (a, (ua, va)) in u.iter_mut().zip(&self.v).enumerate() {
            *ua = combo(va.iter().copied().zip(ct.iter()));
            if let Some(b) = ct.get(LATENT_DIM + a) {
                for (o, bv) in ua.iter_mut().zip(b) {
                    *o += bv;
                }
            }
        }
        let mut w: Sensitivity = [[0.0; LATENT_DIM]; PARAM_DIM];
        for (wa, ua) in w.iter_mut().zip(&u) {
            *wa = combo(ua.iter().copied().zip(tail.si));
        }
        // Everything else the update needs of U and W is six sums over the
        // latent, taken side by side: X = U^T W and c = W^T nu.
        let ([u0, u1], [w0, w1]) = (&u, &w);
        let mut x = [[0.0f32; PARAM_DIM]; PARAM_DIM];
        let mut c = [0.0f32; PARAM_DIM];
        for ((((a0, a1), b0), b1), n) in u0.iter().zip(u1).zip(w0).zip(w1).zip(&nu) {
            let [[x00, x01], [x10, x11]] = &mut x;
            let [c0, c1] = &mut c;
            *x00 += a0 * b0;
            *x01 += a0 * b1;
            *x10 += a1 * b0;
            *x11 += a1 * b1;
            *c0 += b0 * n;
            *c1 += b1 * n;
        }
        // K_b = N W^T with N = (I + P_b X)^-1 P_b, so K_b nu = N c,
        // K_b U = N X^T and K_b S~ K_b^T = N X N^T: 2x2 algebra only.
        let mut m = mul2(&self.pb, &x);
        for (a, row) in m.iter_mut().enumerate() {
            if let Some(d) = row.get_mut(a) {
                *d += 1.0;
            }
        }
        let mi = inverse2(&m).ok_or(Error::FilterNotPositiveDefinite)?;
        let n = mul2(&mi, &self.pb);
        let [[n00, n01], [n10, n11]] = n;
        let [c0, c1] = c;
        let kb_nu = [n00 * c0 + n01 * c1, n10 * c0 + n11 * c1];
        // V = (I - K~) U = R W.
        let mut v = w;
        for va in v.iter_mut() {
            for (d, r) in va.iter_mut().zip(&spec.r) {
                *d *= r;
            }
        }
        // The mean: y = y' + nu - R S~^-1 nu + V K_b nu = z - R S~^-1 nu + V K_b nu.
        let sn = combo(nu.iter().copied().zip(tail.si));
        let vk = combo(kb_nu.iter().copied().zip(&v));
        let mut next = self.mean;
        for ((((ni, zi), r), s), e) in next.iter_mut().zip(z).zip(&spec.r).zip(&sn).zip(&vk) {
            *ni = (zi - r * s) + e;
        }
        for (ni, d) in next.iter_mut().skip(LATENT_DIM).zip(&kb_nu) {
            *ni += d;
        }
        // P_b = J P_b J^T + K_b S~ K_b^T with J = I - K_b U = I - N X^T,
        // then made exactly symmetric from its upper triangle.
        let [[k00, k01], [k10, k11]] = mul2(&n, &transpose2(&x));
        let j = [[1.0 - k00, -k01], [-k10, 1.0 - k11]];
        let jpj = mul2(&mul2(&j, &self.pb), &transpose2(&j));
        let nxn = mul2(&mul2(&n, &x), &transpose2(&n));
        let [[a00, a01], [_, a11]] = jpj;
        let [[b00, b01], [_, b11]] = nxn;
        let p01 = a01 + b01;
        let pb = [[a00 + b00, p01], [p01, a11 + b11]];
        let ok = all_finite(&next)
            && v.iter().all(|c| all_finite(c))
            && pb.iter().all(|r| all_finite(r))
            && pb
                .iter()
                .enumerate()
                .all(|(a, r)| r.get(a).is_none_or(|d| *d >= 0.0));
        if ok {
            Ok((next, v, pb))
        } else {
            Err(Error::FilterNonFinite)
        }
    }
}
