#!/usr/bin/python3
"""Measures two levers on the GP's P x N x N product before building them
(docs/results/speed.md, "levers measured and not taken"):

  * single precision: the predictive variance sf^2 - k^T K^-1 k + sn^2 and the
    variance Jacobian's sums ((K^-1 k) .* k) X with the product K* K^-1 in
    float32 (double accumulation of the variance), and in the whitened form
    |L^-1 k|^2 in float32;
  * low rank plus diagonal: K^-1 = U_r (D_r - 1/s) U_r^T + I/s, the eigen-
    vectors of Kf = K - s I with eigenvalues above a threshold; the rank r
    needed so that the a-priori bound on the variance's relative error,
    sf^2 sum_{i>r} lambda_i^2 / s^3, is below a tolerance. The product then
    costs 4 P N r flops instead of 2 P N^2, a gain only for r < N / 2.

    precision_levers.py SNAPSHOT.json EPISODE

Query points: 300 training inputs (chosen at random) perturbed by Gaussian
noise of about a tenth of each input's spread, as rollout particles near the
data are. Debian's numpy (/usr/bin/python3).
"""
import json
import sys

import numpy as np


def main():
    path, episode = sys.argv[1], int(sys.argv[2])
    snapshots = json.load(open(path))["snapshots"]
    snap = next(s for s in snapshots if s["episode"] == episode)
    x = np.hstack([np.array(snap["states"]), np.array(snap["forces"])[:, None]])
    h = snap["hyperparameters"]
    n = x.shape[0]
    rng = np.random.default_rng(0)
    z = x[rng.integers(0, n, 300)] + rng.normal(size=(300, x.shape[1])) * 0.1 * x.std(0)
    print(f"{path} episode {episode}: N = {n}, P = 300")
    for a in range(len(h["log_signal_std"])):
        ell = np.exp(np.array(h["log_lengthscales"][a]))
        sf2 = np.exp(2 * h["log_signal_std"][a])
        sn2 = np.exp(2 * h["log_noise_std"][a])
        xs, zs = x / ell, z / ell
        kf = sf2 * np.exp(-0.5 * ((xs[:, None, :] - xs[None, :, :]) ** 2).sum(-1))
        k = kf + sn2 * np.eye(n)
        ks = sf2 * np.exp(-0.5 * ((zs[:, None, :] - xs[None, :, :]) ** 2).sum(-1))
        kinv = np.linalg.inv(k)
        kinv = 0.5 * (kinv + kinv.T)
        a_exact = ks @ kinv
        var = sf2 - (a_exact * ks).sum(1) + sn2
        jac = (a_exact * ks) @ xs
        a32 = (ks.astype(np.float32) @ kinv.astype(np.float32)).astype(np.float64)
        var32 = sf2 - (a32 * ks).sum(1) + sn2
        jac32 = (a32 * ks) @ xs
        lower_inv = np.linalg.inv(np.linalg.cholesky(k))
        v32 = (ks.astype(np.float32) @ lower_inv.T.astype(np.float32)).astype(np.float64)
        var_white32 = sf2 - (v32 * v32).sum(1) + sn2
        lam = np.clip(np.linalg.eigvalsh(kf)[::-1], 0, None)
        tail = np.cumsum((lam ** 2)[::-1])[::-1]
        ranks = {}
        for tol in (1e-2, 1e-4, 1e-6):
            ok = sf2 * tail / sn2 ** 3 <= tol
            ranks[tol] = int(np.argmax(ok)) if ok.any() else n
        print(f"  output {a}: sf^2/sn^2 = {sf2 / sn2:9.3g}; float32 K* K^-1: variance rel. error "
              f"max {np.max(np.abs(var32 - var) / var):.2g}, median "
              f"{np.median(np.abs(var32 - var) / var):.2g}; Jacobian sums rel. error "
              f"{np.linalg.norm(jac32 - jac) / np.linalg.norm(jac):.2g}; whitened float32 "
              f"variance max {np.max(np.abs(var_white32 - var) / var):.2g}; low-rank r for "
              f"bound 1e-2/1e-4/1e-6: {ranks[1e-2]}/{ranks[1e-4]}/{ranks[1e-6]} of {n}")


if __name__ == "__main__":
    main()
