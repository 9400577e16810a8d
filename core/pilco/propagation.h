// One PILCO time step by moment matching (pilco-spec.md 6.1) and the
// chained objective J(theta) = sum_{t=1..H} E[c(x_t)] with its exact gradient
// (6.2), by reverse-mode accumulation.
//
// Step, for x ~ N(m, S) over the D-dim state:
//  1. y = [x; sin x_a1; cos x_a1; sin x_a2; ...] (AugmentWithTrig) for the A
//     angles a1 < a2 < ... (none: y = x);
//  2. policy input p = [y without the angles] = [x without the angles,
//     (sin, cos) per angle] (the particles' features, pilco/angle_features.h):
//     Ep = D + A dims; u from PolicyAtGaussian (gp2 + gSat);
//  3. GP input g = [p; u] (Ep + F dims), with Cov(p, u) = S_pp u_cross
//     (Ep x F; F >= 2 controls: MultiPolicyAtGaussian, GSatJoint);
//     state difference Delta from PredictGaussian (gp0/gp1);
//  4. m' = m + E[Delta], S' = S + Cov[Delta] + C + C^T, C = Cov(x, Delta) =
//     Cov(x, g) cross, symmetrised.
// Every cross-covariance is filled in with Cov(z, out) = Cov(z, in) *
// (in-covariance^-1 Cov(in, out)), the latter computed without inverting any
// covariance, so a singular S (deterministic state, nearly singular sin/cos
// block) is fine.
//
// Gradient: the backward pass visits the steps in reverse, recomputing the
// N x N GP matrices of each step (memory O(N^2 + H D^2)); the result is the
// exact derivative of the computed J (no finite differences anywhere).
//
// Thread safety: const methods of Propagator are thread-safe.
#ifndef TOTALGRAD_CORE_PILCO_PROPAGATION_H_
#define TOTALGRAD_CORE_PILCO_PROPAGATION_H_

#include <vector>

#include "absl/status/status.h"
#include "core/common/types.h"
#include "core/gaussian/expected_cost.h"
#include "core/pilco/gp_moments.h"
#include "core/pilco/linear_policy.h"
#include "core/pilco/policy_moments.h"
#include "core/policy/policy_class.h"

namespace totalgrad::pilco {

// The policy's form (policy/policy_class.h). kRbf: the RBF network with
// saturation (gp2 + gSat; RbfPolicyShape's parameters). kLinear: PILCO's
// conlin + gSat (linear_policy.h), u = max_u sat(W p + b) on the policy
// inputs p, with parameters [W column-major (F x Ep), b (F)] as PILCO's
// unwrap orders them (policy::LinearPolicy's); its moments are exact, and
// it always takes the joint step form (F >= 1).
using PolicyClass = policy::PolicyClass;

struct PropagationOptions {
  PolicyClass policy_class = PolicyClass::kRbf;
  int angle_index = -1;                   // -1: GP and policy see the raw state
  // Several angles (strictly increasing state indices); when non-empty,
  // angle_index must stay -1. Angles() is the list either way.
  std::vector<int> angle_indices;
  bool prediction_includes_noise = false;  // add sn^2 to Cov[Delta] (PILCO: false)
  double policy_jitter = 1e-6;            // gp2's output-variance jitter (RBF only)
  double max_force = 10.0;                // u_max of the saturation (one control)
  // F >= 2 controls (the double pendulum): their bounds; the GP's inputs are
  // then [p; u_1 .. u_F] and the policy has C x F weights. Empty: one control.
  Vector max_controls;
  // F >= 2 only: one row of policy log length-scales per control
  // (RbfPolicyShape::lengthscale_per_control; parameters [centres, log l
  // F x Ep, weights C x F]). false: one shared row.
  bool policy_lengthscale_per_control = false;
  int num_basis = 10;                     // C, RBF centres (RBF only)
  // PILCO's general index sets (poli, dyni), 0-based indices into
  // y = [x, sin x_a1, cos x_a1, ...] (D + 2A), each strictly increasing.
  // Empty policy_inputs: the default p above. Empty dynamics_inputs: the GP
  // sees [p; u] (the policy's inputs). When given, the GP sees
  // [y(dynamics_inputs); u] and Cov(y(dynamics_inputs), u) =
  // Cov(y(dynamics_inputs), p) s_pp^-1 Cov(p, u), as PILCO's propagated. A
  // dynamics_inputs equal to the resolved policy inputs is the shared case,
  // computed by the shared code (same bits).
  std::vector<int> policy_inputs;
  std::vector<int> dynamics_inputs;

