#include "core/pilco/trig.h"

#include <cmath>

#include "core/common/check.h"

namespace totalgrad::pilco {

Eigen::Matrix<double, 5, 1> TrigMoments::AsVector() const {
  Eigen::Matrix<double, 5, 1> v;
  v << e_sin, e_cos, var_sin, var_cos, cov_sc;
  return v;
}

TrigMoments GTrig(double mean, double var) {
  TrigMoments t;
  const double e1 = std::exp(-0.5 * var);
  const double s = std::sin(mean), c = std::cos(mean);
  t.e_sin = e1 * s;
  t.e_cos = e1 * c;
  // Var[sin] = 1/2 (1 - e^{-2v} cos 2m) - e^{-v} sin^2 m
  //          = -1/2 expm1(-2v) + e^{-v} expm1(-v) sin^2 m   (no cancellation)
  const double ev = std::exp(-var);
  const double half_one_minus_e2 = -0.5 * std::expm1(-2.0 * var);
  const double ev_expm1 = ev * std::expm1(-var);  // e^{-v} (e^{-v} - 1) <= 0
  t.var_sin = half_one_minus_e2 + ev_expm1 * s * s;
  t.var_cos = half_one_minus_e2 + ev_expm1 * c * c;
  t.cov_sc = ev_expm1 * s * c;  // 1/2 (e^{-2v} - e^{-v}) sin 2m
  return t;
}

Eigen::Matrix<double, 5, 2> Dx_GTrig(double mean, double var) {
  const double e1 = std::exp(-0.5 * var);
  const double ev = std::exp(-var), e2v = std::exp(-2.0 * var);
  const double s = std::sin(mean), c = std::cos(mean);
  const double s2 = std::sin(2.0 * mean), c2 = std::cos(2.0 * mean);
  Eigen::Matrix<double, 5, 2> j;
  j(0, 0) = e1 * c;
  j(0, 1) = -0.5 * e1 * s;
  j(1, 0) = -e1 * s;
  j(1, 1) = -0.5 * e1 * c;
  j(2, 0) = s2 * (e2v - ev);
  j(2, 1) = e2v * c2 + ev * s * s;
  j(3, 0) = -s2 * (e2v - ev);
  j(3, 1) = -e2v * c2 + ev * c * c;
  j(4, 0) = (e2v - ev) * c2;
  j(4, 1) = 0.5 * (-2.0 * e2v + ev) * s2;
  return j;
}

void AugmentWithTrig(const Vector& m, const Matrix& S, int angle_index, Vector* y_mean,
                     Matrix* y_cov) {
  const int d = static_cast<int>(m.size());
  TG_CHECK(S.rows() == d && S.cols() == d);
  TG_CHECK(angle_index >= 0 && angle_index < d);
  const TrigMoments t = GTrig(m(angle_index), S(angle_index, angle_index));
  y_mean->resize(d + 2);
  y_mean->head(d) = m;
  (*y_mean)(d) = t.e_sin;
  (*y_mean)(d + 1) = t.e_cos;
  y_cov->resize(d + 2, d + 2);
  y_cov->topLeftCorner(d, d) = S;
  y_cov->col(d).head(d) = S.col(angle_index) * t.e_cos;
  y_cov->col(d + 1).head(d) = -S.col(angle_index) * t.e_sin;
  y_cov->row(d).head(d) = y_cov->col(d).head(d).transpose();
  y_cov->row(d + 1).head(d) = y_cov->col(d + 1).head(d).transpose();
  (*y_cov)(d, d) = t.var_sin;
  (*y_cov)(d + 1, d + 1) = t.var_cos;
  (*y_cov)(d, d + 1) = t.cov_sc;
  (*y_cov)(d + 1, d) = t.cov_sc;
}

void AugmentWithTrigBackward(const Vector& m, const Matrix& S, int angle_index,
                             const Vector& y_mean_bar, const Matrix& y_cov_bar, Vector* m_bar,
                             Matrix* S_bar) {
  const int d = static_cast<int>(m.size());
  const int a = angle_index;
  TG_CHECK(y_mean_bar.size() == d + 2 && y_cov_bar.rows() == d + 2 && y_cov_bar.cols() == d + 2);
  TG_CHECK(m_bar->size() == d && S_bar->rows() == d && S_bar->cols() == d);
  const TrigMoments t = GTrig(m(a), S(a, a));
  // Adjoint of the trig moments vector [e_sin, e_cos, var_sin, var_cos, cov_sc].
  Eigen::Matrix<double, 5, 1> t_bar;
  t_bar(0) = y_mean_bar(d);
  t_bar(1) = y_mean_bar(d + 1);
  t_bar(2) = y_cov_bar(d, d);
  t_bar(3) = y_cov_bar(d + 1, d + 1);
  t_bar(4) = y_cov_bar(d, d + 1) + y_cov_bar(d + 1, d);
  m_bar->noalias() += y_mean_bar.head(d);
  S_bar->noalias() += y_cov_bar.topLeftCorner(d, d);
  // Cross blocks: y_cov(i, d) = S(i, a) e_cos, y_cov(i, d+1) = -S(i, a) e_sin,
  // and their transposes y_cov(d, i), y_cov(d+1, i) = e_cos S(a, i), ...
  const Vector g_sin = y_cov_bar.col(d).head(d);
  const Vector g_cos = y_cov_bar.col(d + 1).head(d);
  const Vector h_sin = y_cov_bar.row(d).head(d).transpose();
  const Vector h_cos = y_cov_bar.row(d + 1).head(d).transpose();
  S_bar->col(a).noalias() += g_sin * t.e_cos - g_cos * t.e_sin;
  S_bar->row(a).noalias() += (h_sin * t.e_cos - h_cos * t.e_sin).transpose();
  t_bar(1) += S.col(a).dot(g_sin) + S.row(a).dot(h_sin);
  t_bar(0) -= S.col(a).dot(g_cos) + S.row(a).dot(h_cos);
  const Eigen::Matrix<double, 2, 1> in_bar = Dx_GTrig(m(a), S(a, a)).transpose() * t_bar;
  (*m_bar)(a) += in_bar(0);
  (*S_bar)(a, a) += in_bar(1);
}

}  // namespace totalgrad::pilco
