#!/usr/bin/python3
"""One RP gradient iteration in PyTorch autograd: the peer of `totalgrad bench iteration`.

Issue 11 asks that our default path be at least 5x faster than a straightforward
vectorised PyTorch autograd script of the same iteration (Debian's python3-torch,
float64, one thread, K^-1 precomputed per episode). This is that script. It reads
the problem, random numbers and our result from `totalgrad bench dump-iteration`,
first checks that it computes the same objective J and gradient dJ/dtheta as our
RpEstimator (relative error <= 1e-8, or it exits with status 1), and then times
one iteration: the forward rollout over H steps with all particles batched
(policy with its saturation, GP predictive mean and variance, reparameterised
step, cost) and .backward() to the policy parameters.

Not timed, as in an episode of policy optimisation where they are fixed for all
gradient steps: K^-1 and beta = K^-1 y per output (Cholesky in float64) and the
length-scale-scaled training inputs. Also not timed: drawing the standard
normals, which are read from the dump so that both sides use the same numbers
(ours draws them inside its timed iteration; 37k normals at P = 300, H = 30 are
a negligible part of it, and leaving them out favours this script).

How to run the comparison (on a quiet machine; Debian's interpreter has torch,
a `python3` earlier on PATH may not):

    B=build/client/totalgrad
    for N in 120 450; do
      $B bench iteration --data $N --particles 300 --horizon 30 --repeats 7
      $B bench dump-iteration --data $N --particles 300 --horizon 30 --out /tmp/rp-$N.json
      /usr/bin/python3 bench/torch_rp_iteration.py /tmp/rp-$N.json --repeats 7
    done

The ratio is this script's median seconds (timing.wall_seconds_median, or the
CPU seconds, which are one thread's here too) over bench iteration's
seconds_per_iteration (or cpu_seconds_per_iteration). Both run one BLAS thread:
this script pins OpenBLAS, OpenMP and torch to one thread before torch loads.

`--check-only` stops after the agreement check (used by the ctest
client_torch_rp_agreement, at a small size).
"""

import os

# Torch's BLAS here is Debian's OpenBLAS (pthreads), which torch.set_num_threads
# does not reach; its pool size is fixed when the library loads.
for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_variable] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import torch  # noqa: E402

# Predictive variances below this are round-off; ours floors them here
# (kVarianceFloor in core/gp/gp.cc, documented in core/gp/gp.h).
VARIANCE_FLOOR = 1e-12
# Agreement required of J and of the gradient (norm-wise) with ours.
RELATIVE_TOLERANCE = 1e-8
DTYPE = torch.float64


def tensor(values):
    return torch.tensor(values, dtype=DTYPE)


