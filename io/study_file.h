// A gradient study described by a JSON document (the study file of
// `totalgrad study FILE` and of `[[study]]` jobs in sweep files): parsing
// with errors that name the field, resolving and inlining the trial snapshot
// it starts from, and building its frozen problem. JSON and files in, core
// types out: shared by the CLI, the worker and the coordinator's sweep
// parser (core/ itself reads no files).
//
// Study file (every field but "problem" optional; defaults in brackets):
//   {"problem": {"snapshot": "snapshots.json",   // relative to the study file, or
//                                                // the snapshot file's JSON object
//                                                // itself (inlined; see InlineStudyDocument)
//                "episode": 3,                    // [the first in the file]
//                "policy": "before" | "after"}    // ["before"]
//            or {"synthetic": {"data": 450, "horizon": 30, "basis_functions": 50,
//                              "cost": "angle", "scene": "cartpole-swingup",
//                              "seed": 1, "train_iterations": 0,
//                              "angle_features": "auto" | "raw" | "sincos"}},
// A snapshot problem is on the trial's scene and features (raw or sin/cos;
// study::FrozenProblemFromSnapshot). A synthetic problem is on `scene` (any
// one-control scene of `totalgrad scenes`); on the cart-pole scenes with raw
// features (`auto` there) it is the paper's synthetic cart-pole problem,
// elsewhere study::FrozenProblemFromScene on the scene's index sets.
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
// Estimator option keys: those of estimators::EstimatorOptions::Table()
// (lr_weights, lr_baseline, gs_derivative, sn_noise_multiplier, forced_k_lr;
// the trial options of the same names). Values may be strings or numbers.
// Methods: estimators::MethodNames() (parsed here, once).
//
#ifndef TOTALGRAD_IO_STUDY_FILE_H_
#define TOTALGRAD_IO_STUDY_FILE_H_

#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/status/statusor.h"
#include "core/estimators/synthetic_problem.h"
#include "core/learner/trial.h"
#include "core/learner/trial_options.h"
#include "core/study/frozen_problem.h"
#include "core/study/study.h"

namespace totalgrad::io {

struct StudySpec {
  bool from_snapshot = false;
  std::string snapshot_file;  // resolved path; empty when the snapshots are inlined
  std::vector<learner::TrialSnapshot> inline_snapshots;  // problem.snapshot as an object
  int snapshot_episode = -1;  // -1: the first snapshot in the file
  study::SnapshotPolicy snapshot_policy = study::SnapshotPolicy::kBefore;
  estimators::SyntheticProblemOptions synthetic;
  learner::AngleFeatures synthetic_angle_features = learner::AngleFeatures::kAuto;
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

// A study document whose problem is on `scene`: a synthetic problem's
// problem.synthetic.scene is set to it; a snapshot problem (inlined, see
// InlineStudyDocument) must already be on it. InvalidArgument naming the
// scene when it is unknown, or when the snapshot's scene differs, or when the
// snapshot is still a file name. For `scene = "..."` in a sweep's [[study]].
absl::StatusOr<nlohmann::json> SetStudyScene(const nlohmann::json& doc, const std::string& scene);

// Builds the frozen problem the spec names (reads the snapshot file, or
// uses the inlined snapshots).
absl::StatusOr<std::unique_ptr<study::FrozenProblem>> LoadStudyProblem(const StudySpec& spec);

}  // namespace totalgrad::io

#endif  // TOTALGRAD_IO_STUDY_FILE_H_
