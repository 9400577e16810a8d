#include "core/policy/rbf_policy.h"

#include <cmath>

#include "core/common/check.h"

namespace totalgrad::policy {

double Saturate(double a, double u_max) { return u_max * (9.0 * std::sin(a) + std::sin(3.0 * a)) / 8.0; }

double DaSaturate(double a, double u_max) {
  return u_max * (9.0 * std::cos(a) + 3.0 * std::cos(3.0 * a)) / 8.0;
}

RbfPolicy::RbfPolicy(int num_basis, int state_dim, double max_force)
    : num_basis_(num_basis), state_dim_(state_dim), max_force_(max_force) {
  TG_CHECK(num_basis > 0 && state_dim > 0);
  params_ = Vector::Zero(num_parameters());
}

void RbfPolicy::set_parameters(const Vector& p) {
  TG_CHECK_EQ(p.size(), num_parameters());
  params_ = p;
}

Eigen::Map<const RowMatrix> RbfPolicy::centres() const {
  return Eigen::Map<const RowMatrix>(params_.data(), num_basis_, state_dim_);
}
Eigen::Map<const Vector> RbfPolicy::log_lengthscales() const {
  return Eigen::Map<const Vector>(params_.data() + num_basis_ * state_dim_, state_dim_);
}
Eigen::Map<const Vector> RbfPolicy::weights() const {
  return Eigen::Map<const Vector>(params_.data() + num_basis_ * state_dim_ + state_dim_, num_basis_);
}

void RbfPolicy::Initialize(const Vector& mean, const Vector& centre_std, double lengthscale,
                           Rng* rng) {
  TG_CHECK_EQ(mean.size(), state_dim_);
  TG_CHECK_EQ(centre_std.size(), state_dim_);
  TG_CHECK(lengthscale > 0);
  Eigen::Map<RowMatrix> c(params_.data(), num_basis_, state_dim_);
  for (int k = 0; k < num_basis_; ++k)
    for (int m = 0; m < state_dim_; ++m) c(k, m) = mean(m) + centre_std(m) * rng->Normal();
  params_.segment(num_basis_ * state_dim_, state_dim_).setConstant(std::log(lengthscale));
  const double bound = 1.0 / std::sqrt(static_cast<double>(num_basis_));
  for (int k = 0; k < num_basis_; ++k)
    params_(num_basis_ * state_dim_ + state_dim_ + k) = rng->Uniform(-bound, bound);
}

void RbfPolicy::Evaluate(const ConstRowMatrixRef& states, Vector* forces, Cache* cache) const {
  TG_CHECK_EQ(states.cols(), state_dim_);
  const Eigen::Index p = states.rows();
  const Vector inv_l = (-log_lengthscales().array()).exp();
  // Squared scaled distances through one product: |x|^2 + |c|^2 - 2 x.c.
  const RowMatrix xs = states * inv_l.asDiagonal();
  const RowMatrix cs = centres() * inv_l.asDiagonal();
  RowMatrix phi(p, num_basis_);
  phi.noalias() = -2.0 * xs * cs.transpose();
  phi.colwise() += xs.rowwise().squaredNorm();
  phi.rowwise() += cs.rowwise().squaredNorm().transpose();
  phi = (-0.5 * phi.array().max(0.0)).exp();
  Vector pre = phi * weights();
  forces->resize(p);
  for (Eigen::Index i = 0; i < p; ++i) (*forces)(i) = Saturate(pre(i), max_force_);
  if (cache != nullptr) {
    cache->states = states;
    cache->phi = std::move(phi);
    cache->pre = std::move(pre);
  }
}

void RbfPolicy::Backward(const Cache& cache, const Vector& force_bar, RowMatrix* state_bar,
                         RowMatrix* per_particle_param_bar, Vector* param_bar) const {
  const Eigen::Index p = cache.states.rows();
  const int c_count = num_basis_, s_dim = state_dim_;
  TG_CHECK_EQ(force_bar.size(), p);
  const Vector inv_l2 = (-2.0 * log_lengthscales().array()).exp();
  const auto c = centres();
  const auto w = weights();
  // a_bar = force_bar * dforce/da.
  Vector a_bar(p);
  for (Eigen::Index i = 0; i < p; ++i) a_bar(i) = force_bar(i) * DaSaturate(cache.pre(i), max_force_);
  // G(i,k) = a_bar_i w_k phi_ik: the weight of basis k in particle i's adjoint.
  RowMatrix g = cache.phi.array().rowwise() * w.transpose().array();
  g.array().colwise() *= a_bar.array();
  const Vector g_rowsum = g.rowwise().sum();
  // sum_k G_ik (x_im - c_km) = x_im rowsum_i - (G C)_im.
  const RowMatrix gc = g * c;  // P x S
  // d a / d x_m = -sum_k w_k phi_k (x_m - c_km) / l_m^2.
  if (state_bar != nullptr) {
    state_bar->resize(p, s_dim);
    for (Eigen::Index i = 0; i < p; ++i)
      for (int m = 0; m < s_dim; ++m)
        (*state_bar)(i, m) = -(cache.states(i, m) * g_rowsum(i) - gc(i, m)) * inv_l2(m);
  }
  if (per_particle_param_bar == nullptr && param_bar == nullptr) return;
  const int centre_offset = 0;
  const int loglen_offset = c_count * s_dim;
  const int weight_offset = loglen_offset + s_dim;
  if (per_particle_param_bar != nullptr) {
    RowMatrix& pp = *per_particle_param_bar;
    TG_CHECK(pp.rows() == p && pp.cols() == num_parameters());
    for (Eigen::Index i = 0; i < p; ++i) {
      double* row = pp.row(i).data();
      for (int k = 0; k < c_count; ++k) {
        const double gik = g(i, k);
        double* ck = row + centre_offset + k * s_dim;
        for (int m = 0; m < s_dim; ++m) {
          const double diff = cache.states(i, m) - c(k, m);
          // d a / d c_km = w_k phi_k (x_m - c_km) / l_m^2
          ck[m] += gik * diff * inv_l2(m);
          // d a / d log l_m = w_k phi_k (x_m - c_km)^2 / l_m^2
          row[loglen_offset + m] += gik * diff * diff * inv_l2(m);
        }
        row[weight_offset + k] += a_bar(i) * cache.phi(i, k);
      }
    }
  }
  if (param_bar != nullptr) {
    Vector& pb = *param_bar;
    TG_CHECK_EQ(pb.size(), num_parameters());
    // Column sums, via products rather than a loop over particles.
    const Vector gsum = g.colwise().sum();  // C
    const RowMatrix gtx = g.transpose() * cache.states;  // C x S: sum_i G_ik x_im
    RowMatrix states_sq = cache.states.array().square();
    const RowMatrix gtx2 = g.transpose() * states_sq;  // sum_i G_ik x_im^2
    for (int k = 0; k < c_count; ++k) {
      for (int m = 0; m < s_dim; ++m) {
        const double ckm = c(k, m);
        pb(centre_offset + k * s_dim + m) += (gtx(k, m) - gsum(k) * ckm) * inv_l2(m);
        pb(loglen_offset + m) +=
            (gtx2(k, m) - 2.0 * ckm * gtx(k, m) + ckm * ckm * gsum(k)) * inv_l2(m);
      }
    }
    pb.segment(weight_offset, c_count).noalias() += cache.phi.transpose() * a_bar;
  }
}

}  // namespace totalgrad::policy
