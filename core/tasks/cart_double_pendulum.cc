#include "core/tasks/cart_double_pendulum.h"

#include <Eigen/LU>
#include <cmath>

#include "core/common/check.h"

namespace totalgrad::tasks {

void CartDoublePendulum::Derivative(const Vector& x, const Vector& u, Vector* dxdt) const {
  TG_CHECK(x.size() == 6 && u.size() == 1);
  const CartDoublePendulumParams& p = params_;
  const double m1 = p.cart_mass, m2 = p.mass1, m3 = p.mass2, l2 = p.length1, l3 = p.length2;
  const double b = p.friction, g = p.gravity;
  const double dx = x(1), dth1 = x(2), dth2 = x(3), th1 = x(4), th2 = x(5);
  const double c1 = std::cos(th1), s1 = std::sin(th1), c2 = std::cos(th2), s2 = std::sin(th2);
  const double c12 = std::cos(th1 - th2), s12 = std::sin(th1 - th2);
  Eigen::Matrix3d a;
  a << 2.0 * (m1 + m2 + m3), -(m2 + 2.0 * m3) * l2 * c1, -m3 * l3 * c2,
      -(3.0 * m2 + 6.0 * m3) * c1, (2.0 * m2 + 6.0 * m3) * l2, 3.0 * m3 * l3 * c12,
      -3.0 * c2, 3.0 * l2 * c12, 2.0 * l3;
  Eigen::Vector3d r;
  r << 2.0 * u(0) - 2.0 * b * dx - (m2 + 2.0 * m3) * l2 * dth1 * dth1 * s1 - m3 * l3 * dth2 * dth2 * s2,
      (3.0 * m2 + 6.0 * m3) * g * s1 - 3.0 * m3 * l3 * dth2 * dth2 * s12,
      3.0 * l2 * dth1 * dth1 * s12 + 3.0 * g * s2;
  const Eigen::Vector3d acc = a.partialPivLu().solve(r);
  dxdt->resize(6);
  (*dxdt) << dx, acc(0), acc(1), acc(2), dth1, dth2;
}

double CartDoublePendulum::Energy(const Vector& x) const {
  const CartDoublePendulumParams& p = params_;
  const double m1 = p.cart_mass, m2 = p.mass1, m3 = p.mass2, l2 = p.length1, l3 = p.length2;
  const double g = p.gravity;
  const double dx = x(1), dth1 = x(2), dth2 = x(3), th1 = x(4), th2 = x(5);
  const double c1 = std::cos(th1), c2 = std::cos(th2), c12 = std::cos(th1 - th2);
  const double i2 = m2 * l2 * l2 / 12.0, i3 = m3 * l3 * l3 / 12.0;
  const double v1_sq = dx * dx - l2 * c1 * dx * dth1 + l2 * l2 * dth1 * dth1 / 4.0;
  const double v2_sq = dx * dx + l2 * l2 * dth1 * dth1 + l3 * l3 * dth2 * dth2 / 4.0 -
                       2.0 * l2 * c1 * dx * dth1 - l3 * c2 * dx * dth2 + l2 * l3 * c12 * dth1 * dth2;
  const double kinetic = 0.5 * m1 * dx * dx + 0.5 * m2 * v1_sq + 0.5 * i2 * dth1 * dth1 +
                         0.5 * m3 * v2_sq + 0.5 * i3 * dth2 * dth2;
  const double potential = m2 * g * l2 / 2.0 * c1 + m3 * g * (l2 * c1 + l3 / 2.0 * c2);
  return kinetic + potential;
}

}  // namespace totalgrad::tasks
