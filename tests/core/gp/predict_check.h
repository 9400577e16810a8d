// Finite-difference helpers shared by the tests of the GP predictors (full GP
// and FITC), whose Predict methods have the same contract (core/gp/gp.h).
#ifndef TOTALGRAD_TESTS_CORE_GP_PREDICT_CHECK_H_
#define TOTALGRAD_TESTS_CORE_GP_PREDICT_CHECK_H_

#include <gtest/gtest.h>

#include <cmath>

#include "core/common/types.h"
#include "core/diff/gradient_checker.h"
#include "core/gp/gp.h"

namespace totalgrad::gp::testing {

// Jacobian of vec(output) (row-major, P*D) with respect to vec(z) (row-major,
// P*E), built from Predict's per-particle blocks: it is block diagonal because
// particles are predicted independently.
inline Matrix BlockJacobian(const RowMatrix& per_particle, int d, int e) {
  const Eigen::Index p = per_particle.rows();
  Matrix j = Matrix::Zero(p * d, p * e);
  for (Eigen::Index i = 0; i < p; ++i)
    for (int a = 0; a < d; ++a)
      for (int m = 0; m < e; ++m) j(i * d + a, i * e + m) = per_particle(i, a * e + m);
  return j;
}

// f(vec z) = vec(mean) or vec(variance) of `model` (a GpModel or a FitcModel,
// which must outlive the function), for the finite-difference checker.
template <typename Model>
diff::VectorFunction PredictFunction(const Model& model, const PredictOptions& options,
                                     Eigen::Index p, bool variance) {
  return [&model, options, p, variance](const Vector& x, Vector* value) {
    const RowMatrix z = Eigen::Map<const RowMatrix>(x.data(), p, model.num_inputs());
    RowMatrix mean, var;
    model.Predict(z, options, &mean, &var, nullptr, nullptr);
    const RowMatrix& out = variance ? var : mean;
    *value = Eigen::Map<const Vector>(out.data(), out.size());
    return value->allFinite();
  };
}


// The typical slips in a hand-written predictive Jacobian must fail the
// finite-difference check at queries z (P x E): dropping the factor 2 of the
// variance derivative, and dividing output 0's mean block by l once instead of
// l^2 (multiplying it back by output 0's length-scales). `model` must have
// Jacobians that pass the same check (tested separately).
template <typename Model>
void ExpectTypicalSlipsFailTheCheck(const Model& model, const RowMatrix& z,
                                    const PredictOptions& options,
                                    const diff::CheckOptions& check_options) {
  const int d = model.num_outputs(), e = model.num_inputs();
  const Eigen::Index p = z.rows();
  RowMatrix mean, var, dmean, dvar;
  model.Predict(z, options, &mean, &var, &dmean, &dvar);
  const Vector x = Eigen::Map<const Vector>(z.data(), z.size());
  const RowMatrix half_dvar = 0.5 * dvar;
  EXPECT_FALSE(diff::CheckJacobian(PredictFunction(model, options, p, true), x,
                                   BlockJacobian(half_dvar, d, e), check_options)
                   .ok)
      << "half the variance Jacobian passed";
  RowMatrix wrong_dmean = dmean;
  for (int m = 0; m < e; ++m) {
    wrong_dmean.col(m) *= std::exp(model.hyperparameters().log_lengthscales(0, m));
  }
  EXPECT_FALSE(diff::CheckJacobian(PredictFunction(model, options, p, false), x,
                                   BlockJacobian(wrong_dmean, d, e), check_options)
                   .ok)
      << "a mean Jacobian divided by l instead of l^2 passed";
}

}  // namespace totalgrad::gp::testing

#endif  // TOTALGRAD_TESTS_CORE_GP_PREDICT_CHECK_H_
