#!/usr/bin/env bash
# Installs the pinned npm tools (obj2gltf, glTF-Transform, the Khronos glTF-Validator) into
# tools/gltf/node_modules and converts the shared scenes to glTF into OUT (see convert.mjs).
# A finished OUT (its validation.json newer than this folder's scripts) is kept.
#
#   tools/gltf/convert.sh SHARED_SCENES OUT [SCENE...]
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
shared=${1:?usage: convert.sh SHARED_SCENES OUT [SCENE...]}
out=${2:?usage: convert.sh SHARED_SCENES OUT [SCENE...]}
shift 2
command -v node > /dev/null || { echo "node (Node.js >= 18) is needed: apt-get install nodejs npm" >&2; exit 2; }
if [ ! -d "$here/node_modules/obj2gltf" ]; then
    (cd "$here" && npm ci --no-audit --no-fund --loglevel=error)
fi
if [ -f "$out/validation.json" ] && [ $# -eq 0 ] \
    && [ "$out/validation.json" -nt "$here/convert.mjs" ] && [ "$out/validation.json" -nt "$here/package-lock.json" ]; then
    exit 0
fi
mkdir -p "$out"
node "$here/convert.mjs" "$shared" "$out" "$@"
