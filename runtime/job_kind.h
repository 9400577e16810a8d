// What a job runs and reports: the one definition of the job kinds, shared by
// the sweep library (a sweep's entries), the store (the `jobs.kind` column)
// and the service. Everything that differs between kinds (result tables,
// completion check, checkpoints, verdict, stored name) is data in
// server/storage/job_kinds.h; the wire has the proto's JobKind
// (proto/totalgrad/v1/types.proto), converted by an exhaustive switch in
// server/service/convert.cc, so a kind added here and not on the wire does
// not compile (-Wswitch).
//
// Header only: the worker's runtime, the sweep library and the store include
// it without linking one another.
#ifndef TOTALGRAD_RUNTIME_JOB_KIND_H_
#define TOTALGRAD_RUNTIME_JOB_KIND_H_

namespace totalgrad {

enum class JobKind { kTrial, kStudy };

}  // namespace totalgrad

#endif  // TOTALGRAD_RUNTIME_JOB_KIND_H_
