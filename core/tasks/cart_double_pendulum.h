// The cart with a double pendulum of PILCO's cart-double-pendulum scene
// (scenarios/cartDoublePendulum at a0b48b7): a cart (mass m1) on a track with
// viscous friction b, driven by a horizontal force u, carrying two uniform
// rods (masses m2, m3, lengths l2, l3; inertia m l^2 / 12 about their
// centres) in series.
//
// State x = [x, dx, dtheta1, dtheta2, theta1, theta2] (PILCO's order), angles
// absolute, 0 upright, pi hanging. With a = [d(dx), d(dtheta1), d(dtheta2)]/dt,
// A a = r:
//   A = [[2(m1+m2+m3), -(m2+2m3) l2 cos th1, -m3 l3 cos th2],
//        [-(3m2+6m3) cos th1, (2m2+6m3) l2, 3 m3 l3 cos(th1-th2)],
//        [-3 cos th2, 3 l2 cos(th1-th2), 2 l3]]
//   r = [2u - 2b dx - (m2+2m3) l2 dth1^2 sin th1 - m3 l3 dth2^2 sin th2,
//        (3m2+6m3) g sin th1 - 3 m3 l3 dth2^2 sin(th1-th2),
//        3 l2 dth1^2 sin(th1-th2) + 3 g sin th2]
// Energy: the Lagrangian's, with the rods' centres at
// (x - l2/2 sin th1, l2/2 cos th1) and (x - l2 sin th1 - l3/2 sin th2,
// l2 cos th1 + l3/2 cos th2), so dE/dt = (u - b dx) dx (tested).
#ifndef TOTALGRAD_CORE_TASKS_CART_DOUBLE_PENDULUM_H_
#define TOTALGRAD_CORE_TASKS_CART_DOUBLE_PENDULUM_H_

#include "core/tasks/plant.h"

namespace totalgrad::tasks {

struct CartDoublePendulumParams {
  double cart_mass = 0.5;                  // m1, kg
  double mass1 = 0.5, mass2 = 0.5;         // m2, m3, kg
  double length1 = 0.6, length2 = 0.6;     // l2, l3, m
  double friction = 0.1;                   // b, N s / m
  double gravity = 9.82;                   // m/s^2
};

class CartDoublePendulum final : public Plant {
 public:
  CartDoublePendulum(const CartDoublePendulumParams& params, double dt,
                     const ode::IntegratorOptions& integrator)
      : Plant(dt, integrator), params_(params) {}
  int state_dim() const override { return 6; }
  int control_dim() const override { return 1; }
  void Derivative(const Vector& x, const Vector& u, Vector* dxdt) const override;
  double Energy(const Vector& x) const override;
  const CartDoublePendulumParams& params() const { return params_; }

 private:
  CartDoublePendulumParams params_;
};

}  // namespace totalgrad::tasks

#endif  // TOTALGRAD_CORE_TASKS_CART_DOUBLE_PENDULUM_H_
