// The optional (sin, cos) representation of one state angle for the inputs of
// the GP and the policy (pilco-spec.md 1.1: PILCO's poli/dyni), for real
// (deterministic) states. Header-only so that particle estimators can use it
// without linking core_pilco.
//
// With angle index a, a state x (D) maps to the features
//   [x_0 .. x_{a-1}, x_{a+1} .. x_{D-1}, sin x_a, cos x_a]   (D + 1)
// (the other dims in order, then sin, cos); without (a = -1) to x itself.
// With several angles a_1 < a_2 < ... (the vector overloads): the other dims
// in order, then sin x_a1, cos x_a1, sin x_a2, cos x_a2, ... (D + A), which
// is PILCO's z(dyni) for every scene of tasks/scene_catalog.h.
// A GP input is the features followed by the force u.
//
// Thread safety: pure functions.
#ifndef TOTALGRAD_CORE_GAUSSIAN_ANGLE_FEATURES_H_
#define TOTALGRAD_CORE_GAUSSIAN_ANGLE_FEATURES_H_

#include <cmath>
#include <vector>

#include "core/common/check.h"
#include "core/common/types.h"

namespace totalgrad::gaussian {

inline int FeatureDim(int state_dim, int angle_index) {
  return angle_index >= 0 ? state_dim + 1 : state_dim;
}

// states: P x D; *features: P x FeatureDim (resized).
inline void StatesToFeatures(const ConstRowMatrixRef& states, int angle_index,
                             RowMatrix* features) {
  const int d = static_cast<int>(states.cols());
  TG_CHECK(angle_index >= -1 && angle_index < d);
  if (angle_index < 0) {
    *features = states;
    return;
  }
  features->resize(states.rows(), d + 1);
  int col = 0;
  for (int i = 0; i < d; ++i) {
    if (i != angle_index) features->col(col++) = states.col(i);
  }
  features->col(d - 1) = states.col(angle_index).array().sin();
  features->col(d) = states.col(angle_index).array().cos();
}

// Chain rule: from the adjoint of the features (P x FeatureDim) OVERWRITES
// *states_bar (P x D) with the adjoint of the states.
inline void StatesToFeaturesBackward(const ConstRowMatrixRef& states, int angle_index,
                                     const ConstRowMatrixRef& features_bar,
                                     RowMatrix* states_bar) {
  const int d = static_cast<int>(states.cols());
  if (angle_index < 0) {
    *states_bar = features_bar;
    return;
  }
  states_bar->resize(states.rows(), d);
  int col = 0;
  for (int i = 0; i < d; ++i) {
    if (i != angle_index) states_bar->col(i) = features_bar.col(col++);
  }
  states_bar->col(angle_index) =
      features_bar.col(d - 1).cwiseProduct(states.col(angle_index).array().cos().matrix()) -
      features_bar.col(d).cwiseProduct(states.col(angle_index).array().sin().matrix());
}

// One state (D) to its features.
inline Vector StateFeatures(const Vector& x, int angle_index) {
  RowMatrix f;
  StatesToFeatures(x.transpose(), angle_index, &f);
  return f.row(0).transpose();
}

inline int FeatureDim(int state_dim, const std::vector<int>& angle_indices) {
  return state_dim + static_cast<int>(angle_indices.size());
}

// states: P x D; *features: P x FeatureDim (resized). angle_indices strictly
// increasing (empty: the states themselves).
inline void StatesToFeatures(const ConstRowMatrixRef& states, const std::vector<int>& angle_indices,
                             RowMatrix* features) {
  const int d = static_cast<int>(states.cols());
  if (angle_indices.empty()) {
    *features = states;
    return;
  }
  const int a_count = static_cast<int>(angle_indices.size());
  features->resize(states.rows(), d + a_count);
  int col = 0;
  size_t next_angle = 0;
  for (int i = 0; i < d; ++i) {
    if (next_angle < angle_indices.size() && angle_indices[next_angle] == i) {
      ++next_angle;
      continue;
    }
    features->col(col++) = states.col(i);
  }
  TG_CHECK(next_angle == angle_indices.size());
  for (int a = 0; a < a_count; ++a) {
    features->col(d - a_count + 2 * a) = states.col(angle_indices[a]).array().sin();
    features->col(d - a_count + 2 * a + 1) = states.col(angle_indices[a]).array().cos();
  }
}

// One state (D) to its features.
inline Vector StateFeatures(const Vector& x, const std::vector<int>& angle_indices) {
  RowMatrix f;
  StatesToFeatures(x.transpose(), angle_indices, &f);
  return f.row(0).transpose();
}

}  // namespace totalgrad::gaussian

#endif  // TOTALGRAD_CORE_GAUSSIAN_ANGLE_FEATURES_H_
