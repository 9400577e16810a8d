#include "core/estimators/particle_system.h"

#include "core/common/check.h"
#include "core/pilco/angle_features.h"

namespace totalgrad::estimators {

void GpDynamics::Predict(const ConstRowMatrixRef& z, double noise_variance_multiplier,
                         RowMatrix* mean, RowMatrix* variance, RowMatrix* dmean_dz,
                         RowMatrix* dvar_dz) const {
  gp::PredictOptions options;
  options.noise_variance_multiplier = noise_variance_multiplier;
  model_->Predict(z, options, mean, variance, dmean_dz, dvar_dz, pool_);
}

void FitcDynamics::Predict(const ConstRowMatrixRef& z, double noise_variance_multiplier,
                           RowMatrix* mean, RowMatrix* variance, RowMatrix* dmean_dz,
                           RowMatrix* dvar_dz) const {
  gp::PredictOptions options;
  options.noise_variance_multiplier = noise_variance_multiplier;
  model_->Predict(z, options, mean, variance, dmean_dz, dvar_dz, pool_);
}

namespace {

// Chain rule from feature coordinates to raw ones, for `blocks` blocks of
// columns (one per output): a block of `feature` (P x blocks*(E+1)) holds
// derivatives with respect to [phi(x), rest] (phi: S + 1 columns, then E - S
// further columns, e.g. u); the matching block of *raw (P x blocks*E,
// resized) gets them with respect to [x, rest]. sin_a, cos_a: P.
void FeatureColumnsToRaw(const RowMatrix& feature, int blocks, int s_dim, int e_dim,
                         int angle_index, const Vector& sin_a, const Vector& cos_a,
                         RowMatrix* raw) {
  const int ef = e_dim + 1;
  TG_CHECK_EQ(feature.cols(), static_cast<Eigen::Index>(blocks) * ef);
  raw->resize(feature.rows(), static_cast<Eigen::Index>(blocks) * e_dim);
  for (int b = 0; b < blocks; ++b) {
    const int fb = b * ef, rb = b * e_dim;
    for (int m = 0; m < e_dim; ++m) {
      if (m == angle_index) {
        raw->col(rb + m) = feature.col(fb + s_dim - 1).cwiseProduct(cos_a) -
                           feature.col(fb + s_dim).cwiseProduct(sin_a);
      } else {
        const int fm = m < angle_index ? m : (m < s_dim ? m - 1 : m + 1);
        raw->col(rb + m) = feature.col(fb + fm);
      }
    }
  }
}

}  // namespace

AngleFeatureDynamics::AngleFeatureDynamics(const ParticleDynamics* inner, int angle_index)
    : inner_(inner), angle_index_(angle_index) {
  TG_CHECK(inner != nullptr);
  TG_CHECK(angle_index >= 0 && angle_index < inner->state_dim());
}

void AngleFeatureDynamics::Predict(const ConstRowMatrixRef& z, double noise_variance_multiplier,
                                   RowMatrix* mean, RowMatrix* variance, RowMatrix* dmean_dz,
                                   RowMatrix* dvar_dz) const {
  const int s_dim = inner_->state_dim();
  const int e_dim = s_dim + 1;
  TG_CHECK_EQ(z.cols(), e_dim);
  RowMatrix features;
  pilco::StatesToFeatures(z.leftCols(s_dim), angle_index_, &features);
  RowMatrix zf(z.rows(), e_dim + 1);
  zf.leftCols(e_dim) = features;
  zf.col(e_dim) = z.col(s_dim);
  RowMatrix dmean_f, dvar_f;
  inner_->Predict(zf, noise_variance_multiplier, mean, variance,
                  dmean_dz != nullptr ? &dmean_f : nullptr, dvar_dz != nullptr ? &dvar_f : nullptr);
  if (dmean_dz == nullptr && dvar_dz == nullptr) return;
  const Vector sin_a = features.col(s_dim - 1), cos_a = features.col(s_dim);
  if (dmean_dz != nullptr)
    FeatureColumnsToRaw(dmean_f, s_dim, s_dim, e_dim, angle_index_, sin_a, cos_a, dmean_dz);
  if (dvar_dz != nullptr)
    FeatureColumnsToRaw(dvar_f, s_dim, s_dim, e_dim, angle_index_, sin_a, cos_a, dvar_dz);
}

AngleFeaturePolicy::AngleFeaturePolicy(const ParticlePolicy* inner, int angle_index)
    : inner_(inner), angle_index_(angle_index) {
  TG_CHECK(inner != nullptr);
  TG_CHECK(angle_index >= 0 && angle_index < inner->state_dim() - 1);
}

void AngleFeaturePolicy::Evaluate(const ConstRowMatrixRef& states, Vector* forces,
                                  PolicyCache* cache) const {
  TG_CHECK_EQ(states.cols(), state_dim());
  RowMatrix features;
  pilco::StatesToFeatures(states, angle_index_, &features);
  inner_->Evaluate(features, forces, cache);
}

void AngleFeaturePolicy::Backward(const PolicyCache& cache, const Vector& force_bar,
                                  RowMatrix* state_bar, RowMatrix* per_particle_param_bar,
                                  Vector* param_bar) const {
  if (state_bar == nullptr) {
    inner_->Backward(cache, force_bar, nullptr, per_particle_param_bar, param_bar);
    return;
  }
  const int s_dim = state_dim();
  // The features the inner policy saw: [x without x_a, sin x_a, cos x_a].
  TG_CHECK_EQ(cache.states.cols(), s_dim + 1);
  TG_CHECK_EQ(cache.states.rows(), force_bar.size());
  RowMatrix feature_bar;
  inner_->Backward(cache, force_bar, &feature_bar, per_particle_param_bar, param_bar);
  const Vector sin_a = cache.states.col(s_dim - 1), cos_a = cache.states.col(s_dim);
  FeatureColumnsToRaw(feature_bar, 1, s_dim, s_dim, angle_index_, sin_a, cos_a, state_bar);
}

}  // namespace totalgrad::estimators
