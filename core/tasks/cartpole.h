// The cart-pole plant with PILCO's constants (pilco-spec.md section 1), in the
// paper's state order.
//
// State x = [s, beta, s_dot, beta_dot]: cart position (m), pole angle (rad),
// cart velocity (m/s), angular velocity (rad/s). beta = 0 hangs down, beta = pi
// is upright; beta is never wrapped. The control is the horizontal force on
// the cart in newtons, held constant over one control period (zero-order
// hold). The pole is a uniform rod of length pole_length.
//
// Thread safety: const methods are thread-safe.
#ifndef TOTALGRAD_CORE_TASKS_CARTPOLE_H_
#define TOTALGRAD_CORE_TASKS_CARTPOLE_H_

#include <Eigen/Core>

#include "absl/status/status.h"
#include "core/common/option_table.h"
#include "core/common/types.h"
#include "core/ode/integrator.h"
#include "core/tasks/plant.h"

namespace totalgrad::tasks {

inline constexpr int kCartPoleStateDim = 4;
using State = Eigen::Vector4d;

struct CartPoleParams {
  double cart_mass = 0.5;    // kg
  double pole_mass = 0.5;    // kg
  double pole_length = 0.5;  // m
  double friction = 0.1;     // N/(m/s), cart on ground
  double gravity = 9.82;     // m/s^2
  double dt = 0.1;           // s, control period
  double max_force = 10.0;   // N, bound of the policy's saturated output
  ode::IntegratorOptions integrator;

  // Trial option keys cart_mass, pole_mass, pole_length, friction, dt,
  // max_force, gravity and the integrator's (ode::IntegratorOptions::Table()).
  static const OptionTable<CartPoleParams>& Table();
  bool operator==(const CartPoleParams&) const = default;
};

class CartPole final : public Plant {
 public:
  explicit CartPole(const CartPoleParams& params = {})
      : Plant(params.dt, params.integrator), params_(params) {}

  const CartPoleParams& params() const { return params_; }

  // dx/dt at state x under force (N).
  State Derivative(const State& x, double force) const;

  // Total mechanical energy (J), conserved when friction = 0 and force = 0.
  double Energy(const State& x) const;

  // The Plant interface (D = 4, F = 1): the same equations, the same bits.
  int state_dim() const override { return kCartPoleStateDim; }
  int control_dim() const override { return 1; }
  void Derivative(const Vector& x, const Vector& u, Vector* dxdt) const override;
  double Energy(const Vector& x) const override { return Energy(State(x)); }
  using Plant::Step;

  // Integrates one control period dt with the force held constant. On success
  // writes the next state into *next. Fails (leaving *next unchanged) on a
  // non-finite input or when the adaptive integrator cannot meet its
  // tolerances; the status names the cause. `report` may be null.
  // Codes: InvalidArgument for a non-finite state or force; otherwise the
  // integrator's code (see ode::IntegrateAdaptive), message prefixed with
  // "cart-pole step: ". Integrates with params().integrator over params().dt.
  absl::Status Step(const State& x, double force, State* next,
                    ode::IntegrationReport* report = nullptr) const;

 private:
  CartPoleParams params_;
};

}  // namespace totalgrad::tasks

#endif  // TOTALGRAD_CORE_TASKS_CARTPOLE_H_
