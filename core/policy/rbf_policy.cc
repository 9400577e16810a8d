#include "core/policy/rbf_policy.h"

#include <cmath>
#include <cstring>

#include "core/common/check.h"
#include "core/common/simd.h"
#include "core/common/thread_pool.h"
#include "core/common/vector_exp.h"

namespace totalgrad::policy {
namespace {

// Per-thread scratch of Evaluate and Backward (both are const and
// thread-safe): no heap allocation per call once the shapes have been seen.
// Shared: written by the caller's call, rows filled by the blocks.
struct PolicyWorkspace {
  RowMatrix cs, g;
  Vector a_bar;
};
// Per block, on whichever thread runs it.
struct BlockWorkspace {
  RowMatrix xs, gc;
  Vector g_rowsum;
};

PolicyWorkspace& ThreadWorkspace() {
  thread_local PolicyWorkspace workspace;
  return workspace;
}

BlockWorkspace& ThreadBlockWorkspace() {
  thread_local BlockWorkspace workspace;
  return workspace;
}

// Row i's parameter adjoint (n = C S + S + C F entries, ADDED to row):
//   centres:  row[k S + m]     += g_k (x_m - c_km) / l_m^2
//   log l_m:  row[C S + m]     += sum_k g_k (x_m - c_km)^2 / l_m^2   (k in order)
//   weights:  row[C S + S + k F + j] += a_bar_j phi_k
// x: the particle's state (S), g: its C basis weights, centres: C x S
// row-major, inv_l2: S. S = 4 (the cart-pole's) runs on 4-lane vectors, one
// basis function per vector operation; other S on the generic loop. Both do
// the same IEEE operations per entry, so every ISA clone gives the same bits.
typedef double Doubles4 __attribute__((vector_size(4 * sizeof(double))));

// weights(k, j) (row-major C x F) += a_bar_j phi_k.
inline void WeightAdjoint(const double* phi, const double* a_bar, int c_count, int f_count,
                          double* weights) {
  if (f_count == 1) {
    // One control (most scenes): a contiguous axpy that the compiler
    // vectorises; the general loop's runtime-F inner loop is not, and costs
    // the cart-pole's RP iteration ~5 % at N = 30. Same operations, same bits.
    const double a = a_bar[0];
    for (int k = 0; k < c_count; ++k) weights[k] += a * phi[k];
    return;
  }
  for (int k = 0; k < c_count; ++k)
    for (int j = 0; j < f_count; ++j) weights[k * f_count + j] += a_bar[j] * phi[k];
}

TG_VECTOR_CLONES void ParticleParameterAdjoint4(const double* x, const double* g,
                                                const double* centres, const double* inv_l2,
                                                const double* phi, const double* a_bar,
                                                int c_count, int f_count, double* row) {
  Doubles4 xv, il2, loglen = {0.0, 0.0, 0.0, 0.0};
  std::memcpy(&xv, x, sizeof(xv));
  std::memcpy(&il2, inv_l2, sizeof(il2));
  for (int k = 0; k < c_count; ++k) {
    Doubles4 c, r;
    std::memcpy(&c, centres + 4 * k, sizeof(c));
    std::memcpy(&r, row + 4 * k, sizeof(r));
    const Doubles4 diff = xv - c;
    const Doubles4 term = g[k] * diff * il2;
    r += term;
    std::memcpy(row + 4 * k, &r, sizeof(r));
    loglen += term * diff;
  }
  double* ll = row + 4 * c_count;
  for (int m = 0; m < 4; ++m) ll[m] += loglen[m];
  WeightAdjoint(phi, a_bar, c_count, f_count, ll + 4);
}

void ParticleParameterAdjointAny(const double* x, const double* g, const double* centres,
                                 const double* inv_l2, const double* phi, const double* a_bar,
                                 int c_count, int f_count, int s_dim, double* row) {
  double* ll = row + c_count * s_dim;
  for (int m = 0; m < s_dim; ++m) {
    double sum = 0;
    for (int k = 0; k < c_count; ++k) {
      const double diff = x[m] - centres[k * s_dim + m];
      const double term = g[k] * diff * inv_l2[m];
      row[k * s_dim + m] += term;
      sum += term * diff;
    }
    ll[m] += sum;
  }
  WeightAdjoint(phi, a_bar, c_count, f_count, ll + s_dim);
}

}  // namespace

double Saturate(double a, double u_max) { return u_max * (9.0 * std::sin(a) + std::sin(3.0 * a)) / 8.0; }

double DaSaturate(double a, double u_max) {
  return u_max * (9.0 * std::cos(a) + 3.0 * std::cos(3.0 * a)) / 8.0;
}

RbfPolicy::RbfPolicy(int num_basis, int state_dim, double max_force)
    : RbfPolicy(num_basis, state_dim, Vector::Constant(1, max_force)) {}

RbfPolicy::RbfPolicy(int num_basis, int state_dim, const Vector& max_control)
    : num_basis_(num_basis), state_dim_(state_dim), max_control_(max_control) {
  TG_CHECK(num_basis > 0 && state_dim > 0 && max_control.size() > 0);
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
  return Eigen::Map<const Vector>(params_.data() + num_basis_ * state_dim_ + state_dim_,
                                  num_basis_ * control_dim());
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
  for (int k = 0; k < num_basis_ * control_dim(); ++k)
    params_(num_basis_ * state_dim_ + state_dim_ + k) = rng->Uniform(-bound, bound);
}

void RbfPolicy::Evaluate(const ConstRowMatrixRef& states, Vector* forces, Cache* cache,
                         ThreadPool* pool) const {
  TG_CHECK_EQ(states.cols(), state_dim_);
  const Eigen::Index p = states.rows();
  PolicyWorkspace& ws = ThreadWorkspace();
  const Vector inv_l = (-log_lengthscales().array()).exp();
  ws.cs.noalias() = centres() * inv_l.asDiagonal();
  const Vector cs_sq = ws.cs.rowwise().squaredNorm();
  Cache local;
  Cache& out = cache != nullptr ? *cache : local;
  const int f_count = control_dim();
  out.phi.resize(p, num_basis_);
  out.pre.resize(p * f_count);
  forces->resize(p * f_count);
  const auto w = weights();
  const Eigen::Map<const RowMatrix> w_matrix(w.data(), num_basis_, f_count);
  const RowMatrix& cs = ws.cs;
  ParallelForBlocks(pool, p, kParticleBlock, [&](int64_t begin, int64_t end) {
    const Eigen::Index rows = end - begin;
    BlockWorkspace& bw = ThreadBlockWorkspace();
    // Squared scaled distances through one product: |x|^2 + |c|^2 - 2 x.c.
    bw.xs.noalias() = states.middleRows(begin, rows) * inv_l.asDiagonal();
    auto phi = out.phi.middleRows(begin, rows);
    phi.noalias() = -2.0 * bw.xs * cs.transpose();
    phi.colwise() += bw.xs.rowwise().squaredNorm();
    phi.rowwise() += cs_sq.transpose();
    // exp(-1/2 max(d2, 0)): the argument is <= 0 (and NaN stays NaN).
    phi = -0.5 * phi.array().max(0.0);
    ExpNonPositive(phi.data(), phi.data(), phi.size());
    if (f_count == 1) {
      out.pre.segment(begin, rows).noalias() = phi * w;
      for (Eigen::Index i = begin; i < end; ++i) (*forces)(i) = Saturate(out.pre(i), max_control_(0));
      return;
    }
    Eigen::Map<RowMatrix> pre(out.pre.data() + begin * f_count, rows, f_count);
    pre.noalias() = phi * w_matrix;
    for (Eigen::Index i = begin * f_count; i < end * f_count; ++i)
      (*forces)(i) = Saturate(out.pre(i), max_control_(i % f_count));
  });
  if (cache != nullptr) cache->states = states;
}

void RbfPolicy::Backward(const Cache& cache, const Vector& force_bar, RowMatrix* state_bar,
                         RowMatrix* per_particle_param_bar, Vector* param_bar,
                         ThreadPool* pool) const {
  const Eigen::Index p = cache.states.rows();
  const int c_count = num_basis_, s_dim = state_dim_, f_count = control_dim();
  TG_CHECK_EQ(force_bar.size(), p * f_count);
  const Vector inv_l2 = (-2.0 * log_lengthscales().array()).exp();
  const auto c = centres();
  const auto w = weights();
  constexpr int centre_offset = 0;
  const int loglen_offset = c_count * s_dim;
  const int weight_offset = loglen_offset + s_dim;
  PolicyWorkspace& ws = ThreadWorkspace();
  Vector& a_bar = ws.a_bar;
  RowMatrix& g = ws.g;
  a_bar.resize(p * f_count);
  g.resize(p, c_count);
  const Eigen::Map<const RowMatrix> w_matrix(w.data(), c_count, f_count);
  if (state_bar != nullptr) state_bar->resize(p, s_dim);
  if (per_particle_param_bar != nullptr) {
    TG_CHECK(per_particle_param_bar->rows() == p &&
             per_particle_param_bar->cols() == num_parameters());
  }
  ParallelForBlocks(pool, p, kParticleBlock, [&](int64_t begin, int64_t end) {
    const Eigen::Index rows = end - begin;
    BlockWorkspace& bw = ThreadBlockWorkspace();
    // a_bar = force_bar * dforce/da.
    for (Eigen::Index i = begin * f_count; i < end * f_count; ++i)
      a_bar(i) = force_bar(i) * DaSaturate(cache.pre(i), max_control_(i % f_count));
    // G(i,k) = sum_j a_bar_ij w_kj phi_ik: the weight of basis k in particle
    // i's adjoint.
    auto g_rows = g.middleRows(begin, rows);
    if (f_count == 1) {
      g_rows = cache.phi.middleRows(begin, rows).array().rowwise() * w.transpose().array();
      g_rows.array().colwise() *= a_bar.segment(begin, rows).array();
    } else {
      const Eigen::Map<const RowMatrix> a_bar_rows(a_bar.data() + begin * f_count, rows, f_count);
      g_rows.noalias() = a_bar_rows * w_matrix.transpose();
      g_rows.array() *= cache.phi.middleRows(begin, rows).array();
    }
    if (state_bar != nullptr) {
      // d a / d x_m = -sum_k w_k phi_k (x_m - c_km) / l_m^2, with
      // sum_k G_ik (x_im - c_km) = x_im rowsum_i - (G C)_im.
      bw.g_rowsum.noalias() = g_rows.rowwise().sum();
      bw.gc.noalias() = g_rows * c;  // rows x S
      for (Eigen::Index r = 0; r < rows; ++r)
        for (int m = 0; m < s_dim; ++m)
          (*state_bar)(begin + r, m) =
              -(cache.states(begin + r, m) * bw.g_rowsum(r) - bw.gc(r, m)) * inv_l2(m);
    }
    if (per_particle_param_bar != nullptr) {
      RowMatrix& pp = *per_particle_param_bar;
      static_assert(centre_offset == 0, "the centre block starts each row");
      for (Eigen::Index i = begin; i < end; ++i) {
        if (s_dim == 4) {
          ParticleParameterAdjoint4(cache.states.row(i).data(), g.row(i).data(), c.data(),
                                    inv_l2.data(), cache.phi.row(i).data(),
                                    a_bar.data() + i * f_count, c_count, f_count,
                                    pp.row(i).data());
        } else {
          ParticleParameterAdjointAny(cache.states.row(i).data(), g.row(i).data(), c.data(),
                                      inv_l2.data(), cache.phi.row(i).data(),
                                      a_bar.data() + i * f_count, c_count, f_count, s_dim,
                                      pp.row(i).data());
        }
      }
    }
  });
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
    if (f_count == 1) {
      pb.segment(weight_offset, c_count).noalias() += cache.phi.transpose() * a_bar;
    } else {
      Eigen::Map<RowMatrix>(pb.data() + weight_offset, c_count, f_count).noalias() +=
          cache.phi.transpose() * Eigen::Map<const RowMatrix>(a_bar.data(), p, f_count);
    }
  }
}

}  // namespace totalgrad::policy
