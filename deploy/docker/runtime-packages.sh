#!/usr/bin/env bash
# Prints, one per line, the Debian packages that hold the shared libraries the
# given binaries load (ldd), so the runtime image installs exactly those and no
# compiler or -dev package. Run in the build stage of deploy/docker/Dockerfile
# (and by tests/deploy on the host's own build). Fails if a library belongs to
# no installed package.
#
#   deploy/docker/runtime-packages.sh BINARY... > runtime-packages.txt
set -euo pipefail

if [ $# -eq 0 ]; then
  echo "usage: $0 BINARY..." >&2
  exit 2
fi

owner() {  # owner PATH: the package that installed PATH (tries the /usr-merged twin too)
  local path="$1" candidate found
  for candidate in "$path" "$(readlink -f "$path")" "/usr$path" "${path#/usr}"; do
    [ -n "$candidate" ] || continue
    if found=$(dpkg-query -S "$candidate" 2>/dev/null); then
      # "pkg:arch: /path" or "pkg1, pkg2: /path"; the first package is enough.
      echo "$found" | head -n1 | cut -d: -f1 | cut -d, -f1
      return 0
    fi
  done
  return 1
}

libraries=$(ldd "$@" | awk '$2 == "=>" && $3 ~ /^\// {print $3} $1 ~ /^\// && $1 !~ /:$/ {print $1}' | sort -u)
packages=()
missing=0
for library in $libraries; do
  if package=$(owner "$library"); then
    packages+=("$package")
  else
    echo "runtime-packages: no installed package holds $library" >&2
    missing=1
  fi
done
[ "$missing" -eq 0 ] || exit 1
printf '%s\n' "${packages[@]}" | sort -u
