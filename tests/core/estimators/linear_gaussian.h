// Test-only systems for the estimator tests, with exact references.
//
// LinearGaussian: dynamics x_{t+1} = x_t + A x_t + b u_t + sqrt(v) .* eps
// (constant variance v, scaled by the noise multiplier), linear policy
// u = k^T x + k0 with parameters theta = [k (S), k0], quadratic cost
// c(x) = (x - target)^T diag(q) (x - target). The state stays Gaussian:
//   mu_{t+1} = F mu_t + b k0,  Sigma_{t+1} = F Sigma_t F^T + diag(v),
//   F = I + A + b k^T,   J = sum_{t=1..H} (mu_t - target)^T Q (mu_t - target) + tr(Q Sigma_t),
// and dJ/dtheta follows by differentiating the recursion (forward mode).
#ifndef TOTALGRAD_TESTS_CORE_ESTIMATORS_LINEAR_GAUSSIAN_H_
#define TOTALGRAD_TESTS_CORE_ESTIMATORS_LINEAR_GAUSSIAN_H_

#include <cmath>
#include <string>
#include <vector>

#include "core/common/check.h"
#include "core/estimators/rollout.h"
#include "core/tasks/cost.h"

namespace totalgrad::estimators::testing {

// Mean difference A x + b u, variance latent + multiplier * noise (constant).
class LinearDynamics final : public ParticleDynamics {
 public:
  LinearDynamics(Matrix a, Vector b, Vector latent_var, Vector noise_var)
      : a_(std::move(a)), b_(std::move(b)), latent_(std::move(latent_var)), noise_(std::move(noise_var)) {}
  int state_dim() const override { return static_cast<int>(b_.size()); }
  void Predict(const ConstRowMatrixRef& z, double multiplier, RowMatrix* mean, RowMatrix* variance,
               RowMatrix* dmean_dz, RowMatrix* dvar_dz) const override {
    const Eigen::Index p = z.rows();
    const int s = state_dim(), e = s + 1;
    *mean = z.leftCols(s) * a_.transpose();
    *mean += z.col(s) * b_.transpose();
    if (variance != nullptr) {
      variance->resize(p, s);
      variance->rowwise() = (latent_ + multiplier * noise_).transpose();
    }
    if (dmean_dz != nullptr) {
      dmean_dz->resize(p, s * e);
      for (int r = 0; r < s; ++r) {
        for (int m = 0; m < s; ++m) dmean_dz->col(r * e + m).setConstant(a_(r, m));
        dmean_dz->col(r * e + s).setConstant(b_(r));
      }
    }
    if (dvar_dz != nullptr) dvar_dz->setZero(p, s * e);
  }
  const Matrix& a() const { return a_; }
  const Vector& b() const { return b_; }
  Vector variance(double multiplier) const { return latent_ + multiplier * noise_; }

 private:
  Matrix a_;
  Vector b_, latent_, noise_;
};

// u = k^T x + k0; theta = [k, k0]. Uses PolicyCache::states only.
class LinearPolicy final : public ParticlePolicy {
 public:
  explicit LinearPolicy(Vector theta) : theta_(std::move(theta)) {}
  int state_dim() const override { return static_cast<int>(theta_.size()) - 1; }
  int num_parameters() const override { return static_cast<int>(theta_.size()); }
  void Evaluate(const ConstRowMatrixRef& states, Vector* forces, PolicyCache* cache) const override {
    const int s = state_dim();
    *forces = states * theta_.head(s);
    forces->array() += theta_(s);
    if (cache != nullptr) cache->states = states;
  }
  void Backward(const PolicyCache& cache, const Vector& force_bar, RowMatrix* state_bar,
                RowMatrix* per_particle, Vector* param_bar) const override {
    const int s = state_dim();
    const Eigen::Index p = cache.states.rows();
    if (state_bar != nullptr) *state_bar = force_bar * theta_.head(s).transpose();
    if (per_particle != nullptr) {
      TG_CHECK(per_particle->rows() == p && per_particle->cols() == s + 1);
      per_particle->leftCols(s) += force_bar.asDiagonal() * cache.states;
      per_particle->col(s) += force_bar;
    }
    if (param_bar != nullptr) {
      param_bar->head(s) += cache.states.transpose() * force_bar;
      (*param_bar)(s) += force_bar.sum();
    }
  }
  const Vector& theta() const { return theta_; }
  void set_theta(const Vector& t) { theta_ = t; }

 private:
  Vector theta_;
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
    const int s = dynamics.state_dim(), n = s + 1;
    const Vector& theta = policy.theta();
    const Matrix q = cost.q().asDiagonal();
    const Matrix f = Matrix::Identity(s, s) + dynamics.a() + dynamics.b() * theta.head(s).transpose();
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
        Matrix df = Matrix::Zero(s, s);
        Vector dc = Vector::Zero(s);
        if (k < s) df.col(k) = dynamics.b();
        else dc = dynamics.b();
        const Vector dmu_next = df * mu + f * dmu[k] + dc;
        const Matrix dsig_next = df * sigma * f.transpose() + f * sigma * df.transpose() +
                                 f * dsigma[k] * f.transpose();
        dmu[k] = dmu_next;
        dsigma[k] = dsig_next;
      }
      mu = (f * mu + dynamics.b() * theta(s)).eval();
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

}  // namespace totalgrad::estimators::testing

#endif  // TOTALGRAD_TESTS_CORE_ESTIMATORS_LINEAR_GAUSSIAN_H_
