#include "core/gp/gp.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "core/common/check.h"
#include "core/common/finite.h"
#include "core/gp/se_kernel.h"

namespace totalgrad::gp {
namespace {

// Jitter ladder of Create, relative to sf_a^2: 1e-8, 1e-7, ..., 1e-2.
constexpr int kFirstJitterExponent = -8;
constexpr int kLastJitterExponent = -2;

// Scratch matrices of Predict. Predict is const and must stay thread-safe, so
// the buffers cannot live in the model; one set per thread keeps the hot path
// free of heap allocations once the shapes have been seen (Eigen's resize is a
// no-op when the size does not change).
struct PredictWorkspace {
  RowMatrix zs;          // P x E, z / l_a
  Vector zs_sq;          // P, |z / l_a|^2
  Matrix kstar;          // P x N, k_a(z_p, x_n)
  Matrix a;              // P x N, Kstar K^-1, then Kstar .* Kstar K^-1
  // P x r, Kstar U_r M_r of the low-rank variance. A flat buffer that only
  // grows, mapped to P x r per output: the outputs' ranks differ, and a
  // Matrix resized from one output to the next would reallocate every call.
  Vector lowrank_g;
  Matrix mean_product;   // P x (1 + E), Kstar [beta, beta .* Xs]
  Matrix var_product;    // P x (1 + E), (Kstar .* Kstar K^-1) [1, Xs]
};

PredictWorkspace& ThreadWorkspace() {
  thread_local PredictWorkspace workspace;
  return workspace;
}



// The rank GpModelOptions asks for: the smallest r with
// sf^2 lambda_{r+1}^2 / (s^2 (lambda_{r+1} + s)) <= tolerance, lambda_{N+1} = 0
// (gp.h derives the bound). `descending`: Kf's eigenvalues, largest first;
// round-off negatives count as 0. The bound grows with lambda, so the first
// r that meets it is the answer.
int VarianceRank(const Vector& descending, double signal_var, double s, double tolerance) {
  const Eigen::Index n = descending.size();
  for (Eigen::Index r = 0; r < n; ++r) {
    const double lambda = std::max(descending(r), 0.0);  // lambda_{r+1}
    // Written so that an overflow (inf) or NaN counts as "not met".
    if (signal_var * lambda * lambda / (s * s * (lambda + s)) <= tolerance)
      return static_cast<int>(r);
  }
  return static_cast<int>(n);
}

}  // namespace

Vector GpHyperparameters::Packed(int a) const {
  const int e = num_inputs();
  Vector packed(e + 2);
  packed.head(e) = log_lengthscales.row(a).transpose();
  packed(e) = log_signal_std(a);
  packed(e + 1) = log_noise_std(a);
  return packed;
}

absl::Status GpHyperparameters::ValidateFinite() const {
  if (absl::Status s = CheckFinite(log_lengthscales, "hyperparameters.log_lengthscales"); !s.ok())
    return s;
  if (absl::Status s = CheckFinite(log_signal_std, "hyperparameters.log_signal_std"); !s.ok())
    return s;
  return CheckFinite(log_noise_std, "hyperparameters.log_noise_std");
}

absl::Status ValidateGpData(const RowMatrix& inputs, const RowMatrix& targets,
                            const GpHyperparameters& hyp) {
  if (inputs.rows() == 0) return absl::InvalidArgumentError("inputs has no rows (N == 0)");
  if (inputs.cols() == 0) return absl::InvalidArgumentError("inputs has no columns (E == 0)");
  if (targets.cols() == 0) return absl::InvalidArgumentError("targets has no columns (D == 0)");
  if (targets.rows() != inputs.rows()) {
    return absl::InvalidArgumentError(absl::StrCat("targets has ", targets.rows(),
                                                   " rows but inputs has ", inputs.rows()));
  }
  if (hyp.log_lengthscales.rows() != targets.cols()) {
    return absl::InvalidArgumentError(
        absl::StrCat("hyperparameters.log_lengthscales has ", hyp.log_lengthscales.rows(),
                     " rows but targets has ", targets.cols(), " columns (outputs)"));
  }
  if (hyp.log_lengthscales.cols() != inputs.cols()) {
    return absl::InvalidArgumentError(
        absl::StrCat("hyperparameters.log_lengthscales has ", hyp.log_lengthscales.cols(),
                     " columns but inputs has ", inputs.cols()));
  }
  if (hyp.log_signal_std.size() != targets.cols()) {
    return absl::InvalidArgumentError(
        absl::StrCat("hyperparameters.log_signal_std has ", hyp.log_signal_std.size(),
                     " entries but targets has ", targets.cols(), " columns"));
  }
  if (hyp.log_noise_std.size() != targets.cols()) {
    return absl::InvalidArgumentError(
        absl::StrCat("hyperparameters.log_noise_std has ", hyp.log_noise_std.size(),
                     " entries but targets has ", targets.cols(), " columns"));
  }
  if (absl::Status s = CheckFinite(inputs, "inputs"); !s.ok()) return s;
  if (absl::Status s = CheckFinite(targets, "targets"); !s.ok()) return s;
  return hyp.ValidateFinite();
}

void GpHyperparameters::SetPacked(int a, const Vector& packed) {
  const int e = num_inputs();
  TG_CHECK_EQ(packed.size(), e + 2);
  log_lengthscales.row(a) = packed.head(e).transpose();
  log_signal_std(a) = packed(e);
  log_noise_std(a) = packed(e + 1);
}

absl::StatusOr<GpModel> GpModel::Create(const RowMatrix& inputs, const RowMatrix& targets,
                                        const GpHyperparameters& hyperparameters,
                                        const GpModelOptions& options) {
  if (absl::Status s = ValidateGpData(inputs, targets, hyperparameters); !s.ok()) {
    return s;
  }
  const double tolerance = options.variance_rank_tolerance;
  if (!std::isfinite(tolerance) || tolerance < 0 || tolerance >= 1) {
    return absl::InvalidArgumentError(absl::StrCat(
        "variance_rank_tolerance must be finite, >= 0 and < 1 (got ", tolerance, ")"));
  }
  GpModel model;
  model.options_ = options;
  model.num_data_ = static_cast<int>(inputs.rows());
  model.num_inputs_ = static_cast<int>(inputs.cols());
  model.num_outputs_ = static_cast<int>(targets.cols());
  model.hyp_ = hyperparameters;
  model.inputs_ = inputs;
  model.targets_ = targets;
  model.outputs_.resize(model.num_outputs_);

  const Eigen::Index n = inputs.rows();
  Matrix k(n, n);
  Eigen::LLT<Matrix> llt(n);
  for (int a = 0; a < model.num_outputs_; ++a) {
    Output& out = model.outputs_[a];
    // Hyperparameters finite in log space can still over/underflow here.
    out.inv_lengthscales = (-hyperparameters.log_lengthscales.row(a)).array().exp().transpose();
    out.signal_var = std::exp(2.0 * hyperparameters.log_signal_std(a));
    out.noise_var = std::exp(2.0 * hyperparameters.log_noise_std(a));
    if (!out.inv_lengthscales.allFinite()) {
      return absl::InvalidArgumentError(absl::StrCat(
          "hyperparameters.log_lengthscales row ", a, " underflows (a length-scale is 0)"));
    }
    if (!std::isfinite(out.signal_var)) {
      return absl::InvalidArgumentError(
          absl::StrCat("hyperparameters.log_signal_std(", a, ") overflows sf^2"));
    }
    if (!std::isfinite(out.noise_var)) {
      return absl::InvalidArgumentError(
          absl::StrCat("hyperparameters.log_noise_std(", a, ") overflows sn^2"));
    }
    out.scaled_inputs = inputs * out.inv_lengthscales.asDiagonal();
    out.scaled_sq_norms = out.scaled_inputs.rowwise().squaredNorm();

    internal::SeCrossKernel(out.scaled_inputs, out.scaled_sq_norms, out.scaled_inputs,
                            out.scaled_sq_norms, out.signal_var, &k);
    // LLT reads the lower triangle only; the self-distance is exactly zero.
    const double diagonal = out.signal_var + out.noise_var;
    k.diagonal().setConstant(diagonal);
    llt.compute(k);
    bool accepted = internal::CholeskyAccepted(llt, diagonal);
    for (int e = kFirstJitterExponent; !accepted && e <= kLastJitterExponent; ++e) {
      out.jitter = std::pow(10.0, e) * out.signal_var;
      k.diagonal().setConstant(diagonal + out.jitter);
      llt.compute(k);
      accepted = internal::CholeskyAccepted(llt, diagonal + out.jitter);
    }
    if (!accepted) {
      return absl::FailedPreconditionError(absl::StrCat(
          "K for output ", a, " is not positive definite even with jitter ",
          out.jitter, " (sf^2 = ", out.signal_var, ", sn^2 = ", out.noise_var, ")"));
    }
    out.k_inverse = llt.solve(Matrix::Identity(n, n));
    // The solve leaves K^-1 asymmetric at round-off level; Predict's variance
    // Jacobian uses (Kstar K^-1)_pn = (K^-1 k_p)_n, which needs exact symmetry.
    Matrix symmetric = 0.5 * (out.k_inverse + out.k_inverse.transpose());
    out.k_inverse.swap(symmetric);
    out.beta = llt.solve(targets.col(a));
    out.rank = static_cast<int>(n);
    out.bound_rank = static_cast<int>(n);
    if (tolerance > 0) {
      // Kf = K without its diagonal's noise and jitter (k is symmetric in
      // full: SeCrossKernel filled both triangles).
      k.diagonal().setConstant(out.signal_var);
      const double s = out.noise_var + out.jitter;
      Eigen::SelfAdjointEigenSolver<Matrix> eigen(k);
      if (eigen.info() != Eigen::Success) {
        return absl::FailedPreconditionError(absl::StrCat(
            "the eigendecomposition of Kf for output ", a,
            " did not converge (variance_rank_tolerance > 0)"));
      }
      // Eigen sorts ascending; the top r are the last r columns.
      const Vector descending = eigen.eigenvalues().reverse();
      const int r = VarianceRank(descending, out.signal_var, s, tolerance);
      out.bound_rank = r;
      if (2 * static_cast<Eigen::Index>(r) < n) {
        out.rank = r;
        out.inv_noise = 1.0 / s;
        const auto u_r = eigen.eigenvectors().rightCols(r);
        // -lambda / (s (lambda + s)) = 1/(lambda + s) - 1/s without cancellation.
        const Vector m =
            (-eigen.eigenvalues().tail(r).array() / (s * (eigen.eigenvalues().tail(r).array() + s)))
                .matrix();
        out.lowrank_w = u_r * m.asDiagonal();
        out.lowrank_ut = u_r.transpose();
      }
    }
    // Right-hand sides that let one product per pass over Kstar (or over
    // Kstar .* A) give a value and its Jacobian together (see Predict).
    out.mean_rhs.resize(n, 1 + model.num_inputs_);
    out.mean_rhs.col(0) = out.beta;
    out.mean_rhs.rightCols(model.num_inputs_) = out.beta.asDiagonal() * out.scaled_inputs;
    out.var_rhs.resize(n, 1 + model.num_inputs_);
    out.var_rhs.col(0).setOnes();
    out.var_rhs.rightCols(model.num_inputs_) = out.scaled_inputs;
  }
  // Longest task first: with 4 outputs of ranks 49, 107, 113, 151 on two
  // threads, index order gives the threads 162 and 258 rank units, this order
  // 200 and 220.
  model.outputs_by_cost_.resize(model.num_outputs_);
  for (int a = 0; a < model.num_outputs_; ++a) model.outputs_by_cost_[a] = a;
  std::stable_sort(model.outputs_by_cost_.begin(), model.outputs_by_cost_.end(),
                   [&model](int x, int y) { return model.outputs_[x].rank > model.outputs_[y].rank; });
  return model;
}

void GpModel::Predict(const ConstRowMatrixRef& z, const PredictOptions& options, RowMatrix* mean,
                      RowMatrix* variance, RowMatrix* dmean_dz, RowMatrix* dvar_dz,
                      ThreadPool* pool) const {
  TG_CHECK(mean != nullptr);
  TG_CHECK(variance != nullptr || dvar_dz == nullptr);
  TG_CHECK_EQ(z.cols(), num_inputs_);
  const Eigen::Index p = z.rows();
  const int e = num_inputs_;
  mean->resize(p, num_outputs_);
  if (variance != nullptr) variance->resize(p, num_outputs_);
  if (dmean_dz != nullptr) dmean_dz->resize(p, num_outputs_ * e);
  if (dvar_dz != nullptr) dvar_dz->resize(p, num_outputs_ * e);
  if (p == 0) return;
  if (pool == nullptr || pool->size() == 1) {
    for (int a = 0; a < num_outputs_; ++a)
      PredictOutput(a, z, options, mean, variance, dmean_dz, dvar_dz);
    return;
  }
  // Each output writes only its own columns and uses its thread's workspace.
  pool->ParallelFor(num_outputs_, [&](int task) {
    PredictOutput(outputs_by_cost_[task], z, options, mean, variance, dmean_dz, dvar_dz);
  });
}

void GpModel::PredictOutput(int a, const ConstRowMatrixRef& z, const PredictOptions& options,
                            RowMatrix* mean, RowMatrix* variance, RowMatrix* dmean_dz,
                            RowMatrix* dvar_dz) const {
  const Eigen::Index p = z.rows();
  const int e = num_inputs_;
  PredictWorkspace& ws = ThreadWorkspace();
  {
    const Output& out = outputs_[a];
    internal::ScaledQueryCrossKernel(z, out.inv_lengthscales, out.scaled_inputs, out.scaled_sq_norms,
                                     out.signal_var, &ws.zs, &ws.zs_sq, &ws.kstar);

    // Mean and variance are computed the same way whether or not Jacobians are
    // requested, so that asking for derivatives never changes the values. The
    // element-wise passes over the P x N matrices cost memory traffic of the
    // same order as the P x N x N product, so each pass does all it can: one
    // product Kstar [beta, beta .* Xs] gives the mean and the mean Jacobian's
    // sums, one product (A .* Kstar) [1, Xs] gives k^T K^-1 k and the variance
    // Jacobian's sums.
    ws.mean_product.noalias() = ws.kstar * out.mean_rhs;
    const auto mean_a = ws.mean_product.col(0);
    mean->col(a) = mean_a;

    if (dmean_dz != nullptr) {
      // d mean_p / d z_pm = sum_n beta_n k_pn (xs_nm - zs_pm) / l_m
      //                   = [(Kstar (beta .* Xs))_pm - zs_pm mean_p] / l_m.
      dmean_dz->middleCols(a * e, e) =
          ((ws.mean_product.rightCols(e).array() - ws.zs.array().colwise() * mean_a.array())
               .rowwise() *
           out.inv_lengthscales.transpose().array());
    }

    if (variance == nullptr) return;
    if (out.rank < num_data_) {
      // Row p of A is (B_r k_p)^T with B_r = U_r M_r U_r^T + I/s (gp.h,
      // GpModelOptions): two thin products of 2 P N r flops each, then the
      // diagonal's term and the product with Kstar in one pass.
      if (out.rank == 0) {
        ws.a = (out.inv_noise * ws.kstar.array().square()).matrix();
      } else {
        if (ws.lowrank_g.size() < p * out.rank) ws.lowrank_g.resize(p * out.rank);
        Eigen::Map<Matrix> g(ws.lowrank_g.data(), p, out.rank);
        g.noalias() = ws.kstar * out.lowrank_w;
        ws.a.noalias() = g * out.lowrank_ut;
        ws.a.array() = (ws.a.array() + out.inv_noise * ws.kstar.array()) * ws.kstar.array();
      }
    } else {
      // The one P x N x N product per output: row p of A is (K^-1 k_p)^T.
      ws.a.noalias() = ws.kstar * out.k_inverse;
      ws.a.array() *= ws.kstar.array();
    }
    ws.var_product.noalias() = ws.a * out.var_rhs;
    const auto quadratic = ws.var_product.col(0);  // k_p^T K^-1 k_p
    const double prior = out.signal_var + options.noise_variance_multiplier * out.noise_var;
    for (Eigen::Index i = 0; i < p; ++i) {
      const double v = prior - quadratic(i);
      // Written so that a NaN (from a non-finite query) propagates.
      (*variance)(i, a) = v < kVarianceFloor ? kVarianceFloor : v;
    }

    if (dvar_dz != nullptr) {
      // d var_p / d z_pm = -2 sum_n A_pn d k_pn / d z_pm
      //                  = -2 [((A .* Kstar) Xs)_pm - zs_pm rowsum(A .* Kstar)_p] / l_m.
      auto block = dvar_dz->middleCols(a * e, e);
      block = ((ws.var_product.rightCols(e).array() -
                ws.zs.array().colwise() * quadratic.array())
                   .rowwise() *
               (-2.0 * out.inv_lengthscales.transpose().array()));
      for (Eigen::Index i = 0; i < p; ++i) {
        if (prior - quadratic(i) < kVarianceFloor) block.row(i).setZero();
      }
    }
  }
}

}  // namespace totalgrad::gp
