#!/usr/bin/env bash
# Set up the Blender Cycles client (clients/cycles/, docs/renderers.md section 10): a virtual
# environment clients/cycles/.venv with the `bpy` wheel pinned in clients/cycles/requirements.txt
# (Blender as a Python module, ~370 MB, CPython 3.11 only: bpy 4.5 is built for 3.11).
# Optional like the browser clients: where python3.11 or the wheel is unavailable it says so and goes
# on (tests/test_cycles.py then skips). An environment whose bpy already imports at the pinned
# version is kept (stamp: .venv/.requirements.txt, a copy of the requirements it was made from).
# pip's cache keeps the wheel, so a re-made environment does not download it again.
set -uo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
dir="$root/clients/cycles"
venv="$dir/.venv"
req="$dir/requirements.txt"
if [ -x "$venv/bin/python" ] && cmp -s "$req" "$venv/.requirements.txt" &&
   "$venv/bin/python" -c "import bpy" >/dev/null 2>&1; then
  exit 0
fi
py="${CYCLES_PYTHON:-$(command -v python3.11 || true)}"
if [ -z "$py" ]; then
  echo "pbrcheck: the Cycles client needs python3.11 (the bpy wheel is cp311); ext:cycles will not run" >&2
  exit 0
fi
echo "pbrcheck: installing the Cycles client (bpy, ~370 MB download once) into clients/cycles/.venv"
start=$(date +%s)
rm -rf "$venv"
if "$py" -m venv "$venv" && "$venv/bin/python" -m pip install --quiet -r "$req" >/dev/null &&
   "$venv/bin/python" -c "import bpy" >/dev/null 2>&1; then
  cp "$req" "$venv/.requirements.txt"
  echo "pbrcheck: Cycles client installed in $(( $(date +%s) - start )) s"
else
  rm -rf "$venv"
  echo "pbrcheck: could not install bpy (clients/cycles/requirements.txt); ext:cycles will not run; run: $py -m venv $venv && $venv/bin/pip install -r $req" >&2
fi
exit 0
