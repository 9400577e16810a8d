#!/usr/bin/env python3
"""An independent numpy implementation of PILCO's moment matching for the general form
of `totalgrad pilco propagate` (docs/pilco.md, section 4, "The general form against an
independent numpy reference"), written from the published
equations (Deisenroth & Rasmussen 2011; Deisenroth's thesis, 2010; the equations of
PILCO's gTrig, gp0/gp1/gp2, gSat, lossSat and propagated), not from any code. It shares
nothing with the C++ but the file format.

Deliberately straightforward: every moment is formed from its defining formula with
explicit N x N (or M x M) matrices Q_ab, the joint Gaussian of [z, u] is assembled as one
covariance, and no reverse mode exists: the gradient is central finite differences of J
by the complex step: every quantity is computed in complex arithmetic, and
dJ/dtheta_k = Im J(theta + i h e_k) / h with h = 1e-30, exact to rounding as no difference
is taken). With `--json` it prints
the fields of our command for a scenario file.
"""
import json
import sys

import numpy as np

CONGP_NOISE_VAR = 1e-4   # congp's sn^2 = 0.01^2
FITC_RIDGE = 1e-6        # gp1's ridge on Kmm
GP2_JITTER = 1e-6        # gp2's added output variance (the file's output_variance_jitter)


def e_sin(mu, var):
    return np.exp(-var / 2) * np.sin(mu)


def e_cos(mu, var):
    return np.exp(-var / 2) * np.cos(mu)


def augment(m, S, angles):
    """Joint Gaussian of z = [x, sin x_a1, cos x_a1, ...] (gTrig with all pair blocks)."""
    d, a = len(m), len(angles)
    nz = d + 2 * a
    zm = np.zeros(nz, dtype=complex)
    zS = np.zeros((nz, nz), dtype=complex)
    zm[:d] = m
    zS[:d, :d] = S
    for k, ak in enumerate(angles):
        v = S[ak, ak]
        zm[d + 2 * k] = e_sin(m[ak], v)
        zm[d + 2 * k + 1] = e_cos(m[ak], v)
        # Stein: Cov(x, sin x_a) = S[:, a] E cos x_a, Cov(x, cos x_a) = -S[:, a] E sin x_a.
        zS[:d, d + 2 * k] = S[:, ak] * zm[d + 2 * k + 1]
        zS[:d, d + 2 * k + 1] = -S[:, ak] * zm[d + 2 * k]
    for k, ak in enumerate(angles):
        for l, al in enumerate(angles):
            vm = S[ak, ak] + S[al, al] - 2 * S[ak, al]   # var(x_k - x_l)
            vp = S[ak, ak] + S[al, al] + 2 * S[ak, al]   # var(x_k + x_l)
            dm, dp = m[ak] - m[al], m[ak] + m[al]
            ss = 0.5 * (e_cos(dm, vm) - e_cos(dp, vp))   # E sin_k sin_l
            cc = 0.5 * (e_cos(dm, vm) + e_cos(dp, vp))   # E cos_k cos_l
            sc = 0.5 * (e_sin(dp, vp) + e_sin(dm, vm))   # E sin_k cos_l
            cs = 0.5 * (e_sin(dp, vp) - e_sin(dm, vm))   # E cos_k sin_l
            sk, ck = zm[d + 2 * k], zm[d + 2 * k + 1]
            sl, cl = zm[d + 2 * l], zm[d + 2 * l + 1]
            i, j = d + 2 * k, d + 2 * l
            zS[i, j] = ss - sk * sl
            zS[i + 1, j + 1] = cc - ck * cl
            zS[i, j + 1] = sc - sk * cl
            zS[i + 1, j] = cs - ck * sl
    zS[d:, :d] = zS[:d, d:].T
    return zm, zS


