#!/usr/bin/env bash
# Install the Debian packages pbrcheck needs, only if missing. Without root, print the exact
# apt-get line and fail, changing nothing.
set -euo pipefail
# usage: ensure-system-packages.sh [--python PY] PACKAGE...
# With --python, also make sure PY can create a virtualenv (Debian splits venv/ensurepip into
# python3-venv, absent on a bare machine).
# With --optional, a package that cannot be installed (no root, no apt, no network) is reported
# and skipped: the tests that need it skip with a reason.
python=""
optional=0
while [ $# -gt 0 ]; do
  case "$1" in
    --python) python="$2"; shift 2 ;;
    --optional) optional=1; shift ;;
    *) break ;;
  esac
done
missing=()
if [ -n "$python" ] && ! "$python" -c 'import venv, ensurepip' >/dev/null 2>&1; then
  missing+=("python3-venv")
fi
for p in "$@"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed'; then
    missing+=("$p")
  fi
done
[ ${#missing[@]} -eq 0 ] && exit 0
if [ $optional -eq 1 ]; then
  if [ "$(id -u)" -ne 0 ] || ! command -v apt-get >/dev/null 2>&1; then
    echo "pbrcheck: optional packages not installed (${missing[*]}); the tests that need them will skip" >&2
    exit 0
  fi
  echo "pbrcheck: installing optional test packages: ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  if ! { apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null 2>&1 ||
         { apt-get update -qq >/dev/null 2>&1 && apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null 2>&1; }; }; then
    echo "pbrcheck: could not install ${missing[*]}; the tests that need them will skip" >&2
  fi
  exit 0
fi
if ! command -v apt-get >/dev/null 2>&1; then
  echo "pbrcheck: missing system libraries (${missing[*]}); on Debian/Ubuntu: apt-get install -y ${missing[*]}" >&2
  exit 1
fi
if [ "$(id -u)" -ne 0 ]; then
  echo "pbrcheck: missing system packages; run as root: apt-get update && apt-get install -y ${missing[*]}" >&2
  exit 1
fi
echo "pbrcheck: installing system packages: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
