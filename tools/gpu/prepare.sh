#!/usr/bin/env bash
# Fill the ignored .gpu/ for the device tool's GPU machine (Python 3.12, no package registry, 64 MiB
# carried with the checkout): ../shared/gpu/prepare.sh's recipe, then what pbrcheck's suite needs
# beyond it. Run here from the project root:  bash tools/gpu/prepare.sh
# Then device `run` with carry [".gpu"] and a command such as
#   source .gpu/setup.sh && python3 -m pytest -q -n 12 --dist loadfile tests
# (the H100 runs the suite in ~80 s). Measured with it 2026-11-24: docs/reference.md "On a GPU".
set -euo pipefail
top=$(git rev-parse --show-toplevel); cd "$top"
mkdir -p .git/info
bash ../shared/gpu/prepare.sh
py=.venv/bin/python
ver() { "$py" -c "import importlib.metadata as m; print(m.version('$1'))"; }
dl() { python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
  --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 \
  --platform manylinux_2_5_x86_64 --platform manylinux1_x86_64 -d "$1" "$2"; }
# the corpus (Dask) and the glTF reader; DracoPy (5 MB) stays behind: only Draco assets of ../shared need it
for pkg in dask distributed partd locket tblib zict tornado pygltflib dataclasses-json deprecated marshmallow; do
  dl .gpu/whl "$pkg==$(ver "$pkg")"
done
"$py" - <<'PY'
import glob, os, zipfile
# colour-science without its coverage pages, tests and examples (9 MB -> 1.7 MB)
src = glob.glob(".gpu/whl/colour_science-*.whl")[0]
with zipfile.ZipFile(src) as z, zipfile.ZipFile(".gpu/colour_slim.zip", "w", zipfile.ZIP_DEFLATED) as d:
    for i in z.infolist():
        if not (i.filename.startswith(("colour/htmlcov/", "colour/examples/")) or "/tests/" in i.filename):
            d.writestr(i, z.read(i.filename))
os.remove(src)
PY
# Mitsuba's volpath (the `path` mode through glTF cut-outs), which the shared recipe slims away
rm -rf /tmp/pbrcheck-mi && mkdir -p /tmp/pbrcheck-mi && dl /tmp/pbrcheck-mi "mitsuba==$(ver mitsuba)"
"$py" -c "
import glob, zipfile
s = zipfile.ZipFile(glob.glob('/tmp/pbrcheck-mi/mitsuba-*.whl')[0])
with zipfile.ZipFile('.gpu/mitsuba_volpath.zip', 'w', zipfile.ZIP_DEFLATED) as d:
    d.writestr(s.getinfo('mitsuba/plugins/volpath.so'), s.read('mitsuba/plugins/volpath.so'))"
# one real environment and DamagedHelmet (the frame-time benchmark), within the 64 MiB
if [ -d .gpu/shared/envmaps ]; then find .gpu/shared/envmaps -type f ! -name royal_esplanade_1k.hdr ! -name README.md -delete; fi
if [ -d ../shared/assets/DamagedHelmet ]; then mkdir -p .gpu/shared/assets && cp -r ../shared/assets/DamagedHelmet .gpu/shared/assets/; chmod -R u+w .gpu/shared; fi
cp tools/gpu/setup.sh .gpu/setup.sh
echo "carried: $(( ($(du -cb .gpu | tail -1 | cut -f1) + $(git ls-files -z | xargs -0 du -cb | tail -1 | cut -f1)) / 1048576 )) MiB of 64"
