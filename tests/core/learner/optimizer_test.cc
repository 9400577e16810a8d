#include "core/learner/optimizer.h"

#include <cmath>

#include <gtest/gtest.h>

namespace totalgrad::learner {
namespace optimizer_test {

TEST(RmspropLike, FirstStepIsNormalisedByParticleStd) {
  OptimizerOptions o;
  o.learning_rate = 0.1;
  o.momentum = 0.9;
  o.epsilon = 0;
  o.normalisation = Normalisation::kParticleStd;
  RmspropLike opt(o, 2);
  Vector theta = Vector::Zero(2), g(2), var(2);
  g << 2.0, -3.0;
  var << 4.0, 9.0;  // std 2, 3
  opt.Step(g, var, 100, &theta);
  EXPECT_NEAR(theta(0), -0.1 * 1.0, 1e-15);
  EXPECT_NEAR(theta(1), -0.1 * -1.0, 1e-15);
  // Second step: v = 0.9 v + 0.1 s2 = s2 (same s2), m = 0.9 m + g/std.
  opt.Step(g, var, 100, &theta);
  EXPECT_NEAR(theta(0), -0.1 - 0.1 * 1.9, 1e-14);
}

TEST(RmspropLike, MeanStdNormalisationIsSqrtPLarger) {
  OptimizerOptions o;
  o.learning_rate = 1.0;
  o.momentum = 0;
  o.epsilon = 0;
  o.normalisation = Normalisation::kMeanStd;
  RmspropLike opt(o, 1);
  Vector theta = Vector::Zero(1), g = Vector::Constant(1, 1.0), var = Vector::Constant(1, 4.0);
  opt.Step(g, var, 100, &theta);
  EXPECT_NEAR(theta(0), -1.0 / (2.0 / 10.0), 1e-12);
}

TEST(RmspropLike, DefaultIsMeanStd) {
  EXPECT_EQ(OptimizerOptions().normalisation, Normalisation::kMeanStd);
}

TEST(RmspropLike, NoisyGradientsGiveSmallerSteps) {
  OptimizerOptions o;
  o.epsilon = 0;
  RmspropLike quiet(o, 1), noisy(o, 1);
  Vector a = Vector::Zero(1), b = Vector::Zero(1), g = Vector::Constant(1, 1.0);
  quiet.Step(g, Vector::Constant(1, 1.0), 300, &a);
  noisy.Step(g, Vector::Constant(1, 100.0), 300, &b);
  EXPECT_GT(std::abs(a(0)), 9.9 * std::abs(b(0)));
}

TEST(RmspropLike, ResetForgetsState) {
  OptimizerOptions o;
  o.normalisation = Normalisation::kParticleStd;
  RmspropLike opt(o, 1);
  Vector t1 = Vector::Zero(1), t2 = Vector::Zero(1), g = Vector::Constant(1, 1.0), v = g;
  opt.Step(g, v, 10, &t1);
  opt.Step(g, v, 10, &t1);
  opt.Reset();
  opt.Step(g, v, 10, &t2);
  EXPECT_DOUBLE_EQ(t2(0), -o.learning_rate * 1.0 / (1.0 + o.epsilon));
}

}  // namespace optimizer_test
}  // namespace totalgrad::learner
