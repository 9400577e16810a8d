#include "core/pilco/propagation.h"

#include <cmath>

#include "absl/strings/str_cat.h"
#include "core/common/check.h"
#include "core/common/status_context.h"
#include "core/gaussian/trig.h"

namespace totalgrad::pilco {

// What JointStepBackward gives (see there).
struct Propagator::JointInputAdjoints {
  Matrix cxg_bar;
  Vector g_mean_bar;
  Matrix g_cov_bar;
  Matrix r_bar;
  Matrix u_cross_bar;
  // The policy's adjoints through u (PolicyBackward): of p's mean and
  // covariance.
  Vector pm_bar;
  Matrix ps_bar;
};

namespace {

// The next state of every step form: m' = m + E[Delta],
// S' = S + Cov[Delta] + C + C^T with C = cxg * delta.cross (cxg: Cov[x, g],
// D x dim g, g the GP's input), symmetrised. InternalError if not finite.
absl::Status AddDelta(const Vector& m, const Matrix& S, const Matrix& cxg,
                      const GaussianPrediction& delta, Vector* m_next, Matrix* S_next) {
  const Matrix cxd = cxg * delta.cross;
  *m_next = m + delta.mean;
  Matrix sn = S + delta.cov + cxd + cxd.transpose();
  *S_next = 0.5 * (sn + sn.transpose());
  if (!m_next->allFinite() || !S_next->allFinite()) {
    return absl::InternalError("next state distribution not finite");
  }
  return absl::OkStatus();
}


}  // namespace

absl::Status Propagator::Validate(const GaussianInputGp& dynamics,
                                  const PropagationOptions& options) {
  const int d = dynamics.num_outputs();
  if (d < 1) return absl::InvalidArgumentError("dynamics GP has no outputs");
  if (options.angle_index < -1 || options.angle_index >= d) {
    return absl::InvalidArgumentError(
        absl::StrCat("angle_index ", options.angle_index, " out of range for state dim ", d));
  }
  if (!options.angle_indices.empty()) {
    if (options.angle_index >= 0) {
      return absl::InvalidArgumentError("give angle_index or angle_indices, not both");
    }
    for (size_t k = 0; k < options.angle_indices.size(); ++k) {
      const int a = options.angle_indices[k];
      if (a < 0 || a >= d || (k > 0 && a <= options.angle_indices[k - 1])) {
        return absl::InvalidArgumentError(absl::StrCat(
            "angle_indices must be strictly increasing state indices in [0, ", d, "); entry ", k,
            " is ", a));
      }
    }
  }
  const int a_count = static_cast<int>(options.Angles().size());
  const int ny = d + 2 * a_count;
  for (const auto& [name, list] : {std::pair<const char*, const std::vector<int>*>{
                                       "policy_inputs", &options.policy_inputs},
                                   {"dynamics_inputs", &options.dynamics_inputs}}) {
    for (size_t k = 0; k < list->size(); ++k) {
      const int i = (*list)[k];
      if (i < 0 || i >= ny || (k > 0 && i <= (*list)[k - 1])) {
        return absl::InvalidArgumentError(absl::StrCat(
            name, " must be strictly increasing indices into z = [x, (sin, cos) per angle] in [0, ",
            ny, "); entry ", k, " is ", i));
      }
    }
  }
  const int ep = d + a_count;
  const int eg = options.dynamics_inputs.empty()
                     ? (options.policy_inputs.empty()
                            ? ep
                            : static_cast<int>(options.policy_inputs.size()))
                     : static_cast<int>(options.dynamics_inputs.size());
  if (options.max_controls.size() == 1) {
    return absl::InvalidArgumentError("max_controls: give 2 or more bounds (one control: max_force)");
  }
  for (Eigen::Index j = 0; j < options.max_controls.size(); ++j) {
    if (!(options.max_controls(j) > 0) || !std::isfinite(options.max_controls(j)))
      return absl::InvalidArgumentError(absl::StrCat("max_controls(", j, ") must be > 0"));
  }
  const int f = options.max_controls.size() >= 2 ? static_cast<int>(options.max_controls.size()) : 1;
  const bool default_inputs = options.policy_inputs.empty() && options.dynamics_inputs.empty();
  if (dynamics.num_inputs() != eg + f) {
    return absl::InvalidArgumentError(absl::StrCat(
        "dynamics GP has ", dynamics.num_inputs(), " inputs; expected ", eg + f,
        !default_inputs ? " ([z(dynamics inputs), "
        : a_count > 0   ? " ([state without the angles, (sin, cos) per angle, "
                        : " ([state, ",
        f == 1 ? "u])" : absl::StrCat(f, " controls])")));
  }
  if (dynamics.variance_weights.size() != static_cast<size_t>(d)) {
    return absl::InvalidArgumentError("dynamics GP lacks its variance weights (K^-1)");
  }
  if (options.policy_class == PolicyClass::kLinear) {
    if (options.policy_lengthscale_per_control) {
      return absl::InvalidArgumentError("the linear policy has no length-scales");
    }
  } else {
    if (options.policy_lengthscale_per_control && f < 2) {
      return absl::InvalidArgumentError(
          "policy length-scales per control need 2 or more controls (max_controls)");
    }
    if (options.num_basis < 1) return absl::InvalidArgumentError("num_basis must be >= 1");
  }
  if (!(options.max_force > 0) || !std::isfinite(options.max_force)) {
    return absl::InvalidArgumentError("max_force must be > 0");
  }
  if (!(options.policy_jitter >= 0) || !std::isfinite(options.policy_jitter)) {
    return absl::InvalidArgumentError("policy output variance jitter must be >= 0");
  }
  return absl::OkStatus();
}

Propagator::Propagator(const GaussianInputGp* dynamics, const PropagationOptions& options)
    : dynamics_(dynamics), options_(options) {
  TG_CHECK(dynamics != nullptr);
  TG_CHECK(Validate(*dynamics, options).ok());
  state_dim_ = dynamics->num_outputs();
  angles_ = options.Angles();
  const int d = state_dim_;
  // p = [x without the angles, then y's (sin, cos) entries in angle order],
  // unless the options give PILCO's poli.
  if (!options.policy_inputs.empty()) {
    policy_index_ = options.policy_inputs;
  } else {
    size_t next = 0;
    for (int i = 0; i < d; ++i) {
      if (next < angles_.size() && angles_[next] == i) {
        ++next;
      } else {
        policy_index_.push_back(i);
      }
    }
    for (size_t k = 0; k < angles_.size(); ++k) {
      policy_index_.push_back(d + 2 * static_cast<int>(k));
      policy_index_.push_back(d + 2 * static_cast<int>(k) + 1);
    }
  }
  // The GP on the policy's own inputs is the shared path (its own bits).
  if (!options.dynamics_inputs.empty() && options.dynamics_inputs != policy_index_) {
    dynamics_index_ = options.dynamics_inputs;
  }
  policy_input_dim_ = static_cast<int>(policy_index_.size());
  shape_.num_basis = options.num_basis;
  shape_.input_dim = policy_input_dim_;
  shape_.max_force = options.max_force;
  shape_.max_controls = options.max_controls;
  shape_.lengthscale_per_control = options.policy_lengthscale_per_control;
  shape_.jitter = options.policy_jitter;
  dyn_options_.model_variance = true;
  dyn_options_.include_noise = options.prediction_includes_noise;
  dyn_options_.jitter = 0.0;
}

absl::Status Propagator::Step(const Vector& params, const Vector& m, const Matrix& S,
                              Vector* m_next, Matrix* S_next, StepCache* cache) const {
  const int d = state_dim_, ep = policy_input_dim_;
  TG_CHECK(params.size() == num_parameters());
  TG_CHECK(m.size() == d && S.rows() == d && S.cols() == d);
  if (!m.allFinite() || !S.allFinite()) {
    return absl::InvalidArgumentError("state mean or covariance not finite");
  }
  StepCache local;
  StepCache& c = cache != nullptr ? *cache : local;
  c.m = m;
  c.S = S;
  if (!angles_.empty()) {
    gaussian::AugmentWithTrig(m, S, angles_, &c.y_mean, &c.y_cov);
  } else {
    c.y_mean = m;
    c.y_cov = S;
  }
  c.p_mean.resize(ep);
  c.p_cov.resize(ep, ep);
  c.s_xp.resize(d, ep);
  for (int i = 0; i < ep; ++i) {
    c.p_mean(i) = c.y_mean(policy_index_[i]);
    for (int j = 0; j < ep; ++j) c.p_cov(i, j) = c.y_cov(policy_index_[i], policy_index_[j]);
    for (int r = 0; r < d; ++r) c.s_xp(r, i) = c.y_cov(r, policy_index_[i]);
  }
  if (!dynamics_index_.empty()) return StepSeparate(params, m, S, m_next, S_next, &c);
  if (control_dim() > 1 || options_.policy_class == PolicyClass::kLinear) {
    return StepControls(params, m, S, m_next, S_next, &c);
  }
  if (absl::Status st = PolicyAtGaussian(shape_, params, c.p_mean, c.p_cov, &c.policy);
      !st.ok()) {
    return WithContext(st, "policy");
  }
  c.g_mean.resize(ep + 1);
  c.g_mean.head(ep) = c.p_mean;
  c.g_mean(ep) = c.policy.sat.mean;
  c.g_cov.resize(ep + 1, ep + 1);
  c.g_cov.topLeftCorner(ep, ep) = c.p_cov;
  const Vector cov_pu = c.p_cov * c.policy.u_cross;
  c.g_cov.col(ep).head(ep) = cov_pu;
  c.g_cov.row(ep).head(ep) = cov_pu.transpose();
  c.g_cov(ep, ep) = c.policy.sat.var;
  if (absl::Status st = PredictGaussian(*dynamics_, c.g_mean, c.g_cov, dyn_options_, &c.delta);
      !st.ok()) {
    return WithContext(st, "dynamics GP");
  }
  Matrix cxg(d, ep + 1);
  cxg.leftCols(ep) = c.s_xp;
  cxg.col(ep) = c.s_xp * c.policy.u_cross;
  return AddDelta(m, S, cxg, c.delta, m_next, S_next);
}

absl::Status Propagator::StepControls(const Vector& params, const Vector& m, const Matrix& S,
                                      Vector* m_next, Matrix* S_next, StepCache* cache) const {
  // As Step from the policy on, with F controls: g = [p; u] (Ep + F),
  // Cov(p, u) = p_cov u_cross (Ep x F), Cov(u) from GSatJoint.
  StepCache& c = *cache;
  return JointStepForward(params, m, S, c.p_mean, c.p_cov, c.s_xp, c.p_cov, &c, m_next, S_next);
}

absl::Status Propagator::JointStepForward(const Vector& params, const Vector& m, const Matrix& S,
                                          const Vector& a_mean, const Matrix& a_cov,
                                          const Matrix& s_xa, const Matrix& s_ap, StepCache* cache,
                                          Vector* m_next, Matrix* S_next) const {
  const int d = state_dim_, ea = static_cast<int>(a_mean.size()), f = control_dim();
  StepCache& c = *cache;
  Vector u_mean;
  Matrix u_cov;
  if (absl::Status st = JointPolicyForward(params, &c, &u_mean, &u_cov); !st.ok()) return st;
  c.g_mean.resize(ea + f);
  c.g_mean.head(ea) = a_mean;
  c.g_mean.tail(f) = u_mean;
  c.g_cov.resize(ea + f, ea + f);
  c.g_cov.topLeftCorner(ea, ea) = a_cov;
  const Matrix cov_au = s_ap * c.u_cross;
  c.g_cov.topRightCorner(ea, f) = cov_au;
  c.g_cov.bottomLeftCorner(f, ea) = cov_au.transpose();
  c.g_cov.bottomRightCorner(f, f) = u_cov;
  if (absl::Status st = PredictGaussian(*dynamics_, c.g_mean, c.g_cov, dyn_options_, &c.delta);
      !st.ok()) {
    return WithContext(st, "dynamics GP");
  }
  Matrix cxg(d, ea + f);
  cxg.leftCols(ea) = s_xa;
  cxg.rightCols(f) = c.s_xp * c.u_cross;
  return AddDelta(m, S, cxg, c.delta, m_next, S_next);
}

absl::Status Propagator::StepControlsBackward(const Vector& params, const StepCache& c,
                                              const Vector& m_next_bar, const Matrix& sb_next,
                                              Vector* p_mean_bar, Matrix* p_cov_bar,
                                              Matrix* s_xp_bar, Vector* params_bar) const {
  const int ep = policy_input_dim_, f = control_dim();
  JointInputAdjoints j;
  if (absl::Status st = JointStepBackward(params, c, c.s_xp, c.p_cov, c.u_cross, m_next_bar,
                                          sb_next, params_bar, &j);
      !st.ok()) {
    return st;
  }
  *s_xp_bar = j.cxg_bar.leftCols(ep) + j.cxg_bar.rightCols(f) * c.u_cross.transpose();
  *p_mean_bar = j.g_mean_bar.head(ep);
  *p_cov_bar = j.g_cov_bar.topLeftCorner(ep, ep);
  p_cov_bar->noalias() += j.r_bar * c.u_cross.transpose();
  *p_mean_bar += j.pm_bar;
  *p_cov_bar += j.ps_bar;
  return absl::OkStatus();
}

// The adjoints shared by the two step forms whose GP input is the joint
// g = [a; u] (a: the GP's Ea state inputs, u: the F controls) with
// Cov(x, g) = cxg = [s_xa, s_xp u_cross] and Cov(a, u) = s_ap u_cross: the
// adjoints of cxg (cxg_bar, D x (Ea + F)), of g's moments and of the
// symmetric off-diagonal block r_bar (Ea x F), and u_cross_bar (Ep x F)
// through cxg's right block and Cov(a, u); then the policy's adjoints
// through u (pm_bar, ps_bar; params_bar ADDED to). Each step form adds what
// its own a is (the policy input p, or the separate dynamics inputs q).
absl::Status Propagator::JointStepBackward(const Vector& params, const StepCache& c,
                                           const Matrix& s_xa, const Matrix& s_ap,
                                           const Matrix& u_cross, const Vector& m_next_bar,
                                           const Matrix& sb_next, Vector* params_bar,
                                           JointInputAdjoints* out) const {
  const int d = static_cast<int>(s_xa.rows()), ea = static_cast<int>(s_xa.cols());
  const int f = control_dim();
  // m' = m + E[Delta]; S' = S + Cov[Delta] + C + C^T with C = cxg * cross.
  const Matrix c_bar = 2.0 * sb_next;
  Matrix cxg(d, ea + f);
  cxg.leftCols(ea) = s_xa;
  cxg.rightCols(f) = c.s_xp * u_cross;
  out->cxg_bar = c_bar * c.delta.cross.transpose();       // D x (Ea + F)
  const Matrix delta_cross_bar = cxg.transpose() * c_bar;  // (Ea + F) x D
  out->u_cross_bar = c.s_xp.transpose() * out->cxg_bar.rightCols(f);  // Ep x F
  if (absl::Status st = PredictGaussianBackward(*dynamics_, c.g_mean, c.g_cov, dyn_options_,
                                                m_next_bar, sb_next, delta_cross_bar,
                                                &out->g_mean_bar, &out->g_cov_bar, nullptr,
                                                nullptr);
      !st.ok()) {
    return WithContext(st, "dynamics GP (backward)");
  }
  // Both off-diagonal blocks hold Cov(a, u) = s_ap u_cross (and its transpose).
  out->r_bar = out->g_cov_bar.topRightCorner(ea, f) +
               out->g_cov_bar.bottomLeftCorner(f, ea).transpose();
  out->u_cross_bar.noalias() += s_ap.transpose() * out->r_bar;
  return PolicyBackward(params, c, out->g_mean_bar.tail(f), out->g_cov_bar.bottomRightCorner(f, f),
                        out->u_cross_bar, &out->pm_bar, &out->ps_bar, params_bar);
}

absl::Status Propagator::StepBackward(const Vector& params, const StepCache& c,
                                      const Vector& m_next_bar, const Matrix& S_next_bar,
                                      Vector* m_bar, Matrix* S_bar, Vector* params_bar) const {
  const int d = state_dim_, ep = policy_input_dim_;
  TG_CHECK(m_next_bar.size() == d && S_next_bar.rows() == d && S_next_bar.cols() == d);
  const Matrix sb_next = 0.5 * (S_next_bar + S_next_bar.transpose());
  Vector mb = m_next_bar;
  Matrix sb = sb_next;
  Vector p_mean_bar;
  Matrix p_cov_bar, s_xp_bar;
  if (!dynamics_index_.empty()) {
    return StepSeparateBackward(params, c, m_next_bar, sb_next, m_bar, S_bar, params_bar);
  }
  if (control_dim() > 1 || options_.policy_class == PolicyClass::kLinear) {
    if (absl::Status st = StepControlsBackward(params, c, m_next_bar, sb_next, &p_mean_bar,
                                               &p_cov_bar, &s_xp_bar, params_bar);
        !st.ok()) {
      return st;
    }
    return FinishStepBackward(c, p_mean_bar, p_cov_bar, s_xp_bar, std::move(mb), std::move(sb),
                              m_bar, S_bar);
  }
  // m' = m + E[D]; S' = S + Cov[D] + C + C^T with C = cxg * cross.
  const Vector delta_mean_bar = m_next_bar;
  const Matrix delta_cov_bar = sb_next;
  const Matrix c_bar = 2.0 * sb_next;
  Matrix cxg(d, ep + 1);
  cxg.leftCols(ep) = c.s_xp;
  cxg.col(ep) = c.s_xp * c.policy.u_cross;
  const Matrix cxg_bar = c_bar * c.delta.cross.transpose();  // D x Eg
  const Matrix delta_cross_bar = cxg.transpose() * c_bar;     // Eg x D
  s_xp_bar = cxg_bar.leftCols(ep) + cxg_bar.col(ep) * c.policy.u_cross.transpose();
  Vector u_cross_bar = c.s_xp.transpose() * cxg_bar.col(ep);

  Vector g_mean_bar;
  Matrix g_cov_bar;
  if (absl::Status st = PredictGaussianBackward(*dynamics_, c.g_mean, c.g_cov, dyn_options_,
                                                delta_mean_bar, delta_cov_bar, delta_cross_bar,
                                                &g_mean_bar, &g_cov_bar, nullptr, nullptr);
      !st.ok()) {
    return WithContext(st, "dynamics GP (backward)");
  }
  p_mean_bar = g_mean_bar.head(ep);
  const double u_mean_bar = g_mean_bar(ep);
  p_cov_bar = g_cov_bar.topLeftCorner(ep, ep);
  const Vector r_bar = g_cov_bar.col(ep).head(ep) + g_cov_bar.row(ep).head(ep).transpose();
  p_cov_bar.noalias() += r_bar * c.policy.u_cross.transpose();
  u_cross_bar.noalias() += c.p_cov.transpose() * r_bar;
  const double u_var_bar = g_cov_bar(ep, ep);

  Vector pm_bar;
  Matrix ps_bar;
  if (absl::Status st = PolicyBackward(params, c, Vector::Constant(1, u_mean_bar),
                                       Matrix::Constant(1, 1, u_var_bar), u_cross_bar, &pm_bar,
                                       &ps_bar, params_bar);
      !st.ok()) {
    return st;
  }
  p_mean_bar += pm_bar;
  p_cov_bar += ps_bar;
  return FinishStepBackward(c, p_mean_bar, p_cov_bar, s_xp_bar, std::move(mb), std::move(sb), m_bar,
                            S_bar);
}

void Propagator::PolicyInputAdjointsToY(const StepCache& c, const Vector& p_mean_bar,
                                        const Matrix& p_cov_bar, const Matrix& s_xp_bar,
                                        Vector* y_mean_bar, Matrix* y_cov_bar) const {
  const int d = state_dim_, ep = policy_input_dim_;
  const int ny = static_cast<int>(c.y_mean.size());
  *y_mean_bar = Vector::Zero(ny);
  *y_cov_bar = Matrix::Zero(ny, ny);
  for (int i = 0; i < ep; ++i) {
    (*y_mean_bar)(policy_index_[i]) += p_mean_bar(i);
    for (int j = 0; j < ep; ++j) {
      (*y_cov_bar)(policy_index_[i], policy_index_[j]) += p_cov_bar(i, j);
    }
    for (int r = 0; r < d; ++r) (*y_cov_bar)(r, policy_index_[i]) += s_xp_bar(r, i);
  }
}

absl::Status Propagator::FinishStepBackward(const StepCache& c, const Vector& p_mean_bar,
                                            const Matrix& p_cov_bar, const Matrix& s_xp_bar,
                                            Vector mb, Matrix sb, Vector* m_bar,
                                            Matrix* S_bar) const {
  Vector y_mean_bar;
  Matrix y_cov_bar;
  PolicyInputAdjointsToY(c, p_mean_bar, p_cov_bar, s_xp_bar, &y_mean_bar, &y_cov_bar);
  TrigBackward(c, y_mean_bar, y_cov_bar, std::move(mb), std::move(sb), m_bar, S_bar);
  return absl::OkStatus();
}

void Propagator::TrigBackward(const StepCache& c, const Vector& y_mean_bar,
                              const Matrix& y_cov_bar, Vector mb, Matrix sb, Vector* m_bar,
                              Matrix* S_bar) const {
  if (!angles_.empty()) {
    gaussian::AugmentWithTrigBackward(c.m, c.S, angles_, y_mean_bar, y_cov_bar, &mb, &sb);
  } else {
    mb += y_mean_bar;
    sb += y_cov_bar;
  }
  *m_bar = mb;
  *S_bar = 0.5 * (sb + sb.transpose());
}

absl::Status Propagator::StepSeparate(const Vector& params, const Vector& m, const Matrix& S,
                                      Vector* m_next, Matrix* S_next, StepCache* cache) const {
  // g = [q; u] with q = y(dynamics_index_) (Eq), Cov(q, u) = Cov(q, p) u_cross
  // and Cov(x, u) = Cov(x, p) u_cross (u depends on x only through p).
  const int d = state_dim_;
  const int eq = static_cast<int>(dynamics_index_.size()), ep = policy_input_dim_;
  StepCache& c = *cache;
  c.q_mean.resize(eq);
  c.q_cov.resize(eq, eq);
  c.s_xq.resize(d, eq);
  c.s_qp.resize(eq, ep);
  for (int i = 0; i < eq; ++i) {
    c.q_mean(i) = c.y_mean(dynamics_index_[i]);
    for (int j = 0; j < eq; ++j) c.q_cov(i, j) = c.y_cov(dynamics_index_[i], dynamics_index_[j]);
    for (int j = 0; j < ep; ++j) c.s_qp(i, j) = c.y_cov(dynamics_index_[i], policy_index_[j]);
    for (int r = 0; r < d; ++r) c.s_xq(r, i) = c.y_cov(r, dynamics_index_[i]);
  }
  return JointStepForward(params, m, S, c.q_mean, c.q_cov, c.s_xq, c.s_qp, &c, m_next, S_next);
}

absl::Status Propagator::StepSeparateBackward(const Vector& params, const StepCache& c,
                                              const Vector& m_next_bar, const Matrix& sb_next,
                                              Vector* m_bar, Matrix* S_bar,
                                              Vector* params_bar) const {
  const int d = state_dim_, f = control_dim();
  const int eq = static_cast<int>(dynamics_index_.size()), ep = policy_input_dim_;
  JointInputAdjoints j;
  if (absl::Status st = JointStepBackward(params, c, c.s_xq, c.s_qp, c.u_cross, m_next_bar,
                                          sb_next, params_bar, &j);
      !st.ok()) {
    return st;
  }
  const Matrix s_xq_bar = j.cxg_bar.leftCols(eq);
  Matrix s_xp_bar = j.cxg_bar.rightCols(f) * c.u_cross.transpose();
  const Vector q_mean_bar = j.g_mean_bar.head(eq);
  const Matrix q_cov_bar = j.g_cov_bar.topLeftCorner(eq, eq);
  const Matrix s_qp_bar = j.r_bar * c.u_cross.transpose();
  const Vector& p_mean_bar = j.pm_bar;
  const Matrix& p_cov_bar = j.ps_bar;
  // Every y-block the step read: p's and q's moments, Cov(x, p), Cov(x, q)
  // and Cov(q, p) (each entry its own output; TrigBackward symmetrises).
  Vector y_mean_bar;
  Matrix y_cov_bar;
  PolicyInputAdjointsToY(c, p_mean_bar, p_cov_bar, s_xp_bar, &y_mean_bar, &y_cov_bar);
  for (int i = 0; i < eq; ++i) {
    y_mean_bar(dynamics_index_[i]) += q_mean_bar(i);
    for (int j = 0; j < eq; ++j) {
      y_cov_bar(dynamics_index_[i], dynamics_index_[j]) += q_cov_bar(i, j);
    }
    for (int j = 0; j < ep; ++j) y_cov_bar(dynamics_index_[i], policy_index_[j]) += s_qp_bar(i, j);
    for (int r = 0; r < d; ++r) y_cov_bar(r, dynamics_index_[i]) += s_xq_bar(r, i);
  }
  TrigBackward(c, y_mean_bar, y_cov_bar, m_next_bar, sb_next, m_bar, S_bar);
  return absl::OkStatus();
}

}  // namespace totalgrad::pilco
