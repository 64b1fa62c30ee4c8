# Two commands do all the set-up on a fresh machine with Python 3.11+ and make:
#   make run    create .venv, install the pinned runtime (incl. ROS 2 Jazzy wheels), compile
#               the node's kernels into the per-user cache (once), run vibration_node
#   make test   the same, plus the optional extras and test tooling, then the test suite
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
DEV    := $(VENV)/.installed-dev
# ament_index_python finds the message packages (and ours) under the venv prefix.
export AMENT_PREFIX_PATH := $(abspath $(VENV))
# Numba's on-disk cache: not set here, so make and direct runs share the package's per-user
# default, ~/.cache/impact_damper_sim/numba (impact_damper_sim/_cache_dir.py); set it to move it.

SCENE ?= hpotp
NODE_ARGS ?=
PYTEST_ARGS ?=

.PHONY: run test test-slow bench constraints clean validation convergence ros2cli \
        impact-cost docs-tables check-validation check-docs campbell-figures

# runtime only (requirements.txt); the test tooling comes with $(DEV). The editable install
# then becomes an ament package of the venv (tools/ament_develop.py: the ament index marker,
# share/impact_damper_sim/ linked to the checkout, lib/impact_damper_sim/ launchers), so that
# `ros2 run`/`ros2 launch impact_damper_sim ...` find it with AMENT_PREFIX_PATH=.venv.
$(STAMP): requirements.txt constraints.txt setup.py setup.cfg package.xml tools/ament_develop.py
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade 'pip>=23.2'
	$(PY) -m pip install --quiet -r requirements.txt -c constraints.txt
	$(PY) -m pip install --quiet --no-deps --config-settings editable_mode=compat -e .
	$(PY) tools/ament_develop.py
	touch $@

$(DEV): $(STAMP) requirements-dev.txt
	$(PY) -m pip install --quiet -r requirements-dev.txt -c constraints.txt
	touch $@

# the last step of the set-up: the kernels the node calls, compiled into the per-user cache
# once (20-40 s on 2 cores), again only when a kernel source changes, so that the node (make
# run, ros2 run, ros2 launch) starts in about 2 s (tools/precompile_kernels.py)
KERNELS := $(VENV)/.kernels
$(KERNELS): $(STAMP) $(wildcard impact_damper_sim/integrate/kernels/*.py)
	$(PY) tools/precompile_kernels.py
	touch $@

# the package's bytecode, written once ahead of time: where PYTHONDONTWRITEBYTECODE is set
# (CI runners, containers) Python never writes it, and every process that imports the package
# (each node of a plant, each test's subprocess) compiled ~0.4 s of CPU of source at start-up;
# Python still reads bytecode that is there, and recompiles in memory any module edited since
BYTECODE := $(VENV)/.bytecode
$(BYTECODE): $(STAMP) $(wildcard impact_damper_sim/*.py impact_damper_sim/*/*.py \
                                  impact_damper_sim/*/*/*.py)
	$(PY) -m compileall -q impact_damper_sim
	touch $@

# the main job: the live node (Ctrl-C stops it)
run: $(STAMP) $(KERNELS) $(BYTECODE)
	$(VENV)/bin/vibration_node --ros-args --params-file config/vibration_node.yaml \
	    -p scene:=$(SCENE) $(NODE_ARGS)

# the ROS 2 command line and launch (not on PyPI) into the venv: `ros2 run/launch/topic/param/
# service/node/pkg/interface`. From $(ROS2CLI_WHEELS) (pure-Python wheels, offline) when it
# exists, else from the jazzy branches upstream (pip git URLs: needs git and the network)
ROS2CLI_WHEELS ?= ../shared/ros2cli
ROS2CLI := $(VENV)/.installed-ros2cli

$(ROS2CLI): $(STAMP) tools/install_ros2cli.sh
	ROS2CLI_WHEELS='$(ROS2CLI_WHEELS)' bash tools/install_ros2cli.sh $(VENV) -c constraints.txt
	touch $@

ros2cli: $(ROS2CLI)