class Problem:
    """The dumped iteration as float64 tensors, with the per-episode GP precomputation."""

    def __init__(self, doc):
        if doc.get("format") != "totalgrad-rp-iteration" or doc.get("version") != 1:
            raise ValueError("not a totalgrad-rp-iteration version 1 file")
        self.data = doc["data"]
        self.particles = doc["particles"]
        self.horizon = doc["horizon"]

        gp = doc["gp"]
        inputs = tensor(gp["inputs"])                      # N x E
        targets = tensor(gp["targets"])                    # N x D
        self.inv_lengthscales = torch.exp(-tensor(gp["log_lengthscales"]))  # D x E
        self.signal_var = torch.exp(2 * tensor(gp["log_signal_std"]))       # D
        noise_var = torch.exp(2 * tensor(gp["log_noise_std"]))              # D
        jitter = tensor(gp["jitter"])                                       # D
        self.prior_var = self.signal_var + gp["noise_variance_multiplier"] * noise_var

        # Per output a: X / l_a and K_a = k_a(X, X) + (sn_a^2 + jitter_a) I.
        self.scaled_inputs = inputs[None] * self.inv_lengthscales[:, None, :]  # D x N x E
        self.scaled_sq_norms = (self.scaled_inputs ** 2).sum(-1)               # D x N
        k = self.se_kernel(self.scaled_inputs, self.scaled_sq_norms)
        n = inputs.shape[0]
        k = k + (noise_var + jitter)[:, None, None] * torch.eye(n, dtype=DTYPE)
        chol = torch.linalg.cholesky(k)
        identity = torch.eye(n, dtype=DTYPE).expand(k.shape[0], n, n)
        k_inverse = torch.cholesky_solve(identity, chol)
        self.k_inverse = 0.5 * (k_inverse + k_inverse.transpose(1, 2))  # D x N x N
        self.beta = torch.cholesky_solve(targets.T[:, :, None], chol)   # D x N x 1

        policy = doc["policy"]
        self.centres = tensor(policy["centres"])                    # C x S
        self.policy_log_lengthscales = tensor(policy["log_lengthscales"])  # S
        self.weights = tensor(policy["weights"])                    # C
        self.max_force = policy["max_force"]

        cost = doc["cost"]
        self.cost_type = cost["type"]
        if self.cost_type == "angle":
            self.cost_target = tensor(cost["target"])
            self.cost_q = tensor(cost["q_diagonal"])
        elif self.cost_type == "tip":
            self.tip_target_position = cost["target_position"]
            self.tip_length = cost["pendulum_length"]
            self.tip_width = cost["width"]
        else:
            raise ValueError(f"unknown cost type {self.cost_type!r}")

        self.mu0 = tensor(doc["mu0"])
        self.initial_std = tensor(doc["initial_std"])
        self.x0_normals = tensor(doc["normals"]["x0"])  # P x S
        self.eps = tensor(doc["normals"]["eps"])        # H x P x S

        gradient = doc["gradient"]
        self.our_objective = doc["objective"]
        self.our_gradient = torch.cat([tensor(gradient["centres"]).flatten(),
                                       tensor(gradient["log_lengthscales"]),
                                       tensor(gradient["weights"])])

    def se_kernel(self, scaled_queries, query_sq_norms):
        """sf_a^2 exp(-|q - x_n|^2 / 2) per output: D x Q x N from D x Q x E scaled queries."""
        sq_dist = (query_sq_norms[:, :, None] + self.scaled_sq_norms[:, None, :]
                   - 2 * scaled_queries @ self.scaled_inputs.transpose(1, 2))
        # The expanded square can come out slightly negative by cancellation.
        return self.signal_var[:, None, None] * torch.exp(-0.5 * sq_dist.clamp_min(0))

    def policy_force(self, states, centres, log_lengthscales, weights):
        scaled_diff = (states[:, None, :] - centres[None]) * torch.exp(-log_lengthscales)
        activation = torch.exp(-0.5 * (scaled_diff ** 2).sum(-1)) @ weights  # P
        return self.max_force * (9 * torch.sin(activation) + torch.sin(3 * activation)) / 8

    def cost(self, states):
        if self.cost_type == "angle":
            return 1 - torch.exp(-(self.cost_q * (states - self.cost_target) ** 2).sum(-1))
        length = self.tip_length
        dx = states[:, 0] - self.tip_target_position + length * torch.sin(states[:, 1])
        dy = length * (torch.cos(states[:, 1]) + 1)
        return 1 - torch.exp(-(dx ** 2 + dy ** 2) / (2 * self.tip_width ** 2))

    def objective(self, centres, log_lengthscales, weights):
        """J = (1/P) sum_i sum_{t=1..H} c(x_t^i) of the reparameterised rollout."""
        x = self.x0_normals * self.initial_std + self.mu0
        total = 0
        for t in range(self.horizon):
            force = self.policy_force(x, centres, log_lengthscales, weights)
            z = torch.cat([x, force[:, None]], dim=1)             # P x E
            scaled_z = z[None] * self.inv_lengthscales[:, None, :]  # D x P x E
            kstar = self.se_kernel(scaled_z, (scaled_z ** 2).sum(-1))  # D x P x N
            mean = (kstar @ self.beta)[:, :, 0]                     # D x P
            quadratic = ((kstar @ self.k_inverse) * kstar).sum(-1)  # D x P
            variance = (self.prior_var[:, None] - quadratic).clamp_min(VARIANCE_FLOOR)
            x = x + mean.T + variance.sqrt().T * self.eps[t]
            total = total + self.cost(x).sum()
        return total / self.particles


def policy_leaves(problem):
    return [problem.centres.clone().requires_grad_(True),
            problem.policy_log_lengthscales.clone().requires_grad_(True),
            problem.weights.clone().requires_grad_(True)]


