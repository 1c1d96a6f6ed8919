# pbrcheck: `make demo` sets up and runs the main job; `make test` sets up and runs the tests.
# Set-up is idempotent: system packages are checked with dpkg-query (installed only when missing,
# which needs root), the virtualenv is rebuilt only when pyproject.toml changes.

PYTHON     ?= python3
VENV       := .venv
PY         := $(VENV)/bin/python
STAMP      := $(VENV)/.pbrcheck-installed
# Minimal Debian packages: EGL + GL dispatch and Mesa's llvmpipe for headless moderngl,
# LLVM 19 for Dr.Jit's LLVM backend (Mesa's LLVM 15 makes Dr.Jit 1.5 abort).
# libatomic1: Dr.Jit and Mitsuba link it (absent on a bare Debian; found with a debootstrap minbase).
# build-essential: the C compiler that builds the reference MikkTSpace (setup.py, pbrcheck/mikktspace_c).
SYSTEM_PACKAGES := libegl1 libgl1 libgl1-mesa-dri libllvm19 libatomic1 build-essential

# Only for the report's headless-browser test (skipped where it cannot be installed).
TEST_PACKAGES := chromium

.PHONY: setup system-packages client-packages test-packages demo test test-fast gate bench report fidelity clean

setup: system-packages client-packages $(STAMP)

system-packages:
	@bash tools/ensure-system-packages.sh --python $(PYTHON) $(SYSTEM_PACKAGES)

# The external clients (docs/renderers.md): Debian's nodejs, npm, chromium and `npm ci` in every
# clients/*/ with a package-lock.json; without root it prints the commands and goes on (their tests skip).
# The Cycles client: the bpy wheel into clients/cycles/.venv (tools/ensure-cycles.sh; optional too).
client-packages:
	@bash tools/ensure-clients.sh
	@bash tools/ensure-cycles.sh

$(STAMP): pyproject.toml setup.py $(wildcard pbrcheck/mikktspace_c/*.c pbrcheck/mikktspace_c/*.h)
	@$(PY) -m pip --version >/dev/null 2>&1 || { rm -rf $(VENV); $(PYTHON) -m venv $(VENV); }
	@$(PY) -m pip install --quiet --upgrade pip >/dev/null
	$(PY) -m pip install --quiet -e '.[test]'
	@touch $(STAMP)

demo: setup
	$(VENV)/bin/pbrcheck demo

test-packages:
	@bash tools/ensure-system-packages.sh --optional $(TEST_PACKAGES)

test: setup test-packages
	$(PY) -m pytest -q

# The inner loop: every test not marked slow (renders, quadratures, fits).
test-fast: setup
	$(PY) -m pytest -q -m "not slow"

# The CI error-budget gate of the shipped shaders, then of the external clients (three.js, the glTF
# Sample Viewer, Babylon.js, PlayCanvas, Filament): accuracy against the references and change against
# the accepted baselines (compare/budgets/baselines/; accept an intended change with
# `pbrcheck gate BUDGET.toml --accept --reason "..."`).
gate: setup
	@rc=0; \
	$(VENV)/bin/pbrcheck gate compare/budgets/ci.toml --junit out/ci/gate-junit.xml --summary out/ci/gate-summary.md \
		--html out/ci/gate-html || rc=$$?; \
	$(VENV)/bin/pbrcheck gate compare/budgets/clients.toml --junit out/ci/gate-clients-junit.xml \
		--summary out/ci/gate-clients-summary.md --html out/ci/gate-clients-html || { r=$$?; [ $$r -gt $$rc ] && rc=$$r; }; \
	exit $$rc

bench: setup
	$(VENV)/bin/pbrcheck bench reference
	$(VENV)/bin/pbrcheck bench realtime
	$(VENV)/bin/pbrcheck bench fit-roughness
	$(VENV)/bin/pbrcheck bench multiscatter
	$(VENV)/bin/pbrcheck bench corpus
	$(VENV)/bin/pbrcheck bench client --renderer threejs

# The committed accuracy report of the shipped shaders (reports/index.html).
REPORT_SCENES := spheres furnace grazing clearcoat sheen specular anisotropy iridescence
# The external engines measured beside the presets (the built-in clients, fast IBL profile).
REPORT_CLIENTS := ext:threejs,ext:sample-viewer
report: setup
	$(VENV)/bin/pbrcheck report $(REPORT_SCENES) --spp 256 --with $(REPORT_CLIENTS) --hardcases --research --out reports

# The committed Render Fidelity comparison with the ground truth (reports/fidelity/; docs/fidelity.md):
# scenarios of ../shared/rf/config.json through the truth (path mode) and every renderer that runs here
# (the five web clients, three-gpu-pathtracer at 16 spp by reports/fidelity/renderers.toml, the
# default preset, Blender Cycles), at a reduced size and spp, all 17 scenarios (software WebGL on two
# shared cores: ~3 minutes a scenario, ~53 minutes in all); FIDELITY_SCENARIOS=A,B runs a subset.
# Not part of `make test`.
FIDELITY_CONFIG    ?= ../shared/rf/config.json
FIDELITY_SIZE      ?= 64
FIDELITY_SPP       ?= 16
FIDELITY_SCENARIOS ?=
FIDELITY_RENDERERS ?= threejs,filament,babylon,sample-viewer,playcanvas,three-gpu-pathtracer,cycles
fidelity: setup
	$(VENV)/bin/pbrcheck --renderers reports/fidelity/renderers.toml fidelity $(FIDELITY_CONFIG) \
		--renderers $(FIDELITY_RENDERERS) \
		--size $(FIDELITY_SIZE) --spp $(FIDELITY_SPP) $(if $(FIDELITY_SCENARIOS),--scenarios $(FIDELITY_SCENARIOS)) \
		--allow-dir $(dir $(FIDELITY_CONFIG)).. --out reports/fidelity --resume

clean:
	rm -rf $(VENV) build *.egg-info
