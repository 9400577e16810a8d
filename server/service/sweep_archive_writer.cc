#include "server/service/sweep_archive_writer.h"

#include <nlohmann/json.hpp>

namespace totalgrad::service {

SweepArchiveWriter::SweepArchiveWriter(std::ostream* out, const v1::SweepInfo& sweep,
                                       const std::string& exported_by, int64_t exported_ms)
    : out_(out) {
  // The opening is the document without its jobs, "}" replaced by the start
  // of the jobs' array.
  std::string opening = SweepArchiveOpeningJson(sweep, exported_by, exported_ms).dump(1);
  opening.resize(opening.rfind('}'));
  while (!opening.empty() && opening.back() == '\n') opening.pop_back();
  *out_ << opening << ",\n \"jobs\": [";
}

void SweepArchiveWriter::AddJob(const ArchiveJobInput& input) {
  const nlohmann::ordered_json job = ArchiveJobJson(input);
  counted_.set_jobs(counted_.jobs() + 1);
  for (const auto& attempt : job.at("attempt_log")) {
    counted_.set_attempts(counted_.attempts() + 1);
    counted_.set_episodes(counted_.episodes() + static_cast<int64_t>(attempt.at("episodes").size()));
    counted_.set_study_rows(counted_.study_rows() +
                            static_cast<int64_t>(attempt.at("study_cells").size() +
                                                 attempt.at("study_references").size()));
  }
  *out_ << (first_job_ ? "\n" : ",\n") << job.dump();
  first_job_ = false;
}

void SweepArchiveWriter::Finish() { *out_ << "\n ]\n}\n"; }

}  // namespace totalgrad::service
