// dE/dt of a plant along its own right-hand side f(x, u), by central
// differences of Plant::Energy in the direction f: what the energy tests of
// every plant compare with the power of the controls (and friction).
#ifndef TOTALGRAD_TESTS_TESTUTIL_PLANT_ENERGY_H_
#define TOTALGRAD_TESTS_TESTUTIL_PLANT_ENERGY_H_

#include "core/tasks/plant.h"

namespace totalgrad::testing {

inline double EnergyRate(const tasks::Plant& plant, const Vector& x, const Vector& u) {
  Vector f;
  plant.Derivative(x, u, &f);
  const double h = 1e-6;
  return (plant.Energy(x + h * f) - plant.Energy(x - h * f)) / (2 * h);
}

}  // namespace totalgrad::testing

#endif  // TOTALGRAD_TESTS_TESTUTIL_PLANT_ENERGY_H_
