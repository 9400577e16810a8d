// Test-only systems for the estimator tests, with exact references.
//
// LinearGaussian: dynamics x_{t+1} = x_t + A x_t + B u_t + sqrt(v) .* eps
// (constant variance v, scaled by the noise multiplier; B: S x F, F controls),
// linear policy u = K x + k0 with parameters theta = [K row-major (F x S),
// k0 (F)] (one control: [k (S), k0]), quadratic cost
// c(x) = (x - target)^T diag(q) (x - target). The state stays Gaussian:
//   mu_{t+1} = M mu_t + B k0,  Sigma_{t+1} = M Sigma_t M^T + diag(v),
//   M = I + A + B K,   J = sum_{t=1..H} (mu_t - target)^T Q (mu_t - target) + tr(Q Sigma_t),
// and dJ/dtheta follows by differentiating the recursion (forward mode).
// Controls are batched particle-major (estimators::ParticlePolicy).
#ifndef TOTALGRAD_TESTS_CORE_ESTIMATORS_LINEAR_GAUSSIAN_H_
#define TOTALGRAD_TESTS_CORE_ESTIMATORS_LINEAR_GAUSSIAN_H_

#include <cmath>
#include <string>
#include <vector>

#include "core/common/check.h"
#include "core/estimators/rollout.h"
#include "core/tasks/cost.h"

namespace totalgrad::estimators::testing {

// Mean difference A x + B u, variance latent + multiplier * noise (constant).
class LinearDynamics final : public ParticleDynamics {
 public:
  // B: S x F (one control: a vector b converts to S x 1).
  LinearDynamics(Matrix a, Matrix b, Vector latent_var, Vector noise_var)
      : a_(std::move(a)), b_(std::move(b)), latent_(std::move(latent_var)), noise_(std::move(noise_var)) {}
  int state_dim() const override { return static_cast<int>(b_.rows()); }
  int input_dim() const override { return static_cast<int>(b_.rows() + b_.cols()); }
  void Predict(const ConstRowMatrixRef& z, double multiplier, RowMatrix* mean, RowMatrix* variance,
               RowMatrix* dmean_dz, RowMatrix* dvar_dz) const override {
    const Eigen::Index p = z.rows();
    const int s = state_dim(), f = static_cast<int>(b_.cols()), e = s + f;
    *mean = z.leftCols(s) * a_.transpose();
    *mean += z.rightCols(f) * b_.transpose();
    if (variance != nullptr) {
      variance->resize(p, s);
      variance->rowwise() = (latent_ + multiplier * noise_).transpose();
    }
    if (dmean_dz != nullptr) {
      dmean_dz->resize(p, s * e);
      for (int r = 0; r < s; ++r) {
        for (int m = 0; m < s; ++m) dmean_dz->col(r * e + m).setConstant(a_(r, m));
        for (int j = 0; j < f; ++j) dmean_dz->col(r * e + s + j).setConstant(b_(r, j));
      }
    }
    if (dvar_dz != nullptr) dvar_dz->setZero(p, s * e);
  }
  const Matrix& a() const { return a_; }
  const Matrix& b() const { return b_; }  // S x F
  Vector variance(double multiplier) const { return latent_ + multiplier * noise_; }