def rp_iteration(problem, leaves):
    """One iteration: forward rollout and backward pass; returns (J, flat gradient)."""
    for leaf in leaves:
        leaf.grad = None
    objective = problem.objective(*leaves)
    objective.backward()
    return objective.detach(), torch.cat([leaf.grad.flatten() for leaf in leaves])


def parameter_name(index, num_basis, state_dim):
    if index < num_basis * state_dim:
        return f"centres[{index // state_dim}][{index % state_dim}]"
    index -= num_basis * state_dim
    if index < state_dim:
        return f"log_lengthscales[{index}]"
    return f"weights[{index - state_dim}]"


def check_agreement(problem, leaves):
    """Compares J and the gradient with ours; returns (report, agrees)."""
    objective, gradient = rp_iteration(problem, leaves)
    ours = problem.our_gradient
    objective_error = abs(objective.item() - problem.our_objective) / abs(problem.our_objective)
    gradient_error = (torch.linalg.norm(gradient - ours) / torch.linalg.norm(ours)).item()
    component_error = (gradient - ours).abs() / ours.abs()
    num_basis, state_dim = problem.centres.shape
    worst = torch.argsort(component_error, descending=True)[:5].tolist()
    report = {
        "objective_ours": problem.our_objective,
        "objective_torch": objective.item(),
        "objective_relative_error": objective_error,
        "gradient_norm_ours": torch.linalg.norm(ours).item(),
        "gradient_norm_torch": torch.linalg.norm(gradient).item(),
        "gradient_relative_error": gradient_error,
        "gradient_max_component_relative_error": component_error.max().item(),
        "worst_components": [{"parameter": parameter_name(i, num_basis, state_dim),
                              "ours": ours[i].item(), "torch": gradient[i].item(),
                              "relative_error": component_error[i].item()} for i in worst],
        "tolerance": RELATIVE_TOLERANCE,
    }
    agrees = (math.isfinite(objective_error) and math.isfinite(gradient_error)
              and objective_error <= RELATIVE_TOLERANCE and gradient_error <= RELATIVE_TOLERANCE)
    if not agrees:
        print("torch_rp_iteration: DISAGREEMENT with totalgrad's RP iteration "
              f"(J relative error {objective_error:.3e}, gradient {gradient_error:.3e}, "
              f"tolerance {RELATIVE_TOLERANCE:g}); all components (ours, torch):", file=sys.stderr)
        for i in range(ours.numel()):
            print(f"  {parameter_name(i, num_basis, state_dim):22s} {ours[i].item(): .17e} "
                  f"{gradient[i].item(): .17e}", file=sys.stderr)
    return report, agrees


def time_iterations(problem, leaves, repeats):
    rp_iteration(problem, leaves)  # warm-up: allocator and autograd caches
    wall, cpu = [], []
    for _ in range(repeats):
        wall_start, cpu_start = time.perf_counter(), time.process_time()
        rp_iteration(problem, leaves)
        cpu.append(time.process_time() - cpu_start)
        wall.append(time.perf_counter() - wall_start)
    return {"repeats": repeats,
            "wall_seconds_median": statistics.median(wall),
            "wall_seconds_min": min(wall),
            "cpu_seconds_median": statistics.median(cpu),
            "cpu_seconds_min": min(cpu)}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("dump", help="JSON written by `totalgrad bench dump-iteration`")
    parser.add_argument("--repeats", type=int, default=7, help="timed iterations (default 7)")
    parser.add_argument("--check-only", action="store_true",
                        help="only check agreement with ours, do not time")
    args = parser.parse_args()
    if args.repeats < 1:
        parser.error("--repeats must be >= 1")

    torch.set_num_threads(1)
    torch.set_num_interop_threads(1)
    with open(args.dump) as f:
        problem = Problem(json.load(f))
    leaves = policy_leaves(problem)

    check, agrees = check_agreement(problem, leaves)
    result = {"data": problem.data, "particles": problem.particles, "horizon": problem.horizon,
              "torch_version": torch.__version__, "threads": torch.get_num_threads(),
              "dtype": "float64", "check": check}
    if agrees and not args.check_only:
        result["timing"] = time_iterations(problem, leaves, args.repeats)
    print(json.dumps(result, indent=2))
    return 0 if agrees else 1


if __name__ == "__main__":
    sys.exit(main())
