#include "core/tasks/pendulum.h"

#include <cmath>

#include "core/common/check.h"

namespace totalgrad::tasks {

void Pendulum::Derivative(const Vector& x, const Vector& u, Vector* dxdt) const {
  TG_CHECK(x.size() == 2 && u.size() == 1);
  const PendulumParams& p = params_;
  const double dtheta = x(0), theta = x(1);
  dxdt->resize(2);
  (*dxdt)(0) = (u(0) - p.friction * dtheta - p.mass * p.gravity * p.length * std::sin(theta) / 2.0) /
               (p.mass * p.length * p.length / 3.0);
  (*dxdt)(1) = dtheta;
}

double Pendulum::Energy(const Vector& x) const {
  const PendulumParams& p = params_;
  return p.mass * p.length * p.length * x(0) * x(0) / 6.0 -
         p.mass * p.gravity * p.length * std::cos(x(1)) / 2.0;
}

}  // namespace totalgrad::tasks
