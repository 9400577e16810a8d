#include "core/pilco/linear_policy.h"

#include "core/common/check.h"
#include "core/pilco/saturation.h"

namespace totalgrad::pilco {
namespace {

void CheckShapes(const LinearPolicy& policy, const Vector& m, const Matrix& s) {
  const Eigen::Index f = policy.w.rows(), d = policy.w.cols();
  TG_CHECK(f >= 1 && policy.b.size() == f && policy.max_u.size() == f);
  TG_CHECK(m.size() == d && s.rows() == d && s.cols() == d);
}

}  // namespace

void LinearPolicyForward(const LinearPolicy& policy, const Vector& m, const Matrix& s,
                         LinearPolicyMoments* out) {
  CheckShapes(policy, m, s);
  const Matrix& w = policy.w;
  const Vector a_mean = w * m + policy.b;
  const Matrix s_wt = s * w.transpose();  // Cov(x, a), D x F
  Matrix a_cov = w * s_wt;
  a_cov = 0.5 * (a_cov + a_cov.transpose()).eval();
  JointSatMoments sat;
  GSatJoint(a_mean, a_cov, policy.max_u, &sat);
  out->mean = sat.mean;
  out->cov = sat.cov;
  out->cross = s_wt * sat.c.asDiagonal();
  out->u_cross = w.transpose() * sat.c.asDiagonal();
}

void LinearPolicyBackward(const LinearPolicy& policy, const Vector& m, const Matrix& s,
                          const Vector& mean_bar, const Matrix& cov_bar, const Matrix& cross_bar,
                          Vector* m_bar, Matrix* s_bar, Matrix* w_bar, Vector* b_bar,
                          const Matrix* u_cross_bar) {
  CheckShapes(policy, m, s);
  const Matrix& w = policy.w;
  const Eigen::Index f = w.rows(), d = w.cols();
  TG_CHECK(mean_bar.size() == f && cov_bar.rows() == f && cov_bar.cols() == f);
  TG_CHECK(cross_bar.rows() == d && cross_bar.cols() == f);
  // The forward pass again (cheap: F saturations).
  const Vector a_mean = w * m + policy.b;
  const Matrix s_wt = s * w.transpose();
  Matrix a_cov = w * s_wt;
  a_cov = 0.5 * (a_cov + a_cov.transpose()).eval();
  JointSatMoments sat;
  GSatJoint(a_mean, a_cov, policy.max_u, &sat);
  // cross = S W^T diag(c): adjoints of c and of S W^T.
  Vector c_bar = s_wt.cwiseProduct(cross_bar).colwise().sum().transpose();
  Matrix s_wt_bar = cross_bar * sat.c.asDiagonal();
  // u_cross = W^T diag(c): adjoints of c and of W directly.
  Matrix w_direct_bar = Matrix::Zero(f, d);
  if (u_cross_bar != nullptr) {
    TG_CHECK(u_cross_bar->rows() == d && u_cross_bar->cols() == f);
    c_bar += w.transpose().cwiseProduct(*u_cross_bar).colwise().sum().transpose();
    w_direct_bar = sat.c.asDiagonal() * u_cross_bar->transpose();
  }
  Vector a_mean_bar = Vector::Zero(f);
  Matrix a_cov_bar = Matrix::Zero(f, f);
  GSatJointBackward(a_mean, a_cov, policy.max_u, mean_bar, cov_bar, c_bar, &a_mean_bar,
                    &a_cov_bar);
  // a_cov = sym(W S W^T): its adjoint symmetrised, then through W (S W^T).
  const Matrix a_cov_sym_bar = 0.5 * (a_cov_bar + a_cov_bar.transpose());
  s_wt_bar += w.transpose() * a_cov_sym_bar;  // a_cov = W (S W^T), the right factor
  Matrix w_adjoint = a_cov_sym_bar * s_wt.transpose();  // ... and the left W
  w_adjoint += a_mean_bar * m.transpose();
  // S W^T: S's and W's shares.
  w_adjoint += s_wt_bar.transpose() * s;
  w_adjoint += w_direct_bar;
  if (m_bar != nullptr) *m_bar += w.transpose() * a_mean_bar;
  if (b_bar != nullptr) *b_bar += a_mean_bar;
  if (s_bar != nullptr) *s_bar += s_wt_bar * w;
  if (w_bar != nullptr) *w_bar += w_adjoint;
}

}  // namespace totalgrad::pilco
