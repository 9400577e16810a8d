// `totalgrad study summary LABEL=RESULTS ...`: the equal-time summary tables
// of docs/error-vs-time.md (core/study/equal_time.h) from the results.json
// files of finished studies, as Markdown (the doc's tables) or JSON.
#ifndef TOTALGRAD_CLIENT_CORE_COMMANDS_STUDY_SUMMARY_H_
#define TOTALGRAD_CLIENT_CORE_COMMANDS_STUDY_SUMMARY_H_

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/study/equal_time.h"
#include "core/study/study.h"

namespace totalgrad::cli {

// One study in the summary, shown under `label`.
struct LabelledStudy {
  std::string label;
  study::StudyResult result;
};

// One section per study: a table with a row per (horizon, seconds): the
// winner and its error, every particle estimator's error ratio to it ("n/a"
// outside its measured range), "no winner" where the references disagree;
// then PILCO's own (seconds, error) per horizon. Numbers: 2 significant
// digits for ratios, 3 for errors. A winner below the reference's noise
// floor is marked "*", one whose relative error is 1 or more (no better than
// a zero gradient) "(≥ 1)", each with a note under the table. A last column
// names a cell measured in less than the row's time with a lower error than
// the winner's (EqualTimeRow::best_within), "-" when there is none.
std::string StudySummaryMarkdown(const std::vector<LabelledStudy>& studies,
                                 const std::vector<double>& seconds);
nlohmann::ordered_json StudySummaryJson(const std::vector<LabelledStudy>& studies,
                                        const std::vector<double>& seconds);

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_CORE_COMMANDS_STUDY_SUMMARY_H_
