#include "core/gp/fitc.h"

#include <algorithm>
#include <cmath>
#include <exception>
#include <numeric>

#include <Eigen/Cholesky>
#include <LBFGS.h>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "core/common/check.h"
#include "core/gp/se_kernel.h"

namespace totalgrad::gp {
namespace {

// sf2 exp(-1/2 sum_e (a_pe - b_ne)^2 il_e) for rows of a (P x E) and b (N x E),
// with the squared distances from differences of scaled coordinates through
// one product (clamped at 0 against round-off).
Matrix SeKernel(const RowMatrix& a, const RowMatrix& b, const Vector& il, double sf2) {
  const RowMatrix as = a * il.cwiseSqrt().asDiagonal();
  const RowMatrix bs = b * il.cwiseSqrt().asDiagonal();
  Matrix k = -2.0 * as * bs.transpose();
  k.colwise() += as.rowwise().squaredNorm();
  k.rowwise() += bs.rowwise().squaredNorm().transpose();
  return (sf2 * (-0.5 * k.array().max(0.0)).exp()).matrix();
}

// Everything of one output that prediction and the NLML need.
struct OutputTerms {
  Matrix kmm;                 // M x M, with ridge
  Matrix kmn;                 // M x N
  Eigen::LLT<Matrix> l;       // of kmm
  Matrix v;                   // L^-1 Kmn, M x N
  Vector lambda;              // N
  Eigen::LLT<Matrix> la;      // of A = I + V Lam^-1 V^T
  Vector c;                   // V Lam^-1 y
};

bool ComputeTerms(const RowMatrix& x, const Vector& y, const RowMatrix& z, const Vector& il,
                  double sf2, double sn2, OutputTerms* t) {
  const int m = static_cast<int>(z.rows());
  t->kmm = SeKernel(z, z, il, sf2);
  t->kmm.diagonal().array() += kFitcRidge;
  t->kmn = SeKernel(z, x, il, sf2);
  t->l.compute(t->kmm);
  if (t->l.info() != Eigen::Success) return false;
  t->v = t->l.matrixL().solve(t->kmn);
  t->lambda = (sf2 + sn2 - t->v.colwise().squaredNorm().array()).matrix().transpose();
  // Round-off can push sf2 - q below 0 for inducing points on data points.
  t->lambda = t->lambda.cwiseMax(sn2 > 0 ? sn2 * 1e-6 : 1e-300);
  const Matrix vl = t->v * t->lambda.cwiseInverse().asDiagonal();
  Matrix a = vl * t->v.transpose();
  a.diagonal().array() += 1.0;
  t->la.compute(a);
  if (t->la.info() != Eigen::Success) return false;
  t->c = vl * y;
  (void)m;
  return t->kmn.allFinite() && t->lambda.allFinite();
}

absl::Status CheckShapes(const RowMatrix& inputs, const RowMatrix& targets,
                         const GpHyperparameters& hyp, const RowMatrix& inducing) {
  if (inputs.rows() == 0) return absl::InvalidArgumentError("FITC: no training data");
  if (targets.rows() != inputs.rows()) {
    return absl::InvalidArgumentError("FITC: inputs and targets have different row counts");
  }
  if (hyp.num_outputs() != targets.cols() || hyp.num_inputs() != inputs.cols() ||
      hyp.log_signal_std.size() != targets.cols() || hyp.log_noise_std.size() != targets.cols()) {
    return absl::InvalidArgumentError("FITC: hyperparameters do not match the data");
  }
  if (inducing.rows() == 0 || inducing.cols() != inputs.cols()) {
    return absl::InvalidArgumentError(
        absl::StrCat("FITC: inducing inputs must be M x ", inputs.cols(), " with M >= 1"));
  }
  if (!inputs.allFinite() || !targets.allFinite() || !inducing.allFinite() ||
      !hyp.log_lengthscales.allFinite() || !hyp.log_signal_std.allFinite() ||
      !hyp.log_noise_std.allFinite()) {
    return absl::InvalidArgumentError("FITC: non-finite inputs, targets, hyperparameters or Z");
  }
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<FitcModel> FitcModel::Create(const RowMatrix& inputs, const RowMatrix& targets,
                                            const GpHyperparameters& hyperparameters,
                                            const RowMatrix& inducing) {
  if (absl::Status st = CheckShapes(inputs, targets, hyperparameters, inducing); !st.ok()) {
    return st;
  }
  const int d = static_cast<int>(targets.cols());
  const int m = static_cast<int>(inducing.rows());
  FitcModel model;
  model.hyp_ = hyperparameters;
  model.inducing_ = inducing;
  model.beta_.resize(m, d);
  model.outputs_.resize(d);
  for (int a = 0; a < d; ++a) {
    Output& out = model.outputs_[a];
    out.inv_lengthscales = (-hyperparameters.log_lengthscales.row(a)).array().exp().transpose();
    out.signal_var = std::exp(2.0 * hyperparameters.log_signal_std(a));
    out.noise_var = std::exp(2.0 * hyperparameters.log_noise_std(a));
    if (!out.inv_lengthscales.allFinite() || !std::isfinite(out.signal_var) ||
        !std::isfinite(out.noise_var)) {
      return absl::InvalidArgumentError(absl::StrCat(
          "FITC: hyperparameters of output ", a, " overflow (1 / l, sf^2 or sn^2 not finite)"));
    }
    // 1 / l^2 exactly as the NLML computes it.
    const Vector il = (-2.0 * hyperparameters.log_lengthscales.row(a).array()).exp().matrix();
    OutputTerms t;
    if (!ComputeTerms(inputs, targets.col(a), inducing, il, out.signal_var, out.noise_var, &t)) {
      return absl::FailedPreconditionError(
          absl::StrCat("FITC: Kmm or B not positive definite for output ", a));
    }
    // beta = L^-T A^-1 V Lam^-1 y; Vw = L^-T (I - A^-1) L^-1.
    model.beta_.col(a) = t.l.matrixU().solve(t.la.solve(t.c));
    const Matrix a_inv = t.la.solve(Matrix::Identity(m, m));
    Matrix inner = Matrix::Identity(m, m) - a_inv;
    Matrix linv = t.l.matrixL().solve(Matrix::Identity(m, m));
    Matrix vw = linv.transpose() * inner * linv;
    // Exact symmetry: the variance Jacobian uses (Kstar Vw)_pm = (Vw k_p)_m.
    out.variance_weights = 0.5 * (vw + vw.transpose());
    out.scaled_inducing = inducing * out.inv_lengthscales.asDiagonal();
    out.scaled_sq_norms = out.scaled_inducing.rowwise().squaredNorm();
    out.beta_scaled_inducing = model.beta_.col(a).asDiagonal() * out.scaled_inducing;
    if (!model.beta_.col(a).allFinite() || !out.variance_weights.allFinite()) {
      return absl::FailedPreconditionError(
          absl::StrCat("FITC: non-finite weights for output ", a));
    }
  }
  return model;
}

namespace {

// Scratch matrices of FitcModel::Predict, one set per thread (Predict is
// const and thread-safe); no heap allocations once the shapes have been seen.
struct FitcWorkspace {
  RowMatrix zs;    // P x E, z / l_a
  Vector zs_sq;    // P, |z / l_a|^2
  Matrix kstar;    // P x M, k_a(z_p, Z_m)
  Matrix a;        // P x M, Kstar Vw, then Kstar .* Kstar Vw
  Vector column;   // P, one output's mean or k^T Vw k
  Matrix product;  // P x E, Jacobian products
};

FitcWorkspace& ThreadFitcWorkspace() {
  thread_local FitcWorkspace workspace;
  return workspace;
}

}  // namespace

void FitcModel::Predict(const ConstRowMatrixRef& z, const PredictOptions& options,
                        RowMatrix* mean, RowMatrix* variance, RowMatrix* dmean_dz,
                        RowMatrix* dvar_dz, ThreadPool* pool) const {
  TG_CHECK(mean != nullptr);
  TG_CHECK(variance != nullptr || dvar_dz == nullptr);
  TG_CHECK_EQ(z.cols(), num_inputs());
  const Eigen::Index p = z.rows();
  const int e = num_inputs(), d = num_outputs();
  mean->resize(p, d);
  if (variance != nullptr) variance->resize(p, d);
  if (dmean_dz != nullptr) dmean_dz->resize(p, d * e);
  if (dvar_dz != nullptr) dvar_dz->resize(p, d * e);
  if (p == 0) return;
  if (pool == nullptr || pool->size() == 1) {
    for (int a = 0; a < d; ++a) PredictOutput(a, z, options, mean, variance, dmean_dz, dvar_dz);
    return;
  }
  // Each output writes only its own columns and uses its thread's workspace.
  pool->ParallelFor(d, [&](int a) { PredictOutput(a, z, options, mean, variance, dmean_dz, dvar_dz); });
}

void FitcModel::PredictOutput(int a, const ConstRowMatrixRef& z, const PredictOptions& options,
                              RowMatrix* mean, RowMatrix* variance, RowMatrix* dmean_dz,
                              RowMatrix* dvar_dz) const {
  const Eigen::Index p = z.rows();
  const int e = num_inputs();
  FitcWorkspace& ws = ThreadFitcWorkspace();
  {
    const Output& out = outputs_[a];
    internal::ScaledQueryCrossKernel(z, out.inv_lengthscales, out.scaled_inducing, out.scaled_sq_norms,
                                     out.signal_var, &ws.zs, &ws.zs_sq, &ws.kstar);
    ws.column.noalias() = ws.kstar * beta_.col(a);
    mean->col(a) = ws.column;

    if (dmean_dz != nullptr) {
      // d mean_p / d z_pm = sum_j beta_j k_pj (zs_jm - zs_pm) / l_m
      //                   = [(Kstar (beta .* Zs))_pm - zs_pm mean_p] / l_m.
      ws.product.noalias() = ws.kstar * out.beta_scaled_inducing;
      dmean_dz->middleCols(a * e, e) =
          ((ws.product.array() - ws.zs.array().colwise() * ws.column.array()).rowwise() *
           out.inv_lengthscales.transpose().array());
    }

    if (variance == nullptr) return;
    // The one P x M x M product per output: row p of A is (Vw k_p)^T.
    ws.a.noalias() = ws.kstar * out.variance_weights;
    ws.column.noalias() = (ws.a.array() * ws.kstar.array()).rowwise().sum().matrix();
    const double prior = out.signal_var + options.noise_variance_multiplier * out.noise_var;
    for (Eigen::Index i = 0; i < p; ++i) {
      const double v = prior - ws.column(i);
      // Written so that a NaN (from a non-finite query) propagates.
      (*variance)(i, a) = v < kVarianceFloor ? kVarianceFloor : v;
    }

    if (dvar_dz != nullptr) {
      // d var_p / d z_pm = -2 sum_j A_pj d k_pj / d z_pm
      //                  = -2 [((A .* Kstar) Zs)_pm - zs_pm rowsum(A .* Kstar)_p] / l_m.
      ws.a.array() *= ws.kstar.array();
      ws.product.noalias() = ws.a * out.scaled_inducing;
      auto block = dvar_dz->middleCols(a * e, e);
      block = ((ws.product.array() - ws.zs.array().colwise() * ws.column.array()).rowwise() *
               (-2.0 * out.inv_lengthscales.transpose().array()));
      for (Eigen::Index i = 0; i < p; ++i) {
        if (prior - ws.column(i) < kVarianceFloor) block.row(i).setZero();
      }
    }
  }
}

bool FitcNlml(const RowMatrix& inputs, const RowMatrix& targets,
              const GpHyperparameters& hyperparameters, const RowMatrix& inducing,
              double* value, RowMatrix* gradient) {
  if (!CheckShapes(inputs, targets, hyperparameters, inducing).ok()) return false;
  const int n = static_cast<int>(inputs.rows()), d = static_cast<int>(targets.cols());
  const int m = static_cast<int>(inducing.rows()), e = static_cast<int>(inputs.cols());
  double total = 0;
  if (gradient != nullptr) gradient->setZero(m, e);
  for (int a = 0; a < d; ++a) {
    const Vector il = (-2.0 * hyperparameters.log_lengthscales.row(a).array()).exp().matrix();
    const double sf2 = std::exp(2.0 * hyperparameters.log_signal_std(a));
    const double sn2 = std::exp(2.0 * hyperparameters.log_noise_std(a));
    const Vector y = targets.col(a);
    OutputTerms t;
    if (!ComputeTerms(inputs, y, inducing, il, sf2, sn2, &t)) return false;
    const Vector ainv_c = t.la.solve(t.c);
    const double log_det_a = 2.0 * t.la.matrixLLT().diagonal().array().log().sum();
    const Vector inv_lambda = t.lambda.cwiseInverse();
    total += 0.5 * (y.cwiseProduct(inv_lambda).dot(y) - t.c.dot(ainv_c)) + 0.5 * log_det_a +
             0.5 * t.lambda.array().log().sum() + 0.5 * n * std::log(2.0 * M_PI);
    if (gradient == nullptr) continue;
    // G = K~^-1 - alpha alpha^T with K~ = Lam + V^T V; Qbar = 1/2 (G - diag G).
    const Vector alpha = inv_lambda.cwiseProduct(y - t.v.transpose() * ainv_c);
    const Matrix vl = t.v * inv_lambda.asDiagonal();
    const Matrix w = t.la.matrixL().solve(vl);  // LA^-1 V Lam^-1
    const Vector diag_g = inv_lambda - w.colwise().squaredNorm().transpose() -
                          alpha.cwiseProduct(alpha);
    const Matrix vg = t.la.solve(vl) - (t.v * alpha) * alpha.transpose();  // V G, M x N
    const Matrix p = t.l.matrixU().solve(t.v);                            // Kmm^-1 Kmn
    Matrix pg = t.l.matrixU().solve(vg);                                  // P G
    pg -= p * diag_g.asDiagonal();                                        // P (G - diag G)
    const Matrix kmn_bar = pg;                                            // 2 P Qbar
    const Matrix kmm_bar = -0.5 * pg * p.transpose();                     // -P Qbar P^T
    // Through the kernel entries.
    const Matrix w1 = kmn_bar.cwiseProduct(t.kmn);
    Matrix kmm_plain = t.kmm;
    kmm_plain.diagonal().array() -= kFitcRidge;
    const Matrix u = (kmm_bar + kmm_bar.transpose()).cwiseProduct(kmm_plain);
    const Vector r1 = w1.rowwise().sum(), ru = u.rowwise().sum();
    const Matrix w1x = w1 * inputs;
    const Matrix uz = u * inducing;
    for (int k = 0; k < e; ++k) {
      gradient->col(k) -= il(k) * (inducing.col(k).cwiseProduct(r1) - w1x.col(k) +
                                   inducing.col(k).cwiseProduct(ru) - uz.col(k));
    }
  }
  *value = total;
  return std::isfinite(total) && (gradient == nullptr || gradient->allFinite());
}

std::string FitcTrainingSummary::BriefReport() const {
  return absl::StrFormat(
      "FITC inducing inputs: NLML %.6g -> %.6g, %d iterations, %d evaluations%s", initial_nlml,
      final_nlml, iterations, evaluations,
                         line_search_failed ? " (line search failure caught)" : "");
}

absl::StatusOr<FitcTrainingSummary> TrainInducingInputs(const RowMatrix& inputs,
                                                        const RowMatrix& targets,
                                                        const GpHyperparameters& hyperparameters,
                                                        const FitcTrainingOptions& options,
                                                        RowMatrix* inducing) {
  if (absl::Status st = CheckShapes(inputs, targets, hyperparameters, *inducing); !st.ok()) {
    return st;
  }
  FitcTrainingSummary summary;
  const int m = static_cast<int>(inducing->rows()), e = static_cast<int>(inducing->cols());
  if (!FitcNlml(inputs, targets, hyperparameters, *inducing, &summary.initial_nlml, nullptr)) {
    return absl::FailedPreconditionError("FITC: NLML not finite at the initial inducing inputs");
  }
  summary.final_nlml = summary.initial_nlml;
  if (options.max_iterations <= 0) return summary;
  RowMatrix best = *inducing;
  double best_value = summary.initial_nlml;
  auto fun = [&](const Eigen::VectorXd& x, Eigen::VectorXd& grad) -> double {
    ++summary.evaluations;
    const RowMatrix z = Eigen::Map<const RowMatrix>(x.data(), m, e);
    double value;
    RowMatrix g;
    if (!FitcNlml(inputs, targets, hyperparameters, z, &value, &g)) {
      grad.setZero(x.size());
      return 1e300;  // rejected by the line search
    }
    grad = Eigen::Map<const Eigen::VectorXd>(g.data(), m * e);
    if (value < best_value) {
      best_value = value;
      best = z;
    }
    return value;
  };
  LBFGSpp::LBFGSParam<double> param;
  param.max_iterations = options.max_iterations;
  param.epsilon = 1e-6;
  param.epsilon_rel = 1e-6;
  LBFGSpp::LBFGSSolver<double> solver(param);
  Eigen::VectorXd x = Eigen::Map<const Eigen::VectorXd>(inducing->data(), m * e);
  double fx = summary.initial_nlml;
  try {
    summary.iterations = solver.minimize(fun, x, fx);
  } catch (const std::exception&) {
    summary.line_search_failed = true;
  }
  *inducing = best;
  summary.final_nlml = best_value;
  return summary;
}

absl::StatusOr<FitcModel> FitFitcModel(const RowMatrix& inputs, const RowMatrix& targets,
                                       const GpHyperparameters& hyperparameters,
                                       const FitcFitOptions& options, RowMatrix* inducing, Rng* rng,
                                       FitcTrainingSummary* summary) {
  if (options.num_inducing < 1 || options.num_inducing > inputs.rows()) {
    return absl::InvalidArgumentError(absl::StrCat("FITC: ", options.num_inducing,
                                                   " inducing inputs for ", inputs.rows(),
                                                   " data points (need 1 <= M <= N)"));
  }
  FitcTrainingOptions fit;
  if (inducing->rows() != options.num_inducing || inducing->cols() != inputs.cols()) {
    *inducing = RandomSubsetOfInputs(inputs, options.num_inducing, rng);
    fit.max_iterations = options.first_fit_iterations;
  } else {
    fit.max_iterations = options.warm_fit_iterations;
  }
  absl::StatusOr<FitcTrainingSummary> trained =
      TrainInducingInputs(inputs, targets, hyperparameters, fit, inducing);
  if (!trained.ok()) return trained.status();
  if (summary != nullptr) *summary = *trained;
  return FitcModel::Create(inputs, targets, hyperparameters, *inducing);
}

RowMatrix RandomSubsetOfInputs(const RowMatrix& inputs, int m, Rng* rng) {
  const int n = static_cast<int>(inputs.rows());
  m = std::min(m, n);
  std::vector<int> index(n);
  std::iota(index.begin(), index.end(), 0);
  // Partial Fisher-Yates.
  for (int i = 0; i < m; ++i) {
    const int j = i + static_cast<int>(rng->Bits() % static_cast<uint64_t>(n - i));
    std::swap(index[i], index[j]);
  }
  RowMatrix out(m, inputs.cols());
  for (int i = 0; i < m; ++i) out.row(i) = inputs.row(index[i]);
  return out;
}

}  // namespace totalgrad::gp