  // The angles: angle_indices, or {angle_index}, or none.
  std::vector<int> Angles() const {
    if (!angle_indices.empty()) return angle_indices;
    if (angle_index >= 0) return {angle_index};
    return {};
  }
};

// Intermediate quantities of one step (kept by the forward pass for the
// backward pass; small: no N x N matrices).
struct StepCache {
  Vector m;
  Matrix S;
  Vector y_mean;
  Matrix y_cov;
  Vector p_mean;
  Matrix p_cov;
  PolicyMoments policy;         // RBF, one control
  MultiPolicyMoments multi;     // RBF, F >= 2 controls
  LinearPolicyMoments linear;   // the linear policy
  Vector g_mean;
  Matrix g_cov;
  GaussianPrediction delta;
  Matrix s_xp;  // D x Ep, Cov(x, p)
  // Separate dynamics inputs q = y(dynamics_inputs) (Eq) only:
  Vector q_mean;
  Matrix q_cov;  // Eq x Eq
  Matrix s_xq;   // D x Eq, Cov(x, q)
  Matrix s_qp;   // Eq x Ep, Cov(q, p)
  // Ep x F, s_pp^-1 Cov(p, u): every step form but the RBF's one-control
  // shared-input one (which keeps policy.u_cross).
  Matrix u_cross;
};

class Propagator {
 public:
  // `dynamics` must outlive the Propagator. It has D outputs (the state
  // differences) and Ep + F = D + A + F inputs. CHECK-fails on inconsistent dimensions;
  // use Validate first for user input.
  Propagator(const GaussianInputGp* dynamics, const PropagationOptions& options);

  // InvalidArgument naming the mismatch between dynamics, options and state.
  static absl::Status Validate(const GaussianInputGp& dynamics, const PropagationOptions& options);

  int state_dim() const { return state_dim_; }
  int policy_input_dim() const { return policy_input_dim_; }
  int control_dim() const { return shape_.num_controls(); }
  // The RBF policy's shape (its control count and bounds also hold for the
  // linear policy).
  const RbfPolicyShape& policy_shape() const { return shape_; }
  PolicyClass policy_class() const { return options_.policy_class; }
  // RBF: policy_shape().num_parameters(); linear: F (Ep + 1).
  int num_parameters() const;
  // The linear policy of a parameter vector (kLinear only; CHECK-fails
  // otherwise or on a wrong size).
  LinearPolicy LinearPolicyOf(const Vector& params) const;

  // One step from N(m, S) to N(m_next, S_next). `cache` may be null. Errors
  // from the blocks (non-finite or non-PSD covariances), naming the block.
  absl::Status Step(const Vector& params, const Vector& m, const Matrix& S, Vector* m_next,
                    Matrix* S_next, StepCache* cache) const;

  // Reverse mode of Step: from the adjoints of (m_next, S_next) OVERWRITES
  // *m_bar, *S_bar (symmetric) and ADDS to *params_bar (may be null).
  absl::Status StepBackward(const Vector& params, const StepCache& cache, const Vector& m_next_bar,
                            const Matrix& S_next_bar, Vector* m_bar, Matrix* S_bar,
                            Vector* params_bar) const;

  // Policy input of a deterministic state (D): [x without the angles, (sin,
  // cos) per angle] (Ep = D + A), or x.
  Vector PolicyInput(const Vector& x) const;