class Gp:
    """SE-ARD outputs sharing support points X: mean_a(x) = sum_i beta_ai k_a(x_i, x)."""

    def __init__(self, X, beta, inv_l2, sf2, variance_weights=None):
        self.X, self.beta, self.inv_l2, self.sf2 = X, beta, inv_l2, sf2
        self.vw = variance_weights   # list of N x N (K^-1 or Kmm^-1 - B^-1) or None (gp2)

    def kern(self, a, A, B):
        d = A[:, None, :] - B[None, :, :]
        return self.sf2[a] * np.exp(-0.5 * np.einsum("ijk,k,ijk->ij", d, self.inv_l2[a], d))

    def predict(self, m, s, jitter=0.0):
        """Mean (D), covariance (D x D) and inv(s) Cov(x, f) (E x D) for x ~ N(m, s)."""
        X, e = self.X, len(m)
        nu = X - m
        D = self.beta.shape[1]
        mean = np.zeros(D, dtype=complex)
        cross = np.zeros((e, D), dtype=complex)
        kx = []
        for a in range(D):
            lam = np.diag(1.0 / self.inv_l2[a])
            sl = s + lam
            w = np.linalg.solve(sl, nu.T).T                      # (s + Lambda)^-1 nu_i
            c = self.sf2[a] / np.sqrt(np.linalg.det(s @ np.diag(self.inv_l2[a]) + np.eye(e)))
            q = c * np.exp(-0.5 * np.sum(nu * w, axis=1))
            mean[a] = q @ self.beta[:, a]
            cross[:, a] = w.T @ (q * self.beta[:, a])
            kx.append(self.sf2[a] * np.exp(-0.5 * np.sum(nu * nu * self.inv_l2[a], axis=1)))
        cov = np.zeros((D, D), dtype=complex)
        for a in range(D):
            for b in range(a, D):
                ia, ib = np.diag(self.inv_l2[a]), np.diag(self.inv_l2[b])
                R = s @ (ia + ib) + np.eye(e)
                T = np.linalg.solve(R, s)                      # R^-1 s
                za, zb = nu @ ia, nu @ ib
                # z_ij = za_i + zb_j; z^T T z / 2 split into i, j and cross parts.
                qa = 0.5 * np.sum((za @ T) * za, axis=1)
                qb = 0.5 * np.sum((zb @ T) * zb, axis=1)
                qab = za @ (0.5 * (T + T.T)) @ zb.T
                Q = np.outer(kx[a], kx[b]) / np.sqrt(np.linalg.det(R)) * np.exp(
                    qa[:, None] + qb[None, :] + qab)
                v = self.beta[:, a] @ Q @ self.beta[:, b] - mean[a] * mean[b]
                if a == b:
                    if self.vw is not None:
                        v += self.sf2[a] - np.sum(self.vw[a] * Q)
                    v += jitter
                cov[a, b] = cov[b, a] = v
        return mean, cov, cross


def full_gp(X, Y, log_hyp):
    e = X.shape[1]
    inv_l2 = np.exp(-2 * log_hyp[:, :e])
    sf2 = np.exp(2 * log_hyp[:, e])
    sn2 = np.exp(2 * log_hyp[:, e + 1])
    gp = Gp(X, np.zeros(Y.shape, dtype=complex), inv_l2, sf2)
    vw = []
    for a in range(Y.shape[1]):
        K = gp.kern(a, X, X) + sn2[a] * np.eye(X.shape[0])
        Ki = np.linalg.inv(K)
        gp.beta[:, a] = np.linalg.solve(K, Y[:, a])
        vw.append(Ki)
    gp.vw = vw
    return gp


def fitc_gp(X, Y, Z, log_hyp):
    """FITC (gp1): Kmm + ridge, Lambda = diag(Knn - Qnn) + sn^2, B = Kmm + Kmn Lambda^-1 Knm,
    beta = B^-1 Kmn Lambda^-1 y, variance weights Kmm^-1 - B^-1."""
    e = X.shape[1]
    inv_l2 = np.exp(-2 * log_hyp[:, :e])
    sf2 = np.exp(2 * log_hyp[:, e])
    sn2 = np.exp(2 * log_hyp[:, e + 1])
    gp = Gp(Z, np.zeros((Z.shape[0], Y.shape[1]), dtype=complex), inv_l2, sf2)
    vw = []
    for a in range(Y.shape[1]):
        Kmm = gp.kern(a, Z, Z) + FITC_RIDGE * np.eye(Z.shape[0])
        Kmn = gp.kern(a, Z, X)
        Qnn_diag = np.sum(Kmn * np.linalg.solve(Kmm, Kmn), axis=0)
        lam = sf2[a] - Qnn_diag + sn2[a]
        B = Kmm + (Kmn / lam) @ Kmn.T
        gp.beta[:, a] = np.linalg.solve(B, Kmn @ (Y[:, a] / lam))
        vw.append(np.linalg.inv(Kmm) - np.linalg.inv(B))
    gp.vw = vw
    return gp


