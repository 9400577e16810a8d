#include "core/gaussian/trig.h"

#include <cmath>

#include "core/common/check.h"

namespace totalgrad::gaussian {

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

namespace {

bool StrictlyIncreasingIn(const std::vector<int>& v, int d) {
  for (size_t i = 0; i < v.size(); ++i)
    if (v[i] < 0 || v[i] >= d || (i > 0 && v[i] <= v[i - 1])) return false;
  return !v.empty();
}

// The moments of a pair of angles k != l that the product formulas need:
// for sigma = +1, -1 (index 0, 1), x_k + sigma x_l ~ N(w, q) with
// w = m_k + sigma m_l, q = S_kk + S_ll + sigma (S_kl + S_lk), and
// K = E cos(x_k + sigma x_l) = exp(-q/2) cos w, L = E sin(...) = exp(-q/2) sin w.
struct PairMoments {
  double k[2], l[2];
};

PairMoments PairOf(const Vector& m, const Matrix& S, int a, int b) {
  PairMoments p;
  for (int i = 0; i < 2; ++i) {
    const double sigma = i == 0 ? 1.0 : -1.0;
    const double w = m(a) + sigma * m(b);
    const double q = S(a, a) + S(b, b) + sigma * (S(a, b) + S(b, a));
    const double e = std::exp(-0.5 * q);
    p.k[i] = e * std::cos(w);
    p.l[i] = e * std::sin(w);
  }
  return p;
}

}  // namespace

void AugmentWithTrig(const Vector& m, const Matrix& S, const std::vector<int>& angle_indices,
                     Vector* y_mean, Matrix* y_cov) {
  const int d = static_cast<int>(m.size());
  TG_CHECK(S.rows() == d && S.cols() == d);
  TG_CHECK(StrictlyIncreasingIn(angle_indices, d));
  if (angle_indices.size() == 1) {
    AugmentWithTrig(m, S, angle_indices[0], y_mean, y_cov);
    return;
  }
  const int a_count = static_cast<int>(angle_indices.size());
  const int n = d + 2 * a_count;
  std::vector<TrigMoments> t(a_count);
  y_mean->resize(n);
  y_mean->head(d) = m;
  y_cov->resize(n, n);
  y_cov->topLeftCorner(d, d) = S;
  for (int k = 0; k < a_count; ++k) {
    const int a = angle_indices[k], sk = d + 2 * k, ck = sk + 1;
    t[k] = GTrig(m(a), S(a, a));
    (*y_mean)(sk) = t[k].e_sin;
    (*y_mean)(ck) = t[k].e_cos;
    y_cov->col(sk).head(d) = S.col(a) * t[k].e_cos;
    y_cov->col(ck).head(d) = -S.col(a) * t[k].e_sin;
    y_cov->row(sk).head(d) = y_cov->col(sk).head(d).transpose();
    y_cov->row(ck).head(d) = y_cov->col(ck).head(d).transpose();
    (*y_cov)(sk, sk) = t[k].var_sin;
    (*y_cov)(ck, ck) = t[k].var_cos;
    (*y_cov)(sk, ck) = (*y_cov)(ck, sk) = t[k].cov_sc;
  }
  for (int k = 0; k < a_count; ++k) {
    for (int l = k + 1; l < a_count; ++l) {
      const PairMoments p = PairOf(m, S, angle_indices[k], angle_indices[l]);
      const int sk = d + 2 * k, ck = sk + 1, sl = d + 2 * l, cl = sl + 1;
      // Product formulas, then minus the product of the means.
      const double ss = 0.5 * (p.k[1] - p.k[0]) - t[k].e_sin * t[l].e_sin;
      const double sc = 0.5 * (p.l[0] + p.l[1]) - t[k].e_sin * t[l].e_cos;
      const double cs = 0.5 * (p.l[0] - p.l[1]) - t[k].e_cos * t[l].e_sin;
      const double cc = 0.5 * (p.k[1] + p.k[0]) - t[k].e_cos * t[l].e_cos;
      (*y_cov)(sk, sl) = (*y_cov)(sl, sk) = ss;
      (*y_cov)(sk, cl) = (*y_cov)(cl, sk) = sc;
      (*y_cov)(ck, sl) = (*y_cov)(sl, ck) = cs;
      (*y_cov)(ck, cl) = (*y_cov)(cl, ck) = cc;
    }
  }
}

void AugmentWithTrigBackward(const Vector& m, const Matrix& S, const std::vector<int>& angle_indices,
                             const Vector& y_mean_bar, const Matrix& y_cov_bar, Vector* m_bar,
                             Matrix* S_bar) {
  const int d = static_cast<int>(m.size());
  TG_CHECK(StrictlyIncreasingIn(angle_indices, d));
  if (angle_indices.size() == 1) {
    AugmentWithTrigBackward(m, S, angle_indices[0], y_mean_bar, y_cov_bar, m_bar, S_bar);
    return;
  }
  const int a_count = static_cast<int>(angle_indices.size());
  const int n = d + 2 * a_count;
  TG_CHECK(y_mean_bar.size() == n && y_cov_bar.rows() == n && y_cov_bar.cols() == n);
  TG_CHECK(m_bar->size() == d && S_bar->rows() == d && S_bar->cols() == d);
  m_bar->noalias() += y_mean_bar.head(d);
  S_bar->noalias() += y_cov_bar.topLeftCorner(d, d);
  std::vector<TrigMoments> t(a_count);
  // Per angle, the adjoint of GTrig's [e_sin, e_cos, var_sin, var_cos,
  // cov_sc]; the means collect every block's contribution before GTrig's
  // Jacobian is applied (they depend on (m_a, S_aa) only).
  std::vector<Eigen::Matrix<double, 5, 1>> t_bar(a_count);
  for (int k = 0; k < a_count; ++k) {
    const int a = angle_indices[k], sk = d + 2 * k, ck = sk + 1;
    t[k] = GTrig(m(a), S(a, a));
    Eigen::Matrix<double, 5, 1>& tb = t_bar[k];
    tb(0) = y_mean_bar(sk);
    tb(1) = y_mean_bar(ck);
    tb(2) = y_cov_bar(sk, sk);
    tb(3) = y_cov_bar(ck, ck);
    tb(4) = y_cov_bar(sk, ck) + y_cov_bar(ck, sk);
    // x's blocks, as in the one-angle backward.
    const Vector g_sin = y_cov_bar.col(sk).head(d);
    const Vector g_cos = y_cov_bar.col(ck).head(d);
    const Vector h_sin = y_cov_bar.row(sk).head(d).transpose();
    const Vector h_cos = y_cov_bar.row(ck).head(d).transpose();
    S_bar->col(a).noalias() += g_sin * t[k].e_cos - g_cos * t[k].e_sin;
    S_bar->row(a).noalias() += (h_sin * t[k].e_cos - h_cos * t[k].e_sin).transpose();
    tb(1) += S.col(a).dot(g_sin) + S.row(a).dot(h_sin);
    tb(0) -= S.col(a).dot(g_cos) + S.row(a).dot(h_cos);
  }
  for (int k = 0; k < a_count; ++k) {
    for (int l = k + 1; l < a_count; ++l) {
      const int a = angle_indices[k], b = angle_indices[l];
      const int sk = d + 2 * k, ck = sk + 1, sl = d + 2 * l, cl = sl + 1;
      // Both symmetric entries of each covariance are outputs.
      const double b_ss = y_cov_bar(sk, sl) + y_cov_bar(sl, sk);
      const double b_sc = y_cov_bar(sk, cl) + y_cov_bar(cl, sk);
      const double b_cs = y_cov_bar(ck, sl) + y_cov_bar(sl, ck);
      const double b_cc = y_cov_bar(ck, cl) + y_cov_bar(cl, ck);
      // The products of the means.
      t_bar[k](0) -= b_ss * t[l].e_sin + b_sc * t[l].e_cos;
      t_bar[k](1) -= b_cs * t[l].e_sin + b_cc * t[l].e_cos;
      t_bar[l](0) -= b_ss * t[k].e_sin + b_cs * t[k].e_cos;
      t_bar[l](1) -= b_sc * t[k].e_sin + b_cc * t[k].e_cos;
      // The product formulas: ss = (K- - K+)/2, sc = (L+ + L-)/2,
      // cs = (L+ - L-)/2, cc = (K- + K+)/2.
      const PairMoments p = PairOf(m, S, a, b);
      const double k_bar[2] = {0.5 * (b_cc - b_ss), 0.5 * (b_cc + b_ss)};
      const double l_bar[2] = {0.5 * (b_sc + b_cs), 0.5 * (b_sc - b_cs)};
      for (int i = 0; i < 2; ++i) {
        const double sigma = i == 0 ? 1.0 : -1.0;
        // K = e cos w, L = e sin w, e = exp(-q/2).
        const double w_bar = -k_bar[i] * p.l[i] + l_bar[i] * p.k[i];
        const double q_bar = -0.5 * (k_bar[i] * p.k[i] + l_bar[i] * p.l[i]);
        (*m_bar)(a) += w_bar;
        (*m_bar)(b) += sigma * w_bar;
        (*S_bar)(a, a) += q_bar;
        (*S_bar)(b, b) += q_bar;
        (*S_bar)(a, b) += sigma * q_bar;
        (*S_bar)(b, a) += sigma * q_bar;
      }
    }
  }
  for (int k = 0; k < a_count; ++k) {
    const int a = angle_indices[k];
    const Eigen::Matrix<double, 2, 1> in_bar = Dx_GTrig(m(a), S(a, a)).transpose() * t_bar[k];
    (*m_bar)(a) += in_bar(0);
    (*S_bar)(a, a) += in_bar(1);
  }
}

}  // namespace totalgrad::gaussian
