#!/usr/bin/env python3
"""Writes the general-form examples of `totalgrad pilco propagate` (docs/pilco.md).

The general form (a file with "angle_indices") in PILCO's conventions: z = [x,
sin x_a1, cos x_a1, ...], index sets into z, F controls, optional FITC inducing
inputs, lossSat on z. The transitions come from the real plants, integrated by
`totalgrad simulate --scene NAME --json` (random controls U(-u_max, u_max),
start drawn from the scene's start distribution, observation noise std 0.01 on
every recorded state); the scene's index sets, Q, widths and target from
`totalgrad scenes --json`. GP hyperparameters are PILCO's initialisation (log l =
log std(inputs), log sf = log std(targets), log sn = log(std(targets) / 10)).
Deterministic (numpy's default_rng with fixed seeds). Run from the repository
root, with the CLI built:
    python3 docs/pilco-examples/make_general_examples.py [build/client/totalgrad]
"""
import json
import os
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def scenes(cli):
    out = subprocess.run([cli, "scenes", "--json"], check=True, capture_output=True, text=True)
    return {s["name"]: s for s in json.loads(out.stdout)}


def simulate(cli, scene, start, controls):
    """States (H + 1) x D of the noise-free plant under controls H x F."""
    out = subprocess.run(
        [cli, "simulate", "--scene", scene, "--json",
         "--start", ",".join(repr(float(v)) for v in start),
         "--forces", ",".join(repr(float(v)) for v in np.asarray(controls).ravel())],
        check=True, capture_output=True, text=True)
    return np.array(json.loads(out.stdout)["states"])


def augment(x, angles):
    """z = [x, sin x_a1, cos x_a1, ...] of a state (or of rows of states)."""
    x = np.atleast_2d(x)
    parts = [x]
    for a in angles:
        parts += [np.sin(x[:, [a]]), np.cos(x[:, [a]])]
    return np.hstack(parts)


def data(cli, sc, rng, episodes, steps, dyni):
    d, f = sc["state_dim"], sc["control_dim"]
    umax = np.array(sc["max_control"])
    inputs, targets = [], []
    for _ in range(episodes):
        start = np.array(sc["mu0"]) + np.array(sc["start_std"]) * rng.standard_normal(d)
        u = rng.uniform(-1, 1, size=(steps, f)) * umax
        states = simulate(cli, sc["name"], start, u)
        obs = states + 0.01 * rng.standard_normal(states.shape)
        z = augment(obs[:-1], sc["angle_indices"])
        inputs.append(np.hstack([z[:, dyni], u]))
        targets.append(obs[1:] - obs[:-1])
    return np.vstack(inputs), np.vstack(targets)


def init_hyp(x, y):
    sx = np.std(x, axis=0, ddof=1)
    sy = np.std(y, axis=0, ddof=1)
    return np.hstack([np.tile(np.log(sx), (y.shape[1], 1)), np.log(sy)[:, None],
                      np.log(sy / 10)[:, None]])


def centres(sc, rng, c, poli):
    x = np.array(sc["mu0"]) + np.array(sc["start_std"]) * rng.standard_normal((c, sc["state_dim"]))
    return augment(x, sc["angle_indices"])[:, poli]


def write(name, doc):
    path = os.path.join(HERE, name)
    with open(path, "w") as fh:
        json.dump(doc, fh, indent=1)
        fh.write("\n")
    print("wrote", path)


def double_pendulum(cli, sc):
    """Two angles, two torques, full GP, PILCO's pseudo-targets (C x 2),
    shared length-scales."""
    rng = np.random.default_rng(3)
    dyni = poli = sc["dynamics_inputs"]
    x, y = data(cli, sc, rng, episodes=2, steps=25, dyni=dyni)
    c = 8
    ll = np.zeros(len(poli))
    ll[-4:] = np.log(0.7)
    return {
        "angle_indices": sc["angle_indices"],
        "dynamics_inputs": dyni,
        "policy_inputs": poli,
        "train_inputs": x.tolist(),
        "train_targets": y.tolist(),
        "gp_log_hyp": init_hyp(x, y).tolist(),
        "policy": {
            "centres": centres(sc, rng, c, poli).tolist(),
            "targets": (0.1 * rng.standard_normal((c, 2))).tolist(),
            "log_lengthscales": ll.tolist(),
            "max_force": sc["max_control"],
        },
        "mu0": sc["mu0"],
        "S0": np.diag(np.square(sc["start_std"])).tolist(),
        "horizon": 15,
        "cost": {"type": "saturating", "target": sc["target"], "Q": sc["saturating_cost"]["Q"],
                 "width": sc["saturating_cost"]["widths"]},
    }


