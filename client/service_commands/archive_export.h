// `results export SWEEP -f json` and `sweep delete`'s archive: the sweep's
// archive (server/service/sweep_archive.h) written job by job as the
// coordinator's answers arrive, so its size is bounded by neither a gRPC
// message nor the client's memory (it holds one page of jobs, one job's
// attempts and episodes, and the sweep's study rows).
#ifndef TOTALGRAD_CLIENT_SERVICE_COMMANDS_ARCHIVE_EXPORT_H_
#define TOTALGRAD_CLIENT_SERVICE_COMMANDS_ARCHIVE_EXPORT_H_

#include <ostream>
#include <string>

#include "client/service_commands/connection.h"
#include "totalgrad/v1/control_service.pb.h"

namespace totalgrad::cli {

// Writes the archive of `sweep_name` to `out`. `with_checkpoints`: each
// completed trial's final checkpoint goes in with the attempt it belongs to
// (sizes reported on stderr). Returns 0, or the exit code of the error it
// reported on stderr (the output is then incomplete: the caller discards
// it). *counted (may be null): what the archive holds, DeleteSweep's guard.
int ExportArchive(Connection* connection, const std::string& sweep_name, std::ostream& out,
                  bool with_checkpoints, v1::SweepContents* counted);

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_SERVICE_COMMANDS_ARCHIVE_EXPORT_H_
