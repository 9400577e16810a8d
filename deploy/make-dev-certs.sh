#!/usr/bin/env bash
# Makes a throwaway development CA, a coordinator certificate, a client
# certificate (for coordinators started with --tls-client-ca) and the two
# bearer tokens. For development and tests only: the CA key sits next to the
# certificates and everything expires after 30 days.
#
#   deploy/make-dev-certs.sh OUT_DIR [HOST ...]
#
# The server certificate is valid for localhost, 127.0.0.1, ::1 and every
# HOST given (names or IP addresses). Then:
#
#   totalgrad-coordinator --db r.db --listen 0.0.0.0:7070 \
#       --tls-cert OUT_DIR/server.pem --tls-key OUT_DIR/server.key \
#       --worker-token-file OUT_DIR/worker.token --user-token-file OUT_DIR/user.token
#   totalgrad-worker --coordinator HOST:7070 --ca-cert OUT_DIR/ca.pem --token-file OUT_DIR/worker.token
#   totalgrad sweep list --coordinator HOST:7070 --ca-cert OUT_DIR/ca.pem --token-file OUT_DIR/user.token
set -euo pipefail

if [ $# -lt 1 ]; then
  echo "usage: $0 OUT_DIR [HOST ...]" >&2
  exit 2
fi
out="$1"
shift
mkdir -p "$out"
umask 077

san="DNS:localhost,IP:127.0.0.1,IP:::1"
for host in "$@"; do
  if [[ "$host" =~ ^[0-9.]+$ || "$host" == *:* ]]; then
    san="$san,IP:$host"
  else
    san="$san,DNS:$host"
  fi
done

# EC P-256 keys: small and fast, and accepted by gRPC's TLS stack.
key_options=(-newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes)

openssl req -x509 "${key_options[@]}" -days 30 -subj "/CN=totalgrad development CA" \
  -addext "basicConstraints=critical,CA:TRUE" -addext "keyUsage=critical,keyCertSign,cRLSign" \
  -keyout "$out/ca.key" -out "$out/ca.pem" 2>/dev/null

sign() {  # sign NAME CN EXTENSIONS
  local name="$1" cn="$2" extensions="$3"
  openssl req -new "${key_options[@]}" -subj "/CN=$cn" \
    -keyout "$out/$name.key" -out "$out/$name.csr" 2>/dev/null
  openssl x509 -req -in "$out/$name.csr" -CA "$out/ca.pem" -CAkey "$out/ca.key" \
    -CAcreateserial -days 30 -out "$out/$name.pem" \
    -extfile <(printf '%s\n' "$extensions") 2>/dev/null
  rm -f "$out/$name.csr"
}

sign server "totalgrad coordinator" \
  "basicConstraints=CA:FALSE
keyUsage=critical,digitalSignature,keyEncipherment
extendedKeyUsage=serverAuth
subjectAltName=$san"
sign client "totalgrad client" \
  "basicConstraints=CA:FALSE
keyUsage=critical,digitalSignature,keyEncipherment
extendedKeyUsage=clientAuth"

for role in worker user; do
  if [ ! -s "$out/$role.token" ]; then
    openssl rand -hex 24 > "$out/$role.token"
  fi
done
chmod 0644 "$out/ca.pem" "$out/server.pem" "$out/client.pem"
echo "development CA, certificates and tokens written to $out (server names: $san)"