 private:
  // Step and StepBackward from the policy on when the GP's inputs are a
  // separate index set q (any F): g = [q; u].
  absl::Status StepSeparate(const Vector& params, const Vector& m, const Matrix& S,
                            Vector* m_next, Matrix* S_next, StepCache* cache) const;
  absl::Status StepSeparateBackward(const Vector& params, const StepCache& c,
                                    const Vector& m_next_bar, const Matrix& sb_next,
                                    Vector* m_bar, Matrix* S_bar, Vector* params_bar) const;
  // From the adjoints of y's mean and covariance (and of m, S through the
  // identity paths) back through the trig augmentation.
  void TrigBackward(const StepCache& c, const Vector& y_mean_bar, const Matrix& y_cov_bar,
                    Vector mb, Matrix sb, Vector* m_bar, Matrix* S_bar) const;
  // The policy's moments at p ~ N(c->p_mean, c->p_cov) for the joint step
  // forms: *u_mean (F), *u_cov (F x F), and c->u_cross; the policy's own
  // moments in c->policy, c->multi or c->linear.
  absl::Status JointPolicyForward(const Vector& params, StepCache* c, Vector* u_mean,
                                  Matrix* u_cov) const;
  // The forward half of the two step forms whose GP input is the joint
  // g = [a; u] (a: the GP's state inputs, a_mean, a_cov, with Cov(x, a) =
  // s_xa and Cov(a, p) = s_ap; a = p or q): the policy's moments, g's, the
  // GP's prediction and the next state. JointStepBackward is its reverse.
  absl::Status JointStepForward(const Vector& params, const Vector& m, const Matrix& S,
                                const Vector& a_mean, const Matrix& a_cov, const Matrix& s_xa,
                                const Matrix& s_ap, StepCache* cache, Vector* m_next,
                                Matrix* S_next) const;
  // Step and StepBackward from the policy on, with F >= 2 controls or the
  // linear policy (the GP sees [p; u]).
  absl::Status StepControls(const Vector& params, const Vector& m, const Matrix& S,
                            Vector* m_next, Matrix* S_next, StepCache* cache) const;
  // Gives the adjoints of p's mean and covariance and of s_xp = Cov(x, p).
  absl::Status StepControlsBackward(const Vector& params, const StepCache& c,
                                    const Vector& m_next_bar, const Matrix& sb_next,
                                    Vector* p_mean_bar, Matrix* p_cov_bar, Matrix* s_xp_bar,
                                    Vector* params_bar) const;
  // The adjoints of a step whose GP input is [a; u], the controls u
  // from the policy: through the GP and on into the policy (PolicyBackward).
  struct JointInputAdjoints;
  absl::Status JointStepBackward(const Vector& params, const StepCache& c, const Matrix& s_xa,
                                 const Matrix& s_ap, const Matrix& u_cross,
                                 const Vector& m_next_bar, const Matrix& sb_next,
                                 Vector* params_bar, JointInputAdjoints* out) const;
  // The policy's adjoints (*pm_bar, *ps_bar: of p's mean and covariance;
  // params_bar ADDED to) from those of its output u (F, F x F, Ep x F), for
  // either control count and policy class.
  absl::Status PolicyBackward(const Vector& params, const StepCache& c, const Vector& u_mean_bar,
                              const Matrix& u_cov_bar, const Matrix& u_cross_bar, Vector* pm_bar,
                              Matrix* ps_bar, Vector* params_bar) const;
  // The adjoints of y = [x, sin, cos ...] that p's mean, covariance and
  // s_xp = Cov(x, p) give (zeros elsewhere; each entry its own output).
  void PolicyInputAdjointsToY(const StepCache& c, const Vector& p_mean_bar,
                              const Matrix& p_cov_bar, const Matrix& s_xp_bar,
                              Vector* y_mean_bar, Matrix* y_cov_bar) const;
  // From the adjoints of p and s_xp (and of m, S through the identity paths,
  // mb and sb) back through the trig augmentation to *m_bar, *S_bar.
  absl::Status FinishStepBackward(const StepCache& c, const Vector& p_mean_bar,
                                  const Matrix& p_cov_bar, const Matrix& s_xp_bar, Vector mb,
                                  Matrix sb, Vector* m_bar, Matrix* S_bar) const;

  const GaussianInputGp* dynamics_;
  PropagationOptions options_;
  std::vector<int> angles_;  // options_.Angles()
  int state_dim_ = 0;
  int policy_input_dim_ = 0;
  std::vector<int> policy_index_;  // Ep indices into y
  std::vector<int> dynamics_index_;  // Eq indices into y; empty: the GP sees p
  RbfPolicyShape shape_;
  GaussianPredictionOptions dyn_options_;
};

// Predicted state distributions and expected costs over a horizon.
struct Trajectory {
  std::vector<Vector> means;  // H + 1, means[0] = mu0
  std::vector<Matrix> covs;   // H + 1
  Vector cost_mean;           // H, E[c(x_t)] for t = 1..H
  Vector cost_std;            // H, sqrt(Var[c(x_t)])
  double total_cost = 0;      // J = sum of cost_mean
};

// Runs the horizon from N(mu0, S0). If `gradient` is non-null it receives
// dJ/dparams (num_parameters()). Errors name the step (1-based) and block.
absl::Status PredictTrajectory(const Propagator& propagator, const gaussian::GaussianCost& cost,
                               const Vector& params, const Vector& mu0, const Matrix& S0,
                               int horizon, Trajectory* trajectory, Vector* gradient);

}  // namespace totalgrad::pilco

#endif  // TOTALGRAD_CORE_PILCO_PROPAGATION_H_
