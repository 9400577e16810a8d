// A submitted sweep (v1::SubmitSweepRequest) turned into what the store
// keeps (storage::NewSweep): checked, canonical and counted
// (sweep::PrepareSweep), with the source text and the coordinator's build.
// Its jobs are not held: NewSweep::generated_jobs expands them from the spec
// while the store inserts them.
#ifndef TOTALGRAD_SERVER_SERVICE_SUBMISSION_H_
#define TOTALGRAD_SERVER_SERVICE_SUBMISSION_H_

#include <string>

#include "absl/status/statusor.h"
#include "server/storage/store.h"
#include "totalgrad/v1/control_service.pb.h"

namespace totalgrad::service {

// InvalidArgument naming the field at fault (the source's size, the spec's
// fields).
absl::StatusOr<storage::NewSweep> PrepareSubmission(const v1::SubmitSweepRequest& request,
                                                    const std::string& coordinator_build);

}  // namespace totalgrad::service

#endif  // TOTALGRAD_SERVER_SERVICE_SUBMISSION_H_
