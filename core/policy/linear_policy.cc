#include "core/policy/linear_policy.h"

#include "core/common/check.h"

namespace totalgrad::policy {

LinearPolicy::LinearPolicy(int state_dim, const Vector& max_control)
    : state_dim_(state_dim), max_control_(max_control) {
  TG_CHECK(state_dim > 0 && max_control.size() > 0);
  for (Eigen::Index j = 0; j < max_control.size(); ++j) TG_CHECK(max_control(j) > 0);
  params_ = Vector::Zero(num_parameters());
}

void LinearPolicy::set_parameters(const Vector& p) {
  TG_CHECK_EQ(p.size(), num_parameters());
  params_ = p;
}

Eigen::Map<const Matrix> LinearPolicy::gain() const {
  return Eigen::Map<const Matrix>(params_.data(), control_dim(), state_dim_);
}

Eigen::Map<const Vector> LinearPolicy::bias() const {
  return Eigen::Map<const Vector>(params_.data() + control_dim() * state_dim_, control_dim());
}

void LinearPolicy::Initialize(double weight_std, Rng* rng) {
  TG_CHECK(weight_std >= 0);
  const int n_w = control_dim() * state_dim_;
  for (int k = 0; k < n_w; ++k) params_(k) = weight_std * rng->Normal();
  params_.tail(control_dim()).setZero();
}

void LinearPolicy::Evaluate(const ConstRowMatrixRef& states, Vector* forces,
                            RbfPolicy::Cache* cache) const {
  TG_CHECK_EQ(states.cols(), state_dim_);
  const Eigen::Index p = states.rows();
  const int f = control_dim();
  RbfPolicy::Cache local;
  RbfPolicy::Cache& out = cache != nullptr ? *cache : local;
  out.pre.resize(p * f);
  Eigen::Map<RowMatrix> pre(out.pre.data(), p, f);  // particle-major
  pre.noalias() = states * gain().transpose();
  pre.rowwise() += bias().transpose();
  forces->resize(p * f);
  for (Eigen::Index i = 0; i < p * f; ++i) (*forces)(i) = Saturate(out.pre(i), max_control_(i % f));
  if (cache != nullptr) {
    cache->states = states;
    cache->phi.resize(0, 0);
  }
}

void LinearPolicy::Backward(const RbfPolicy::Cache& cache, const Vector& force_bar,
                            RowMatrix* state_bar, RowMatrix* per_particle_param_bar,
                            Vector* param_bar) const {
  const Eigen::Index p = cache.states.rows();
  const int f = control_dim(), s = state_dim_;
  TG_CHECK_EQ(force_bar.size(), p * f);
  TG_CHECK_EQ(cache.pre.size(), p * f);
  // a_bar = force_bar * du/da, particle-major P x F.
  RowMatrix a_bar(p, f);
  for (Eigen::Index i = 0; i < p; ++i) {
    for (int j = 0; j < f; ++j) {
      a_bar(i, j) = force_bar(i * f + j) * DaSaturate(cache.pre(i * f + j), max_control_(j));
    }
  }
  if (state_bar != nullptr) state_bar->noalias() = a_bar * gain();
  if (per_particle_param_bar != nullptr) {
    TG_CHECK(per_particle_param_bar->rows() == p &&
             per_particle_param_bar->cols() == num_parameters());
    // d a_j / d W(j, m) = x_m: entry m F + j of the column-major W.
    for (int m = 0; m < s; ++m) {
      for (int j = 0; j < f; ++j) {
        per_particle_param_bar->col(m * f + j) += a_bar.col(j).cwiseProduct(cache.states.col(m));
      }
    }
    per_particle_param_bar->rightCols(f) += a_bar;
  }
  if (param_bar != nullptr) {
    TG_CHECK_EQ(param_bar->size(), num_parameters());
    // dW = a_bar^T X (F x S), column-major as the parameters.
    const Matrix w_bar = a_bar.transpose() * cache.states;
    param_bar->head(f * s) += Eigen::Map<const Vector>(w_bar.data(), f * s);
    param_bar->tail(f) += a_bar.colwise().sum().transpose();
  }
}

}  // namespace totalgrad::policy
