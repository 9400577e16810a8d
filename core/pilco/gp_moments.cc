#include "core/pilco/gp_moments.h"

#include <cmath>
#include <string>

#include <Eigen/Cholesky>

#include "absl/strings/str_cat.h"
#include "core/common/check.h"
#include "core/common/vector_exp.h"

namespace totalgrad::pilco {
namespace {

// Terms of the mean and cross-covariance of output a:
//   A = (s + Lambda_a)^-1,  q_i = sf^2 det(s Lambda^-1 + I)^-1/2 exp(-1/2 d_i^T A d_i)
// with d_i = x_i - m (row i of delta).
struct MeanTerms {
  Matrix a;   // E x E
  Matrix da;  // N x E, delta * A
  Vector q;   // N
};

absl::Status ComputeMeanTerms(const Matrix& delta, const Matrix& s, const Vector& il, double sf2,
                              int output, MeanTerms* t) {
  const int e = static_cast<int>(s.rows());
  Matrix b = s;
  b.diagonal() += il.cwiseInverse();
  Eigen::LLT<Matrix> llt(b);
  if (llt.info() != Eigen::Success) {
    return absl::FailedPreconditionError(absl::StrCat(
        "input covariance + Lambda is not positive definite (output ", output,
        "); the input covariance is not positive semi-definite"));
  }
  t->a = llt.solve(Matrix::Identity(e, e));
  t->a = 0.5 * (t->a + t->a.transpose()).eval();
  // log det(s Lambda^-1 + I)^-1/2 = 1/2 sum log Lambda - 1/2 log det(s + Lambda)
  const double log_c =
      -0.5 * il.array().log().sum() - llt.matrixLLT().diagonal().array().log().sum();
  t->da.noalias() = delta * t->a;
  const Vector quad = t->da.cwiseProduct(delta).rowwise().sum();
  t->q = (std::log(sf2) + log_c - 0.5 * quad.array()).exp().matrix();
  return absl::OkStatus();
}

// Terms of Q_ab (pilco-spec.md 4.3), with Psi = Lambda_a^-1 + Lambda_b^-1,
// R = s Psi + I and Rs = Psi^1/2 s Psi^1/2 + I (symmetric positive definite,
// det Rs = det R):
//   log Q_ij = log(sf_a^2 sf_b^2) - 1/2 log det R + ra_i + rb_j + (Za T Zb^T)_ij,
//   T = R^-1 s (symmetric), Za = delta Lambda_a^-1, Zb = delta Lambda_b^-1,
//   ra_i = -1/2 za_i . d_i + 1/2 za_i^T T za_i, rb_j likewise.
struct PairTerms {
  Vector sqrt_psi;          // E
  Eigen::LLT<Matrix> llt;   // of Rs
  Matrix t;                 // E x E
  Matrix za, zb;            // N x E
  Matrix q;                 // N x N
};

absl::Status ComputePairTerms(const Matrix& delta, const Matrix& s, const Vector& ila,
                              const Vector& ilb, double sf2a, double sf2b, int a, int b,
                              PairTerms* p) {
  const int e = static_cast<int>(s.rows());
  p->sqrt_psi = (ila + ilb).cwiseSqrt();
  Matrix rs = p->sqrt_psi.asDiagonal() * s * p->sqrt_psi.asDiagonal();
  rs.diagonal().array() += 1.0;
  p->llt.compute(rs);
  if (p->llt.info() != Eigen::Success) {
    return absl::FailedPreconditionError(
        absl::StrCat("s (Lambda_a^-1 + Lambda_b^-1) + I is not invertible (outputs ", a, ", ", b,
                     "); the input covariance is not positive semi-definite"));
  }
  const double log_det_r = 2.0 * p->llt.matrixLLT().diagonal().array().log().sum();
  p->t = p->sqrt_psi.cwiseInverse().asDiagonal() *
         p->llt.solve(Matrix(p->sqrt_psi.asDiagonal() * s));
  p->t = 0.5 * (p->t + p->t.transpose()).eval();
  (void)e;
  p->za = delta * ila.asDiagonal();
  p->zb = delta * ilb.asDiagonal();
  const Matrix zat = p->za * p->t;
  const Vector ra = -0.5 * p->za.cwiseProduct(delta).rowwise().sum() +
                    0.5 * zat.cwiseProduct(p->za).rowwise().sum();
  const Vector rb = -0.5 * p->zb.cwiseProduct(delta).rowwise().sum() +
                    0.5 * (p->zb * p->t).cwiseProduct(p->zb).rowwise().sum();
  p->q.noalias() = zat * p->zb.transpose();
  // Q_ij = E[k_a(x_i, x) k_b(x_j, x)] <= sf_a^2 sf_b^2, so with the signal
  // variances factored out the exponent is <= 0 (up to round-off, clamped):
  // Q_ij = sf_a^2 sf_b^2 exp(((Za T Zb^T)_ij + ra_i) + (rb_j - 1/2 log det R)),
  // one fused vectorised pass per column (SeKernelColumn computes
  // sf2 exp(min((dot_i - a_i / 2) - b / 2, 0))).
  const Vector minus_two_ra = -2.0 * ra;
  const double sf2_product = sf2a * sf2b;
  const Eigen::Index n = p->q.rows();
  if (a == b) {
    // Q_aa is symmetric: exponentiate the lower triangle and mirror it.
    for (Eigen::Index j = 0; j < n; ++j) {
      double* column = p->q.col(j).data() + j;
      SeKernelColumn(column, minus_two_ra.data() + j, -2.0 * (rb(j) - 0.5 * log_det_r),
                     sf2_product, column, n - j);
    }
    for (Eigen::Index j = 1; j < n; ++j) {
      for (Eigen::Index i = 0; i < j; ++i) p->q(i, j) = p->q(j, i);
    }
    return absl::OkStatus();
  }
  for (Eigen::Index j = 0; j < n; ++j) {
    double* column = p->q.col(j).data();
    SeKernelColumn(column, minus_two_ra.data(), -2.0 * (rb(j) - 0.5 * log_det_r), sf2_product,
                   column, n);
  }
  return absl::OkStatus();
}

absl::Status CheckInputs(const GaussianInputGp& gp, const Vector& m, const Matrix& s,
                         const GaussianPredictionOptions& options) {
  const int e = gp.num_inputs();
  TG_CHECK(m.size() == e);
  TG_CHECK(s.rows() == e && s.cols() == e);
  TG_CHECK(gp.inv_lengthscale_sq.rows() == gp.num_outputs() &&
           gp.inv_lengthscale_sq.cols() == e);
  TG_CHECK(gp.beta.rows() == gp.num_points());
  TG_CHECK(gp.signal_var.size() == gp.num_outputs());
  if (options.model_variance) {
    TG_CHECK(static_cast<int>(gp.variance_weights.size()) == gp.num_outputs());
  }
  if (options.include_noise) TG_CHECK(gp.noise_var.size() == gp.num_outputs());
  if (!m.allFinite()) return absl::InvalidArgumentError("input mean is not finite");
  if (!s.allFinite()) return absl::InvalidArgumentError("input covariance is not finite");
  return absl::OkStatus();
}

Matrix Delta(const GaussianInputGp& gp, const Vector& m) {
  Matrix delta = gp.inputs;
  delta.rowwise() -= m.transpose();
  return delta;
}

}  // namespace

absl::StatusOr<GaussianInputGp> GaussianInputGpFromData(const RowMatrix& inputs,
                                                        const RowMatrix& targets,
                                                        const RowMatrix& log_hyp) {
  const int n = static_cast<int>(inputs.rows());
  const int e = static_cast<int>(inputs.cols());
  const int d = static_cast<int>(targets.cols());
  if (n == 0) return absl::InvalidArgumentError("no training data");
  if (targets.rows() != n) {
    return absl::InvalidArgumentError(
        absl::StrCat("train_targets has ", targets.rows(), " rows, train_inputs ", n));
  }
  if (log_hyp.rows() != d || log_hyp.cols() != e + 2) {
    return absl::InvalidArgumentError(absl::StrCat("gp_log_hyp must be ", d, " x ", e + 2,
                                                   ", is ", log_hyp.rows(), " x ",
                                                   log_hyp.cols()));
  }
  if (!inputs.allFinite()) return absl::InvalidArgumentError("train_inputs not finite");
  if (!targets.allFinite()) return absl::InvalidArgumentError("train_targets not finite");
  if (!log_hyp.allFinite()) return absl::InvalidArgumentError("gp_log_hyp not finite");
  GaussianInputGp gp;
  gp.inputs = inputs;
  gp.inv_lengthscale_sq = (-2.0 * log_hyp.leftCols(e).array()).exp().matrix();
  gp.signal_var = (2.0 * log_hyp.col(e).array()).exp().matrix();
  gp.noise_var = (2.0 * log_hyp.col(e + 1).array()).exp().matrix();
  gp.beta.resize(n, d);
  gp.variance_weights.resize(d);
  for (int a = 0; a < d; ++a) {
    const RowMatrix scaled = inputs * gp.inv_lengthscale_sq.row(a).cwiseSqrt().asDiagonal();
    // Pairwise differences directly (no |x|^2 + |y|^2 - 2 x.y cancellation).
    Matrix k(n, n);
    for (int j = 0; j < n; ++j) {
      for (int i = j; i < n; ++i) {
        const double r2 = (scaled.row(i) - scaled.row(j)).squaredNorm();
        k(i, j) = k(j, i) = gp.signal_var(a) * std::exp(-0.5 * r2);
      }
    }
    k.diagonal().array() += gp.noise_var(a);
    Eigen::LLT<Matrix> llt(k);
    if (llt.info() != Eigen::Success) {
      return absl::FailedPreconditionError(absl::StrCat(
          "Cholesky factorisation of K + sn^2 I failed for output ", a,
          " (kernel matrix not positive definite; check gp_log_hyp and duplicate inputs)"));
    }
    gp.beta.col(a) = llt.solve(targets.col(a));
    const Matrix k_inv = llt.solve(Matrix::Identity(n, n));
    gp.variance_weights[a] = 0.5 * (k_inv + k_inv.transpose());
  }
  return gp;
}

namespace {

// The moment-matching view of a trained model (a full GP or FITC, which
// share the interface: centres, hyperparameters, beta_a and the matrix the
// predictive variance weights, K^-1 or FITC's): per output a, the centres'
// weights beta_a and W_a = model.VarianceWeights(a).
template <typename Model, typename VarianceWeights>
GaussianInputGp GaussianInputGpFrom(const Model& model, const RowMatrix& centres,
                                    VarianceWeights variance_weights) {
  GaussianInputGp gp;
  const int d = model.num_outputs();
  const gp::GpHyperparameters& h = model.hyperparameters();
  gp.inputs = centres;
  gp.inv_lengthscale_sq = (-2.0 * h.log_lengthscales.array()).exp().matrix();
  gp.signal_var = (2.0 * h.log_signal_std.array()).exp().matrix();
  gp.noise_var = (2.0 * h.log_noise_std.array()).exp().matrix();
  gp.beta.resize(centres.rows(), d);
  gp.variance_weights.resize(d);
  for (int a = 0; a < d; ++a) {
    gp.beta.col(a) = model.beta(a);
    gp.variance_weights[a] = variance_weights(a);
  }
  return gp;
}

// The second moments' share of the reverse passes: for every pair of
// outputs a <= b whose covariance adjoint gamma (sym_bar(a, a), or
// 2 sym_bar(a, b)) is not 0, the pair's terms (ComputePairTerms), the
// pair's share of beta's adjoint when `beta_bar` is given, and then p.q
// replaced by the weights W = Q_ab o gamma (beta_a beta_b^T - [a == b,
// model variance] Vw_a), handed to visit(a, b, p).
template <typename Visit>
absl::Status ForEachWeightedPair(const GaussianInputGp& gp, const Matrix& delta, const Matrix& s,
                                 const Matrix& sym_bar, bool model_variance, Matrix* beta_bar,
                                 Visit visit) {
  const int d = gp.num_outputs();
  PairTerms p;
  for (int a = 0; a < d; ++a) {
    const Vector ila = gp.inv_lengthscale_sq.row(a).transpose();
    for (int b = a; b < d; ++b) {
      const double gamma = a == b ? sym_bar(a, a) : 2.0 * sym_bar(a, b);
      if (gamma == 0.0) continue;
      const Vector ilb = gp.inv_lengthscale_sq.row(b).transpose();
      if (absl::Status st = ComputePairTerms(delta, s, ila, ilb, gp.signal_var(a),
                                             gp.signal_var(b), a, b, &p);
          !st.ok()) {
        return st;
      }
      if (beta_bar != nullptr) {
        beta_bar->col(a).noalias() += gamma * (p.q * gp.beta.col(b));
        beta_bar->col(b).noalias() += gamma * (p.q.transpose() * gp.beta.col(a));
      }
      Matrix& w = p.q;
      if (a == b && model_variance) {
        w.array() *= gamma * ((gp.beta.col(a) * gp.beta.col(b).transpose()).array() -
                              gp.variance_weights[a].array());
      } else {
        w.array() *= gamma * (gp.beta.col(a) * gp.beta.col(b).transpose()).array();
      }
      visit(a, b, ila, ilb, p);
    }
  }
  return absl::OkStatus();
}

}  // namespace

GaussianInputGp GaussianInputGpFromModel(const gp::GpModel& model) {
  return GaussianInputGpFrom(model, model.inputs(),
                             [&](int a) -> const Matrix& { return model.k_inverse(a); });
}

GaussianInputGp GaussianInputGpFromFitc(const gp::FitcModel& model) {
  return GaussianInputGpFrom(model, model.inducing(),
                             [&](int a) -> const Matrix& { return model.variance_weights(a); });
}

absl::Status PredictGaussian(const GaussianInputGp& gp, const Vector& m, const Matrix& s,
                             const GaussianPredictionOptions& options, GaussianPrediction* out) {
  if (absl::Status st = CheckInputs(gp, m, s, options); !st.ok()) return st;
  const int e = gp.num_inputs(), d = gp.num_outputs();
  const Matrix delta = Delta(gp, m);
  out->mean.resize(d);
  out->cov.resize(d, d);
  out->cross.resize(e, d);
  MeanTerms mt;
  for (int a = 0; a < d; ++a) {
    const Vector il = gp.inv_lengthscale_sq.row(a).transpose();
    if (absl::Status st = ComputeMeanTerms(delta, s, il, gp.signal_var(a), a, &mt); !st.ok()) {
      return st;
    }
    const Vector bq = gp.beta.col(a).cwiseProduct(mt.q);
    out->mean(a) = bq.sum();
    out->cross.col(a).noalias() = mt.da.transpose() * bq;
  }
  PairTerms p;
  for (int a = 0; a < d; ++a) {
    const Vector ila = gp.inv_lengthscale_sq.row(a).transpose();
    for (int b = a; b < d; ++b) {
      const Vector ilb = gp.inv_lengthscale_sq.row(b).transpose();
      if (absl::Status st = ComputePairTerms(delta, s, ila, ilb, gp.signal_var(a),
                                             gp.signal_var(b), a, b, &p);
          !st.ok()) {
        return st;
      }
      double v = gp.beta.col(a).dot(p.q * gp.beta.col(b)) - out->mean(a) * out->mean(b);
      if (a == b) {
        if (options.model_variance) {
          v += gp.signal_var(a) - gp.variance_weights[a].cwiseProduct(p.q).sum();
        }
        if (options.include_noise) v += gp.noise_var(a);
        v += options.jitter;
      }
      out->cov(a, b) = v;
      out->cov(b, a) = v;
    }
  }
  if (!out->mean.allFinite() || !out->cov.allFinite() || !out->cross.allFinite()) {
    return absl::InternalError("GP prediction at a Gaussian input is not finite");
  }
  return absl::OkStatus();
}

absl::Status PredictGaussianBackward(const GaussianInputGp& gp, const Vector& m, const Matrix& s,
                                     const GaussianPredictionOptions& options,
                                     const Vector& mean_bar, const Matrix& cov_bar,
                                     const Matrix& cross_bar, Vector* m_bar, Matrix* s_bar,
                                     RowMatrix* inputs_bar, Matrix* beta_bar) {
  if (absl::Status st = CheckInputs(gp, m, s, options); !st.ok()) return st;
  const int n = gp.num_points(), e = gp.num_inputs(), d = gp.num_outputs();
  TG_CHECK(mean_bar.size() == d);
  TG_CHECK(cov_bar.rows() == d && cov_bar.cols() == d);
  TG_CHECK(cross_bar.rows() == e && cross_bar.cols() == d);
  const Matrix delta = Delta(gp, m);
  const Matrix sym_bar = 0.5 * (cov_bar + cov_bar.transpose());

  // Recompute the means (needed for the -M_a M_b terms) and mean terms.
  std::vector<MeanTerms> mts(d);
  Vector mean(d);
  for (int a = 0; a < d; ++a) {
    const Vector il = gp.inv_lengthscale_sq.row(a).transpose();
    if (absl::Status st = ComputeMeanTerms(delta, s, il, gp.signal_var(a), a, &mts[a]);
        !st.ok()) {
      return st;
    }
    mean(a) = gp.beta.col(a).dot(mts[a].q);
  }
  const Vector total_mean_bar = mean_bar - 2.0 * sym_bar * mean;

  Matrix delta_bar = Matrix::Zero(n, e);
  Matrix sb = Matrix::Zero(e, e);
  if (beta_bar != nullptr) beta_bar->setZero(n, d);

  // Second moments.
  const absl::Status pairs = ForEachWeightedPair(
      gp, delta, s, sym_bar, options.model_variance, beta_bar,
      [&](int a, int b, const Vector& ila, const Vector& ilb, const PairTerms& p) {
        const Matrix& w = p.q;
        // For a == b, W is symmetric (Q_aa, beta beta^T and Vw_a are), so
        // c = r and W^T Za = W Zb: one product instead of two.
        const Vector r = w.rowwise().sum();
        const Vector c = a == b ? r : Vector(w.colwise().sum().transpose());
        const double sum_w = r.sum();
        const Matrix wzb = w * p.zb;                                     // N x E
        const Matrix wtza = a == b ? wzb : Matrix(w.transpose() * p.za);  // N x E
        const Matrix rza = r.asDiagonal() * p.za;
        const Matrix czb = c.asDiagonal() * p.zb;
        delta_bar.noalias() -= rza + czb;
        delta_bar.noalias() += (rza + wzb) * p.t * ila.asDiagonal();
        delta_bar.noalias() += (wtza + czb) * p.t * ilb.asDiagonal();
        const Matrix cross_g = p.za.transpose() * wzb;
        const Matrix g = p.za.transpose() * rza + p.zb.transpose() * czb + cross_g +
                         cross_g.transpose();
        // d(-1/2 log det R)/ds = -1/2 R^-T Psi = -1/2 Psi^1/2 Rs^-1 Psi^1/2;
        // d(1/2 zeta^T T zeta)/ds = 1/2 R^-T zeta zeta^T R^-1, with
        // R^-T = Psi^1/2 Rs^-1 Psi^-1/2.
        const Matrix rs_inv = p.llt.solve(Matrix::Identity(e, e));
        const Matrix r_inv_t =
            p.sqrt_psi.asDiagonal() * rs_inv * p.sqrt_psi.cwiseInverse().asDiagonal();
        sb.noalias() -= 0.5 * sum_w *
                        (p.sqrt_psi.asDiagonal() * rs_inv * p.sqrt_psi.asDiagonal());
        sb.noalias() += 0.5 * r_inv_t * g * r_inv_t.transpose();
      });
  if (!pairs.ok()) return pairs;

  // Means and cross-covariances.
  for (int a = 0; a < d; ++a) {
    const MeanTerms& t = mts[a];
    const Vector beta = gp.beta.col(a);
    const Vector bq = beta.cwiseProduct(t.q);
    const Vector u = delta.transpose() * bq;
    const Vector vbar = cross_bar.col(a);
    const Vector ubar = t.a * vbar;
    Matrix abar = vbar * u.transpose();
    const Vector du = delta * ubar;  // N
    const Vector qbar = total_mean_bar(a) * beta + beta.cwiseProduct(du);
    if (beta_bar != nullptr) {
      beta_bar->col(a).noalias() += total_mean_bar(a) * t.q + t.q.cwiseProduct(du);
    }
    delta_bar.noalias() += bq * ubar.transpose();
    const Vector w = qbar.cwiseProduct(t.q);
    delta_bar.noalias() -= w.asDiagonal() * t.da;
    abar.noalias() -= 0.5 * delta.transpose() * w.asDiagonal() * delta;
    sb.noalias() -= 0.5 * w.sum() * t.a;
    sb.noalias() -= t.a * abar * t.a;
  }

  *m_bar = -delta_bar.colwise().sum().transpose();
  *s_bar = 0.5 * (sb + sb.transpose());
  if (inputs_bar != nullptr) *inputs_bar = delta_bar;
  if (!m_bar->allFinite() || !s_bar->allFinite()) {
    return absl::InternalError("GP prediction derivative is not finite");
  }
  return absl::OkStatus();
}

absl::Status PredictGaussianLengthscaleAdjoint(const GaussianInputGp& gp, const Vector& m,
                                               const Matrix& s,
                                               const GaussianPredictionOptions& options,
                                               const Vector& mean_bar, const Matrix& cov_bar,
                                               const Matrix& cross_bar, RowMatrix* il_bar) {
  if (absl::Status st = CheckInputs(gp, m, s, options); !st.ok()) return st;
  const int n = gp.num_points(), e = gp.num_inputs(), d = gp.num_outputs();
  TG_CHECK(mean_bar.size() == d && cov_bar.rows() == d && cov_bar.cols() == d);
  TG_CHECK(cross_bar.rows() == e && cross_bar.cols() == d);
  const Matrix delta = Delta(gp, m);  // rows nu_i
  const Matrix sym_bar = 0.5 * (cov_bar + cov_bar.transpose());
  il_bar->setZero(d, e);

  std::vector<MeanTerms> mts(d);
  Vector mean(d);
  for (int a = 0; a < d; ++a) {
    const Vector il = gp.inv_lengthscale_sq.row(a).transpose();
    if (absl::Status st = ComputeMeanTerms(delta, s, il, gp.signal_var(a), a, &mts[a]); !st.ok()) {
      return st;
    }
    mean(a) = gp.beta.col(a).dot(mts[a].q);
  }
  // cov_ab carries -mean_a mean_b: its adjoint reaches the means.
  const Vector total_mean_bar = mean_bar - 2.0 * sym_bar * mean;

  // Means and cross-covariances.
  for (int a = 0; a < d; ++a) {
    const MeanTerms& t = mts[a];
    const Vector lambda = gp.inv_lengthscale_sq.row(a).transpose().cwiseInverse();
    const Vector bq = gp.beta.col(a).cwiseProduct(t.q);  // beta_i q_i
    const Vector u = delta.transpose() * bq;              // sum_i beta_i q_i nu_i
    const Vector au = t.a * u;                            // cross_a
    const Vector acb = t.a * cross_bar.col(a);
    const Vector nu_acb = delta * acb;                    // nu_i . A cb
    const Vector as_diag = (t.a * s).diagonal();
    // weight_i multiplies g_im = d log q_i / dP_m in every term.
    const Vector weight = bq.cwiseProduct(Vector::Constant(n, total_mean_bar(a)) + nu_acb);
    for (int k = 0; k < e; ++k) {
      const double l = lambda(k);
      double sum = 0;
      for (int i = 0; i < n; ++i) {
        const double g = -0.5 * (l * as_diag(k) + l * l * t.da(i, k) * t.da(i, k));
        sum += weight(i) * g;
      }
      (*il_bar)(a, k) += sum + l * l * acb(k) * au(k);
    }
  }

  // Second moments: cov_ab = beta_a^T Q_ab beta_b (- [a == b] tr(Vw_a Q_aa)).
  const absl::Status pairs = ForEachWeightedPair(
      gp, delta, s, sym_bar, options.model_variance, /*beta_bar=*/nullptr,
      [&](int a, int b, const Vector&, const Vector&, const PairTerms& p) {
        const Matrix& w = p.q;
        // T z_ij = (Za T)_i + (Zb T)_j (T symmetric).
        const Matrix tza = p.za * p.t;  // N x E
        const Matrix tzb = p.zb * p.t;
        for (int k = 0; k < e; ++k) {
          const double tkk = p.t(k, k);
          double sa = 0, sb = 0;
          for (int j = 0; j < n; ++j) {
            for (int i = 0; i < n; ++i) {
              const double wij = w(i, j);
              if (wij == 0.0) continue;
              const double tz = tza(i, k) + tzb(j, k);
              const double ra = delta(i, k) - tz, rb = delta(j, k) - tz;
              sa += wij * (ra * ra + tkk);
              sb += wij * (rb * rb + tkk);
            }
          }
          (*il_bar)(a, k) -= 0.5 * sa;
          (*il_bar)(b, k) -= 0.5 * sb;
        }
      });
  if (!pairs.ok()) return pairs;
  if (!il_bar->allFinite()) {
    return absl::InternalError("GP prediction length-scale derivative is not finite");
  }
  return absl::OkStatus();
}

}  // namespace totalgrad::pilco