def policy_weights(centres, log_l, values, targets):
    """beta per control: (K_cc + 1e-4 I)^-1 y (congp) for pseudo-targets, else the weights."""
    if not targets:
        return values
    w = np.zeros(values.shape, dtype=complex)
    for j in range(values.shape[1]):
        il2 = np.exp(-2 * log_l[j])
        d = centres[:, None, :] - centres[None, :, :]
        K = np.exp(-0.5 * np.einsum("ijk,k,ijk->ij", d, il2, d))
        w[:, j] = np.linalg.solve(K + CONGP_NOISE_VAR * np.eye(len(centres)), values[:, j])
    return w


def gsat(am, aS, umax):
    """u_j = umax_j (9 sin a_j + sin 3 a_j) / 8 for a ~ N(am, aS): mean, cov, and
    c_j with Cov(a, u_j) = Cov(a, a_j) c_j (Stein)."""
    F = len(am)
    qm = np.concatenate([am, 3 * am])
    M = np.vstack([np.eye(F), 3 * np.eye(F)])
    qS = M @ aS @ M.T
    es = e_sin(qm, np.diag(qS))
    n = 2 * F
    cs = np.zeros((n, n), dtype=complex)
    for i in range(n):
        for j in range(n):
            vm = qS[i, i] + qS[j, j] - 2 * qS[i, j]
            vp = qS[i, i] + qS[j, j] + 2 * qS[i, j]
            cs[i, j] = 0.5 * (e_cos(qm[i] - qm[j], vm) - e_cos(qm[i] + qm[j], vp)) - es[i] * es[j]
    L = np.hstack([np.diag(umax * 9 / 8), np.diag(umax / 8)])
    um = L @ es
    uS = L @ cs @ L.T
    c = umax * (9 * e_cos(am, np.diag(aS)) + 3 * e_cos(3 * am, 9 * np.diag(aS))) / 8
    return um, uS, c


def loss_sat(zm, zS, zt, Q, widths):
    """lossSat: mean over widths of E[1 - exp(-(z - zt)^T W (z - zt) / 2)], W = Q / w^2;
    variance the mean of the per-width variances."""
    n = len(zm)
    L, V = 0.0, 0.0
    dz = zm - zt
    for w in widths:
        W = Q / w ** 2
        A1 = np.eye(n) + zS @ W
        e1 = np.exp(-0.5 * dz @ W @ np.linalg.solve(A1, dz)) / np.sqrt(np.linalg.det(A1))
        A2 = np.eye(n) + 2 * zS @ W
        e2 = np.exp(-dz @ W @ np.linalg.solve(A2, dz)) / np.sqrt(np.linalg.det(A2))
        var = e2 - e1 ** 2
        L += (1 - e1) / len(widths)
        V += (var if var.real >= 1e-12 else 0.0) / len(widths)
    return L, V


