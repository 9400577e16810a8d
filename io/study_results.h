// A gradient study's result (study::StudyResult) as JSON: the results.json
// that `totalgrad study --output-dir` writes, and reading it back for
// `totalgrad study summary` (core/study/equal_time.h). Numbers are written
// as parsed doubles (non-finite ones as null, read back as NaN), so a result
// read back gives the same tables.
//
// Format: {"source", "scene", "num_parameters", "seconds", "blas",
//          "options": {...the study's options...},
//          "references": [{"horizon", "norm", "relative_error", "floor",
//                          "objective", "used", "replicates",
//                          "agreement_max_z", "agreement_mean_z2",
//                          "agreement_resolution", "agree",
//                          "note", "seconds", "gradient", "standard_error"}],
//          "cells": [{"estimator", "method", "particles", "horizon",
//                     "replicates", "nonfinite", "errors", "error",
//                     "budget_hit", "omitted", "omission_reason",
//                     "time_min_s", "time_median_s", "rel_rmse", "rel_bias",
//                     "rel_bias_noise", "total_variance", "cos_mean",
//                     "objective_mean", "ess_mean", "ess_min", "k_lr_mean",
//                     "k_lr_per_step", "reference_agrees"}]}
// Files written before "scene" existed read with an empty scene, before
// "agreement_resolution" existed with NaN (not computed).
#ifndef TOTALGRAD_IO_STUDY_RESULTS_H_
#define TOTALGRAD_IO_STUDY_RESULTS_H_

#include <string>

#include <nlohmann/json.hpp>

#include "absl/status/statusor.h"
#include "core/study/study.h"
#include "io/study_file.h"

namespace totalgrad::io {

nlohmann::ordered_json StudyResultToJson(const study::StudyResult& result, const StudySpec& spec);

// InvalidArgument naming the field (and index) that is missing or mistyped.
absl::StatusOr<study::StudyResult> StudyResultFromJson(const nlohmann::json& doc);

// Reads a results.json (or a directory holding one). NotFound /
// InvalidArgument naming the path.
absl::StatusOr<study::StudyResult> ReadStudyResultFile(const std::string& path);

}  // namespace totalgrad::io

#endif  // TOTALGRAD_IO_STUDY_RESULTS_H_