 private:
  Matrix a_, b_;
  Vector latent_, noise_;
};

// u = K x + k0 (F controls); theta = [K row-major (F x S), k0 (F)], F = 1:
// [k, k0]. Uses PolicyCache::states only.
class LinearPolicy final : public ParticlePolicy {
 public:
  explicit LinearPolicy(Vector theta, int controls = 1) : theta_(std::move(theta)), f_(controls) {
    TG_CHECK(f_ >= 1 && theta_.size() % f_ == 0 && theta_.size() / f_ >= 2);
  }
  int state_dim() const override { return static_cast<int>(theta_.size()) / f_ - 1; }
  int control_dim() const override { return f_; }
  int num_parameters() const override { return static_cast<int>(theta_.size()); }
  void Evaluate(const ConstRowMatrixRef& states, Vector* forces, PolicyCache* cache) const override {
    const Eigen::Index p = states.rows();
    forces->resize(p * f_);
    Eigen::Map<RowMatrix> u(forces->data(), p, f_);  // particle-major
    u = states * gain().transpose();
    u.rowwise() += theta_.tail(f_).transpose();
    if (cache != nullptr) cache->states = states;
  }
  void Backward(const PolicyCache& cache, const Vector& force_bar, RowMatrix* state_bar,
                RowMatrix* per_particle, Vector* param_bar) const override {
    const int s = state_dim();
    const Eigen::Index p = cache.states.rows();
    TG_CHECK(force_bar.size() == p * f_);
    const Eigen::Map<const RowMatrix> ub(force_bar.data(), p, f_);
    if (state_bar != nullptr) *state_bar = ub * gain();
    if (per_particle != nullptr) {
      TG_CHECK(per_particle->rows() == p && per_particle->cols() == num_parameters());
      for (int j = 0; j < f_; ++j) {
        per_particle->middleCols(j * s, s) += ub.col(j).asDiagonal() * cache.states;
        per_particle->col(f_ * s + j) += ub.col(j);
      }
    }
    if (param_bar != nullptr) {
      for (int j = 0; j < f_; ++j) {
        param_bar->segment(j * s, s) += cache.states.transpose() * ub.col(j);
        (*param_bar)(f_ * s + j) += ub.col(j).sum();
      }
    }
  }
  // K (F x S).
  Eigen::Map<const RowMatrix> gain() const {
    return Eigen::Map<const RowMatrix>(theta_.data(), f_, state_dim());
  }
  const Vector& theta() const { return theta_; }
  void set_theta(const Vector& t) { theta_ = t; }

 private:
  Vector theta_;
  int f_;
};

// c(x) = (x - target)^T diag(q) (x - target), any state dimension.
class QuadraticCost final : public tasks::StateCost {
 public:
  QuadraticCost(Vector target, Vector q) : target_(std::move(target)), q_(std::move(q)) {}
  void Evaluate(const ConstRowMatrixRef& x, Vector* cost, RowMatrix* grad) const override {
    const RowMatrix d = x.rowwise() - target_.transpose();
    const RowMatrix qd = d * q_.asDiagonal();
    *cost = qd.cwiseProduct(d).rowwise().sum();
    if (grad != nullptr) *grad = 2.0 * qd;
  }
  std::string Name() const override { return "quadratic"; }
  const Vector& target() const { return target_; }
  const Vector& q() const { return q_; }

 private:
  Vector target_, q_;
};

// A linear-Gaussian problem with its exact objective and gradient.
struct LinearGaussian {
  LinearDynamics dynamics;
  LinearPolicy policy;
  QuadraticCost cost;
  Problem problem;

  LinearGaussian(LinearDynamics d, LinearPolicy p, QuadraticCost c, Vector mu0, Vector s0, int horizon)
      : dynamics(std::move(d)), policy(std::move(p)), cost(std::move(c)) {
    problem.dynamics = &dynamics;
    problem.policy = &policy;
    problem.cost = &cost;
    problem.mu0 = std::move(mu0);
    problem.initial_std = std::move(s0);
    problem.horizon = horizon;
  }
  LinearGaussian(const LinearGaussian&) = delete;
  LinearGaussian& operator=(const LinearGaussian&) = delete;

