#!/usr/bin/env bash
# Set up the external clients (clients/*/ with a package-lock.json: threejs, gltf-sample-viewer,
# babylon, playcanvas, filament, three-gpu-pathtracer):
# Debian's nodejs, npm and chromium, then `npm ci` in each (their packages pinned by
# package-lock.json; no browser download: Debian's chromium).
# Installs only what is missing, and only as root; otherwise prints the exact commands and goes on
# (the tests that need the clients skip with a reason, and `make gate`'s client checks error).
set -uo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
missing=()
# node/npm may come from elsewhere (NodeSource bundles npm into its nodejs): check the commands.
command -v node >/dev/null 2>&1 || missing+=("nodejs")
command -v npm >/dev/null 2>&1 || missing+=("npm")
command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1 || missing+=("chromium")
if [ ${#missing[@]} -gt 0 ]; then
  if [ "$(id -u)" -eq 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "pbrcheck: installing client packages: ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null 2>&1 ||
      { apt-get update -qq >/dev/null 2>&1 && apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null 2>&1; } ||
      echo "pbrcheck: could not install ${missing[*]}; the browser clients (three.js, the glTF Sample Viewer, Babylon.js, PlayCanvas, Filament) will not run" >&2
  else
    echo "pbrcheck: the browser clients (three.js, the glTF Sample Viewer, Babylon.js, PlayCanvas, Filament) need ${missing[*]}; run as root: apt-get update && apt-get install -y ${missing[*]}" >&2
  fi
fi
command -v npm >/dev/null 2>&1 || exit 0
# Every client with a lockfile (clients/threejs, clients/gltf-sample-viewer, clients/babylon, ...,
# clients/three-gpu-pathtracer).
for lock in "$root"/clients/*/package-lock.json; do
  dir="$(dirname "$lock")"
  stamp="$dir/node_modules/.package-lock.json"
  if [ -f "$stamp" ] && [ "$stamp" -nt "$lock" ]; then
    continue
  fi
  echo "pbrcheck: npm ci in clients/$(basename "$dir")"
  if ! (cd "$dir" && npm ci --no-audit --no-fund --loglevel=error >/dev/null); then
    echo "pbrcheck: npm ci failed; run: (cd $dir && npm ci)" >&2
  fi
done
exit 0
