// Helpers shared by the PILCO tests: random well-conditioned covariances, a
// small GP on cart-pole-like data, Gaussian sampling, Monte Carlo moment
// estimates with standard errors, and a finite-difference harness for blocks
// whose covariance input is symmetric (parameterised by its lower triangle).
#ifndef TOTALGRAD_TESTS_CORE_PILCO_PILCO_TEST_UTIL_H_
#define TOTALGRAD_TESTS_CORE_PILCO_PILCO_TEST_UTIL_H_

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <random>
#include <string>

#include <Eigen/Eigenvalues>

#include "core/common/types.h"
#include "core/diff/gradient_checker.h"
#include "core/pilco/gp_moments.h"

namespace totalgrad::pilco::testing {

inline Matrix RandomCovariance(int n, double scale, std::mt19937_64* rng) {
  std::normal_distribution<double> normal;
  Matrix a(n, n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) a(i, j) = normal(*rng);
  Matrix s = scale * (a * a.transpose() / n + 0.3 * Matrix::Identity(n, n));
  return 0.5 * (s + s.transpose());
}

inline Vector RandomVector(int n, double scale, std::mt19937_64* rng) {
  std::normal_distribution<double> normal;
  Vector v(n);
  for (int i = 0; i < n; ++i) v(i) = scale * normal(*rng);
  return v;
}

// A D-output GP on E inputs with N points and smooth targets.
inline GaussianInputGp MakeTestGp(int n, int e, int d, std::mt19937_64* rng,
                                  double lengthscale = 1.0) {
  std::normal_distribution<double> normal;
  RowMatrix x(n, e), y(n, d);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < e; ++j) x(i, j) = normal(*rng);
    for (int a = 0; a < d; ++a) {
      double v = 0;
      for (int j = 0; j < e; ++j) v += std::sin((a + 1) * 0.7 * x(i, j) + 0.3 * j);
      y(i, a) = 0.3 * v + 0.05 * normal(*rng);
    }
  }
  RowMatrix log_hyp(d, e + 2);
  for (int a = 0; a < d; ++a) {
    for (int j = 0; j < e; ++j) log_hyp(a, j) = std::log(lengthscale * (0.8 + 0.15 * ((a + j) % 4)));
    log_hyp(a, e) = std::log(0.6 + 0.1 * a);
    log_hyp(a, e + 1) = std::log(0.05 + 0.01 * a);
  }
  auto gp = GaussianInputGpFromData(x, y, log_hyp);
  EXPECT_TRUE(gp.ok()) << gp.status();
  return *gp;
}

// Rows of L z for z standard normal: samples of N(m, S), S PSD (may be
// singular).
class GaussianSampler {
 public:
  GaussianSampler(const Vector& m, const Matrix& s) : m_(m) {
    Eigen::SelfAdjointEigenSolver<Matrix> eig(s);
    l_ = eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal();
  }
  // n x D samples.
  RowMatrix Sample(int n, std::mt19937_64* rng) const {
    std::normal_distribution<double> normal;
    RowMatrix z(n, m_.size());
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < m_.size(); ++j) z(i, j) = normal(*rng);
    RowMatrix x = z * l_.transpose();
    x.rowwise() += m_.transpose();
    return x;
  }

 private:
  Vector m_;
  Matrix l_;
};

// Running Monte Carlo estimate of the mean and covariance of vectors, with
// standard errors (two passes: the mean is known exactly enough after pass
// one; here a streaming shifted estimate is used).
class MomentAccumulator {
 public:
  explicit MomentAccumulator(int dim) : n_(0), sum_(Vector::Zero(dim)), sum2_(Matrix::Zero(dim, dim)),
                                        sum4_(Matrix::Zero(dim, dim)), shift_(Vector::Zero(dim)) {}
  void SetShift(const Vector& shift) { shift_ = shift; }
  void Add(const Vector& v) {
    const Vector c = v - shift_;
    ++n_;
    sum_ += c;
    const Matrix p = c * c.transpose();
    sum2_ += p;
    sum4_ += p.cwiseProduct(p);
  }
  // Rows of x are samples.
  void AddBatch(const RowMatrix& x) {
    RowMatrix c = x;
    c.rowwise() -= shift_.transpose();
    n_ += static_cast<long>(c.rows());
    sum_ += c.colwise().sum().transpose();
    sum2_.noalias() += c.transpose() * c;
    for (Eigen::Index i = 0; i < c.cols(); ++i) {
      for (Eigen::Index j = i; j < c.cols(); ++j) {
        const double s4 = (c.col(i).array() * c.col(j).array()).square().sum();
        sum4_(i, j) += s4;
        if (j != i) sum4_(j, i) += s4;
      }
    }
  }
  double n() const { return static_cast<double>(n_); }
  Vector Mean() const { return shift_ + sum_ / n(); }
  Vector MeanStdError() const {
    const Vector mc = sum_ / n();
    return ((sum2_.diagonal() / n() - mc.cwiseProduct(mc)).cwiseMax(0.0) / n()).cwiseSqrt();
  }
  Matrix Cov() const {
    const Vector mc = sum_ / n();
    return sum2_ / n() - mc * mc.transpose();
  }
  // Standard error of each covariance entry (shift close to the mean).
  Matrix CovStdError() const {
    const Matrix e2 = sum2_ / n();
    return ((sum4_ / n() - e2.cwiseProduct(e2)).cwiseMax(0.0) / n()).cwiseSqrt();
  }

