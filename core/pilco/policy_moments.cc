#include "core/pilco/policy_moments.h"

#include <cmath>

#include <Eigen/Cholesky>

#include "core/common/check.h"
#include "core/pilco/gp_moments.h"

namespace totalgrad::pilco {
namespace {

// gp2 in scaled coordinates: support points centres / l, unit length-scales,
// sf = 1, beta = weights.
struct Scaled {
  Vector il;  // 1 / l
  GaussianInputGp gp;
  Vector m;
  Matrix s;
};

Scaled MakeScaled(const RbfPolicyShape& shape, const Vector& params, const Vector& m,
                  const Matrix& s) {
  const int c = shape.num_basis, e = shape.input_dim, f = shape.num_controls();
  TG_CHECK(params.size() == shape.num_parameters());
  TG_CHECK(m.size() == e && s.rows() == e && s.cols() == e);
  Scaled sc;
  sc.il = (-params.segment(c * e, e).array()).exp().matrix();
  const Eigen::Map<const RowMatrix> centres(params.data(), c, e);
  sc.gp.inputs = centres * sc.il.asDiagonal();
  // One output per control, all on the same scaled centres (shared l, sf = 1).
  sc.gp.inv_lengthscale_sq = RowMatrix::Ones(f, e);
  sc.gp.signal_var = Vector::Ones(f);
  sc.gp.noise_var = Vector::Zero(f);
  if (f == 1) {
    sc.gp.beta = params.tail(c);
  } else {
    sc.gp.beta = Eigen::Map<const RowMatrix>(params.data() + c * e + e, c, f);
  }
  sc.m = sc.il.cwiseProduct(m);
  sc.s = sc.il.asDiagonal() * s * sc.il.asDiagonal();
  return sc;
}

// gp2 with one row of length-scales per control, unscaled: support points
// the centres, P_j = exp(-2 log l_j), sf = 1, beta = weights (C x F).
GaussianInputGp PerControlGp(const RbfPolicyShape& shape, const Vector& params) {
  const int c = shape.num_basis, e = shape.input_dim, f = shape.num_controls();
  TG_CHECK(params.size() == shape.num_parameters() && shape.num_lengthscale_rows() == f);
  GaussianInputGp gp;
  gp.inputs = Eigen::Map<const RowMatrix>(params.data(), c, e);
  gp.inv_lengthscale_sq =
      (-2.0 * Eigen::Map<const RowMatrix>(params.data() + c * e, f, e).array()).exp().matrix();
  gp.signal_var = Vector::Ones(f);
  gp.noise_var = Vector::Zero(f);
  gp.beta = Eigen::Map<const RowMatrix>(params.data() + c * e + f * e, c, f);
  return gp;
}

GaussianPredictionOptions Gp2Options(const RbfPolicyShape& shape) {
  GaussianPredictionOptions o;
  o.model_variance = false;
  o.include_noise = false;
  o.jitter = shape.jitter;
  return o;
}


// Adjoints through the unsquashed outputs a = gp2(m, s) in scaled coordinates
// (one row of length-scales), F columns: a_mean_bar (F), a_cov_bar (F x F),
// a_cross_bar (E x F). `a_cross` is the forward Cov(x, a) (E x F), read only
// with params_bar (a_cross = diag(il) cross_scaled depends on log l
// explicitly; summed over the controls).
absl::Status ScaledUnsquashedBackward(const RbfPolicyShape& shape, const Scaled& sc,
                                      const Vector& a_mean_bar, const Matrix& a_cov_bar,
                                      const Matrix& a_cross_bar, const Matrix& a_cross,
                                      Vector* m_bar, Matrix* s_bar, Vector* params_bar) {
  const int c = shape.num_basis, e = shape.input_dim, f = shape.num_controls();
  const Matrix cross_bar_scaled = sc.il.asDiagonal() * a_cross_bar;
  Vector m_bar_scaled;
  Matrix s_bar_scaled;
  RowMatrix inputs_bar;
  Matrix beta_bar;
  if (absl::Status st = PredictGaussianBackward(sc.gp, sc.m, sc.s, Gp2Options(shape), a_mean_bar,
                                                a_cov_bar, cross_bar_scaled, &m_bar_scaled,
                                                &s_bar_scaled, params_bar ? &inputs_bar : nullptr,
                                                params_bar ? &beta_bar : nullptr);
      !st.ok()) {
    return st;
  }
  *m_bar = sc.il.cwiseProduct(m_bar_scaled);
  *s_bar = sc.il.asDiagonal() * s_bar_scaled * sc.il.asDiagonal();
  if (params_bar != nullptr) {
    TG_CHECK(params_bar->size() == shape.num_parameters());
    TG_CHECK(a_cross.rows() == e && a_cross.cols() == f);
    Eigen::Map<RowMatrix> centres_bar(params_bar->data(), c, e);
    centres_bar += inputs_bar * sc.il.asDiagonal();
    const Vector log_l_bar =
        -(inputs_bar.cwiseProduct(sc.gp.inputs).colwise().sum().transpose() +
          m_bar_scaled.cwiseProduct(sc.m) + 2.0 * s_bar_scaled.cwiseProduct(sc.s).rowwise().sum() +
          a_cross_bar.cwiseProduct(a_cross).rowwise().sum());
    params_bar->segment(c * e, e) += log_l_bar;
    Eigen::Map<RowMatrix>(params_bar->data() + c * e + e, c, f) += beta_bar;
  }
  return absl::OkStatus();
}
}  // namespace

absl::Status PolicyAtGaussian(const RbfPolicyShape& shape, const Vector& params, const Vector& m,
                              const Matrix& s, PolicyMoments* out) {
  TG_CHECK(shape.num_controls() == 1);
  const Scaled sc = MakeScaled(shape, params, m, s);
  GaussianPrediction pred;
  if (absl::Status st = PredictGaussian(sc.gp, sc.m, sc.s, Gp2Options(shape), &pred); !st.ok()) {
    return st;
  }
  out->a_mean = pred.mean(0);
  out->a_var = pred.cov(0, 0);
  out->a_cross = sc.il.cwiseProduct(pred.cross.col(0));
  out->sat = GSat(out->a_mean, out->a_var, shape.max_force);
  out->u_cross = out->a_cross * out->sat.c;
  return absl::OkStatus();
}

absl::Status UnsquashedPolicyBackward(const RbfPolicyShape& shape, const Vector& params,
                                      const Vector& m, const Matrix& s, double a_mean_bar,
                                      double a_var_bar, const Vector& a_cross_bar, Vector* m_bar,
                                      Matrix* s_bar, Vector* params_bar) {
  TG_CHECK(shape.num_controls() == 1);
  const Scaled sc = MakeScaled(shape, params, m, s);
  TG_CHECK(a_cross_bar.size() == shape.input_dim);
  Matrix a_cross;
  if (params_bar != nullptr) {
    GaussianPrediction pred;
    if (absl::Status st = PredictGaussian(sc.gp, sc.m, sc.s, Gp2Options(shape), &pred);
        !st.ok()) {
      return st;
    }
    a_cross = sc.il.cwiseProduct(pred.cross.col(0));
  }
  return ScaledUnsquashedBackward(shape, sc, Vector::Constant(1, a_mean_bar),
                                  Matrix::Constant(1, 1, a_var_bar), a_cross_bar, a_cross, m_bar,
                                  s_bar, params_bar);
}

absl::Status MultiPolicyAtGaussian(const RbfPolicyShape& shape, const Vector& params,
                                   const Vector& m, const Matrix& s, MultiPolicyMoments* out) {
  TG_CHECK(shape.num_controls() >= 2);
  if (shape.num_lengthscale_rows() > 1) {
    // No common scaled coordinates: gp2 on the centres as they are.
    GaussianPrediction pred;
    if (absl::Status st = PredictGaussian(PerControlGp(shape, params), m, s, Gp2Options(shape),
                                          &pred);
        !st.ok()) {
      return st;
    }
    out->a_mean = pred.mean;
    out->a_cov = pred.cov;
    out->a_cross = pred.cross;
    GSatJoint(out->a_mean, out->a_cov, shape.max_controls, &out->sat);
    out->u_cross = out->a_cross * out->sat.c.asDiagonal();
    return absl::OkStatus();
  }
  const Scaled sc = MakeScaled(shape, params, m, s);
  GaussianPrediction pred;
  if (absl::Status st = PredictGaussian(sc.gp, sc.m, sc.s, Gp2Options(shape), &pred); !st.ok()) {
    return st;
  }
  out->a_mean = pred.mean;
  out->a_cov = pred.cov;
  out->a_cross = sc.il.asDiagonal() * pred.cross;
  GSatJoint(out->a_mean, out->a_cov, shape.max_controls, &out->sat);
  out->u_cross = out->a_cross * out->sat.c.asDiagonal();
  return absl::OkStatus();
}

absl::Status MultiPolicyAtGaussianBackward(const RbfPolicyShape& shape, const Vector& params,
                                           const Vector& m, const Matrix& s,
                                           const Vector& u_mean_bar, const Matrix& u_cov_bar,
                                           const Matrix& u_cross_bar, Vector* m_bar, Matrix* s_bar,
                                           Vector* params_bar) {
  const int c = shape.num_basis, e = shape.input_dim, f = shape.num_controls();
  TG_CHECK(f >= 2 && u_cross_bar.rows() == e && u_cross_bar.cols() == f);
  MultiPolicyMoments pm;
  if (absl::Status st = MultiPolicyAtGaussian(shape, params, m, s, &pm); !st.ok()) return st;
  // u_cross = a_cross diag(c).
  const Matrix a_cross_bar = u_cross_bar * pm.sat.c.asDiagonal();
  const Vector c_bar = pm.a_cross.cwiseProduct(u_cross_bar).colwise().sum().transpose();
  Vector a_mean_bar = Vector::Zero(f);
  Matrix a_cov_bar = Matrix::Zero(f, f);
  GSatJointBackward(pm.a_mean, pm.a_cov, shape.max_controls, u_mean_bar, u_cov_bar, c_bar,
                    &a_mean_bar, &a_cov_bar);
  if (shape.num_lengthscale_rows() > 1) {
    const GaussianInputGp gp = PerControlGp(shape, params);
    RowMatrix inputs_bar;
    Matrix beta_bar;
    if (absl::Status st = PredictGaussianBackward(gp, m, s, Gp2Options(shape), a_mean_bar,
                                                  a_cov_bar, a_cross_bar, m_bar, s_bar,
                                                  params_bar ? &inputs_bar : nullptr,
                                                  params_bar ? &beta_bar : nullptr);
        !st.ok()) {
      return st;
    }
    if (params_bar != nullptr) {
      TG_CHECK(params_bar->size() == shape.num_parameters());
      RowMatrix il_bar;
      if (absl::Status st = PredictGaussianLengthscaleAdjoint(gp, m, s, Gp2Options(shape),
                                                              a_mean_bar, a_cov_bar, a_cross_bar,
                                                              &il_bar);
          !st.ok()) {
        return st;
      }
      Eigen::Map<RowMatrix>(params_bar->data(), c, e) += inputs_bar;
      // P = exp(-2 log l): dP/dlog l = -2 P.
      Eigen::Map<RowMatrix>(params_bar->data() + c * e, f, e) +=
          (-2.0 * il_bar.array() * gp.inv_lengthscale_sq.array()).matrix();
      Eigen::Map<RowMatrix>(params_bar->data() + c * e + f * e, c, f) += beta_bar;
    }
    return absl::OkStatus();
  }
  return ScaledUnsquashedBackward(shape, MakeScaled(shape, params, m, s), a_mean_bar, a_cov_bar,
                                  a_cross_bar, pm.a_cross, m_bar, s_bar, params_bar);
}

absl::Status PolicyAtGaussianBackward(const RbfPolicyShape& shape, const Vector& params,
                                      const Vector& m, const Matrix& s, double u_mean_bar,
                                      double u_var_bar, const Vector& u_cross_bar, Vector* m_bar,
                                      Matrix* s_bar, Vector* params_bar) {
  PolicyMoments pm;
  if (absl::Status st = PolicyAtGaussian(shape, params, m, s, &pm); !st.ok()) return st;
  // u_cross = a_cross * c.
  const Vector a_cross_bar = u_cross_bar * pm.sat.c;
  const double c_bar = pm.a_cross.dot(u_cross_bar);
  const Eigen::Vector3d sat_bar(u_mean_bar, u_var_bar, c_bar);
  const Eigen::Vector2d in_bar =
      Dx_GSat(pm.a_mean, pm.a_var, shape.max_force).transpose() * sat_bar;
  return UnsquashedPolicyBackward(shape, params, m, s, in_bar(0), in_bar(1), a_cross_bar, m_bar,
                                  s_bar, params_bar);
}

namespace {

// K_cc (C x C) of the scaled centres.
Matrix CentreKernel(const RowMatrix& scaled) {
  const int c = static_cast<int>(scaled.rows());
  Matrix k(c, c);
  for (int j = 0; j < c; ++j) {
    for (int i = j; i < c; ++i) {
      k(i, j) = k(j, i) = std::exp(-0.5 * (scaled.row(i) - scaled.row(j)).squaredNorm());
    }
  }
  return k;
}

}  // namespace

// congp's K_cc of the centres at the length-scales of `params` (either
// layout: centres and log l come first in both), without the noise term.
namespace {
Matrix CongpCentreKernel(const RbfPolicyShape& shape, const Vector& params) {
  const int c = shape.num_basis, e = shape.input_dim;
  const Vector il = (-params.segment(c * e, e).array()).exp().matrix();
  const Eigen::Map<const RowMatrix> centres(params.data(), c, e);
  return CentreKernel(centres * il.asDiagonal());
}
}  // namespace

namespace {

// One control's view of a per-control-length-scale parameter vector:
// [centres, log l_j, column j of the values].
RbfPolicyShape OneControl(const RbfPolicyShape& shape) {
  RbfPolicyShape one = shape;
  one.max_controls.resize(0);
  one.lengthscale_per_control = false;
  return one;
}

Vector ColumnView(const RbfPolicyShape& shape, const Vector& params, int j) {
  const int c = shape.num_basis, e = shape.input_dim, f = shape.num_controls();
  Vector out(c * e + e + c);
  out.head(c * e) = params.head(c * e);
  out.segment(c * e, e) = params.segment(c * e + j * e, e);
  const Eigen::Map<const RowMatrix> values(params.data() + c * e + f * e, c, f);
  out.tail(c) = values.col(j);
  return out;
}

}  // namespace

absl::Status PseudoTargetsToWeights(const RbfPolicyShape& shape, const Vector& pilco_params,
                                    Vector* params) {
  const int c = shape.num_basis, e = shape.input_dim, f = shape.num_controls();
  TG_CHECK(pilco_params.size() == shape.num_parameters());
  if (shape.num_lengthscale_rows() > 1) {
    // Column j solves (K_cc(l_j) + 1e-4 I) w_j = y_j: congp per control.
    *params = pilco_params;
    Eigen::Map<RowMatrix> w(params->data() + c * e + f * e, c, f);
    for (int j = 0; j < f; ++j) {
      Vector one;
      if (absl::Status st = PseudoTargetsToWeights(OneControl(shape),
                                                   ColumnView(shape, pilco_params, j), &one);
          !st.ok()) {
        return st;
      }
      w.col(j) = one.tail(c);
    }
    return absl::OkStatus();
  }
  Matrix a = CongpCentreKernel(shape, pilco_params);
  a.diagonal().array() += kCongpNoiseVar;
  Eigen::LLT<Matrix> llt(a);
  if (llt.info() != Eigen::Success || !a.allFinite()) {
    return absl::FailedPreconditionError(
        "policy: K_cc + 1e-4 I of the centres is not positive definite");
  }
  *params = pilco_params;
  if (f == 1) {
    params->tail(c) = llt.solve(pilco_params.tail(c));
  } else {
    // The targets' columns, one per control, through the same solve.
    const Matrix y = Eigen::Map<const RowMatrix>(pilco_params.data() + c * e + e, c, f);
    Eigen::Map<RowMatrix>(params->data() + c * e + e, c, f) = llt.solve(y);
  }
  return absl::OkStatus();
}

absl::Status WeightsToPseudoTargets(const RbfPolicyShape& shape, const Vector& params,
                                    Vector* pilco_params) {
  const int c = shape.num_basis, e = shape.input_dim, f = shape.num_controls();
  TG_CHECK(params.size() == shape.num_parameters());
  if (shape.num_lengthscale_rows() > 1) {
    *pilco_params = params;
    Eigen::Map<RowMatrix> y(pilco_params->data() + c * e + f * e, c, f);
    for (int j = 0; j < f; ++j) {
      Vector one;
      if (absl::Status st =
              WeightsToPseudoTargets(OneControl(shape), ColumnView(shape, params, j), &one);
          !st.ok()) {
        return st;
      }
      y.col(j) = one.tail(c);
    }
    return absl::OkStatus();
  }
  Matrix a = CongpCentreKernel(shape, params);
  a.diagonal().array() += kCongpNoiseVar;
  if (!a.allFinite() || !params.tail(c * f).allFinite()) {
    return absl::FailedPreconditionError("policy: centres, length-scales or weights not finite");
  }
  *pilco_params = params;
  // Y = A W, one column per control (the weights C x F, row-major).
  const Matrix w = Eigen::Map<const RowMatrix>(params.data() + c * e + e, c, f);
  Eigen::Map<RowMatrix>(pilco_params->data() + c * e + e, c, f) = a * w;
  return absl::OkStatus();
}

absl::Status PseudoTargetsBackward(const RbfPolicyShape& shape, const Vector& pilco_params,
                                   const Vector& params_bar, Vector* pilco_params_bar) {
  const int c = shape.num_basis, e = shape.input_dim, f = shape.num_controls();
  TG_CHECK(pilco_params.size() == shape.num_parameters());
  TG_CHECK(params_bar.size() == shape.num_parameters());
  if (shape.num_lengthscale_rows() > 1) {
    // Column j's weights depend on the centres, log l_j and y_j only: the
    // one-control chain rule per column, the centres' parts summed (the
    // direct centres adjoint enters once, with column 0).
    *pilco_params_bar = params_bar;
    Eigen::Map<RowMatrix> centres_bar(pilco_params_bar->data(), c, e);
    centres_bar.setZero();
    Eigen::Map<RowMatrix> y_bar(pilco_params_bar->data() + c * e + f * e, c, f);
    for (int j = 0; j < f; ++j) {
      Vector bar_j = ColumnView(shape, params_bar, j);
      if (j > 0) bar_j.head(c * e).setZero();
      Vector out;
      if (absl::Status st = PseudoTargetsBackward(OneControl(shape), ColumnView(shape, pilco_params, j),
                                                  bar_j, &out);
          !st.ok()) {
        return st;
      }
      centres_bar += Eigen::Map<const RowMatrix>(out.data(), c, e);
      pilco_params_bar->segment(c * e + j * e, e) = out.segment(c * e, e);
      y_bar.col(j) = out.tail(c);
    }
    return absl::OkStatus();
  }
  const Vector il = (-pilco_params.segment(c * e, e).array()).exp().matrix();
  const Eigen::Map<const RowMatrix> centres(pilco_params.data(), c, e);
  const Matrix k = CentreKernel(centres * il.asDiagonal());
  Matrix a = k;
  a.diagonal().array() += kCongpNoiseVar;
  Eigen::LLT<Matrix> llt(a);
  if (llt.info() != Eigen::Success || !a.allFinite()) {
    return absl::FailedPreconditionError(
        "policy: K_cc + 1e-4 I of the centres is not positive definite");
  }
  // W = A^-1 Y (one column per control): Y_bar = A^-1 W_bar,
  // A_bar = -Y_bar W^T (summed over the columns).
  Matrix y_bar, a_bar;
  if (f == 1) {
    const Vector w = llt.solve(pilco_params.tail(c));
    const Vector yb = llt.solve(params_bar.tail(c));
    a_bar = -yb * w.transpose();
    y_bar = yb;
  } else {
    const Matrix y = Eigen::Map<const RowMatrix>(pilco_params.data() + c * e + e, c, f);
    const Matrix w_bar = Eigen::Map<const RowMatrix>(params_bar.data() + c * e + e, c, f);
    const Matrix w = llt.solve(y);
    y_bar = llt.solve(w_bar);
    a_bar = -y_bar * w.transpose();
  }
  const Matrix b = (a_bar + a_bar.transpose()).cwiseProduct(k);  // symmetric
  const Vector il2 = il.cwiseProduct(il);
  *pilco_params_bar = params_bar;
  Eigen::Map<RowMatrix> centres_bar(pilco_params_bar->data(), c, e);
  const Vector row_b = b.rowwise().sum();
  // dK_kl/dc_km = -K_kl (c_km - c_lm) / l_m^2.
  const RowMatrix bc = b * centres;
  centres_bar -= (row_b.asDiagonal() * centres - bc) * il2.asDiagonal();
  // dK_kl/dlog l_m = K_kl (c_km - c_lm)^2 / l_m^2.
  for (int m = 0; m < e; ++m) {
    double acc = 0;
    for (int l = 0; l < c; ++l) {
      for (int kk = 0; kk < c; ++kk) {
        const double diff = centres(kk, m) - centres(l, m);
        acc += b(kk, l) * diff * diff;
      }
    }
    (*pilco_params_bar)(c * e + m) += 0.5 * acc * il2(m);
  }
  if (f == 1) {
    pilco_params_bar->tail(c) = y_bar.col(0);
  } else {
    Eigen::Map<RowMatrix>(pilco_params_bar->data() + c * e + e, c, f) = y_bar;
  }
  return absl::OkStatus();
}

}  // namespace totalgrad::pilco
