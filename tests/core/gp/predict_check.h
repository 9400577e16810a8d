// Finite-difference helpers shared by the tests of the GP predictors (full GP
// and FITC), whose Predict methods have the same contract (core/gp/gp.h).
#ifndef TOTALGRAD_TESTS_CORE_GP_PREDICT_CHECK_H_
#define TOTALGRAD_TESTS_CORE_GP_PREDICT_CHECK_H_

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>

#include "core/common/rng.h"
#include "core/common/types.h"
#include "core/diff/gradient_checker.h"
#include "core/gp/gp.h"

namespace totalgrad::gp::testing {

// rows x cols, entries uniform in [lo, hi), drawn row by row.
inline RowMatrix UniformMatrix(Rng* rng, int rows, int cols, double lo, double hi) {
  RowMatrix m(rows, cols);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) m(r, c) = rng->Uniform(lo, hi);
  return m;
}

// The GP predictors' test problem: N inputs uniform in [-2, 2]^3, two outputs
// y0 = sin(z0) + z1 z2 + N(0, noise0^2), y1 = cos(z1) - 0.3 z0 + N(0, noise1^2),
// with hyperparameters that differ per output (length-scales `lengthscales`,
// 2 x 3; sf = 1.2 and 0.7; sn = noise0 and noise1), so that a mixed-up output
// index or length-scale shows in every check.
struct TwoOutputProblem {
  RowMatrix inputs;   // N x 3
  RowMatrix targets;  // N x 2
  GpHyperparameters hyp;
};

// The length-scales of most tests: short against the box, so predictions vary.
inline RowMatrix ShortLengthscales() {
  RowMatrix l(2, 3);
  l << 0.9, 1.3, 0.7, 1.5, 0.8, 1.1;
  return l;
}

inline TwoOutputProblem MakeTwoOutputProblem(int n, uint64_t seed, double noise0, double noise1,
                                             const RowMatrix& lengthscales) {
  Rng rng(seed, Stream::kStudy);
  TwoOutputProblem problem;
  problem.inputs = UniformMatrix(&rng, n, 3, -2.0, 2.0);
  problem.targets.resize(n, 2);
  for (int i = 0; i < n; ++i) {
    const auto x = problem.inputs.row(i);
    problem.targets(i, 0) = std::sin(x(0)) + x(1) * x(2) + noise0 * rng.Normal();
    problem.targets(i, 1) = std::cos(x(1)) - 0.3 * x(0) + noise1 * rng.Normal();
  }
  problem.hyp.log_lengthscales.resize(2, 3);
  for (int a = 0; a < 2; ++a)
    for (int m = 0; m < 3; ++m) problem.hyp.log_lengthscales(a, m) = std::log(lengthscales(a, m));
  problem.hyp.log_signal_std.resize(2);
  problem.hyp.log_signal_std << std::log(1.2), std::log(0.7);
  problem.hyp.log_noise_std.resize(2);
  problem.hyp.log_noise_std << std::log(noise0), std::log(noise1);
  return problem;
}

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
