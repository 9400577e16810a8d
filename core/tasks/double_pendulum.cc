#include "core/tasks/double_pendulum.h"

#include <cmath>

#include "core/common/check.h"

namespace totalgrad::tasks {

DoublePendulum::DoublePendulum(const DoublePendulumParams& params, double dt,
                               const ode::IntegratorOptions& integrator)
    : Plant(dt, integrator), params_(params) {
  TG_CHECK(params.input_map.rows() == 2 && params.input_map.cols() >= 1);
}

void DoublePendulum::Derivative(const Vector& x, const Vector& u, Vector* dxdt) const {
  TG_CHECK(x.size() == 4 && u.size() == control_dim());
  const DoublePendulumParams& p = params_;
  const double m1 = p.mass1, m2 = p.mass2, l1 = p.length1, l2 = p.length2, g = p.gravity;
  const double i1 = m1 * l1 * l1 / 12.0, i2 = m2 * l2 * l2 / 12.0;
  const double dth1 = x(0), dth2 = x(1), th1 = x(2), th2 = x(3);
  const Eigen::Vector2d tau = p.input_map * u;
  const double c12 = std::cos(th1 - th2), s12 = std::sin(th1 - th2);
  const double a11 = l1 * l1 * (m1 / 4.0 + m2) + i1;
  const double a12 = m2 * l1 * l2 * c12 / 2.0;
  const double a22 = l2 * l2 * m2 / 4.0 + i2;
  const double r1 = g * l1 * std::sin(th1) * (m1 / 2.0 + m2) - m2 * l1 * l2 * dth2 * dth2 * s12 / 2.0 + tau(0);
  const double r2 = m2 * l2 * (l1 * dth1 * dth1 * s12 + g * std::sin(th2)) / 2.0 + tau(1);
  // 2 x 2 solve by Cramer's rule; det = a11 a22 - a12^2 > 0 (the inertia
  // matrix is positive definite for positive masses and lengths).
  const double det = a11 * a22 - a12 * a12;
  dxdt->resize(4);
  (*dxdt)(0) = (a22 * r1 - a12 * r2) / det;
  (*dxdt)(1) = (a11 * r2 - a12 * r1) / det;
  (*dxdt)(2) = dth1;
  (*dxdt)(3) = dth2;
}

double DoublePendulum::Energy(const Vector& x) const {
  const DoublePendulumParams& p = params_;
  const double m1 = p.mass1, m2 = p.mass2, l1 = p.length1, l2 = p.length2, g = p.gravity;
  const double i1 = m1 * l1 * l1 / 12.0, i2 = m2 * l2 * l2 / 12.0;
  const double dth1 = x(0), dth2 = x(1), th1 = x(2), th2 = x(3);
  return m1 * l1 * l1 * dth1 * dth1 / 8.0 + i1 * dth1 * dth1 / 2.0 +
         m2 / 2.0 * (l1 * l1 * dth1 * dth1 + l2 * l2 * dth2 * dth2 / 4.0 +
                     l1 * l2 * dth1 * dth2 * std::cos(th1 - th2)) +
         i2 * dth2 * dth2 / 2.0 + m1 * g * l1 * std::cos(th1) / 2.0 +
         m2 * g * (l1 * std::cos(th1) + l2 * std::cos(th2) / 2.0);
}

}  // namespace totalgrad::tasks