def cart_double_pendulum_fitc(cli, sc):
    """Two angles, one force, FITC with 25 inducing inputs (a random subset of
    the 80 training inputs, as PILCO starts them), our weights, two widths,
    the scene's Q towards the hanging start."""
    rng = np.random.default_rng(4)
    dyni = poli = sc["dynamics_inputs"]
    x, y = data(cli, sc, rng, episodes=2, steps=40, dyni=dyni)
    inducing = x[rng.choice(x.shape[0], size=25, replace=False)]
    c = 6
    ll = np.zeros(len(poli))
    ll[-4:] = np.log(0.7)
    return {
        "angle_indices": sc["angle_indices"],
        "dynamics_inputs": dyni,
        "policy_inputs": poli,
        "train_inputs": x.tolist(),
        "train_targets": y.tolist(),
        "inducing_inputs": inducing.tolist(),
        "gp_log_hyp": init_hyp(x, y).tolist(),
        "policy": {
            "centres": centres(sc, rng, c, poli).tolist(),
            "weights": rng.uniform(-1, 1, size=c).tolist(),
            "log_lengthscales": ll.tolist(),
            "max_force": sc["max_control"],
        },
        "mu0": sc["mu0"],
        "S0": np.diag(np.square(sc["start_std"])).tolist(),
        "horizon": 20,
        # Target the hanging start (upright costs about 1 everywhere from a
        # hanging start with a random policy: a flat J checks little).
        "cost": {"type": "saturating", "target": sc["mu0"], "Q": sc["saturating_cost"]["Q"],
                 "width": [0.5, 1.0]},
    }


def pendulum_own_dynamics_inputs(cli, sc):
    """One angle, one torque, a GP that also sees the raw angle (dynamics
    inputs [dtheta, theta, sin, cos] beside the policy's [dtheta, sin, cos]),
    pseudo-targets, widths [0.5, 1]."""
    rng = np.random.default_rng(5)
    dyni = [0, 1, 2, 3]
    poli = sc["policy_inputs"]
    x, y = data(cli, sc, rng, episodes=2, steps=20, dyni=dyni)
    c = 6
    return {
        "angle_indices": sc["angle_indices"],
        "dynamics_inputs": dyni,
        "policy_inputs": poli,
        "train_inputs": x.tolist(),
        "train_targets": y.tolist(),
        "gp_log_hyp": init_hyp(x, y).tolist(),
        "policy": {
            "centres": centres(sc, rng, c, poli).tolist(),
            "targets": (0.1 * rng.standard_normal(c)).tolist(),
            "log_lengthscales": [0.0, np.log(0.7), np.log(0.7)],
            "max_force": sc["max_control"],
        },
        "mu0": sc["mu0"],
        "S0": np.diag(np.square(sc["start_std"])).tolist(),
        "horizon": 25,
        "cost": {"type": "saturating", "target": sc["target"], "Q": sc["saturating_cost"]["Q"],
                 "width": [0.5, 1.0]},
    }


def double_pendulum_per_control(cli, sc):
    """Two angles, two torques, one row of policy length-scales per torque
    (PILCO's per-output gp2 hyperparameters), FITC with 20 inducing inputs,
    pseudo-targets C x 2."""
    rng = np.random.default_rng(6)
    dyni = poli = sc["dynamics_inputs"]
    x, y = data(cli, sc, rng, episodes=2, steps=25, dyni=dyni)
    inducing = x[rng.choice(x.shape[0], size=20, replace=False)]
    c = 8
    ll = np.zeros((2, len(poli)))
    ll[:, -4:] = np.log(0.7)
    ll += 0.3 * rng.standard_normal(ll.shape)
    return {
        "angle_indices": sc["angle_indices"],
        "dynamics_inputs": dyni,
        "policy_inputs": poli,
        "train_inputs": x.tolist(),
        "train_targets": y.tolist(),
        "inducing_inputs": inducing.tolist(),
        "gp_log_hyp": init_hyp(x, y).tolist(),
        "policy": {
            "centres": centres(sc, rng, c, poli).tolist(),
            "targets": (0.1 * rng.standard_normal((c, 2))).tolist(),
            "log_lengthscales": ll.tolist(),
            "max_force": sc["max_control"],
        },
        "mu0": sc["mu0"],
        "S0": np.diag(np.square(sc["start_std"])).tolist(),
        "horizon": 15,
        "cost": {"type": "saturating", "target": sc["target"], "Q": sc["saturating_cost"]["Q"],
                 "width": sc["saturating_cost"]["widths"]},
    }


