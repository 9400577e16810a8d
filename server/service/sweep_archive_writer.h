// Writes a sweep archive (the format of sweep_archive.h) job by job, so that
// an archive of any size is written holding one job in memory: the opening
// (format, version, exporter, time, the sweep's record), then each job's
// object on a line of its own as it arrives, then the closing. The document
// is the one SweepArchiveToJson makes, but for whitespace.
//
// Threading: one writer per archive, used by one thread.
#ifndef TOTALGRAD_SERVER_SERVICE_SWEEP_ARCHIVE_WRITER_H_
#define TOTALGRAD_SERVER_SERVICE_SWEEP_ARCHIVE_WRITER_H_

#include <cstdint>
#include <ostream>
#include <string>

#include "server/service/sweep_archive.h"
#include "totalgrad/v1/control_service.pb.h"
#include "totalgrad/v1/types.pb.h"

namespace totalgrad::service {

class SweepArchiveWriter {
 public:
  // Writes the opening to *out, which must outlive the writer.
  SweepArchiveWriter(std::ostream* out, const v1::SweepInfo& sweep, const std::string& exported_by,
                     int64_t exported_ms);
  SweepArchiveWriter(const SweepArchiveWriter&) = delete;
  SweepArchiveWriter& operator=(const SweepArchiveWriter&) = delete;

  // Appends one job (jobs in the order they are to be read, by job id).
  void AddJob(const ArchiveJobInput& job);

  // Writes the closing: the document is complete only after it.
  void Finish();

  // What the jobs written so far hold, counted as storage::SweepContents
  // counts a sweep (every attempt of the attempt logs, their episodes and
  // study rows): what `sweep delete` sends as DeleteSweep's guard.
  const v1::SweepContents& counted() const { return counted_; }

 private:
  std::ostream* out_;
  bool first_job_ = true;
  v1::SweepContents counted_;
};

}  // namespace totalgrad::service

#endif  // TOTALGRAD_SERVER_SERVICE_SWEEP_ARCHIVE_WRITER_H_
