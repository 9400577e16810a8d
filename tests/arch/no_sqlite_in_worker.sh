#!/usr/bin/env bash
# The worker must not link SQLite (the coordinator alone owns the database),
# and core/ must not include gRPC, protobuf or SQLite headers.
set -euo pipefail
worker="$1"; source_dir="$2"
if ldd "$worker" | grep -qi sqlite; then
  echo "FAIL: $worker links SQLite:"; ldd "$worker" | grep -i sqlite; exit 1
fi
if nm -D --undefined-only "$worker" | grep -q 'sqlite3_'; then
  echo "FAIL: $worker references sqlite3_ symbols"; exit 1
fi
if grep -rEn '#include [<"](grpc|google/protobuf|sqlite3)' "$source_dir/core"; then
  echo "FAIL: core/ includes a service header (above)"; exit 1
fi
echo "ok: worker links no SQLite; core/ includes no gRPC/protobuf/SQLite"
