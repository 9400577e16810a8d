// The double pendulum of PILCO's double-pendulum and pendubot scenes
// (scenarios/doublePendulum, scenarios/pendubot at a0b48b7): two uniform
// rods (inertia I_i = m_i l_i^2 / 12 about their centres) in series, no joint
// friction, torques at the joints through an input map B (2 x F): the double
// pendulum actuates both joints (B = I, F = 2), the pendubot the first only
// (B = [1; 0], F = 1).
//
// State x = [dtheta1, dtheta2, theta1, theta2] (PILCO's order), angles
// absolute, 0 upright, pi hanging. With tau = B u and
// A [d(dtheta1), d(dtheta2)]/dt = r:
//   A = [[l1^2 (m1/4 + m2) + I1, m2 l1 l2 cos(th1 - th2) / 2],
//        [m2 l1 l2 cos(th1 - th2) / 2, l2^2 m2 / 4 + I2]]
//   r = [g l1 sin th1 (m1/2 + m2) - m2 l1 l2 dth2^2 sin(th1 - th2) / 2 + tau1,
//        m2 l2 (l1 dth1^2 sin(th1 - th2) + g sin th2) / 2 + tau2]
// Energy (conserved with tau = 0):
//   m1 l1^2 dth1^2 / 8 + I1 dth1^2 / 2 + m2 / 2 (l1^2 dth1^2 + l2^2 dth2^2 / 4
//   + l1 l2 dth1 dth2 cos(th1 - th2)) + I2 dth2^2 / 2 + m1 g l1 cos th1 / 2
//   + m2 g (l1 cos th1 + l2 cos th2 / 2).
#ifndef TOTALGRAD_CORE_TASKS_DOUBLE_PENDULUM_H_
#define TOTALGRAD_CORE_TASKS_DOUBLE_PENDULUM_H_

#include "core/tasks/plant.h"

namespace totalgrad::tasks {

struct DoublePendulumParams {
  double mass1 = 0.5, mass2 = 0.5;      // kg
  double length1 = 0.5, length2 = 0.5;  // m
  double gravity = 9.82;                // m/s^2
  Matrix input_map = Matrix::Identity(2, 2);  // B, 2 x F: joint torques = B u
};

class DoublePendulum final : public Plant {
 public:
  // params.input_map must have 2 rows and at least one column.
  DoublePendulum(const DoublePendulumParams& params, double dt,
                 const ode::IntegratorOptions& integrator);
  int state_dim() const override { return 4; }
  int control_dim() const override { return static_cast<int>(params_.input_map.cols()); }
  void Derivative(const Vector& x, const Vector& u, Vector* dxdt) const override;
  double Energy(const Vector& x) const override;
  const DoublePendulumParams& params() const { return params_; }

 private:
  DoublePendulumParams params_;
};

}  // namespace totalgrad::tasks

#endif  // TOTALGRAD_CORE_TASKS_DOUBLE_PENDULUM_H_
