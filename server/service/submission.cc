#include "server/service/submission.h"

#include <functional>
#include <memory>
#include <utility>

#include "absl/strings/str_cat.h"
#include "server/service/convert.h"
#include "server/sweep/prepared_sweep.h"

namespace totalgrad::service {
namespace {

// A prepared sweep's jobs as the store inserts them: expanded again, one at
// a time, on each walk (sweep::PreparedSweep::ForEachJob).
class PreparedJobs : public storage::NewJobGenerator {
 public:
  explicit PreparedJobs(sweep::PreparedSweep prepared) : prepared_(std::move(prepared)) {}

  int64_t size() const override { return prepared_.jobs_total; }
  int64_t episodes_expected() const override { return prepared_.episodes_expected; }

  absl::Status ForEach(
      const std::function<absl::Status(const storage::NewJob&)>& visit) const override {
    return prepared_.ForEachJob([&](sweep::ExpandedJob&& job) {
      storage::NewJob stored;
      stored.method = std::move(job.method);
      stored.seed = std::move(job.seed);
      stored.variant = std::move(job.variant);
      stored.options = std::move(job.options);
      stored.episodes_expected = job.episodes_expected;
      stored.kind = job.kind;
      stored.payload = std::move(job.payload);
      return visit(stored);
    });
  }

 private:
  const sweep::PreparedSweep prepared_;
};

}  // namespace

absl::StatusOr<storage::NewSweep> PrepareSubmission(const v1::SubmitSweepRequest& request,
                                                    const std::string& coordinator_build) {
  if (request.source_text().size() > sweep::kMaxSourceBytes) {
    return absl::InvalidArgumentError(absl::StrCat("source_text is ", request.source_text().size(),
                                                   " bytes; at most ", sweep::kMaxSourceBytes));
  }
  if (request.source_name().size() > 4096) {
    return absl::InvalidArgumentError("source_name: at most 4096 bytes");
  }
  absl::StatusOr<sweep::PreparedSweep> prepared = sweep::PrepareSweep(FromProto(request.spec()));
  if (!prepared.ok()) return prepared.status();
  storage::NewSweep sweep;
  sweep.name = prepared->spec.name;
  sweep.description = prepared->spec.description;
  sweep.canonical_spec = std::move(prepared->canonical_json);
  sweep.spec_hash = std::move(prepared->spec_hash);
  sweep.equivalent_spec_hashes = std::move(prepared->equivalent_spec_hashes);
  sweep.source_name = request.source_name();
  sweep.source_text = request.source_text();
  sweep.coordinator_build = coordinator_build;
  sweep.max_attempts = prepared->spec.max_attempts;
  sweep.max_lost_leases = prepared->spec.max_lost_leases;
  sweep.max_concurrent = prepared->spec.max_concurrent;
  sweep.generated_jobs = std::make_shared<const PreparedJobs>(*std::move(prepared));
  return sweep;
}

}  // namespace totalgrad::service