 private:
  long n_;
  Vector sum_;
  Matrix sum2_, sum4_;
  Vector shift_;
};

// |a - b| <= k * se + abs_tol entry-wise.
inline ::testing::AssertionResult WithinMcError(const Matrix& analytic, const Matrix& mc,
                                                const Matrix& se, double k,
                                                double abs_tol = 1e-12) {
  for (Eigen::Index r = 0; r < analytic.rows(); ++r) {
    for (Eigen::Index c = 0; c < analytic.cols(); ++c) {
      const double diff = std::abs(analytic(r, c) - mc(r, c));
      if (!(diff <= k * se(r, c) + abs_tol)) {
        return ::testing::AssertionFailure()
               << "entry (" << r << "," << c << "): analytic " << analytic(r, c) << " MC "
               << mc(r, c) << " diff " << diff << " > " << k << " x SE " << se(r, c);
      }
    }
  }
  return ::testing::AssertionSuccess();
}

// ---------------------------------------------------------------------------
// Finite-difference harness. A block maps (m (n), S (n x n symmetric),
// theta (k)) to an output vector y (q); its reverse mode maps y_bar to
// (m_bar, S_bar, theta_bar). The checked input vector is
// x = [m; vech(S) (lower triangle, column by column); theta].

inline int VechSize(int n) { return n * (n + 1) / 2; }

inline void Unpack(const Vector& x, int n, int k, Vector* m, Matrix* s, Vector* theta) {
  *m = x.head(n);
  s->resize(n, n);
  int idx = n;
  for (int j = 0; j < n; ++j)
    for (int i = j; i < n; ++i) (*s)(i, j) = (*s)(j, i) = x(idx++);
  *theta = x.tail(k);
}

inline Vector Pack(const Vector& m, const Matrix& s, const Vector& theta) {
  const int n = static_cast<int>(m.size());
  Vector x(n + VechSize(n) + theta.size());
  x.head(n) = m;
  int idx = n;
  for (int j = 0; j < n; ++j)
    for (int i = j; i < n; ++i) x(idx++) = s(i, j);
  x.tail(theta.size()) = theta;
  return x;
}

using BlockForward =
    std::function<bool(const Vector& m, const Matrix& s, const Vector& theta, Vector* y)>;
using BlockBackward = std::function<bool(const Vector& m, const Matrix& s, const Vector& theta,
                                         const Vector& y_bar, Vector* m_bar, Matrix* s_bar,
                                         Vector* theta_bar)>;

// Gradient with respect to vech(S) from the full-matrix adjoint.
inline Vector VechGradient(const Matrix& s_bar, bool symmetrise = true) {
  const int n = static_cast<int>(s_bar.rows());
  Vector g(VechSize(n));
  int idx = 0;
  for (int j = 0; j < n; ++j)
    for (int i = j; i < n; ++i)
      g(idx++) = (i == j || !symmetrise) ? s_bar(i, j) : s_bar(i, j) + s_bar(j, i);
  return g;
}

// Analytic Jacobian (q x (n + vech + k)) from the reverse mode, one output at
// a time. symmetrise = false reproduces the classic bug of forgetting that an
// off-diagonal covariance entry appears twice.
inline Matrix ReverseJacobian(const BlockBackward& backward, const Vector& m, const Matrix& s,
                              const Vector& theta, int q, bool symmetrise = true) {
  const int n = static_cast<int>(m.size());
  const int k = static_cast<int>(theta.size());
  Matrix j(q, n + VechSize(n) + k);
  for (int r = 0; r < q; ++r) {
    Vector y_bar = Vector::Zero(q);
    y_bar(r) = 1.0;
    Vector m_bar, theta_bar = Vector::Zero(k);
    Matrix s_bar;
    EXPECT_TRUE(backward(m, s, theta, y_bar, &m_bar, &s_bar, &theta_bar));
    j.row(r).head(n) = m_bar.transpose();
    j.row(r).segment(n, VechSize(n)) = VechGradient(s_bar, symmetrise).transpose();
    if (k > 0) j.row(r).tail(k) = theta_bar.transpose();
  }
  return j;
}

inline diff::CheckResult CheckBlock(const BlockForward& forward, const BlockBackward& backward,
                                    const Vector& m, const Matrix& s, const Vector& theta,
                                    const diff::CheckOptions& options, bool symmetrise = true) {
  const int n = static_cast<int>(m.size());
  const int k = static_cast<int>(theta.size());
  Vector y0;
  EXPECT_TRUE(forward(m, s, theta, &y0));
  const Matrix analytic =
      ReverseJacobian(backward, m, s, theta, static_cast<int>(y0.size()), symmetrise);
  const diff::VectorFunction f = [&](const Vector& x, Vector* y) {
    Vector mm, th;
    Matrix ss;
    Unpack(x, n, k, &mm, &ss, &th);
    return forward(mm, ss, th, y);
  };
  return diff::CheckJacobian(f, Pack(m, s, theta), analytic, options);
}

inline Vector Flatten(const Matrix& a) { return Eigen::Map<const Vector>(a.data(), a.size()); }

}  // namespace totalgrad::pilco::testing

#endif  // TOTALGRAD_TESTS_CORE_PILCO_PILCO_TEST_UTIL_H_
