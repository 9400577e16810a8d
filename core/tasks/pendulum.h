// The pendulum of PILCO's swing-up scene (scenarios/pendulum at a0b48b7): a
// uniform rod on a pivot with viscous friction, driven by a torque.
//
// State x = [dtheta, theta] (PILCO's order): angular velocity (rad/s), angle
// (rad, 0 hanging, pi upright). Control u: torque (N m).
//   d(dtheta)/dt = (u - b dtheta - m g l sin(theta) / 2) / (m l^2 / 3)
//   d(theta)/dt  = dtheta
// Energy: m l^2 dtheta^2 / 6 - m g l cos(theta) / 2 (zero at the pivot's
// height), so dE/dt = (u - b dtheta) dtheta.
#ifndef TOTALGRAD_CORE_TASKS_PENDULUM_H_
#define TOTALGRAD_CORE_TASKS_PENDULUM_H_

#include "core/tasks/plant.h"

namespace totalgrad::tasks {

struct PendulumParams {
  double mass = 1.0;      // kg
  double length = 1.0;    // m
  double friction = 0.01; // N m s / rad
  double gravity = 9.82;  // m/s^2
};

class Pendulum final : public Plant {
 public:
  Pendulum(const PendulumParams& params, double dt, const ode::IntegratorOptions& integrator)
      : Plant(dt, integrator), params_(params) {}
  int state_dim() const override { return 2; }
  int control_dim() const override { return 1; }
  void Derivative(const Vector& x, const Vector& u, Vector* dxdt) const override;
  double Energy(const Vector& x) const override;
  const PendulumParams& params() const { return params_; }

 private:
  PendulumParams params_;
};

}  // namespace totalgrad::tasks

#endif  // TOTALGRAD_CORE_TASKS_PENDULUM_H_
