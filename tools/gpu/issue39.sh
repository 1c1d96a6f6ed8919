#!/usr/bin/env bash
# Issue 39's GPU checks in one device call (about 4-5 minutes on an H100; every step has its own
# timeout so that one hang cannot eat the lease). Prepare here once:  bash tools/gpu/prepare.sh
# then run on the device machine with carry [".gpu"] and timeout_s 560:
#   source .gpu/setup.sh && bash tools/gpu/issue39.sh
# What comes back under $OUT/issue39/:
#   variant.txt         the Mitsuba variant chosen (cuda_ad_rgb expected) and the GPU
#   frozen_tests.txt    the frozen render / BSDF path / fit step tests on CUDA (within rounding there)
#   throughput.json     pbrcheck bench reference --section throughput: the default reference against
#                       mi.render + path + the same BSDF and roughconductor at 64, 1024, 4096 spp,
#                       360 x 300 and 720 x 600 (goal >= 1.0 at 1024 spp, >= 0.8 G samples/s)
#   bench_report.json   pbrcheck bench report: the first report's wall time (goal <= 30 s) with its
#                       stages and kernels launched / compiled per stage (dr.kernel_history)
#   frozen_timings.json tools/frozen_timings.py at 360 x 300: traced against frozen on CUDA
# docs/reference.md ("Frozen BSDF path and fit steps", "Against Mitsuba's own integrator") lists the
# figures a run of it fills in.
set -uo pipefail
out=${OUT:-/tmp/out}/issue39
mkdir -p "$out"
step() {  # name, timeout, command...: stdout to $out/name, stderr's tail beside it
  local name=$1 limit=$2; shift 2
  local t0=$SECONDS
  timeout "$limit" "$@" > "$out/$name" 2> "$out/$name.err"
  local rc=$?
  echo "$name: rc $rc, $((SECONDS - t0)) s" | tee -a "$out/steps.txt"
  tail -c 20000 "$out/$name.err" > "$out/$name.err.tail" && mv "$out/$name.err.tail" "$out/$name.err"
}
{ python3 -c "from reference.variant import ensure_variant; print(ensure_variant())"; nvidia-smi -L; } > "$out/variant.txt" 2>&1
cat "$out/variant.txt"
step frozen_tests.txt 150 python3 -m pytest -q -p no:cacheprovider tests/test_reference_speed.py tests/test_reference_diff.py -k frozen
step throughput.json 180 pbrcheck bench reference --section throughput
step bench_report.json 200 pbrcheck bench report
step frozen_timings.json 90 python3 tools/frozen_timings.py --size 360x300
cat "$out/steps.txt"
