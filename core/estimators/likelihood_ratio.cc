#include "core/estimators/likelihood_ratio.h"

#include <cmath>
#include <limits>

#include "core/common/check.h"

namespace totalgrad::estimators {
namespace {

constexpr double kNegInf = -std::numeric_limits<double>::infinity();

// mean_bar and var_bar of one source from its weighted sums
// s0 = sum_j w_ij, s1 = sum_j w_ij Delta_ij, s2 = sum_j w_ij Delta_ij^2 (per dim).
inline void FinishSource(double s0, double s1, double s2, double v, double* mean_bar,
                         double* var_bar) {
  *mean_bar = s1 / v;
  *var_bar = 0.5 * (s2 / (v * v) - s0 / v);
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
  const Eigen::Index s = step.state.cols();
  const RowMatrix mu = step.state + step.mean;
  const RowMatrix inv_v = step.variance.cwiseInverse();
  log_density->resize(p, p);
  const double log_two_pi = std::log(2.0 * M_PI);
  for (Eigen::Index i = 0; i < p; ++i) {
    double norm = 0;
    for (Eigen::Index d = 0; d < s; ++d) norm += log_two_pi + std::log(step.variance(i, d));
    norm *= -0.5;
    const double* mu_i = mu.row(i).data();
    const double* iv_i = inv_v.row(i).data();
    for (Eigen::Index j = 0; j < p; ++j) {
      const double* x_j = step.next_state.row(j).data();
      double q = 0;
      for (Eigen::Index d = 0; d < s; ++d) {
        const double delta = x_j[d] - mu_i[d];
        q += delta * delta * iv_i[d];
      }
      (*log_density)(i, j) = norm - 0.5 * q;
    }
  }
}

void BiwLogWeights(const StepRecord& step, RowMatrix* log_weights, RowMatrix* weights) {
  TransitionLogDensities(step, log_weights);
  const Eigen::Index p = log_weights->rows();
  RowMatrix& lw = *log_weights;
  // Row-major sweeps with per-column accumulators (cache friendly): column
  // maxima, then exponentials and their column sums, then normalisation.
  Eigen::RowVectorXd m = Eigen::RowVectorXd::Constant(p, kNegInf);
  for (Eigen::Index i = 0; i < p; ++i)
    for (Eigen::Index j = 0; j < p; ++j)
      if (lw(i, j) > m(j)) m(j) = lw(i, j);
  RowMatrix local;
  RowMatrix& e = weights != nullptr ? *weights : local;
  e.resize(p, p);
  Eigen::RowVectorXd sum = Eigen::RowVectorXd::Zero(p);
  for (Eigen::Index i = 0; i < p; ++i)
    for (Eigen::Index j = 0; j < p; ++j) {
      // A column without a finite maximum (all -Inf or NaN) is left as it is.
      const double v = std::isfinite(m(j)) ? std::exp(lw(i, j) - m(j)) : std::nan("");
      e(i, j) = v;
      sum(j) += v;
    }
  Eigen::RowVectorXd lse(p), inv(p);
  for (Eigen::Index j = 0; j < p; ++j) {
    lse(j) = std::isfinite(m(j)) ? m(j) + std::log(sum(j)) : 0.0;
    inv(j) = 1.0 / sum(j);
  }
  for (Eigen::Index i = 0; i < p; ++i)
    for (Eigen::Index j = 0; j < p; ++j) {
      if (std::isfinite(m(j))) {
        lw(i, j) -= lse(j);
        e(i, j) *= inv(j);
      } else {
        e(i, j) = std::exp(lw(i, j));
      }
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
    double num = 0, den = 0;
    for (Eigen::Index j = 0; j < p; ++j) {
      if (j == i) continue;
      num += weights(i, j) * cost_to_go(j);
      den += weights(i, j);
    }
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

// w_ij = scale c_ij (G_j - baseline(i, j)); Baseline is a callable (i, j) -> b.
template <typename Baseline>
void WeightedLr(const StepRecord& step, const RowMatrix& weights, const Vector& cost_to_go,
                const Baseline& baseline, double scale, ZetaCotangent* out) {
  const Eigen::Index p = step.state.rows(), s = step.state.cols();
  TG_CHECK(weights.rows() == p && weights.cols() == p && cost_to_go.size() == p);
  out->mean.resize(p, s);
  out->variance.resize(p, s);
  Vector s1(s), s2(s);
  for (Eigen::Index i = 0; i < p; ++i) {
    double s0 = 0;
    s1.setZero();
    s2.setZero();
    for (Eigen::Index j = 0; j < p; ++j) {
      const double c = weights(i, j);
      if (c == 0) continue;  // an underflowed weight contributes exactly nothing
      const double w = scale * c * (cost_to_go(j) - baseline(i, j));
      s0 += w;
      for (Eigen::Index d = 0; d < s; ++d) {
        const double delta = step.next_state(j, d) - (step.state(i, d) + step.mean(i, d));
        s1(d) += w * delta;
        s2(d) += w * delta * delta;
      }
    }
    for (Eigen::Index d = 0; d < s; ++d)
      FinishSource(s0, s1(d), s2(d), step.variance(i, d), &out->mean(i, d), &out->variance(i, d));
  }
}

}  // namespace

void WeightedLrCotangent(const StepRecord& step, const RowMatrix& weights,
                         const Vector& cost_to_go, const Vector& baseline, double scale,
                         ZetaCotangent* out) {
  TG_CHECK(baseline.size() == cost_to_go.size());
  WeightedLr(step, weights, cost_to_go,
             [&baseline](Eigen::Index i, Eigen::Index) { return baseline(i); }, scale, out);
}

void WeightedLrCotangent(const StepRecord& step, const RowMatrix& weights,
                         const Vector& cost_to_go, const RowMatrix& pair_baseline, double scale,
                         ZetaCotangent* out) {
  TG_CHECK(pair_baseline.rows() == cost_to_go.size() && pair_baseline.cols() == cost_to_go.size());
  WeightedLr(step, weights, cost_to_go,
             [&pair_baseline](Eigen::Index i, Eigen::Index j) { return pair_baseline(i, j); },
             scale, out);
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