# with the wheels beside the checkout (as in CI), the tests of the real tools run
# (test/test_ros2_tools.py); without them those tests skip and say why
# make test runs the validation check first (docs/validation.md regenerated and compared, 1.5-3
# min on 2 cores); `make test CHECK_VALIDATION=` skips it for a quick local run
CHECK_VALIDATION ?= check-validation
test: $(DEV) $(KERNELS) $(BYTECODE) $(if $(wildcard $(ROS2CLI_WHEELS)/install.sh),$(ROS2CLI)) $(CHECK_VALIDATION)
	$(PY) -m pytest $(PYTEST_ARGS)

test-slow: $(DEV)
	$(PY) -m pytest -m slow $(PYTEST_ARGS)

# Generated documents (tools/generated_docs.py). Fast ones are regenerated and compared by CI;
# slow ones record their commit, command and a digest of their sources in docs/generated.json,
# and test/test_generated_docs.py fails when those sources change: their code or their scene
# values, not their comments or docstrings (an edit of those needs no accept).

# the paper's results next to ours (docs/validation.md and docs/validation/*.png; the run
# time is in the document's header); OpenBLAS's Haswell kernels on x86-64, so that the chaotic
# impact runs give the same numbers on every CPU (tools/generated_docs.py pinned_numerics_env)
validation: $(DEV)
	$(PY) tools/generated_docs.py validation --write

# regenerate docs/validation.md into a temporary directory and fail on any difference in
# results (dates and wall times aside); make test runs it first
check-validation: $(DEV)
	$(PY) -m pytest -q -m slow test/test_generated_docs.py -k validation

# speed/accuracy trade: docs/convergence.md, docs/convergence/*.{csv,json,png} (slow: the
# wall time of each scene is in the document), recorded in docs/generated.json
convergence: $(DEV)
	$(PY) tools/generated_docs.py make convergence

# the impact-cost curve: docs/impact-cost/cost_curve.{csv,png} (bench/impact_cost.py --curve;
# CPU times: on a quiet machine), recorded in docs/generated.json
impact-cost: $(DEV)
	$(PY) tools/generated_docs.py make impact-cost

# the Campbell figures of docs/rbs-model.md and docs/hpotp-model.md (seconds each); rerun after
# a change to the modal model, the whirl solver or the plot
campbell-figures: $(DEV)
	$(VENV)/bin/study campbell rbs_kcc --speeds 0:10000:101 --plot docs/campbell/rbs_kcc.png --overwrite
	$(VENV)/bin/study campbell hpotp --speeds 0:22918.3:101 --harmonics 1,2 --plot docs/campbell/hpotp.png --overwrite

# tables printed from recorded data: docs/fidelity.md's from docs/fidelity/*.json, the copies
# of docs/validation.md's tables in docs/hpotp-model.md and docs/rbs-model.md, the scene key
# table of docs/scenes.md from the schema
docs-tables: $(DEV)
	$(PY) tools/generated_docs.py tables
	$(PY) tools/generated_docs.py keys

# every check of the generated documents (fast: the slow ones by their digests)
check-docs: check-validation
	$(PY) -m pytest -q test/test_generated_docs.py

# benchmarks print ratios measured in the same run (calibration scripts in bench/ are not run)
BENCHES := bench/sdof_methods.py bench/ivp_baseline.py bench/modal_vs_direct.py \
           bench/realtime_offline.py bench/long_run.py bench/node_realtime.py \
           bench/node_startup.py bench/impact_cost.py bench/node_scenes.py \
           bench/record_throughput.py

bench: $(DEV)
	for b in $(BENCHES); do $(PY) $$b || exit 1; done

# pip freeze less the names that exist only as egg-info inside the ROS wheels (not on PyPI)
constraints: $(DEV)
	( echo '# Full pinned environment (pip freeze of a fresh `make test` venv, Python 3.11, less the'; \
	  echo '# egg-info names inside the ROS wheels). Regenerate with `make constraints`.'; \
	  $(PY) -m pip freeze --all --exclude-editable | $(PY) -c "import sys, importlib.metadata as m; \
	  eggs = {d.metadata['Name'].lower().replace('_', '-') for d in m.distributions() \
	          if str(getattr(d, '_path', '')).endswith('.egg-info')}; \
	  sys.stdout.writelines(l for l in sys.stdin \
	                        if l.split('==')[0].lower().replace('_', '-') not in eggs | {'pip'})" ) > constraints.txt

clean:
	rm -rf $(VENV) build install log
	find impact_damper_sim -name __pycache__ -type d -prune -exec rm -rf {} +
