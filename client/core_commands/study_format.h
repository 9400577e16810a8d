// Text, CSV and JSON renderings of a gradient study's result (core/study/
// study.h): the tables `totalgrad study` prints and writes to --output-dir.
#ifndef TOTALGRAD_CLIENT_CORE_COMMANDS_STUDY_FORMAT_H_
#define TOTALGRAD_CLIENT_CORE_COMMANDS_STUDY_FORMAT_H_

#include <string>

#include <nlohmann/json.hpp>

#include "core/study/study.h"
#include "io/study_file.h"

namespace totalgrad::cli {

// The result as a fixed-width table (references, cells, omissions), as CSV
// (one row per cell, header first) and as JSON (NaN as null).
std::string StudyTableText(const study::StudyResult& result);
std::string StudyTableCsv(const study::StudyResult& result);
std::string StudyReferenceCsv(const study::StudyResult& result);
nlohmann::ordered_json StudyToJson(const study::StudyResult& result, const io::StudySpec& spec);

// The reference gradient of `horizon` in `result`, or null.
const study::ReferenceGradient* ReferenceFor(const study::StudyResult& result, int horizon);

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_CORE_COMMANDS_STUDY_FORMAT_H_
