#include "core/pilco/saturation.h"

#include <cmath>
#include <vector>

#include "core/common/check.h"
#include "core/gaussian/trig.h"

namespace totalgrad::pilco {

// With s1 = sin a, s3 = sin 3a, u = U (9/8 s1 + 1/8 s3):
//   Var[u] = U^2 (81/64 Var s1 + 1/64 Var s3 + 18/64 Cov(s1, s3)),
//   Var s1      = -1/2 expm1(-2v)  + e^{-v}  expm1(-v)  sin^2 m,
//   Var s3      = -1/2 expm1(-18v) + e^{-9v} expm1(-9v) sin^2 3m,
//   Cov(s1, s3) = 1/2 e^{-5v} (expm1(3v) cos 2m - expm1(-3v) cos 4m)
//               = -1/2 expm1(-3v) (e^{-2v} cos 2m + e^{-5v} cos 4m).
SatMoments GSat(double mean, double var, double max_u) {
  const double m = mean, v = var, u = max_u;
  const double e1 = std::exp(-0.5 * v), e9 = std::exp(-4.5 * v);
  SatMoments out;
  out.mean = u * (9.0 / 8.0 * e1 * std::sin(m) + 1.0 / 8.0 * e9 * std::sin(3.0 * m));
  out.c = u * (9.0 / 8.0 * e1 * std::cos(m) + 3.0 / 8.0 * e9 * std::cos(3.0 * m));
  const double s1 = std::sin(m), s3 = std::sin(3.0 * m);
  const double var1 = -0.5 * std::expm1(-2.0 * v) + std::exp(-v) * std::expm1(-v) * s1 * s1;
  const double var3 = -0.5 * std::expm1(-18.0 * v) + std::exp(-9.0 * v) * std::expm1(-9.0 * v) * s3 * s3;
  // e^{-5v} expm1(3v) is written as -e^{-2v} expm1(-3v): the same value, but
  // expm1(3v) overflows to Inf for v > 236 while e^{-5v} underflows to 0, and
  // 0 * Inf would make Var[u] NaN for a wide input distribution.
  const double cov13 = -0.5 * std::expm1(-3.0 * v) *
                       (std::exp(-2.0 * v) * std::cos(2.0 * m) + std::exp(-5.0 * v) * std::cos(4.0 * m));
  out.var = u * u * (81.0 / 64.0 * var1 + 1.0 / 64.0 * var3 + 18.0 / 64.0 * cov13);
  return out;
}

Eigen::Matrix<double, 3, 2> Dx_GSat(double mean, double var, double max_u) {
  const double m = mean, v = var, u = max_u;
  const double e1 = std::exp(-0.5 * v), e9 = std::exp(-4.5 * v);
  Eigen::Matrix<double, 3, 2> j;
  j(0, 0) = u * (9.0 / 8.0 * e1 * std::cos(m) + 3.0 / 8.0 * e9 * std::cos(3.0 * m));
  j(0, 1) = u * (-9.0 / 16.0 * e1 * std::sin(m) - 9.0 / 16.0 * e9 * std::sin(3.0 * m));
  j(2, 0) = u * (-9.0 / 8.0 * e1 * std::sin(m) - 9.0 / 8.0 * e9 * std::sin(3.0 * m));
  j(2, 1) = u * (-9.0 / 16.0 * e1 * std::cos(m) - 27.0 / 16.0 * e9 * std::cos(3.0 * m));
  const double ev = std::exp(-v), e2v = std::exp(-2.0 * v), e5v = std::exp(-5.0 * v),
               e8v = std::exp(-8.0 * v), e9v = std::exp(-9.0 * v), e18v = std::exp(-18.0 * v);
  const double s1 = std::sin(m), s3 = std::sin(3.0 * m);
  const double c2 = std::cos(2.0 * m), s2 = std::sin(2.0 * m), c4 = std::cos(4.0 * m),
               s4 = std::sin(4.0 * m), c6 = std::cos(6.0 * m), s6 = std::sin(6.0 * m);
  const double dvar1_dm = s2 * (e2v - ev);
  const double dvar1_dv = e2v * c2 + ev * s1 * s1;
  const double dvar3_dm = 3.0 * s6 * (e18v - e9v);
  const double dvar3_dv = 9.0 * e18v * c6 + 9.0 * e9v * s3 * s3;
  const double dcov_dm = 0.5 * (-2.0 * e2v * s2 + 4.0 * e8v * s4 + 2.0 * e5v * s2 - 4.0 * e5v * s4);
  const double dcov_dv = 0.5 * (-2.0 * e2v * c2 + 8.0 * e8v * c4 + 5.0 * e5v * c2 - 5.0 * e5v * c4);
  j(1, 0) = u * u * (81.0 / 64.0 * dvar1_dm + 1.0 / 64.0 * dvar3_dm + 18.0 / 64.0 * dcov_dm);
  j(1, 1) = u * u * (81.0 / 64.0 * dvar1_dv + 1.0 / 64.0 * dvar3_dv + 18.0 / 64.0 * dcov_dv);
  return j;
}

namespace {

// q = M a, M = [I; 3 I] (2F x F), and the indices of q's entries as angles.
struct QMap {
  Matrix m;
  std::vector<int> all;
};

QMap MakeQMap(int f) {
  QMap q;
  q.m = Matrix::Zero(2 * f, f);
  for (int j = 0; j < f; ++j) {
    q.m(j, j) = 1.0;
    q.m(f + j, j) = 3.0;
  }
  for (int k = 0; k < 2 * f; ++k) q.all.push_back(k);
  return q;
}

// L (F x 2F): u = L sin q.
Matrix SinMap(const Vector& max_u) {
  const int f = static_cast<int>(max_u.size());
  Matrix l = Matrix::Zero(f, 2 * f);
  for (int j = 0; j < f; ++j) {
    l(j, j) = 9.0 / 8.0 * max_u(j);
    l(j, f + j) = 1.0 / 8.0 * max_u(j);
  }
  return l;
}

}  // namespace

void GSatJoint(const Vector& mean, const Matrix& cov, const Vector& max_u, JointSatMoments* out) {
  const int f = static_cast<int>(mean.size());
  TG_CHECK(f >= 1 && cov.rows() == f && cov.cols() == f && max_u.size() == f);
  const QMap q = MakeQMap(f);
  const Vector qm = q.m * mean;
  const Matrix qs = q.m * cov * q.m.transpose();
  Vector ym;
  Matrix ys;
  gaussian::AugmentWithTrig(qm, qs, q.all, &ym, &ys);
  // sin q_k at 2F + 2k, cos q_k at 2F + 2k + 1.
  const int n = 2 * f;
  Vector e_sin(n), e_cos(n);
  Matrix cov_sin(n, n);
  for (int k = 0; k < n; ++k) {
    e_sin(k) = ym(n + 2 * k);
    e_cos(k) = ym(n + 2 * k + 1);
    for (int l = 0; l < n; ++l) cov_sin(k, l) = ys(n + 2 * k, n + 2 * l);
  }
  const Matrix l = SinMap(max_u);
  out->mean = l * e_sin;
  out->cov = l * cov_sin * l.transpose();
  out->c.resize(f);
  for (int j = 0; j < f; ++j) out->c(j) = max_u(j) / 8.0 * (9.0 * e_cos(j) + 3.0 * e_cos(f + j));
}

void GSatJointBackward(const Vector& mean, const Matrix& cov, const Vector& max_u,
                       const Vector& u_mean_bar, const Matrix& u_cov_bar, const Vector& c_bar,
                       Vector* mean_bar, Matrix* cov_bar) {
  const int f = static_cast<int>(mean.size());
  TG_CHECK(f >= 1 && cov.rows() == f && cov.cols() == f && max_u.size() == f);
  TG_CHECK(u_mean_bar.size() == f && u_cov_bar.rows() == f && u_cov_bar.cols() == f &&
           c_bar.size() == f);
  TG_CHECK(mean_bar->size() == f && cov_bar->rows() == f && cov_bar->cols() == f);
  const QMap q = MakeQMap(f);
  const Vector qm = q.m * mean;
  const Matrix qs = q.m * cov * q.m.transpose();
  const int n = 2 * f;
  const Matrix l = SinMap(max_u);
  // Adjoints of y's entries that the forward read.
  Vector ym_bar = Vector::Zero(3 * n);
  Matrix ys_bar = Matrix::Zero(3 * n, 3 * n);
  const Vector e_sin_bar = l.transpose() * u_mean_bar;
  const Matrix cov_sin_bar = l.transpose() * u_cov_bar * l;
  for (int k = 0; k < n; ++k) {
    ym_bar(n + 2 * k) = e_sin_bar(k);
    for (int m = 0; m < n; ++m) ys_bar(n + 2 * k, n + 2 * m) = cov_sin_bar(k, m);
  }
  for (int j = 0; j < f; ++j) {
    ym_bar(n + 2 * j + 1) += max_u(j) / 8.0 * 9.0 * c_bar(j);
    ym_bar(n + 2 * (f + j) + 1) += max_u(j) / 8.0 * 3.0 * c_bar(j);
  }
  Vector qm_bar = Vector::Zero(n);
  Matrix qs_bar = Matrix::Zero(n, n);
  gaussian::AugmentWithTrigBackward(qm, qs, q.all, ym_bar, ys_bar, &qm_bar, &qs_bar);
  mean_bar->noalias() += q.m.transpose() * qm_bar;
  cov_bar->noalias() += q.m.transpose() * qs_bar * q.m;
}

}  // namespace totalgrad::pilco