def trajectory(sc, gp, centres, log_l, w):
    angles, poli, dyni = sc["angle_indices"], sc["policy_inputs"], sc["dynamics_inputs"]
    umax = np.atleast_1d(np.array(sc["policy"]["max_force"], dtype=float))
    jitter = sc["policy"].get("output_variance_jitter", GP2_JITTER)
    F = w.shape[1]
    pol = Gp(centres, w, np.exp(-2 * log_l), np.ones(F))     # gp2: sf = 1, no model variance
    m = np.array(sc["mu0"], dtype=complex)
    S = np.array(sc["S0"], dtype=complex)
    d = len(m)
    cst = sc["cost"]
    zt, _ = augment(np.array(cst["target"], dtype=float), np.zeros((d, d)), angles)
    Q = np.array(cst["Q"], dtype=float)
    widths = np.atleast_1d(np.array(cst["width"], dtype=float))
    means, covs, cm, cs = [m], [S], [], []
    for _ in range(sc["horizon"]):
        zm, zS = augment(m, S, angles)
        nz = len(zm)
        pm, pS = zm[poli], zS[np.ix_(poli, poli)]
        am, aS, at = pol.predict(pm, pS, jitter)           # at = inv(pS) Cov(p, a)
        um, uS, c = gsat(am, aS, umax)
        cov_za = zS[:, poli] @ at                          # Cov(z, a)
        cov_zu = cov_za * c                                # Cov(z, u_j) = Cov(z, a_j) c_j
        jm = np.concatenate([zm, um])                      # joint of [z, u]
        jS = np.block([[zS, cov_zu], [cov_zu.T, uS]])
        gi = list(dyni) + [nz + j for j in range(F)]
        gm, gS = jm[gi], jS[np.ix_(gi, gi)]
        dm, dS, dt = gp.predict(gm, gS)
        C = jS[:d, gi] @ dt                                # Cov(x, Delta)
        m = m + dm
        S = S + dS + C + C.T
        S = 0.5 * (S + S.T)
        means.append(m)
        covs.append(S)
        zm, zS = augment(m, S, angles)
        L, V = loss_sat(zm, zS, zt, Q, widths)
        cm.append(L)
        cs.append(np.sqrt(V.real if np.iscomplexobj(V) else V))
    return means, covs, np.array(cm), np.array(cs)


def model(sc):
    X = np.array(sc["train_inputs"], dtype=float)
    Y = np.array(sc["train_targets"], dtype=float)
    hyp = np.array(sc["gp_log_hyp"], dtype=float)
    if "inducing_inputs" in sc:
        return fitc_gp(X, Y, np.array(sc["inducing_inputs"], dtype=float), hyp)
    return full_gp(X, Y, hyp)


def unpack(sc):
    p = sc["policy"]
    targets = "targets" in p
    values = np.array(p["targets"] if targets else p["weights"], dtype=float)
    if values.ndim == 1:
        values = values[:, None]
    log_l = np.array(p["log_lengthscales"], dtype=float)
    shared = log_l.ndim == 1
    if shared:
        log_l = np.tile(log_l, (values.shape[1], 1))
    return np.array(p["centres"], dtype=float), log_l, values, targets, shared


def run(sc, step=1e-30):
    gp = model(sc)
    centres, log_l, values, targets, shared = unpack(sc)

    def J(cen, ll, val):
        w = policy_weights(cen, ll, val, targets)
        return trajectory(sc, gp, cen, ll, w)[2].sum()

    w = policy_weights(centres, log_l, values, targets)
    means, covs, cm, cs = trajectory(sc, gp, centres, log_l, w)

    def fd(arr, setter):
        """Complex-step derivative of setter at arr, entry by entry."""
        g = np.zeros(arr.shape)
        for idx in np.ndindex(arr.shape):
            x = arr.astype(complex)
            x[idx] += 1j * step
            g[idx] = setter(x).imag / step
        return g

    g_c = fd(centres, lambda c: J(c, log_l, values))
    g_v = fd(values, lambda v: J(centres, log_l, v))
    if shared:
        g_l = fd(log_l[0], lambda l: J(centres, np.tile(l, (values.shape[1], 1)), values))
    else:
        g_l = fd(log_l, lambda l: J(centres, l, values))
    vec = np.ndim(sc["policy"]["targets" if targets else "weights"]) == 1
    shape_v = (lambda a: a[:, 0]) if vec else (lambda a: a)
    out = {
        "mean": [x.real.tolist() for x in means],
        "cov": [x.real.tolist() for x in covs],
        "cost_mean": cm.real.tolist(),
        "cost_std": cs.real.tolist(),
        "J": float(cm.real.sum()),
        "dJ_dcentres": g_c.tolist(),
    }
    if targets:
        out["dJ_dtargets"] = shape_v(g_v).tolist()
        out["weights"] = shape_v(w.real).tolist()
    else:
        out["dJ_dweights"] = shape_v(g_v).tolist()
    out["dJ_dlog_lengthscales"] = g_l.tolist()
    return out


if __name__ == "__main__":
    with open(sys.argv[1]) as fh:
        print(json.dumps(run(json.load(fh))))
