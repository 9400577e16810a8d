// A plant of a scene: D state dimensions, F controls, the right-hand side
// dx/dt = f(x, u), integrated over one control period dt with the controls
// held (zero-order hold) by the adaptive integrator (ode/integrator.h).
//
// Plants (one class per set of equations; a scene that only changes numbers
// of an existing plant needs no new class):
//   Pendulum            [dtheta, theta], 1 torque          (pendulum.h)
//   CartPole            [s, beta, s_dot, beta_dot], 1 force (cartpole.h)
//   CartDoublePendulum  [x, dx, dtheta1, dtheta2, theta1, theta2], 1 force
//   DoublePendulum      [dtheta1, dtheta2, theta1, theta2], torques through an
//                       input map (two torques; the pendubot's one, at joint 1)
//   Unicycle            PILCO's 12 ODE states, 2 torques (unicycle.h; not yet
//                       a scene of the catalog: its cost, linear policy and
//                       augmented state come with it)
// Units SI, angles in radians, never wrapped.
//
// Thread safety: plants are immutable after construction; const methods are
// thread-safe.
#ifndef TOTALGRAD_CORE_TASKS_PLANT_H_
#define TOTALGRAD_CORE_TASKS_PLANT_H_

#include "absl/status/status.h"
#include "core/common/types.h"
#include "core/ode/integrator.h"

namespace totalgrad::tasks {

class Plant {
 public:
  Plant(double dt, const ode::IntegratorOptions& integrator) : dt_(dt), integrator_(integrator) {}
  virtual ~Plant() = default;

  virtual int state_dim() const = 0;    // D
  virtual int control_dim() const = 0;  // F
  // f(x, u) for x (D) and u (F); *dxdt is resized to D.
  virtual void Derivative(const Vector& x, const Vector& u, Vector* dxdt) const = 0;
  // Total mechanical energy (J), conserved without friction and controls.
  virtual double Energy(const Vector& x) const = 0;

  double dt() const { return dt_; }
  const ode::IntegratorOptions& integrator() const { return integrator_; }

  // One control period dt from x with u held. On success writes x(dt) into
  // *next (resized); on failure leaves it unchanged. InvalidArgument for a
  // non-finite or wrongly sized x or u; otherwise the integrator's errors
  // (ode::IntegrateAdaptive). `report` may be null.
  absl::Status Step(const Vector& x, const Vector& u, Vector* next,
                    ode::IntegrationReport* report = nullptr) const;

 private:
  double dt_;
  ode::IntegratorOptions integrator_;
};

}  // namespace totalgrad::tasks

#endif  // TOTALGRAD_CORE_TASKS_PLANT_H_