def unicycle_gp_state(x, wheel_radius):
    """The unicycle's GP state [dtheta, dphi, dpsiw, dpsif, dpsit, xc, yc,
    theta, phi, psif] of ODE states (rows, PILCO's odei order): (xc, yc) =
    -R(phi)^T (x, y), the origin in the unicycle's coordinates."""
    x = np.atleast_2d(x)
    c, s = np.cos(x[:, 8]), np.sin(x[:, 8])
    xc = -(c * x[:, 5] + s * x[:, 6])
    yc = -(-s * x[:, 5] + c * x[:, 6])
    return np.column_stack([x[:, :5], xc, yc, x[:, 7], x[:, 8], x[:, 10]])


def unicycle_linear(cli, sc):
    """The unicycle's sets: the linear policy on the 10-entry GP state, the
    GP on 9 of them (not the yaw) and both torques, full GP, loss_unicycle.
    Transitions from short rollouts with random torques of a fifth of the
    bounds (PILCO's initial rollouts), observation noise std 0.003."""
    rng = np.random.default_rng(7)
    umax = np.array(sc["max_control"])
    rw = sc["unicycle_cost"]["wheel_radius"]
    dyni = sc["full_state"]["dynamics_inputs"]  # into the GP state, as PILCO's dyni
    d = len(sc["full_state"]["policy_inputs"])
    inputs, targets = [], []
    for _ in range(3):
        start = np.array(sc["mu0"]) + np.array(sc["start_std"]) * rng.standard_normal(12)
        u = rng.uniform(-1, 1, size=(10, 2)) * umax / 5
        states = unicycle_gp_state(simulate(cli, "unicycle", start, u), rw)
        obs = states + 0.003 * rng.standard_normal(states.shape)
        inputs.append(np.hstack([obs[:-1][:, dyni], u]))
        targets.append(obs[1:] - obs[:-1])
    x, y = np.vstack(inputs), np.vstack(targets)
    # The GP state's start spread: xc, yc have x's and y's at yaw 0.
    start_std = np.array(sc["start_std"])[[0, 1, 2, 3, 4, 5, 6, 7, 8, 10]]
    return {
        "angle_indices": [],
        "dynamics_inputs": dyni,
        "policy_inputs": list(range(d)),
        "train_inputs": x.tolist(),
        "train_targets": y.tolist(),
        "gp_log_hyp": init_hyp(x, y).tolist(),
        "policy": {
            "type": "linear",
            "w": (0.5 * rng.standard_normal((2, d))).tolist(),
            "b": (0.1 * rng.standard_normal(2)).tolist(),
            "max_force": sc["max_control"],
        },
        "mu0": [0.0] * d,
        "S0": np.diag(np.square(start_std)).tolist(),
        "horizon": 10,
        "cost": {"type": "unicycle", "wheel_radius": rw,
                 "rod_length": sc["unicycle_cost"]["rod_length"],
                 "width": sc["unicycle_cost"]["widths"]},
    }


if __name__ == "__main__":
    cli = sys.argv[1] if len(sys.argv) > 1 else "build/client/totalgrad"
    sc = scenes(cli)
    write("general_double_pendulum.json", double_pendulum(cli, sc["double-pendulum"]))
    write("general_cdp_fitc.json", cart_double_pendulum_fitc(cli, sc["cart-double-pendulum"]))
    write("general_pendulum_dyni.json", pendulum_own_dynamics_inputs(cli, sc["pendulum"]))
    write("general_double_pendulum_per_control.json",
          double_pendulum_per_control(cli, sc["double-pendulum"]))
    write("general_unicycle_linear.json", unicycle_linear(cli, sc["unicycle"]))
