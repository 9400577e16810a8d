#include "core/estimators/particle_system.h"

#include <utility>

#include "core/common/check.h"
#include "core/gaussian/angle_features.h"

namespace totalgrad::estimators {

namespace {

// Chain rule from feature coordinates to raw ones, for `blocks` blocks of
// columns (one per output): a block of `feature` (P x blocks*(E+A)) holds
// derivatives with respect to [phi(x), rest] (phi: S + A columns, the
// non-angle dims then (sin, cos) per angle; then E - S further columns, e.g.
// u); the matching block of *raw (P x blocks*E, resized) gets them with
// respect to [x, rest]. sin_a, cos_a: P x A, the angles' sin and cos.
void FeatureColumnsToRaw(const RowMatrix& feature, int blocks, int s_dim, int e_dim,
                         const std::vector<int>& angles, const RowMatrix& sin_a,
                         const RowMatrix& cos_a, RowMatrix* raw) {
  const int a_count = static_cast<int>(angles.size());
  const int ef = e_dim + a_count;
  TG_CHECK_EQ(feature.cols(), static_cast<Eigen::Index>(blocks) * ef);
  // Where each raw state column lives among the features: an index into the
  // non-angle columns, or -(k + 1) for the k-th angle.
  std::vector<int> source(s_dim);
  int plain = 0;
  size_t next_angle = 0;
  for (int m = 0; m < s_dim; ++m) {
    if (next_angle < angles.size() && angles[next_angle] == m) {
      source[m] = -static_cast<int>(next_angle) - 1;
      ++next_angle;
    } else {
      source[m] = plain++;
    }
  }
  const int trig = s_dim - a_count;  // the first sin column
  raw->resize(feature.rows(), static_cast<Eigen::Index>(blocks) * e_dim);
  for (int b = 0; b < blocks; ++b) {
    const int fb = b * ef, rb = b * e_dim;
    for (int m = 0; m < e_dim; ++m) {
      if (m >= s_dim) {
        raw->col(rb + m) = feature.col(fb + m + a_count);
      } else if (source[m] >= 0) {
        raw->col(rb + m) = feature.col(fb + source[m]);
      } else {
        const int k = -source[m] - 1;
        raw->col(rb + m) = feature.col(fb + trig + 2 * k).cwiseProduct(cos_a.col(k)) -
                           feature.col(fb + trig + 2 * k + 1).cwiseProduct(sin_a.col(k));
      }
    }
  }
}

// The angles' sin and cos (P x A each) from features laid out as above.
void AngleSinCos(const RowMatrix& features, int s_dim, int a_count, RowMatrix* sin_a,
                 RowMatrix* cos_a) {
  const int trig = s_dim - a_count;
  sin_a->resize(features.rows(), a_count);
  cos_a->resize(features.rows(), a_count);
  for (int k = 0; k < a_count; ++k) {
    sin_a->col(k) = features.col(trig + 2 * k);
    cos_a->col(k) = features.col(trig + 2 * k + 1);
  }
}

bool StrictlyIncreasingWithin(const std::vector<int>& v, int bound) {
  if (v.empty()) return false;
  for (size_t i = 0; i < v.size(); ++i) {
    if (v[i] < 0 || v[i] >= bound || (i > 0 && v[i] <= v[i - 1])) return false;
  }
  return true;
}

}  // namespace

AngleFeatureDynamics::AngleFeatureDynamics(const ParticleDynamics* inner, std::vector<int> angle_indices)
    : inner_(inner), angles_(std::move(angle_indices)) {
  TG_CHECK(inner != nullptr);
  TG_CHECK(StrictlyIncreasingWithin(angles_, inner->state_dim()));
}

void AngleFeatureDynamics::Predict(const ConstRowMatrixRef& z, double noise_variance_multiplier,
                                   RowMatrix* mean, RowMatrix* variance, RowMatrix* dmean_dz,
                                   RowMatrix* dvar_dz) const {
  const int s_dim = inner_->state_dim();
  const int e_dim = input_dim();  // S + F
  const int a_count = static_cast<int>(angles_.size());
  TG_CHECK_EQ(z.cols(), e_dim);
  RowMatrix features;
  gaussian::StatesToFeatures(z.leftCols(s_dim), angles_, &features);
  RowMatrix zf(z.rows(), e_dim + a_count);
  zf.leftCols(s_dim + a_count) = features;
  zf.rightCols(e_dim - s_dim) = z.rightCols(e_dim - s_dim);
  RowMatrix dmean_f, dvar_f;
  inner_->Predict(zf, noise_variance_multiplier, mean, variance,
                  dmean_dz != nullptr ? &dmean_f : nullptr, dvar_dz != nullptr ? &dvar_f : nullptr);
  if (dmean_dz == nullptr && dvar_dz == nullptr) return;
  RowMatrix sin_a, cos_a;
  AngleSinCos(features, s_dim, a_count, &sin_a, &cos_a);
  if (dmean_dz != nullptr)
    FeatureColumnsToRaw(dmean_f, s_dim, s_dim, e_dim, angles_, sin_a, cos_a, dmean_dz);
  if (dvar_dz != nullptr)
    FeatureColumnsToRaw(dvar_f, s_dim, s_dim, e_dim, angles_, sin_a, cos_a, dvar_dz);
}

InputSubsetDynamics::InputSubsetDynamics(const ParticleDynamics* inner, std::vector<int> inputs)
    : inner_(inner), inputs_(std::move(inputs)) {
  TG_CHECK(inner != nullptr);
  TG_CHECK(!inputs_.empty() && StrictlyIncreasingWithin(inputs_, inner->state_dim()));
  TG_CHECK(inner->input_dim() > static_cast<int>(inputs_.size()));  // F >= 1 controls
}

void InputSubsetDynamics::Predict(const ConstRowMatrixRef& z, double noise_variance_multiplier,
                                  RowMatrix* mean, RowMatrix* variance, RowMatrix* dmean_dz,
                                  RowMatrix* dvar_dz) const {
  const int s_dim = state_dim(), e_dim = input_dim();
  const int q_dim = static_cast<int>(inputs_.size());
  const int inner_dim = inner_->input_dim();  // q + F
  const int f_dim = inner_dim - q_dim;
  TG_CHECK_EQ(z.cols(), e_dim);
  // inner column k reads z's column at[k]: the subset, then the controls.
  std::vector<int> at(inputs_);
  for (int j = 0; j < f_dim; ++j) at.push_back(s_dim + j);
  RowMatrix zq(z.rows(), inner_dim);
  for (int k = 0; k < inner_dim; ++k) zq.col(k) = z.col(at[k]);
  RowMatrix dmean_q, dvar_q;
  inner_->Predict(zq, noise_variance_multiplier, mean, variance,
                  dmean_dz != nullptr ? &dmean_q : nullptr, dvar_dz != nullptr ? &dvar_q : nullptr);
  // Row-major Jacobians: (p, a * E + m) = d out(p, a) / d z(p, m).
  const auto scatter = [&](const RowMatrix& inner, RowMatrix* out) {
    out->setZero(z.rows(), static_cast<Eigen::Index>(s_dim) * e_dim);
    for (int a = 0; a < s_dim; ++a) {
      for (int k = 0; k < inner_dim; ++k) out->col(a * e_dim + at[k]) = inner.col(a * inner_dim + k);
    }
  };
  if (dmean_dz != nullptr) scatter(dmean_q, dmean_dz);
  if (dvar_dz != nullptr) scatter(dvar_q, dvar_dz);
}

AngleFeaturePolicy::AngleFeaturePolicy(const ParticlePolicy* inner, std::vector<int> angle_indices)
    : inner_(inner), angles_(std::move(angle_indices)) {
  TG_CHECK(inner != nullptr);
  TG_CHECK(StrictlyIncreasingWithin(angles_, inner->state_dim() - static_cast<int>(angles_.size())));
}

void AngleFeaturePolicy::Evaluate(const ConstRowMatrixRef& states, Vector* forces,
                                  PolicyCache* cache) const {
  TG_CHECK_EQ(states.cols(), state_dim());
  RowMatrix features;
  gaussian::StatesToFeatures(states, angles_, &features);
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
  const int a_count = static_cast<int>(angles_.size());
  // The features the inner policy saw: [x without the angles, (sin, cos) per angle].
  TG_CHECK_EQ(cache.states.cols(), s_dim + a_count);
  TG_CHECK_EQ(cache.states.rows() * control_dim(), force_bar.size());
  RowMatrix feature_bar;
  inner_->Backward(cache, force_bar, &feature_bar, per_particle_param_bar, param_bar);
  RowMatrix sin_a, cos_a;
  AngleSinCos(cache.states, s_dim, a_count, &sin_a, &cos_a);
  FeatureColumnsToRaw(feature_bar, 1, s_dim, s_dim, angles_, sin_a, cos_a, state_bar);
}

}  // namespace totalgrad::estimators
