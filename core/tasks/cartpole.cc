#include "core/tasks/cartpole.h"

#include <cmath>

#include "absl/strings/str_cat.h"
#include "core/common/check.h"

namespace totalgrad::tasks {

const OptionTable<CartPoleParams>& CartPoleParams::Table() {
  static const OptionTable<CartPoleParams>* table = [] {
    auto* t = new OptionTable<CartPoleParams>();
    // Ranges: a plant the integrator and the GP can still follow, wide
    // around the paper's (tests/core/stability covers masses of 1e-4 kg,
    // a pole of 1 mm and friction of 1e4).
    t->Double("cart_mass", &CartPoleParams::cart_mass, {1e-6, 1e6, "kg"})
        .Double("pole_mass", &CartPoleParams::pole_mass, {1e-6, 1e6, "kg"})
        .Double("pole_length", &CartPoleParams::pole_length, {1e-4, 1e3, "m"})
        .Double("friction", &CartPoleParams::friction, {0, 1e6, "cart friction, N s/m"})
        .Double("dt", &CartPoleParams::dt, {1e-5, 10, "control period, s"})
        .Double("max_force", &CartPoleParams::max_force, {0, 1e6, "N"})
        .Double("gravity", &CartPoleParams::gravity, {0, 1e3, "m/s^2"})
        .Nest(&CartPoleParams::integrator, ode::IntegratorOptions::Table());
    return t;
  }();
  return *table;
}

// PILCO's dynamics_cp (pilco-spec.md 1.2) with x = s, v = s_dot,
// omega = beta_dot, theta = beta. Derived from the Lagrangian of a cart with a
// uniform rod (inertia m l^2 / 12 about its centre, centre at l / 2) and
// viscous cart friction; Energy() below is that Lagrangian's energy, so
// dE/dt = (force - friction * s_dot) * s_dot, which the tests check.
State CartPole::Derivative(const State& x, double force) const {
  const double mc = params_.cart_mass;
  const double mp = params_.pole_mass;
  const double l = params_.pole_length;
  const double b = params_.friction;
  const double g = params_.gravity;
  const double total = mc + mp;
  const double s_dot = x(2);
  const double beta = x(1);
  const double beta_dot = x(3);
  const double sn = std::sin(beta);
  const double cs = std::cos(beta);
  const double denominator = 4.0 * total - 3.0 * mp * cs * cs;  // > 0: 4(M+m) > 3m
  const double s_ddot =
      (2.0 * mp * l * beta_dot * beta_dot * sn + 3.0 * mp * g * sn * cs + 4.0 * force -
       4.0 * b * s_dot) /
      denominator;
  const double beta_ddot = (-3.0 * mp * l * beta_dot * beta_dot * sn * cs - 6.0 * total * g * sn -
                            6.0 * (force - b * s_dot) * cs) /
                           (l * denominator);
  State dxdt;
  dxdt << s_dot, beta_dot, s_ddot, beta_ddot;
  return dxdt;
}

void CartPole::Derivative(const Vector& x, const Vector& u, Vector* dxdt) const {
  TG_CHECK(x.size() == kCartPoleStateDim && u.size() == 1);
  *dxdt = Derivative(State(x), u(0));
}

double CartPole::Energy(const State& x) const {
  const double mp = params_.pole_mass;
  const double l = params_.pole_length;
  const double total = params_.cart_mass + mp;
  const double s_dot = x(2);
  const double beta = x(1);
  const double beta_dot = x(3);
  // Kinetic energy of cart and rod plus the rod's potential energy, zero
  // potential at the pivot height (pilco-spec.md 1.2).
  return 0.5 * total * s_dot * s_dot + mp * l * l * beta_dot * beta_dot / 6.0 +
         0.5 * mp * l * (s_dot * beta_dot - params_.gravity) * std::cos(beta);
}

absl::Status CartPole::Step(const State& x, double force, State* next,
                            ode::IntegrationReport* report) const {
  TG_CHECK(next != nullptr);
  if (!x.allFinite()) {
    return absl::InvalidArgumentError(absl::StrCat("cart-pole step: non-finite state [", x(0),
                                                   ", ", x(1), ", ", x(2), ", ", x(3), "]"));
  }
  if (!std::isfinite(force)) {
    return absl::InvalidArgumentError(absl::StrCat("cart-pole step: non-finite force ", force));
  }
  const ode::Rhs rhs = [this, force](const Vector& z, Vector* dzdt) {
    *dzdt = Derivative(State(z), force);
  };
  Vector z = x;
  const absl::Status status = ode::IntegrateAdaptive(rhs, params_.dt, params_.integrator, &z, report);
  if (!status.ok()) {
    return absl::Status(status.code(), absl::StrCat("cart-pole step: ", status.message()));
  }
  *next = z;
  return absl::OkStatus();
}

}  // namespace totalgrad::tasks
