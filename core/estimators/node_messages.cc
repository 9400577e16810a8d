#include "core/estimators/node_messages.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "core/common/check.h"
#include "core/common/simd.h"

namespace totalgrad::estimators {

void RpZetaCotangent(const StepRecord& step, const RowMatrix& gamma, ZetaCotangent* out) {
  TG_CHECK(gamma.rows() == step.noise.rows() && gamma.cols() == step.noise.cols());
  out->mean = gamma;
  // Where a model predicts exactly zero variance (a deterministic transition)
  // the variance path is dropped, as the GP does where its variance floor
  // binds: its Jacobian there is zero, and 0 * Inf must not become NaN.
  out->variance = (step.variance.array() > 0)
                      .select(gamma.array() * step.noise.array() / (2.0 * step.variance.array().sqrt()), 0.0)
                      .matrix();
}

void TransitionVjp(const StepRecord& step, const ZetaCotangent& cotangent, Vector* force_bar,
                   RowMatrix* state_bar, ThreadPool* pool) {
  const Eigen::Index p = step.state.rows();
  const int s_dim = static_cast<int>(step.state.cols());
  const int f_dim = static_cast<int>(step.force.size() / std::max<Eigen::Index>(p, 1));
  const int e_dim = s_dim + f_dim;
  TG_CHECK(step.dmean_dz.rows() == p && step.dmean_dz.cols() == s_dim * e_dim);
  TG_CHECK(cotangent.mean.rows() == p && cotangent.variance.rows() == p);
  TG_CHECK(e_dim <= 64);
  force_bar->resize(p * f_dim);
  if (state_bar != nullptr) *state_bar = cotangent.mean;  // mu = x_t + mean(z): identity path
  ParallelForBlocks(pool, p, kParticleBlock, [&](int64_t begin, int64_t end) {
    double z_bar[64];
    for (Eigen::Index i = begin; i < end; ++i) {
      std::fill(z_bar, z_bar + e_dim, 0.0);
      const double* dm_row = step.dmean_dz.row(i).data();
      const double* dv_row = step.dvar_dz.row(i).data();
      for (int a = 0; a < s_dim; ++a) {
        const double m_bar = cotangent.mean(i, a);
        const double v_bar = cotangent.variance(i, a);
        const double* dm = dm_row + a * e_dim;
        const double* dv = dv_row + a * e_dim;
        for (int m = 0; m < e_dim; ++m) z_bar[m] += m_bar * dm[m] + v_bar * dv[m];
      }
      if (state_bar != nullptr)
        for (int m = 0; m < s_dim; ++m) (*state_bar)(i, m) += z_bar[m];
      for (int j = 0; j < f_dim; ++j) (*force_bar)(i * f_dim + j) = z_bar[s_dim + j];
    }
  });
}

double TraceVariance::value() const {
  if (non_finite) return std::numeric_limits<double>::infinity();
  return scale * scale * normalized;
}

TraceVariance RowTraceVariance(const RowMatrix& rows) {
  TraceVariance v;
  const Eigen::Index p = rows.rows();
  if (!rows.allFinite()) {
    v.non_finite = true;
    v.scale = std::numeric_limits<double>::infinity();
    return v;
  }
  if (p < 2) return v;
  const RowMatrix deviation = rows.rowwise() - rows.colwise().mean();
  v.scale = deviation.cwiseAbs().maxCoeff();
  if (!(v.scale > 0)) return v;
  v.normalized = (deviation / v.scale).squaredNorm() / static_cast<double>(p - 1);
  return v;
}

namespace {

// Calls visit.Lanes(d) on full packets and visit.Tail(d) on the rest of the
// deviations d_ij = factor_i rows_ij - mean_j (rows: p x n, row-major), rows
// in order, j ascending. Inlined into each vector clone of its callers, with
// the visitor's members.
template <typename Visitor>
__attribute__((always_inline)) inline void VisitDeviations(const double* factor,
                                                           const double* rows, Eigen::Index p,
                                                           Eigen::Index n, const double* mean,
                                                           Visitor* visit) {
  for (Eigen::Index i = 0; i < p; ++i) {
    const double f = factor[i];
    const double* r = rows + i * n;
    Eigen::Index j = 0;
    for (; j + simd::kLanes <= n; j += simd::kLanes) {
      visit->Lanes(f * simd::Load(r + j) - simd::Load(mean + j));
    }
    for (; j < n; ++j) visit->Tail(f * r[j] - mean[j]);
  }
}

// max over i, j of |factor_i rows_ij - mean_j|.
struct MaxAbsDeviation {
  simd::Doubles lanes = simd::Broadcast(0.0);
  double tail = 0;
  __attribute__((always_inline)) void Lanes(simd::Doubles d) {
    d = simd::Select(d < 0.0, -d, d);
    lanes = simd::Select(d > lanes, d, lanes);
  }
  __attribute__((always_inline)) void Tail(double d) { tail = std::max(tail, std::abs(d)); }
  __attribute__((always_inline)) double Result() const {
    double max = tail;
    for (int l = 0; l < simd::kLanes; ++l) max = std::max(max, lanes[l]);
    return max;
  }
};

// sum over i, j of ((factor_i rows_ij - mean_j) * inv)^2: lanes over j, rows
// in order, lanes combined in order.
struct ScaledSquares {
  double inv;
  simd::Doubles lanes = simd::Broadcast(0.0);
  double tail = 0;
  __attribute__((always_inline)) void Lanes(simd::Doubles d) {
    const simd::Doubles scaled = d * inv;
    lanes += scaled * scaled;
  }
  __attribute__((always_inline)) void Tail(double d) {
    const double scaled = d * inv;
    tail += scaled * scaled;
  }
  __attribute__((always_inline)) double Result() const { return simd::CombineLanes(lanes) + tail; }
};

TG_VECTOR_CLONES double MaxDeviation(const double* factor, const double* rows, Eigen::Index p,
                                     Eigen::Index n, const double* mean) {
  MaxAbsDeviation visit;
  VisitDeviations(factor, rows, p, n, mean, &visit);
  return visit.Result();
}

TG_VECTOR_CLONES double ScaledSquareSum(const double* factor, const double* rows, Eigen::Index p,
                                        Eigen::Index n, const double* mean, double inv) {
  ScaledSquares visit{inv};
  VisitDeviations(factor, rows, p, n, mean, &visit);
  return visit.Result();
}

// VisitDeviations for two factors over the same rows: each visitor sees the
// same deviations in the same order as VisitDeviations gives it alone.
template <typename VisitorA, typename VisitorB>
__attribute__((always_inline)) inline void VisitDeviationPairs(
    const double* factor_a, const double* factor_b, const double* rows, Eigen::Index p,
    Eigen::Index n, const double* mean_a, const double* mean_b, VisitorA* visit_a,
    VisitorB* visit_b) {
  for (Eigen::Index i = 0; i < p; ++i) {
    const double fa = factor_a[i], fb = factor_b[i];
    const double* r = rows + i * n;
    Eigen::Index j = 0;
    for (; j + simd::kLanes <= n; j += simd::kLanes) {
      const simd::Doubles x = simd::Load(r + j);
      visit_a->Lanes(fa * x - simd::Load(mean_a + j));
      visit_b->Lanes(fb * x - simd::Load(mean_b + j));
    }
    for (; j < n; ++j) {
      visit_a->Tail(fa * r[j] - mean_a[j]);
      visit_b->Tail(fb * r[j] - mean_b[j]);
    }
  }
}

TG_VECTOR_CLONES void MaxDeviationPair(const double* factor_a, const double* factor_b,
                                       const double* rows, Eigen::Index p, Eigen::Index n,
                                       const double* mean_a, const double* mean_b, double* max_a,
                                       double* max_b) {
  MaxAbsDeviation visit_a, visit_b;
  VisitDeviationPairs(factor_a, factor_b, rows, p, n, mean_a, mean_b, &visit_a, &visit_b);
  *max_a = visit_a.Result();
  *max_b = visit_b.Result();
}

TG_VECTOR_CLONES void ScaledSquareSumPair(const double* factor_a, const double* factor_b,
                                          const double* rows, Eigen::Index p, Eigen::Index n,
                                          const double* mean_a, const double* mean_b,
                                          double inv_a, double inv_b, double* sum_a,
                                          double* sum_b) {
  ScaledSquares visit_a{inv_a}, visit_b{inv_b};
  VisitDeviationPairs(factor_a, factor_b, rows, p, n, mean_a, mean_b, &visit_a, &visit_b);
  *sum_a = visit_a.Result();
  *sum_b = visit_b.Result();
}

}  // namespace

TraceVariance ScaledRowTraceVariance(const Vector& factor, const RowMatrix& rows, Vector* mean) {
  TraceVariance v;
  const Eigen::Index p = rows.rows(), n = rows.cols();
  TG_CHECK(factor.size() == p);
  if (!factor.allFinite() || !rows.allFinite()) {
    // A non-finite row entry: factor_i * rows_ij, with 0 * Inf counting too.
    v.non_finite = true;
    v.scale = std::numeric_limits<double>::infinity();
    return v;
  }
  if (p < 2) return v;
  // Column means, summed over i in order.
  mean->setZero(n);
  for (Eigen::Index i = 0; i < p; ++i) mean->noalias() += factor(i) * rows.row(i).transpose();
  *mean /= static_cast<double>(p);
  v.scale = MaxDeviation(factor.data(), rows.data(), p, n, mean->data());
  if (!(v.scale > 0)) return v;
  v.normalized = ScaledSquareSum(factor.data(), rows.data(), p, n, mean->data(), 1.0 / v.scale) /
                 static_cast<double>(p - 1);
  return v;
}

void ScaledRowTraceVariances(const Vector& factor_a, const Vector& factor_b,
                             const RowMatrix& rows, Vector* mean_a, Vector* mean_b,
                             TraceVariance* a, TraceVariance* b) {
  const Eigen::Index p = rows.rows(), n = rows.cols();
  TG_CHECK(factor_a.size() == p && factor_b.size() == p);
  // Where ScaledRowTraceVariance returns early for either branch, or either
  // reaches its last pass alone, each is computed on its own: the shared
  // passes below are only for the steps both take.
  const bool rows_finite = rows.allFinite();
  if (!rows_finite || !factor_a.allFinite() || !factor_b.allFinite() || p < 2) {
    *a = ScaledRowTraceVariance(factor_a, rows, mean_a);
    *b = ScaledRowTraceVariance(factor_b, rows, mean_b);
    return;
  }
  *a = TraceVariance();
  *b = TraceVariance();
  // Column means, each summed over i in order, as ScaledRowTraceVariance.
  mean_a->setZero(n);
  mean_b->setZero(n);
  for (Eigen::Index i = 0; i < p; ++i) {
    mean_a->noalias() += factor_a(i) * rows.row(i).transpose();
    mean_b->noalias() += factor_b(i) * rows.row(i).transpose();
  }
  *mean_a /= static_cast<double>(p);
  *mean_b /= static_cast<double>(p);
  MaxDeviationPair(factor_a.data(), factor_b.data(), rows.data(), p, n, mean_a->data(),
                   mean_b->data(), &a->scale, &b->scale);
  const bool spread_a = a->scale > 0, spread_b = b->scale > 0;
  if (spread_a && spread_b) {
    double sum_a = 0, sum_b = 0;
    ScaledSquareSumPair(factor_a.data(), factor_b.data(), rows.data(), p, n, mean_a->data(),
                        mean_b->data(), 1.0 / a->scale, 1.0 / b->scale, &sum_a, &sum_b);
    a->normalized = sum_a / static_cast<double>(p - 1);
    b->normalized = sum_b / static_cast<double>(p - 1);
    return;
  }
  if (spread_a) {
    a->normalized = ScaledSquareSum(factor_a.data(), rows.data(), p, n, mean_a->data(),
                                    1.0 / a->scale) / static_cast<double>(p - 1);
  }
  if (spread_b) {
    b->normalized = ScaledSquareSum(factor_b.data(), rows.data(), p, n, mean_b->data(),
                                    1.0 / b->scale) / static_cast<double>(p - 1);
  }
}

double CombinationWeight(const TraceVariance& rp, const TraceVariance& lr) {
  const bool rp_bad = rp.non_finite || !std::isfinite(rp.scale) || !std::isfinite(rp.normalized);
  const bool lr_bad = lr.non_finite || !std::isfinite(lr.scale) || !std::isfinite(lr.normalized);
  if (rp_bad && lr_bad) return 0.5;
  if (rp_bad) return 1.0;
  if (lr_bad) return 0.0;
  if (rp.zero() && lr.zero()) return 0.5;
  if (rp.zero()) return 0.0;
  if (lr.zero()) return 1.0;
  // log(var_LR / var_RP) without forming either variance.
  const double log_ratio = 2.0 * (std::log(lr.scale) - std::log(rp.scale)) +
                           std::log(lr.normalized) - std::log(rp.normalized);
  const double k = 1.0 / (1.0 + std::exp(log_ratio));  // exp overflow -> k = 0
  return std::clamp(k, 0.0, 1.0);
}

double CombinationWeight(double var_rp, double var_lr) {
  TraceVariance rp, lr;
  auto to = [](double v, TraceVariance* out) {
    if (!std::isfinite(v)) {
      out->non_finite = true;
      out->scale = std::numeric_limits<double>::infinity();
    } else if (v > 0) {
      out->scale = std::sqrt(v);
      out->normalized = 1.0;
      if (!(out->scale > 0)) {  // a denormal variance: keep the ratio exact
        out->scale = 1.0;
        out->normalized = v;
      }
    }
  };
  to(var_rp, &rp);
  to(var_lr, &lr);
  return CombinationWeight(rp, lr);
}

}  // namespace totalgrad::estimators
