// Conversions between the wire messages (totalgrad.v1) and the storage /
// scheduler / sweep domain types, and from absl::Status to grpc::Status.
// Pure functions; no I/O.
#ifndef TOTALGRAD_SERVER_SERVICE_CONVERT_H_
#define TOTALGRAD_SERVER_SERVICE_CONVERT_H_

#include <grpcpp/support/status.h>

#include <vector>

#include "absl/status/status.h"
#include "server/scheduler/scheduler.h"
#include "server/storage/store.h"
#include "server/sweep/sweep_spec.h"
#include "totalgrad/v1/control_service.pb.h"
#include "totalgrad/v1/types.pb.h"
#include "totalgrad/v1/worker_service.pb.h"

namespace totalgrad::service {

// Same canonical code, same message (the codes are shared by design).
grpc::Status ToGrpcStatus(const absl::Status& status);

storage::WorkerIdentity FromProto(const v1::WorkerIdentity& worker);
storage::LeaseKey FromProto(const v1::LeaseKey& key);
storage::Episode FromProto(const v1::EpisodeReport& report);
std::vector<storage::Episode> FromProto(
    const google::protobuf::RepeatedPtrField<v1::EpisodeReport>& reports);
sweep::SweepSpec FromProto(const v1::SweepSpec& spec);
// Study rows as a worker sends them (job_id, attempt and study are ignored).
storage::StudyCell FromProto(const v1::StudyCellRow& row);
storage::StudyReference FromProto(const v1::StudyReferenceRow& row);
storage::StudyRows StudyRowsFromProto(
    const google::protobuf::RepeatedPtrField<v1::StudyCellRow>& cells,
    const google::protobuf::RepeatedPtrField<v1::StudyReferenceRow>& references);
// The rows of a heartbeat (HeartbeatRequest) and a completion
// (CompleteRequest): one bundle and one completion for every job kind. The
// wire keeps a field per table (episodes, study_cells, study_references,
// and their totals), so older workers and coordinators still understand
// each other; the kind's rules apply in the store.
storage::JobResults ResultsFromProto(const v1::HeartbeatRequest& request);
storage::JobCompletion CompletionFromProto(const v1::CompleteRequest& request);
// Unspecified maps to nullopt.
std::optional<storage::JobState> FromProto(v1::JobState state);
// A value this build does not know maps to nullopt.
std::optional<storage::PruneScope> FromProto(v1::PruneScope scope);
void ToProto(const storage::SweepDiskUse& use, v1::PruneSweepResponse* out);
// nullopt when the message carries no checkpoint (no data).
std::optional<storage::Checkpoint> CheckpointFromProto(bool present,
                                                       const v1::TrialCheckpoint& checkpoint);
void ToProto(const storage::Checkpoint& checkpoint, v1::TrialCheckpoint* out);

void ToProto(const sweep::SweepSpec& spec, v1::SweepSpec* out);
void ToProto(const storage::SweepRecord& sweep, v1::SweepInfo* out);
void ToProto(const storage::JobRecord& job, v1::JobInfo* out);
// The CLI's way back: what the coordinator sent, as the record it was made
// from (the store's bookkeeping, not on the wire, at its defaults; an
// UNSPECIFIED state or kind at the record's default).
storage::SweepRecord FromProto(const v1::SweepInfo& info);
storage::JobRecord FromProto(const v1::JobInfo& info);
void ToProto(const storage::AttemptRecord& attempt, v1::AttemptInfo* out);
// An attempt as a sweep archive carries it (storage::ImportedAttemptFields(),
// by name): job_id, the lease expiry, episodes_stored and
// checkpoint_episode are not carried; episodes and study rows are left empty.
storage::ImportedAttempt FromProto(const v1::AttemptInfo& info);
void ToProto(const storage::EventRecord& event, v1::Event* out);
// `now_ms` and `lease_timeout_ms` decide ACTIVE vs GONE.
void ToProto(const storage::WorkerRecord& worker, int64_t now_ms, int64_t lease_timeout_ms,
             v1::WorkerInfo* out);
void ToProto(const results::CompletedTrial& result, v1::TrialResult* out);
void ToProto(const storage::Episode& episode, v1::EpisodeReport* out);
void ToProto(const storage::EpisodeRowRecord& row, v1::EpisodeRow* out);
void ToProto(const scheduler::Lease& lease, v1::Lease* out);
void ToProto(const storage::StudyCell& cell, v1::StudyCellRow* out);
void ToProto(const storage::StudyReference& reference, v1::StudyReferenceRow* out);
void ToProto(const storage::StudyCellRecord& record, v1::StudyCellRow* out);
void ToProto(const storage::StudyReferenceRecord& record, v1::StudyReferenceRow* out);
// The imported sweep as it now stands here, and what the import took over.
void ToProto(const storage::SweepRecord& sweep, const storage::ImportResult& result,
             v1::ImportSweepResponse* out);
v1::JobKind ToProto(storage::JobKind kind);
storage::JobKind FromProto(v1::JobKind kind);  // unspecified: a trial
v1::Directive ToProto(scheduler::Directive directive);
v1::JobState ToProto(storage::JobState state);
v1::SweepState ToProto(storage::SweepState state);
v1::AttemptState ToProto(storage::AttemptState state);

}  // namespace totalgrad::service

#endif  // TOTALGRAD_SERVER_SERVICE_CONVERT_H_
