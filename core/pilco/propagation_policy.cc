// The policy block of a moment-matched step (propagation.h): the policy
// input of a deterministic state, the policy's moments for the joint step
// forms and its adjoints, for both policy classes (RBF and linear).
#include <cmath>

#include "core/common/check.h"
#include "core/common/status_context.h"
#include "core/pilco/propagation.h"

namespace totalgrad::pilco {

int Propagator::num_parameters() const {
  if (options_.policy_class == PolicyClass::kLinear) {
    return control_dim() * (policy_input_dim_ + 1);
  }
  return shape_.num_parameters();
}

LinearPolicy Propagator::LinearPolicyOf(const Vector& params) const {
  TG_CHECK(options_.policy_class == PolicyClass::kLinear);
  TG_CHECK(params.size() == num_parameters());
  const int f = control_dim(), ep = policy_input_dim_;
  LinearPolicy policy;
  policy.w = Eigen::Map<const Matrix>(params.data(), f, ep);
  policy.b = params.tail(f);
  policy.max_u = shape_.max_controls.size() > 0 ? shape_.max_controls
                                                : Vector::Constant(1, shape_.max_force);
  return policy;
}

Vector Propagator::PolicyInput(const Vector& x) const {
  TG_CHECK(x.size() == state_dim_);
  Vector y(state_dim_ + 2 * angles_.size());
  y.head(state_dim_) = x;
  for (size_t k = 0; k < angles_.size(); ++k) {
    y(state_dim_ + 2 * k) = std::sin(x(angles_[k]));
    y(state_dim_ + 2 * k + 1) = std::cos(x(angles_[k]));
  }
  Vector p(policy_input_dim_);
  for (int i = 0; i < policy_input_dim_; ++i) p(i) = y(policy_index_[i]);
  return p;
}

absl::Status Propagator::JointPolicyForward(const Vector& params, StepCache* c, Vector* u_mean,
                                            Matrix* u_cov) const {
  const int f = control_dim();
  if (options_.policy_class == PolicyClass::kLinear) {
    LinearPolicyForward(LinearPolicyOf(params), c->p_mean, c->p_cov, &c->linear);
    if (!c->linear.mean.allFinite() || !c->linear.cov.allFinite() ||
        !c->linear.u_cross.allFinite()) {
      return absl::InternalError("policy: linear policy's moments not finite");
    }
    *u_mean = c->linear.mean;
    *u_cov = c->linear.cov;
    c->u_cross = c->linear.u_cross;
    return absl::OkStatus();
  }
  if (f == 1) {
    if (absl::Status st = PolicyAtGaussian(shape_, params, c->p_mean, c->p_cov, &c->policy);
        !st.ok()) {
      return WithContext(st, "policy");
    }
    *u_mean = Vector::Constant(1, c->policy.sat.mean);
    *u_cov = Matrix::Constant(1, 1, c->policy.sat.var);
    c->u_cross = c->policy.u_cross;
    return absl::OkStatus();
  }
  if (absl::Status st = MultiPolicyAtGaussian(shape_, params, c->p_mean, c->p_cov, &c->multi);
      !st.ok()) {
    return WithContext(st, "policy");
  }
  *u_mean = c->multi.sat.mean;
  *u_cov = c->multi.sat.cov;
  c->u_cross = c->multi.u_cross;
  return absl::OkStatus();
}

absl::Status Propagator::PolicyBackward(const Vector& params, const StepCache& c,
                                        const Vector& u_mean_bar, const Matrix& u_cov_bar,
                                        const Matrix& u_cross_bar, Vector* pm_bar, Matrix* ps_bar,
                                        Vector* params_bar) const {
  if (options_.policy_class == PolicyClass::kLinear) {
    // The step carries u_cross, never Cov(p, u) itself: its adjoint is zero.
    const int f = control_dim(), ep = policy_input_dim_;
    *pm_bar = Vector::Zero(ep);
    *ps_bar = Matrix::Zero(ep, ep);
    Matrix w_bar = Matrix::Zero(f, ep);
    Vector b_bar = Vector::Zero(f);
    LinearPolicyBackward(LinearPolicyOf(params), c.p_mean, c.p_cov, u_mean_bar, u_cov_bar,
                         Matrix::Zero(ep, f), pm_bar, ps_bar, &w_bar, &b_bar, &u_cross_bar);
    if (params_bar != nullptr) {
      params_bar->head(f * ep) += Eigen::Map<const Vector>(w_bar.data(), f * ep);
      params_bar->tail(f) += b_bar;
    }
    if (!pm_bar->allFinite() || !ps_bar->allFinite()) {
      return absl::InternalError("policy (backward): linear policy's adjoints not finite");
    }
    return absl::OkStatus();
  }
  absl::Status st =
      control_dim() == 1
          ? PolicyAtGaussianBackward(shape_, params, c.p_mean, c.p_cov, u_mean_bar(0),
                                     u_cov_bar(0, 0), u_cross_bar.col(0), pm_bar, ps_bar,
                                     params_bar)
          : MultiPolicyAtGaussianBackward(shape_, params, c.p_mean, c.p_cov, u_mean_bar, u_cov_bar,
                                          u_cross_bar, pm_bar, ps_bar, params_bar);
  return WithContext(st, "policy (backward)");
}

}  // namespace totalgrad::pilco
