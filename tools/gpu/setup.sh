# Source on the GPU machine from the project root (tools/gpu/prepare.sh copies it to .gpu/):
#   source .gpu/setup.sh
# Installs the carried GL loaders, the wheels and Mitsuba into the interpreter's own site-packages
# (so subprocesses with their own PYTHONPATH find them), the project editable (console script, MikkTSpace).
for f in .gpu/deb/*.deb; do dpkg -x "$f" /; done; ldconfig
export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
SITE=$(python3 -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade .gpu/whl/*.whl
for z in .gpu/mitsuba_slim.zip .gpu/mitsuba_volpath.zip .gpu/colour_slim.zip; do python3 -m zipfile -e $z "$SITE"; done
python3 -m pip install -q --no-index --no-deps --no-build-isolation -e . > /tmp/pip-e.log 2>&1 || { echo "editable install failed"; tail -5 /tmp/pip-e.log; }
export PYTHONUNBUFFERED=1 PBRCHECK_CACHE=/tmp/pbrcheck-cache
[ -d .gpu/shared ] && [ ! -e ../shared ] && ln -s "$PWD/.gpu/shared" ../shared
which pbrcheck; ls pbrcheck/_mikktspace*.so
python3 -c "import mitsuba as mi, drjit as dr; print('mitsuba', mi.__version__, 'cuda', dr.has_backend(dr.JitBackend.CUDA))"
python3 -c "import moderngl; c = moderngl.create_standalone_context(backend='egl', require=430); print(c.info['GL_RENDERER'], c.max_samples)"
