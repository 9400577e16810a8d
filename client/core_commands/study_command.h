// `totalgrad study FILE`: a gradient study (core/study/study.h) described by a
// JSON file, printed as a table (text, CSV or JSON) and, with --output-dir,
// written there with log-log work-precision plots (gnuplot, PNG).
//
// Study file (every field but "problem" optional; defaults in brackets):
//   {"problem": {"snapshot": "snapshots.json",   // relative to the study file, or
//                                                // the snapshot file's JSON object
//                                                // itself (inlined; see InlineStudyDocument)
//                "episode": 3,                    // [the first in the file]
//                "policy": "before" | "after"}    // ["before"]
//            or {"synthetic": {"data": 450, "horizon": 30, "basis_functions": 50,
//                              "cost": "angle", "scene": "cartpole-swingup",
//                              "seed": 1, "train_iterations": 0}},
//    "estimators": ["RP", "LR", ..., "PILCO",     // [every registered method + PILCO]
//                   {"label": "LR(plain,loo)", "method": "LR",
//                    "options": {"lr_weights": "plain", "lr_baseline": "loo"}}],
//    "particles": [10, 30, 100, 300, 1000, 3000],
//    "horizons": [10, 30, 60, 100],
//    "replicates": 20, "seed": 1, "cell_budget_seconds": 20,
//    "ess_replicates": 2, "ess_max_particles": 3000,
//    "reference": {"estimators": [...], "particles": 1000, "replicates": 40,
//                  "budget_seconds": 120, "agreement_max_z": 4.5,
//                  "agreement_mean_z2": 3},
//    "sweep_particles": 100}                      // P of the horizon-sweep plot
// Estimator option keys: lr_weights, lr_baseline, gs_derivative,
// sn_noise_multiplier (as the trial options of the same names) and
// forced_k_lr. Values may be strings or numbers.
//
// The parsing, formatting and plotting are exposed for in-process tests.
#ifndef TOTALGRAD_CLIENT_CORE_COMMANDS_STUDY_COMMAND_H_
#define TOTALGRAD_CLIENT_CORE_COMMANDS_STUDY_COMMAND_H_

#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/status/statusor.h"
#include "core/estimators/synthetic_problem.h"
#include "core/learner/trial.h"
#include "core/study/frozen_problem.h"
#include "core/study/study.h"

namespace totalgrad::cli {

struct StudySpec {
  bool from_snapshot = false;
  std::string snapshot_file;  // resolved path; empty when the snapshots are inlined
  std::vector<learner::TrialSnapshot> inline_snapshots;  // problem.snapshot as an object
  int snapshot_episode = -1;  // -1: the first snapshot in the file
  study::SnapshotPolicy snapshot_policy = study::SnapshotPolicy::kBefore;
  estimators::SyntheticProblemOptions synthetic;
  study::StudyOptions options;
  int sweep_particles = 100;
};

// InvalidArgument naming the field (and entry) that is wrong. Relative
// snapshot paths are resolved against base_dir.
absl::StatusOr<StudySpec> ParseStudySpec(const nlohmann::json& doc, const std::string& base_dir);

// Reads and parses a study file (NotFound / InvalidArgument naming the path).
absl::StatusOr<nlohmann::json> ReadStudyDocument(const std::string& path);

// A self-contained copy of a study document: a snapshot given as a path
// (relative to base_dir) is replaced by the snapshot file's JSON object,
// keeping only the snapshot the study uses (problem.episode, else the
// first). Numbers are copied as parsed, so the inlined problem is the same
// bit for bit. Documents without a snapshot path are returned unchanged.
// Errors name the snapshot file and what is wrong with it.
absl::StatusOr<nlohmann::json> InlineStudyDocument(const nlohmann::json& doc,
                                                   const std::string& base_dir);

// Builds the frozen problem the spec names (reads the snapshot file, or
// uses the inlined snapshots).
absl::StatusOr<std::unique_ptr<study::FrozenProblem>> LoadStudyProblem(const StudySpec& spec);

// The result as a fixed-width table (references, cells, omissions), as CSV
// (one row per cell, header first) and as JSON (NaN as null).
std::string StudyTableText(const study::StudyResult& result);
// The `note` column of table.csv for one cell (omission, budget, reference
// disagreement, first error), "" when there is nothing to note.
std::string StudyCellNote(const study::CellResult& cell);
std::string StudyTableCsv(const study::StudyResult& result);
std::string StudyReferenceCsv(const study::StudyResult& result);
nlohmann::ordered_json StudyToJson(const study::StudyResult& result, const StudySpec& spec);

// Writes the gnuplot data and scripts of the work-precision plot (relative
// RMSE against seconds per gradient, log-log, one panel per horizon, one
// curve per estimator over P, PILCO as a point, the reference's noise floor
// as a dashed line) and of the horizon sweep at spec.sweep_particles (or the
// nearest P of the study), into `dir`. When run_gnuplot, runs gnuplot on the
// scripts to make PNGs. Returns the files written. Cells that are omitted or
// whose horizon's reference estimators disagree are not drawn (they are
// listed in the table's omissions).
absl::StatusOr<std::vector<std::string>> WriteStudyPlots(const study::StudyResult& result,
                                                         const StudySpec& spec,
                                                         const std::string& dir, bool run_gnuplot);

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_CORE_COMMANDS_STUDY_COMMAND_H_
