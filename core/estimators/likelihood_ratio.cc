#include "core/estimators/likelihood_ratio.h"

#include <cmath>
#include <limits>

#include "core/common/check.h"
#include "core/common/simd.h"
#include "core/common/vector_exp.h"

namespace totalgrad::estimators {
namespace {

constexpr double kNegInf = -std::numeric_limits<double>::infinity();

// The P x P loops below run over samples j with kLanes independent partial
// sums (lane l takes j = l, l + kLanes, ...), combined in lane order at the
// end: the compiler can map the lanes onto SIMD registers without reordering
// any floating-point sum, so the result is the same bits whatever vector
// width the CPU has (the clones below), and it never depends on a thread
// count. kMaxDims bounds the state dimension S of the per-lane arrays.
constexpr int kLanes = 8;
constexpr int kMaxDims = 16;


// mean_bar and var_bar of one source from its weighted sums
// s0 = sum_j w_ij, s1 = sum_j w_ij Delta_ij, s2 = sum_j w_ij Delta_ij^2 (per dim).
inline void FinishSource(double s0, double s1, double s2, double v, double* mean_bar,
                         double* var_bar) {
  *mean_bar = s1 / v;
  *var_bar = 0.5 * (s2 / (v * v) - s0 / v);
}

double CombineLanes(const double* lanes) {
  double total = 0;
  for (int l = 0; l < kLanes; ++l) total += lanes[l];
  return total;
}

// row[j] = norm - 0.5 sum_d (xt[d * p + j] - mu[d])^2 iv[d] for j < p, the
// sum over d in order (xt: the samples' coordinates, one row of p per
// dimension).
TG_VECTOR_CLONES void LogDensityRow(const double* xt, int s, Eigen::Index p, const double* mu,
                                    const double* iv, double norm, double* row) {
  for (Eigen::Index j = 0; j < p; ++j) row[j] = 0.0;
  for (int d = 0; d < s; ++d) {
    const double* x = xt + d * p;
    const double m = mu[d], v = iv[d];
    for (Eigen::Index j = 0; j < p; ++j) {
      const double delta = x[j] - m;
      row[j] += delta * delta * v;
    }
  }
  for (Eigen::Index j = 0; j < p; ++j) row[j] = norm - 0.5 * row[j];
}

// column_max[j] = max(column_max[j], row[j]) (NaN never replaces a value).
TG_VECTOR_CLONES void ColumnMax(const double* row, Eigen::Index p, double* column_max) {
  Eigen::Index j = 0;
  for (; j + kLanes <= p; j += kLanes) {
    const simd::Doubles r = simd::Load(row + j), m = simd::Load(column_max + j);
    simd::Store(column_max + j, simd::Select(r > m, r, m));
  }
  for (; j < p; ++j) column_max[j] = row[j] > column_max[j] ? row[j] : column_max[j];
}

// shifted[j] = row[j] - shift[j].
TG_VECTOR_CLONES void Subtract(const double* row, const double* shift, Eigen::Index p,
                               double* shifted) {
  for (Eigen::Index j = 0; j < p; ++j) shifted[j] = row[j] - shift[j];
}

// sum[j] += row[j].
TG_VECTOR_CLONES void Accumulate(const double* row, Eigen::Index p, double* sum) {
  for (Eigen::Index j = 0; j < p; ++j) sum[j] += row[j];
}

// log_row[j] -= lse[j]; weight_row[j] *= inv[j].
TG_VECTOR_CLONES void Normalise(const double* lse, const double* inv, Eigen::Index p,
                                double* log_row, double* weight_row) {
  for (Eigen::Index j = 0; j < p; ++j) {
    log_row[j] -= lse[j];
    weight_row[j] *= inv[j];
  }
}

// sum_j weights[j] * values[j] and sum_j weights[j] over j in [begin, end),
// added to the lanes.
TG_VECTOR_CLONES void WeightedSumLanes(const double* weights, const double* values,
                                       Eigen::Index begin, Eigen::Index end, double* num_lanes,
                                       double* den_lanes) {
  simd::Doubles num = simd::Load(num_lanes), den = simd::Load(den_lanes);
  Eigen::Index j = begin;
  for (; j + kLanes <= end; j += kLanes) {
    const simd::Doubles w = simd::Load(weights + j);
    num += w * simd::Load(values + j);
    den += w;
  }
  simd::Store(num_lanes, num);
  simd::Store(den_lanes, den);
  for (int l = 0; j < end; ++j, ++l) {
    num_lanes[l] += weights[j] * values[j];
    den_lanes[l] += weights[j];
  }
}

// The weighted sums of one source i: for every sample j with weight
// w_j = scale c_j (g_j - b_j) (b_j = baseline[j], or baseline[0] for all j
// when baseline_stride is 0), s0 = sum_j w_j, and per dimension d
// s1[d] = sum_j w_j Delta_jd, s2[d] = sum_j w_j Delta_jd^2, Delta_jd =
// xt[d * p + j] - mu[d]. A zero weight c_j contributes exactly nothing (its
// other factors may be infinite). S is the state dimension (0 = `s`, read at
// run time); with S fixed the accumulators stay in registers.
template <int S>
__attribute__((always_inline)) inline void WeightedScoreSumsBody(
    const double* c, const double* g, const double* baseline, int baseline_stride, double scale,
    const double* xt, int s, Eigen::Index p, const double* mu, double* s0, double* s1, double* s2) {
  const int dims = S > 0 ? S : s;
  using simd::Doubles;
  const Doubles zero = simd::Broadcast(0.0);
  Doubles v0 = zero;
  Doubles v1[S > 0 ? S : kMaxDims], v2[S > 0 ? S : kMaxDims];
  for (int d = 0; d < dims; ++d) v1[d] = v2[d] = zero;
  Eigen::Index j = 0;
  for (; j + kLanes <= p; j += kLanes) {
    const Doubles cj = simd::Load(c + j);
    const Doubles bj = baseline_stride == 0 ? simd::Broadcast(baseline[0]) : simd::Load(baseline + j);
    const simd::Mask live = cj != zero;
    const Doubles w = simd::Select(live, scale * cj * (simd::Load(g + j) - bj), zero);
    v0 += w;
    for (int d = 0; d < dims; ++d) {
      const Doubles delta = simd::Load(xt + d * p + j) - mu[d];
      const Doubles wd = simd::Select(live, w * delta, zero);
      v1[d] += wd;
      v2[d] += simd::Select(live, wd * delta, zero);
    }
  }
  double l0[kLanes], l1[S > 0 ? S : kMaxDims][kLanes], l2[S > 0 ? S : kMaxDims][kLanes];
  for (int l = 0; l < kLanes; ++l) {
    l0[l] = v0[l];
    for (int d = 0; d < dims; ++d) l1[d][l] = v1[d][l], l2[d][l] = v2[d][l];
  }
  // The last, partial block: sample j goes to lane j - (its block start), as
  // in a full block.
  for (int l = 0; j < p; ++j, ++l) {
    if (c[j] == 0.0) continue;
    const double w = scale * c[j] * (g[j] - baseline[j * baseline_stride]);
    l0[l] += w;
    for (int d = 0; d < dims; ++d) {
      const double delta = xt[d * p + j] - mu[d];
      const double wd = w * delta;
      l1[d][l] += wd;
      l2[d][l] += wd * delta;
    }
  }
  *s0 = CombineLanes(l0);
  for (int d = 0; d < dims; ++d) {
    s1[d] = CombineLanes(l1[d]);
    s2[d] = CombineLanes(l2[d]);
  }
}

#define TG_WEIGHTED_SCORE_SUMS(NAME, S)                                                        \
  TG_VECTOR_CLONES void NAME(const double* c, const double* g, const double* baseline,         \
                             int baseline_stride, double scale, const double* xt, int s,       \
                             Eigen::Index p, const double* mu, double* s0, double* s1,         \
                             double* s2) {                                                     \
    WeightedScoreSumsBody<S>(c, g, baseline, baseline_stride, scale, xt, s, p, mu, s0, s1, s2); \
  }
TG_WEIGHTED_SCORE_SUMS(WeightedScoreSums2, 2)
TG_WEIGHTED_SCORE_SUMS(WeightedScoreSums4, 4)
TG_WEIGHTED_SCORE_SUMS(WeightedScoreSums6, 6)
TG_WEIGHTED_SCORE_SUMS(WeightedScoreSumsAny, 0)
#undef TG_WEIGHTED_SCORE_SUMS

void WeightedScoreSums(const double* c, const double* g, const double* baseline,
                       int baseline_stride, double scale, const double* xt, int s, Eigen::Index p,
                       const double* mu, double* s0, double* s1, double* s2) {
  switch (s) {
    case 2: return WeightedScoreSums2(c, g, baseline, baseline_stride, scale, xt, s, p, mu, s0, s1, s2);
    case 4: return WeightedScoreSums4(c, g, baseline, baseline_stride, scale, xt, s, p, mu, s0, s1, s2);
    case 6: return WeightedScoreSums6(c, g, baseline, baseline_stride, scale, xt, s, p, mu, s0, s1, s2);
    default: return WeightedScoreSumsAny(c, g, baseline, baseline_stride, scale, xt, s, p, mu, s0, s1, s2);
  }
}

}  // namespace

Vector LeaveOneOutBaseline(const Vector& cost_to_go) {
  const Eigen::Index p = cost_to_go.size();
  if (p < 2) return Vector::Zero(p);
  const double total = cost_to_go.sum();
  return ((total - cost_to_go.array()) / static_cast<double>(p - 1)).matrix();
}

void TransitionLogDensities(const StepRecord& step, RowMatrix* log_density) {
  const Eigen::Index p = step.state.rows();
  const int s = static_cast<int>(step.state.cols());
  TG_CHECK(s <= kMaxDims);
  // Samples by dimension (row d contiguous over j) for the vectorised rows.
  const RowMatrix xt = step.next_state.transpose();
  log_density->resize(p, p);
  const double log_two_pi = std::log(2.0 * M_PI);
  double mu[kMaxDims], iv[kMaxDims];
  for (Eigen::Index i = 0; i < p; ++i) {
    double norm = 0;
    for (int d = 0; d < s; ++d) norm += log_two_pi + std::log(step.variance(i, d));
    norm *= -0.5;
    for (int d = 0; d < s; ++d) {
      mu[d] = step.state(i, d) + step.mean(i, d);
      iv[d] = 1.0 / step.variance(i, d);
    }
    LogDensityRow(xt.data(), s, p, mu, iv, norm, log_density->row(i).data());
  }
}

double MeanEffectiveSampleSize(const RowMatrix& weights) {
  const Eigen::Index p = weights.rows();
  if (p == 0) return std::nan("");
  double total = 0;
  for (Eigen::Index i = 0; i < p; ++i) {
    const double sum = weights.row(i).sum();
    const double sum_sq = weights.row(i).squaredNorm();
    // Written so that NaN weights give NaN, and an all-zero row 0.
    total += sum_sq > 0 ? sum * sum / sum_sq : (sum_sq == 0 ? 0.0 : sum_sq);
  }
  return total / static_cast<double>(p);
}

void BiwLogWeights(const StepRecord& step, RowMatrix* log_weights, RowMatrix* weights) {
  TransitionLogDensities(step, log_weights);
  const Eigen::Index p = log_weights->rows();
  RowMatrix& lw = *log_weights;
  // Row-major sweeps with per-column accumulators (contiguous, vectorised over
  // j; each column's sum runs over i in order): column maxima, then
  // exponentials and their column sums, then normalisation.
  Eigen::RowVectorXd m = Eigen::RowVectorXd::Constant(p, kNegInf);
  for (Eigen::Index i = 0; i < p; ++i) ColumnMax(lw.row(i).data(), p, m.data());
  RowMatrix local;
  RowMatrix& e = weights != nullptr ? *weights : local;
  e.resize(p, p);
  Eigen::RowVectorXd sum = Eigen::RowVectorXd::Zero(p);
  Eigen::RowVectorXd shifted(p);
  bool all_finite = true;
  for (Eigen::Index j = 0; j < p; ++j) all_finite = all_finite && std::isfinite(m(j));
  for (Eigen::Index i = 0; i < p; ++i) {
    // lw - m <= 0 for a finite column maximum; a column without one (all -Inf
    // or NaN) gives NaN here and is redone below.
    Subtract(lw.row(i).data(), m.data(), p, shifted.data());
    ExpNonPositive(shifted.data(), e.row(i).data(), p);
    Accumulate(e.row(i).data(), p, sum.data());
  }
  Eigen::RowVectorXd lse(p), inv(p);
  for (Eigen::Index j = 0; j < p; ++j) {
    lse(j) = std::isfinite(m(j)) ? m(j) + std::log(sum(j)) : 0.0;
    inv(j) = std::isfinite(m(j)) ? 1.0 / sum(j) : 1.0;
  }
  for (Eigen::Index i = 0; i < p; ++i) Normalise(lse.data(), inv.data(), p, lw.row(i).data(), e.row(i).data());
  if (all_finite) return;
  // Columns without a finite maximum: log weights left as they are, weights
  // their plain exponentials (0 for -Inf, NaN for NaN).
  for (Eigen::Index j = 0; j < p; ++j) {
    if (std::isfinite(m(j))) continue;
    for (Eigen::Index i = 0; i < p; ++i) e(i, j) = std::exp(lw(i, j));
  }
}

namespace {

// Row i of the BIW baseline from log weights (exact for any underflow).
double BiwBaselineRowFromLogs(const RowMatrix& log_weights, const Vector& cost_to_go,
                              Eigen::Index i, double fallback) {
  const Eigen::Index p = cost_to_go.size();
  double m = kNegInf;
  for (Eigen::Index j = 0; j < p; ++j)
    if (j != i && log_weights(i, j) > m) m = log_weights(i, j);
  if (!std::isfinite(m)) return fallback;
  double num = 0, den = 0;
  for (Eigen::Index j = 0; j < p; ++j) {
    if (j == i) continue;
    const double w = std::exp(log_weights(i, j) - m);  // <= 1, the largest is 1
    num += w * cost_to_go(j);
    den += w;
  }
  return num / den;
}

}  // namespace

void BiwBaseline(const RowMatrix& log_weights, const Vector& cost_to_go, Vector* baseline) {
  const Eigen::Index p = cost_to_go.size();
  TG_CHECK(log_weights.rows() == p && log_weights.cols() == p);
  const Vector loo = LeaveOneOutBaseline(cost_to_go);
  baseline->resize(p);
  for (Eigen::Index i = 0; i < p; ++i)
    (*baseline)(i) = BiwBaselineRowFromLogs(log_weights, cost_to_go, i, loo(i));
}

void BiwBaseline(const RowMatrix& log_weights, const RowMatrix& weights, const Vector& cost_to_go,
                 Vector* baseline) {
  const Eigen::Index p = cost_to_go.size();
  TG_CHECK(log_weights.rows() == p && log_weights.cols() == p);
  TG_CHECK(weights.rows() == p && weights.cols() == p);
  const Vector loo = LeaveOneOutBaseline(cost_to_go);
  baseline->resize(p);
  for (Eigen::Index i = 0; i < p; ++i) {
    double num_lanes[kLanes] = {}, den_lanes[kLanes] = {};
    const double* row = weights.row(i).data();
    WeightedSumLanes(row, cost_to_go.data(), 0, i, num_lanes, den_lanes);
    WeightedSumLanes(row, cost_to_go.data(), i + 1, p, num_lanes, den_lanes);
    const double num = CombineLanes(num_lanes), den = CombineLanes(den_lanes);
    (*baseline)(i) = den > 1e-250 ? num / den
                                  : BiwBaselineRowFromLogs(log_weights, cost_to_go, i, loo(i));
  }
}

void PlainLrCotangent(const StepRecord& step, const Vector& cost_to_go, const Vector& baseline,
                      double scale, ZetaCotangent* out) {
  const Eigen::Index p = step.state.rows(), s = step.state.cols();
  TG_CHECK(cost_to_go.size() == p && baseline.size() == p);
  out->mean.resize(p, s);
  out->variance.resize(p, s);
  for (Eigen::Index i = 0; i < p; ++i) {
    const double a = scale * (cost_to_go(i) - baseline(i));
    for (Eigen::Index d = 0; d < s; ++d) {
      const double delta = step.next_state(i, d) - (step.state(i, d) + step.mean(i, d));
      FinishSource(a, a * delta, a * delta * delta, step.variance(i, d), &out->mean(i, d),
                   &out->variance(i, d));
    }
  }
}

namespace {

// w_ij = scale c_ij (G_j - b_ij): with a per-source baseline (pair_baseline
// null, b_ij = baseline(i)) or a per-pair one (b_ij = pair_baseline(i, j)).
void WeightedLr(const StepRecord& step, const RowMatrix& weights, const Vector& cost_to_go,
                const Vector* baseline, const RowMatrix* pair_baseline, double scale,
                ZetaCotangent* out) {
  const Eigen::Index p = step.state.rows();
  const int s = static_cast<int>(step.state.cols());
  TG_CHECK(weights.rows() == p && weights.cols() == p && cost_to_go.size() == p);
  TG_CHECK(s <= kMaxDims);
  out->mean.resize(p, s);
  out->variance.resize(p, s);
  const RowMatrix xt = step.next_state.transpose();
  double mu[kMaxDims], s1[kMaxDims], s2[kMaxDims];
  for (Eigen::Index i = 0; i < p; ++i) {
    for (int d = 0; d < s; ++d) mu[d] = step.state(i, d) + step.mean(i, d);
    double s0;
    if (pair_baseline != nullptr) {
      WeightedScoreSums(weights.row(i).data(), cost_to_go.data(), pair_baseline->row(i).data(), 1,
                        scale, xt.data(), s, p, mu, &s0, s1, s2);
    } else {
      WeightedScoreSums(weights.row(i).data(), cost_to_go.data(), baseline->data() + i, 0, scale,
                        xt.data(), s, p, mu, &s0, s1, s2);
    }
    for (int d = 0; d < s; ++d)
      FinishSource(s0, s1[d], s2[d], step.variance(i, d), &out->mean(i, d), &out->variance(i, d));
  }
}

}  // namespace

void WeightedLrCotangent(const StepRecord& step, const RowMatrix& weights,
                         const Vector& cost_to_go, const Vector& baseline, double scale,
                         ZetaCotangent* out) {
  TG_CHECK(baseline.size() == cost_to_go.size());
  WeightedLr(step, weights, cost_to_go, &baseline, nullptr, scale, out);
}

void WeightedLrCotangent(const StepRecord& step, const RowMatrix& weights,
                         const Vector& cost_to_go, const RowMatrix& pair_baseline, double scale,
                         ZetaCotangent* out) {
  TG_CHECK(pair_baseline.rows() == cost_to_go.size() && pair_baseline.cols() == cost_to_go.size());
  WeightedLr(step, weights, cost_to_go, nullptr, &pair_baseline, scale, out);
}

void BiwPairBaseline(const RowMatrix& log_weights, const Vector& cost_to_go, RowMatrix* baseline) {
  const Eigen::Index p = cost_to_go.size();
  TG_CHECK(log_weights.rows() == p && log_weights.cols() == p);
  const Vector loo = LeaveOneOutBaseline(cost_to_go);
  baseline->resize(p, p);
  Vector e(p);
  for (Eigen::Index i = 0; i < p; ++i) {
    Eigen::Index top = -1;
    double m = kNegInf;
    for (Eigen::Index k = 0; k < p; ++k)
      if (log_weights(i, k) > m) m = log_weights(i, k), top = k;
    if (top < 0) {  // no finite weight in the row
      baseline->row(i) = loo.transpose();
      continue;
    }
    double sum = 0, num = 0;
    for (Eigen::Index k = 0; k < p; ++k) {
      e(k) = std::exp(log_weights(i, k) - m);  // e(top) = 1
      sum += e(k);
      num += e(k) * cost_to_go(k);
    }
    for (Eigen::Index j = 0; j < p; ++j) {
      if (j == top) continue;
      // sum - e_j >= e(top) = 1: no cancellation.
      (*baseline)(i, j) = (num - e(j) * cost_to_go(j)) / (sum - e(j));
    }
    // Without the heaviest sample: rescale by the second largest weight.
    double m2 = kNegInf;
    for (Eigen::Index k = 0; k < p; ++k)
      if (k != top && log_weights(i, k) > m2) m2 = log_weights(i, k);
    if (!std::isfinite(m2)) {
      (*baseline)(i, top) = loo(top);
      continue;
    }
    double sum2 = 0, num2 = 0;
    for (Eigen::Index k = 0; k < p; ++k) {
      if (k == top) continue;
      const double w = std::exp(log_weights(i, k) - m2);
      sum2 += w;
      num2 += w * cost_to_go(k);
    }
    (*baseline)(i, top) = num2 / sum2;
  }
}

void DensityEstimationCotangent(const GaussianFit& fit, const Vector& weights, RowMatrix* x_bar) {
  const Eigen::Index p = fit.centred.rows(), s = fit.centred.cols();
  TG_CHECK(weights.size() == p);
  const Matrix y = SolveWithFit(fit, fit.centred.transpose());  // S x P, Sigma^-1 d_i
  const Vector mean_bar = y * weights;
  const Matrix sigma_inv = SolveWithFit(fit, Matrix::Identity(s, s));
  Matrix cov_bar = y * weights.asDiagonal() * y.transpose() - weights.sum() * sigma_inv;
  cov_bar = (0.25 * (cov_bar + cov_bar.transpose())).eval();  // 1/2 and symmetrised
  GaussianFitBackward(fit, mean_bar, cov_bar, x_bar);
}

}  // namespace totalgrad::estimators
