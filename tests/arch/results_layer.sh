#!/usr/bin/env bash
# The layers around results/ (docs/core.md, "results/"): the store, then
# results/, then its readers. So
#   * nothing under server/ or worker/ includes a client/ header (the
#     coordinator's dashboard reads results/, never the CLI), and
#   * results/ includes no gRPC, protobuf (nor generated totalgrad/v1/),
#     SQLite, server/ or client/ header, and its CMake target links none of
#     them: pure C++ over plain records, callable by the CLI, the dashboard
#     and any later reader;
#   * client/ and python/ include no storage implementation
#     (server/storage/sqlite_*): the CLI and the Python module read results
#     through the results library's read interface, and a database file
#     (--db) through storage::OpenStoreReadOnly.
#   * runtime/ (build id, clocks, tokens, the RPC client: shared by the
#     coordinator, the worker and the CLI) includes nothing from server/,
#     worker/ or client/.
# Usage: results_layer.sh SOURCE_DIR
set -euo pipefail
source_dir="$1"
failed=0
include='^[[:space:]]*#[[:space:]]*include[[:space:]]*[<"]'

if hits=$(grep -rEn --include='*.h' --include='*.cc' --include='*.inc' \
            "${include}client/" "$source_dir/server" "$source_dir/worker"); then
  echo "FAIL: server/ or worker/ includes a client/ header:"; echo "$hits"; failed=1
fi

# runtime/ sits below the coordinator, the worker and the CLI it serves.
if hits=$(grep -rEn --include='*.h' --include='*.cc' --include='*.inc' --include='*.in' \
            "${include}(server|worker|client)/" "$source_dir/runtime"); then
  echo "FAIL: runtime/ includes a server/, worker/ or client/ header:"; echo "$hits"; failed=1
fi

if [ ! -d "$source_dir/results" ]; then
  echo "FAIL: $source_dir/results does not exist"; exit 1
fi
if hits=$(grep -rEn --include='*.h' --include='*.cc' --include='*.inc' \
            "${include}(grpc|grpcpp|google/protobuf|sqlite3|totalgrad/v1/|server/|client/)" \
            "$source_dir/results"); then
  echo "FAIL: results/ includes a gRPC, protobuf, SQLite, server/ or client/ header:"
  echo "$hits"; failed=1
fi
if hits=$(grep -En 'gRPC|grpc|protobuf|SQLite|sqlite|totalgrad_proto|totalgrad_storage|totalgrad_service|totalgrad_client|totalgrad_dashboard' \
            "$source_dir/results/CMakeLists.txt" | grep -Ev '^[0-9]+:[[:space:]]*#'); then
  echo "FAIL: results/CMakeLists.txt links a service library:"; echo "$hits"; failed=1
fi

if hits=$(grep -rEn --include='*.h' --include='*.cc' --include='*.inc' \
            "${include}server/storage/sqlite_" "$source_dir/client" "$source_dir/python"); then
  echo "FAIL: client/ or python/ includes a storage implementation (use server/storage/store.h):"
  echo "$hits"; failed=1
fi

if [ "$failed" -ne 0 ]; then exit 1; fi
echo "ok: runtime/ includes no server/, worker/ or client/ header; server/ and worker/ include no client/ header; results/ includes and links no gRPC, protobuf, SQLite, server/ or client/; client/ and python/ include no storage implementation"
