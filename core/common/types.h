// Eigen aliases used throughout core/ (Ceres style).
//
// Conventions, everywhere in core/:
//  * A batch of P row-vectors (particles, data points) is a RowMatrix with one
//    particle per row: P x D. Row-major so that one particle's coordinates are
//    contiguous and a particle can be handed out as a row.
//  * Column vectors are Vector (Eigen::VectorXd).
//  * Units are SI unless a header says otherwise; angles are radians.
#ifndef TOTALGRAD_CORE_COMMON_TYPES_H_
#define TOTALGRAD_CORE_COMMON_TYPES_H_

#include <Eigen/Core>

namespace totalgrad {

using Vector = Eigen::VectorXd;
using Matrix = Eigen::MatrixXd;  // column-major
using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using VectorRef = Eigen::Ref<Vector>;
using ConstVectorRef = Eigen::Ref<const Vector>;
using ConstMatrixRef = Eigen::Ref<const Matrix>;
using ConstRowMatrixRef = Eigen::Ref<const RowMatrix>;

}  // namespace totalgrad

#endif  // TOTALGRAD_CORE_COMMON_TYPES_H_
