#!/usr/bin/env python3
"""Writes the two example scenarios of `totalgrad pilco propagate` (docs/pilco.md).

Pure Python (no numpy), deterministic (random.Random with fixed seeds). The
cart-pole is PILCO's (pilco-spec.md 1.2: l = m = M = 0.5, b = 0.1, g = 9.82,
dt = 0.1, zero-order hold), integrated with classical RK4, 100 substeps, in
our state order [s, beta, s_dot, beta_dot] (beta = 0 hanging, pi upright).
GP hyperparameters are PILCO's initialisation (pilco-spec.md 4.5): log l =
log std(inputs), log sf = log std(targets), log sn = log(std(targets) / 10),
std with N - 1. Run from the repository root:
    python3 docs/pilco-examples/make_examples.py
"""
import json
import math
import os
import random

L, M_POLE, M_CART, B, G, DT = 0.5, 0.5, 0.5, 0.1, 9.82, 0.1


def deriv(x, f):
    s, beta, v, w = x
    sb, cb = math.sin(beta), math.cos(beta)
    m, mc = M_POLE, M_CART
    vdot = (2 * m * L * w * w * sb + 3 * m * G * sb * cb + 4 * f - 4 * B * v) / (
        4 * (mc + m) - 3 * m * cb * cb)
    wdot = (-3 * m * L * w * w * sb * cb - 6 * (mc + m) * G * sb - 6 * (f - B * v) * cb) / (
        4 * L * (mc + m) - 3 * m * L * cb * cb)
    return [v, w, vdot, wdot]


def step(x, f, substeps=100):
    h = DT / substeps
    for _ in range(substeps):
        k1 = deriv(x, f)
        k2 = deriv([a + 0.5 * h * b for a, b in zip(x, k1)], f)
        k3 = deriv([a + 0.5 * h * b for a, b in zip(x, k2)], f)
        k4 = deriv([a + h * b for a, b in zip(x, k3)], f)
        x = [a + h / 6 * (b1 + 2 * b2 + 2 * b3 + b4) for a, b1, b2, b3, b4 in zip(x, k1, k2, k3, k4)]
    return x


def std(col):
    mean = sum(col) / len(col)
    return math.sqrt(sum((c - mean) ** 2 for c in col) / (len(col) - 1))


def gp_input(x, u, sin_cos):
    if sin_cos:
        return [x[0], x[2], x[3], math.sin(x[1]), math.cos(x[1]), u]
    return list(x) + [u]


def policy_input(x, sin_cos):
    return gp_input(x, 0.0, sin_cos)[:-1]


def pilco_init_hyp(inputs, targets):
    e = len(inputs[0])
    rows = []
    for a in range(len(targets[0])):
        sd = std([t[a] for t in targets])
        rows.append([math.log(std([r[j] for r in inputs])) for j in range(e)] +
                    [math.log(sd), math.log(sd / 10)])
    return rows


def rollouts(rng, mu0, sd0, episodes, steps, sin_cos, noise_std=0.01):
    """Random-force episodes (u ~ U(-10, 10)), as PILCO's first rollout;
    observation noise std 0.01 on every recorded state."""
    inputs, targets = [], []
    for _ in range(episodes):
        x = [m + sd0 * rng.gauss(0, 1) for m in mu0]
        obs = [a + noise_std * rng.gauss(0, 1) for a in x]
        for _ in range(steps):
            u = rng.uniform(-10, 10)
            x = step(x, u)
            nobs = [a + noise_std * rng.gauss(0, 1) for a in x]
            inputs.append(gp_input(obs, u, sin_cos))
            targets.append([b - a for a, b in zip(obs, nobs)])
            obs = nobs
    return inputs, targets


def write(name, doc):
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), name)
    with open(path, "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")
    print("wrote", path)


def swingup_sincos_tip():
    """PILCO's own cart-pole setting after its random rollout: sin/cos inputs,
    tip cost, hanging start, PILCO's initial policy in congp form."""
    rng = random.Random(1)
    mu0, sd0 = [0.0, 0.0, 0.0, 0.0], 0.1
    inputs, targets = rollouts(rng, mu0, sd0, episodes=1, steps=40, sin_cos=True)
    centres = [policy_input([m + sd0 * rng.gauss(0, 1) for m in mu0], True) for _ in range(10)]
    return {
        "angle_index": 1,
        "train_inputs": inputs,
        "train_targets": targets,
        "gp_log_hyp": pilco_init_hyp(inputs, targets),
        "prediction_includes_noise": False,
        "policy": {
            "centres": centres,
            "targets": [0.1 * rng.gauss(0, 1) for _ in range(10)],
            "log_lengthscales": [0.0, 0.0, 0.0, math.log(0.7), math.log(0.7)],
            "max_force": 10.0,
            "output_variance_jitter": 1e-6,
        },
        "mu0": mu0,
        "S0": [[0.01 if i == j else 0.0 for j in range(4)] for i in range(4)],
        "horizon": 40,
        "cost": {"type": "tip", "position_index": 0, "angle_index": 1,
                 "pendulum_length": 0.5, "width": 0.25},
    }


def balance_raw_angle():
    """The paper's particle-run setting: the GP and policy see the raw angle,
    angle cost, upright start, our weight parameterisation."""
    rng = random.Random(2)
    mu0, sd0 = [0.0, math.pi, 0.0, 0.0], 0.1
    inputs, targets = rollouts(rng, mu0, sd0, episodes=3, steps=15, sin_cos=False)
    centres = [[m + sd0 * rng.gauss(0, 1) for m in mu0] for _ in range(10)]
    return {
        "angle_index": None,
        "train_inputs": inputs,
        "train_targets": targets,
        "gp_log_hyp": pilco_init_hyp(inputs, targets),
        "prediction_includes_noise": False,
        "policy": {
            "centres": centres,
            "weights": [rng.uniform(-1, 1) / math.sqrt(10) for _ in range(10)],
            "log_lengthscales": [0.0, 0.0, 0.0, 0.0],
            "max_force": 10.0,
            "output_variance_jitter": 1e-6,
        },
        "mu0": mu0,
        "S0": [[0.01 if i == j else 0.0 for j in range(4)] for i in range(4)],
        "horizon": 30,
        "cost": {"type": "angle", "target": [0.0, math.pi, 0.0, 0.0], "Q": [1.0, 1.0, 0.0, 0.0]},
    }


if __name__ == "__main__":
    write("swingup_sincos_tip.json", swingup_sincos_tip())
    write("balance_raw_angle.json", balance_raw_angle())
