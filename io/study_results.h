// A gradient study's result (study::StudyResult) as JSON: the results.json
// that `totalgrad study --output-dir` writes, and reading it back for
// `totalgrad study summary` (core/study/equal_time.h). Numbers are written
// as parsed doubles (non-finite ones as null, read back as NaN), so a result
// read back gives the same tables.
//
// Format: {"source", "scene", "num_parameters", "seconds", "blas",
//          "options": {...the study's options...},
//          "references": [one object per study::ReferenceGradient],
//          "cells": [one object per study::CellResult]}
// A reference or a cell is its record's JSON (io/record_format.h) over its
// field table (study::ReferenceFields(), study::CellFields()): every field in
// table order, the derived "note" included (written, ignored on reading).
// Files written before "scene" existed read with an empty scene, before
// "agreement_resolution" existed with NaN (not computed), cells before
// "reference_floor" existed with their horizon's reference's floor.
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
