# Crowd sandbox: set-up, demo, tests, benchmarks.
#   make demo    set up, then render scenes/quickstart.toml headless into out/quickstart/ (frames + video.mp4)
#   make test    set up (and xvfb, chromium for the window and browser tests), then run the test suite on
#                every core (pytest-xdist; PYTEST_WORKERS=0 for one process; fails when no test is collected)
#   make bench   set up, then run the benchmark scenes (short default runs)
#   make setup   .venv + the package with test extras + the system GL libraries (idempotent)
#   make corpus  set up, then every glTF model in ../shared/assets (CORPUS_DIRS) and the generated corpus through
#                info, build and a frame in every LOD mode (scripts/corpus.py; the table goes to docs/corpus.md)
#   make report  set up, then the frame-time and accuracy report of the seven benchmark scenes
#                (scripts/report_seeds.sh: out/report_seeds/<scene>/index.html and table.md)
#   make bench-peers  .venv-peers: the benchmark-only peer engines (panda3d, panda3d-gltf, jupedsim, pedpy) in
#                their own environment, never runtime dependencies; then scripts/bench_peer.py (Panda3D) runs
#                with --peers-python .venv-peers/bin/python (its default)

PYTHON   ?= python3
VENV     ?= .venv
VPY      := $(VENV)/bin/python
SENTINEL := $(VENV)/.crowd-setup-done
# Debian/Ubuntu packages for headless OpenGL (Mesa llvmpipe through EGL): all that rendering (make demo) needs
SYSTEM_PACKAGES := libegl1 libgl1-mesa-dri
# and for the tests: a virtual X server (the fly-through's window tests) and the headless browser the report test
# opens index.html in (tests/crowd/report/test_report_browser.py)
TEST_PACKAGES   := xvfb chromium
# benchmark scenes: every scene but the quick start, and the replays (scenes/replay_*.toml) only where their data
# (../shared/data/pedestrian) are (override: make bench BENCH_SCENES=scenes/office.toml)
REPLAY_DATA  := $(wildcard ../shared/data/pedestrian)
BENCH_SCENES ?= $(sort $(filter-out scenes/quickstart.toml $(if $(REPLAY_DATA),,scenes/replay_%.toml),$(wildcard scenes/*.toml)))
# short default runs: full-detail (lod "none") frames of the big scenes take seconds each on llvmpipe
BENCH_FRAMES ?= 3
BENCH_SIZE   ?= 1280x720
PYTEST_ARGS  ?=
# pytest-xdist workers of `make test`: every core by default (0: one process, no workers)
PYTEST_WORKERS ?= auto
# benchmark-only peers (make bench-peers): their own virtual environment and packages
PEERS_VENV     ?= .venv-peers
PEERS_PACKAGES ?= panda3d panda3d-gltf jupedsim pedpy
PEERS_SENTINEL := $(PEERS_VENV)/.crowd-peers-done
CORPUS_DIRS  ?= ../shared/assets

.PHONY: setup system-packages test-packages apt-packages demo test bench bench-peers corpus report clean

setup: $(SENTINEL)

# Re-runs only when pyproject.toml changes; a second `make setup` is instant.
$(SENTINEL): pyproject.toml Makefile
	@$(MAKE) --no-print-directory system-packages
	@test -x $(VPY) || $(PYTHON) -m venv $(VENV)
	$(VPY) -m pip install --quiet -e '.[test,report]'
	@touch $(SENTINEL)

system-packages:
	@$(MAKE) --no-print-directory apt-packages PACKAGES="$(SYSTEM_PACKAGES)"

test-packages:
	@$(MAKE) --no-print-directory apt-packages PACKAGES="$(TEST_PACKAGES)"

# installs the Debian packages $(PACKAGES) that are missing (root), or names them (otherwise)
apt-packages:
	@missing=""; \
	if command -v dpkg-query >/dev/null 2>&1; then \
	  for p in $(PACKAGES); do \
	    dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "install ok installed" || missing="$$missing $$p"; \
	  done; \
	  if [ ! -x $(VPY) ] && ! $(PYTHON) -c "import ensurepip" >/dev/null 2>&1; then missing="$$missing python3-venv"; fi; \
	else \
	  echo "note: not a Debian/Ubuntu system; make sure these are installed: $(PACKAGES)"; \
	fi; \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	    echo "installing system packages:$$missing"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$missing; \
	  else \
	    echo "error: missing system packages:$$missing; install them with: sudo apt-get install -y$$missing" >&2; \
	    exit 1; \
	  fi; \
	fi

demo: setup
	$(VPY) -m crowd run scenes/quickstart.toml --out out/quickstart --video
	@echo "frames, video.mp4, frames.csv, summary.json and trace.json are in out/quickstart/"

# pytest exit code 5 (no tests collected) is a failure here.
test: setup
	@$(MAKE) --no-print-directory test-packages
	@$(VPY) -m pytest -n $(PYTEST_WORKERS) $(PYTEST_ARGS); rc=$$?; \
	if [ $$rc -eq 5 ]; then echo "error: pytest collected no tests" >&2; exit 1; fi; exit $$rc

bench: setup
	@test -n "$(BENCH_SCENES)" || { echo "error: no benchmark scenes found (scenes/*.toml)" >&2; exit 1; }
	@for s in $(BENCH_SCENES); do \
	  n=$$(basename $$s .toml); \
	  echo "== $$s"; \
	  $(VPY) -m crowd run $$s --frames $(BENCH_FRAMES) --size $(BENCH_SIZE) --png-every 0 --out out/bench/$$n --quiet || exit $$?; \
	  $(VPY) -c "import json,sys; s=json.load(open(sys.argv[1])); st=s['stages']; print('  %d frames, mean frame %.1f ms (simulate %.1f, select %.1f, draw %.1f), %d triangles/frame' % (s['frames'], 1e3*st['total']['mean'], 1e3*st['simulate']['mean'], 1e3*st['select']['mean'], 1e3*st['draw']['mean'], s['counts']['triangles']['mean']))" out/bench/$$n/summary.json; \
	done

bench-peers: $(PEERS_SENTINEL)

# Re-runs only when the package list (this Makefile) changes.
$(PEERS_SENTINEL): Makefile
	@test -x $(PEERS_VENV)/bin/python || $(PYTHON) -m venv $(PEERS_VENV)
	$(PEERS_VENV)/bin/python -m pip install --quiet $(PEERS_PACKAGES)
	@$(PEERS_VENV)/bin/python -c "import panda3d.core, gltf, jupedsim, pedpy; print('peers:', panda3d.core.PandaSystem.getVersionString())"
	@touch $(PEERS_SENTINEL)

corpus: setup
	$(VPY) scripts/corpus.py $(CORPUS_DIRS) --with-generated --md docs/corpus.md

report: setup
	PYTHON=$(VPY) scripts/report_seeds.sh

clean:
	rm -rf out .pytest_cache