  // Per-step marginal moments mu_t, Sigma_t for t = 1..H and their
  // derivatives along theta_k (forward mode); J and dJ/dtheta; also
  // sum_t tr(Q Sigma_t) and its gradient (the Gaussian-shaping bias term).
  struct Exact {
    double j = 0;
    Vector gradient;
    double trace_term = 0;
    Vector trace_gradient;
  };
  Exact Solve() const {
    const int s = dynamics.state_dim(), fc = policy.control_dim(), n = policy.num_parameters();
    const Vector& theta = policy.theta();
    const Matrix& b = dynamics.b();
    const Matrix q = cost.q().asDiagonal();
    const Matrix f = Matrix::Identity(s, s) + dynamics.a() + b * Matrix(policy.gain());
    const Vector v = dynamics.variance(problem.noise_variance_multiplier);
    Vector mu = problem.mu0;
    Matrix sigma = problem.initial_std.array().square().matrix().asDiagonal();
    std::vector<Vector> dmu(n, Vector::Zero(s));
    std::vector<Matrix> dsigma(n, Matrix::Zero(s, s));
    Exact out;
    out.gradient = Vector::Zero(n);
    out.trace_gradient = Vector::Zero(n);
    for (int t = 0; t < problem.horizon; ++t) {
      for (int k = 0; k < n; ++k) {
        // theta_k is K(j, m) (k = j S + m: dM = B(:, j) e_m^T) or k0_j
        // (k = F S + j: the constant term B(:, j)).
        Matrix df = Matrix::Zero(s, s);
        Vector dc = Vector::Zero(s);
        if (k < fc * s) df.col(k % s) = b.col(k / s);
        else dc = b.col(k - fc * s);
        const Vector dmu_next = df * mu + f * dmu[k] + dc;
        const Matrix dsig_next = df * sigma * f.transpose() + f * sigma * df.transpose() +
                                 f * dsigma[k] * f.transpose();
        dmu[k] = dmu_next;
        dsigma[k] = dsig_next;
      }
      mu = (f * mu + b * theta.tail(fc)).eval();
      sigma = (f * sigma * f.transpose()).eval();
      sigma.diagonal() += v;
      const Vector d = mu - cost.target();
      out.j += d.dot(q * d) + (q * sigma).trace();
      out.trace_term += (q * sigma).trace();
      for (int k = 0; k < n; ++k) {
        out.gradient(k) += 2.0 * d.dot(q * dmu[k]) + (q * dsigma[k]).trace();
        out.trace_gradient(k) += (q * dsigma[k]).trace();
      }
    }
    return out;
  }
};

// A 2-D example: a lightly damped oscillator, pushed by the force.
inline std::unique_ptr<LinearGaussian> MakeOscillator(int horizon, double noise_std = 0.1) {
  Matrix a(2, 2);
  a << 0.0, 0.1, -0.1, -0.05;
  Vector b(2);
  b << 0.0, 0.1;
  Vector latent = Vector::Zero(2);
  Vector noise = Vector::Constant(2, noise_std * noise_std);
  Vector theta(3);
  theta << -0.5, -0.3, 0.2;
  Vector target(2);
  target << 1.0, 0.0;
  Vector q(2);
  q << 1.0, 0.5;
  Vector mu0(2);
  mu0 << 0.0, 0.0;
  Vector s0 = Vector::Constant(2, 0.2);
  return std::make_unique<LinearGaussian>(LinearDynamics(a, b, latent, noise), LinearPolicy(theta),
                                          QuadraticCost(target, q), mu0, s0, horizon);
}

// A 3-D system pushed by two controls (F = 2) through a B whose columns
// reach different states, so that each control's gain matters on its own.
inline std::unique_ptr<LinearGaussian> MakeTwoControlSystem(int horizon, double noise_std = 0.1) {
  Matrix a(3, 3);
  a << 0.0, 0.1, 0.0,  //
      -0.1, -0.05, 0.05,  //
      0.0, 0.02, -0.1;
  Matrix b(3, 2);
  b << 0.0, 0.05,  //
      0.1, 0.0,  //
      0.02, 0.1;
  Vector latent = Vector::Zero(3);
  Vector noise = Vector::Constant(3, noise_std * noise_std);
  Vector theta(8);  // K (2 x 3) row-major, then k0 (2)
  theta << -0.5, -0.3, 0.1,  //
      0.2, -0.1, -0.4,  //
      0.2, -0.1;
  Vector target(3);
  target << 1.0, 0.0, -0.5;
  Vector q(3);
  q << 1.0, 0.5, 0.8;
  Vector mu0 = Vector::Zero(3);
  Vector s0 = Vector::Constant(3, 0.2);
  return std::make_unique<LinearGaussian>(LinearDynamics(a, b, latent, noise), LinearPolicy(theta, 2),
                                          QuadraticCost(target, q), mu0, s0, horizon);
}

}  // namespace totalgrad::estimators::testing

#endif  // TOTALGRAD_TESTS_CORE_ESTIMATORS_LINEAR_GAUSSIAN_H_
