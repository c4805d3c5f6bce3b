# portal-lights: one Makefile for set-up, the renderer, its tests, the
# harness venv, the figures and the benchmarks. Results are file targets so
# that make redoes only what changed.

SHELL := /bin/bash
ROOT := $(CURDIR)

CC ?= cc
SANITIZE ?= 0
# Jobs for the steps that run in parallel inside `make test` (the C builds,
# the C test programs, pytest -n): CI's limit is 30 minutes on 2 cores.
JOBS ?= $(shell nproc 2>/dev/null || echo 1)
BUILD := renderer/build
ifeq ($(SANITIZE),1)
BUILD := renderer/build-san
SAN_FLAGS := -fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined
endif

# -O3 runs fewer instructions in the render passes than -O2 (bench-ab
# INSTRUCTIONS=1, every case; docs/performance.md) and gives the same
# images bit for bit: it changes no floating-point rule. Without
# -fno-tree-loop-distribution it split camera_row's vectorised loop
# (render/render_pool.c) into four, which then took more instructions.
CFLAGS ?= -O3 -fno-tree-loop-distribution -g
# ISO C mode also means no contraction into fused multiply-adds, which the
# vectorised samplers rely on to match the one-point code bit for bit.
WARN := -std=c99 -Wall -Wextra -Wpedantic -Wshadow
# Nothing reads errno after a libm call: without the flag every sqrt keeps a
# branch to the library for negative arguments (docs/performance.md).
# Nothing reads floating-point exception flags either: without
# -fno-trapping-math GCC will not turn a guarded division into a select,
# and the sampler loops marked `#pragma omp simd` (-fopenmp-simd: the
# pragma only, no OpenMP runtime) would not vectorise.
MATH := -fno-math-errno -fno-trapping-math -fopenmp-simd
CPPFLAGS := -D_POSIX_C_SOURCE=200809L -Irenderer/src -MMD -MP
ALL_CFLAGS := $(WARN) $(MATH) $(CFLAGS) $(SAN_FLAGS) -pthread
# assimp (mesh_file.c): pkg-config --libs assimp gives -lassimp; zlib
# (mesh_serialized.c): -lz.
LDLIBS := -lembree3 -lOpenEXRCore -lyaml -lassimp -lz -lm -pthread

# The renderer's layers, lowest first: a file may include its own layer and
# the ones before it (make lint-c runs tests/check_layers.sh). The list is
# repeated there.
LAYERS := base geometry config scene sampling render cli
SRCS := $(filter-out renderer/src/cli/main.c,$(wildcard $(LAYERS:%=renderer/src/%/*.c)))
OBJS := $(SRCS:renderer/src/%.c=$(BUILD)/obj/%.o)
TEST_SRCS := $(wildcard tests/renderer/test_*.c)
TEST_BINS := $(TEST_SRCS:tests/renderer/%.c=$(BUILD)/tests/%)
# Test support (tests/renderer/*.c that are not tests, e.g. exr_read.c):
# linked into every test.
TEST_SUPPORT_SRCS := $(filter-out $(TEST_SRCS),$(wildcard tests/renderer/*.c))
TEST_SUPPORT_OBJS := $(TEST_SUPPORT_SRCS:tests/renderer/%.c=$(BUILD)/tests/%.o)
# The benchmark programs and the fuzzers' plain replay drivers, built with
# the library's flags by every test-c so that they cannot rot.
BENCH_BINS := $(BUILD)/bench/micro $(BUILD)/bench/raw_embree $(BUILD)/bench/mesh_load
# The firefly diagnostics (tools/firefly): built by every test-c as well.
TOOL_BINS := $(BUILD)/tools/firefly $(BUILD)/tools/replay $(BUILD)/tools/scan
FUZZ_REPLAY := $(BUILD)/fuzz/fuzz_config_replay
FUZZ_CORPUS := configs/scenes tests/configs/good tests/configs/bad $(wildcard tests/configs/fuzz)
FUZZ_MESH_REPLAY := $(BUILD)/fuzz/fuzz_mesh_replay
FUZZ_MESH_CORPUS := tests/configs/meshes tests/configs/bad/meshes $(wildcard tests/configs/fuzz_mesh)
FUZZ_PORTALS_REPLAY := $(BUILD)/fuzz/fuzz_portals_replay
FUZZ_PORTALS_CORPUS := tests/configs/fuzz_portals
# The libFuzzer builds (make fuzz): clang, the config loader's sources only,
# and the mesh loaders' sources only.
FUZZ_CC ?= clang
FUZZ_BUILD := renderer/build-fuzz
FUZZ_SRCS := $(wildcard renderer/src/config/config*.c) renderer/src/base/kinds.c renderer/src/base/json_write.c \
             renderer/src/config/mesh_file.c renderer/src/config/ply_check.c renderer/src/config/mesh_serialized.c \
             renderer/src/base/transform.c \
             renderer/src/config/expr.c renderer/src/geometry/polygon.c renderer/src/base/error.c
FUZZ_MESH_SRCS := renderer/src/config/mesh_file.c renderer/src/config/ply_check.c renderer/src/config/mesh_serialized.c \
                  renderer/src/base/error.c
DEPS_STAMP := renderer/build/.deps-installed
VENV := .venv
VENV_STAMP := $(VENV)/.installed

.SECONDARY:
.PHONY: FORCE all deps venv browser test lint-c format test-c test-c-san test-py lint-py figures bench bench-ab same-images bench-bins fuzz crosscheck clean
.DEFAULT_GOAL := all

all: $(BUILD)/render

# System packages: installed with apt-get when a header is missing.
$(DEPS_STAMP):
	@mkdir -p $(@D)
	@if [ ! -f /usr/include/embree3/rtcore.h ] || [ ! -f /usr/include/OpenEXR/openexr.h ] || \
	    [ ! -f /usr/include/yaml.h ] || [ ! -f /usr/include/assimp/cimport.h ] || [ ! -f /usr/include/zlib.h ] || \
	    ! command -v pkg-config >/dev/null; then \
	  echo "installing libembree-dev libopenexr-dev libyaml-dev libassimp-dev zlib1g-dev with apt-get" >&2; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
	    libembree-dev libopenexr-dev libyaml-dev libassimp-dev zlib1g-dev pkg-config >/dev/null; \
	fi
	@touch $@
deps: $(DEPS_STAMP)

# The C formatter (.clang-format); only the tests need it.
CLANG_FORMAT_STAMP := renderer/build/.clang-format-installed
$(CLANG_FORMAT_STAMP):
	@mkdir -p $(@D)
	@if ! command -v clang-format >/dev/null; then \
	  echo "installing clang-format with apt-get" >&2; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq clang-format >/dev/null; \
	fi
	@touch $@

# Every C file of the project is as clang-format writes it (make format fixes).
C_FORMATTED = $(shell git ls-files '*.c' '*.h' 2>/dev/null || find renderer tests tools -name '*.[ch]')
lint-c: $(CLANG_FORMAT_STAMP)
	@clang-format --dry-run --Werror $(C_FORMATTED)
	@echo "lint-c: $(words $(C_FORMATTED)) C files formatted"
	@tests/check_layers.sh renderer/src
	@tests/check_layers_fails.sh
format: $(CLANG_FORMAT_STAMP)
	clang-format -i $(C_FORMATTED)

# The compiler and its flags, kept in a file that changes only when they
# do (a new default here, or CFLAGS=... given to make): every object
# depends on it, so a build never mixes objects of two flag sets.
FLAGS_STAMP := $(BUILD)/.flags
FLAGS_NOW := $(CC) $(CPPFLAGS) $(ALL_CFLAGS)
$(FLAGS_STAMP): FORCE
	@mkdir -p $(@D)
	@if [ "$$(cat $@ 2>/dev/null)" != '$(FLAGS_NOW)' ]; then echo '$(FLAGS_NOW)' > $@; fi
FORCE:

$(BUILD)/obj/%.o: renderer/src/%.c $(FLAGS_STAMP) | $(DEPS_STAMP)
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) $(ALL_CFLAGS) -c $< -o $@

$(BUILD)/librender.a: $(OBJS)
	@rm -f $@
	ar rcs $@ $^

$(BUILD)/render: $(BUILD)/obj/cli/main.o $(BUILD)/librender.a
	$(CC) $(ALL_CFLAGS) $^ -o $@ $(LDLIBS)

$(BUILD)/tests/%.o: tests/renderer/%.c $(FLAGS_STAMP) | $(DEPS_STAMP)
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) -Itests/renderer $(ALL_CFLAGS) -c $< -o $@

$(BUILD)/tests/%: $(BUILD)/tests/%.o $(TEST_SUPPORT_OBJS) $(BUILD)/librender.a
	$(CC) $(ALL_CFLAGS) $^ -o $@ $(LDLIBS)

$(BUILD)/bench/%.o: renderer/bench/%.c $(FLAGS_STAMP) | $(DEPS_STAMP)
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) $(ALL_CFLAGS) -c $< -o $@

$(BUILD)/bench/%: $(BUILD)/bench/%.o $(BUILD)/librender.a
	$(CC) $(ALL_CFLAGS) $^ -o $@ $(LDLIBS)

bench-bins: $(BENCH_BINS)

$(BUILD)/tools/%.o: tools/firefly/%.c $(FLAGS_STAMP) | $(DEPS_STAMP)
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) $(ALL_CFLAGS) -c $< -o $@

$(BUILD)/tools/%: $(BUILD)/tools/%.o $(BUILD)/librender.a
	$(CC) $(ALL_CFLAGS) $^ -o $@ $(LDLIBS)

$(BUILD)/fuzz/%.o: renderer/fuzz/%.c $(FLAGS_STAMP) | $(DEPS_STAMP)
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) $(ALL_CFLAGS) -c $< -o $@

# Linked from FUZZ_SRCS alone, as the libFuzzer build is, so that make test-c
# notices when that list misses a file the config module needs.
$(FUZZ_REPLAY): $(BUILD)/fuzz/fuzz_config.o $(BUILD)/fuzz/replay.o $(FUZZ_SRCS:renderer/src/%.c=$(BUILD)/obj/%.o)
	$(CC) $(ALL_CFLAGS) $^ -o $@ -lyaml -lassimp -lz -lm -pthread

$(FUZZ_MESH_REPLAY): $(BUILD)/fuzz/fuzz_mesh.o $(BUILD)/fuzz/replay.o $(FUZZ_MESH_SRCS:renderer/src/%.c=$(BUILD)/obj/%.o)
	$(CC) $(ALL_CFLAGS) $^ -o $@ -lassimp -lz -lm -pthread

# The auto portals' target builds whole scenes: the whole library.
$(FUZZ_PORTALS_REPLAY): $(BUILD)/fuzz/fuzz_portals.o $(BUILD)/fuzz/replay.o $(BUILD)/librender.a
	$(CC) $(ALL_CFLAGS) $^ -o $@ $(LDLIBS)

# libFuzzer itself needs clang (renderer/fuzz/run.sh installs it).
FUZZ_FLAGS := -std=c99 -g -O1 -D_POSIX_C_SOURCE=200809L -Irenderer/src \
              -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined
$(FUZZ_BUILD)/fuzz_config: renderer/fuzz/fuzz_config.c $(FUZZ_SRCS) $(wildcard renderer/src/*/*.h)
	@mkdir -p $(@D)
	$(FUZZ_CC) $(FUZZ_FLAGS) $(filter %.c,$^) -o $@ -lyaml -lassimp -lz -lm
$(FUZZ_BUILD)/fuzz_mesh: renderer/fuzz/fuzz_mesh.c $(FUZZ_MESH_SRCS) $(wildcard renderer/src/*/*.h)
	@mkdir -p $(@D)
	$(FUZZ_CC) $(FUZZ_FLAGS) $(filter %.c,$^) -o $@ -lassimp -lz -lm
$(FUZZ_BUILD)/fuzz_portals: renderer/fuzz/fuzz_portals.c $(SRCS) $(wildcard renderer/src/*/*.h)
	@mkdir -p $(@D)
	$(FUZZ_CC) $(FUZZ_FLAGS) $(filter %.c,$^) -o $@ $(LDLIBS)

# C tests: every tests/renderer/test_*.c is its own executable. The runner
# also takes a filter: tests/run_c_tests.sh $(BUILD) PROGRAM [CASE].
# The programs are built JOBS at a time (a sub-make, so that `make test`
# itself still runs its steps one after another).
C_TEST_PROGRAMS = $(BUILD)/render $(TEST_BINS) $(BENCH_BINS) $(TOOL_BINS) $(FUZZ_REPLAY) $(FUZZ_MESH_REPLAY) \
                  $(FUZZ_PORTALS_REPLAY)
test-c:
	@$(MAKE) --no-print-directory -j$(JOBS) $(C_TEST_PROGRAMS)
	@C_TEST_JOBS=$(JOBS) tests/run_c_tests.sh $(BUILD)
	@tests/check_run_c_tests.sh $(BUILD)
	@$(FUZZ_REPLAY) $(FUZZ_CORPUS)
	@$(FUZZ_MESH_REPLAY) $(FUZZ_MESH_CORPUS)
	@$(FUZZ_PORTALS_REPLAY) $(FUZZ_PORTALS_CORPUS)

test-c-san:
	@$(MAKE) --no-print-directory SANITIZE=1 test-c

# Python harness in a local venv.
$(VENV_STAMP): harness/pyproject.toml
	@test -x $(VENV)/bin/python || python3 -m venv $(VENV)
	$(VENV)/bin/pip install -q --upgrade pip
	$(VENV)/bin/pip install -q -e harness[test]
	@touch $@
# The commit-msg hook (.githooks/commit-msg: a subject of at most 72
# characters and a body) is on in every clone that makes the venv.
venv: $(VENV_STAMP)
	@if git rev-parse --git-dir >/dev/null 2>&1; then git config core.hooksPath .githooks; fi

# A real browser for the page tests of the service and the viewer
# (tests/harness/browser.py): Debian's
# chromium and its driver, never a browser downloaded by a tool. The lock
# timeout lets two makes that install packages at once wait for each other.
CHROMIUM_STAMP := renderer/build/.chromium-installed
$(CHROMIUM_STAMP):
	@mkdir -p $(@D)
	@if [ ! -x /usr/bin/chromium ] || [ ! -x /usr/bin/chromedriver ]; then \
	  echo "installing chromium chromium-driver with apt-get" >&2; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get -o DPkg::Lock::Timeout=600 install -y -qq \
	    chromium chromium-driver >/dev/null; \
	fi
	@touch $@
browser: $(CHROMIUM_STAMP)

test-py: $(VENV_STAMP) $(BUILD)/render $(CHROMIUM_STAMP)
	@if [ -d tests/harness ] && ls tests/harness/test_*.py >/dev/null 2>&1; then \
	  $(VENV)/bin/python -m pytest -q -n $(JOBS) --dist loadfile --durations=15 tests/harness tests/bench tests/tools tests/docs; fi

# Linters of every Python file of the project: the harness, its tests, the tools
# and the benchmark scripts (configured in harness/pyproject.toml). ruff and
# mypy --strict cover the same files; mitsuba is not installed in this venv
# (tools/crosscheck runs in .venv-xcheck), so mypy takes its imports as missing.
# A Python file that git tracks outside these folders fails the target.
PY_LINT := harness tests/harness tests/support tests/bench tests/tools tests/docs tests/crosscheck tools/closed_form tools/crosscheck tools/held_out tools/little_lamp tools/sobol tools/white_room renderer/bench tests/configs/meshes \
           tools/service_load
PY_MYPY := harness/portal_harness $(filter-out harness,$(PY_LINT))
SPACE := $(eval) $(eval)
lint-py: $(VENV_STAMP)
	@if git rev-parse --git-dir >/dev/null 2>&1; then \
	  left="$$(git ls-files '*.py' | grep -Ev '^($(subst $(SPACE),|,$(PY_LINT)))/' || true)"; \
	  if [ -n "$$left" ]; then echo "lint-py: Python files outside PY_LINT: $$left" >&2; exit 1; fi; \
	fi
	$(VENV)/bin/ruff check --config harness/pyproject.toml $(PY_LINT)
	$(VENV)/bin/ruff format --check --config harness/pyproject.toml $(PY_LINT)
	$(VENV)/bin/mypy --config-file harness/pyproject.toml $(PY_MYPY)

test: lint-c test-c test-c-san test-py lint-py

# The experiments `make figures` runs, in order: the ratio sweep, its
# variants (both samplers: after it, as they share its references; path
# tracing), the third-party Little Lamp, then the scenes of several lamps
# (the weights share multi_lamp's direct reference), the same scenes with
# automatic portals, and the White Room at night (auto portals, then hand).
# NAME.yaml is the small default, NAME_full.yaml the paper-quality version
# (FULL=1).
# Two passes: a later sweep may extend a reference an earlier one shares
# (the samplers' runs ask more of the ratio sweep's), so every sweep is
# measured again, from stored runs only, before its figures are drawn.
# EXPERIMENTS=NAME... runs only those (e.g. one FULL experiment at a time:
# make figures FULL=1 EXPERIMENTS=lampshade_ratio), in the order given.
# RERUN=1: the FULL experiments' headline points again with other seeds
# (NAME_full_rerun.yaml), on the FULL runs' references: the check of their
# stated precision (portal-harness results-page compares the two).
FIGURE_EXPERIMENTS := lampshade_ratio lampshade_ratio_samplers lampshade_ratio_path little_lamp multi_lamp \
                      multi_lamp_weights auto_portals auto_portals_multi_lamp auto_portals_little_lamp \
                      white_room_night white_room_night_hand
RERUN_EXPERIMENTS := lampshade_ratio white_room_night lampshade_ratio_path multi_lamp little_lamp
EXPERIMENTS ?= $(if $(RERUN),$(RERUN_EXPERIMENTS),$(FIGURE_EXPERIMENTS))
FIGURE_FILE = configs/experiments/$${e}$(if $(FULL)$(RERUN),_full,)$(if $(RERUN),_rerun,).yaml
figures: $(BUILD)/render $(VENV_STAMP)
	@set -e; for e in $(EXPERIMENTS); do \
	  echo "figures: $(FIGURE_FILE)" >&2; \
	  $(VENV)/bin/portal-harness sweep $(FIGURE_FILE); \
	done; \
	for e in $(EXPERIMENTS); do \
	  echo "figures: $(FIGURE_FILE), measured against the final references" >&2; \
	  $(VENV)/bin/portal-harness sweep --no-progress $(FIGURE_FILE); \
	  $(VENV)/bin/portal-harness figures $(FIGURE_FILE); \
	done

# Mitsuba 3 for the bench's `mitsuba` section (renderer/bench/mitsuba_time.py):
# its own venv, the one make crosscheck uses, and LLVM 19 for its llvm_ad_rgb
# variant (Debian 12's LLVM 14 and 15 abort inside Dr.Jit).
XCHECK_BENCH_STAMP := .venv-xcheck/.bench-installed
LIBLLVM := /usr/lib/x86_64-linux-gnu/libLLVM.so.19.1
$(XCHECK_BENCH_STAMP):
	@test -x .venv-xcheck/bin/python || python3 -m venv .venv-xcheck
	@.venv-xcheck/bin/pip install -q mitsuba pytest -e harness
	@touch $@
$(LIBLLVM):
	@echo "installing libllvm19 with apt-get (Mitsuba's llvm_ad_rgb variant)" >&2
	@apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libllvm19 >/dev/null
	@test -f $@ || { echo "bench: libllvm19 did not install $@" >&2; exit 1; }

# perf for the `time_split` section (renderer/bench/time_split.py).
PERF := /usr/bin/perf
$(PERF):
	@echo "installing linux-perf with apt-get (the bench's time_split section)" >&2
	@apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq linux-perf >/dev/null
	@test -x $@ || { echo "bench: linux-perf did not install $@" >&2; exit 1; }

bench: $(BUILD)/render $(BENCH_BINS) $(XCHECK_BENCH_STAMP) $(LIBLLVM) $(PERF)
	@DRJIT_LIBLLVM_PATH="$${DRJIT_LIBLLVM_PATH:-$(LIBLLVM)}" renderer/bench/run.sh $(BUILD)

# Bit-identity of the images against another build, for changes that claim
# to keep behaviour: make same-images BASE=path/to/old/render.
same-images: $(BUILD)/render
	@test -x "$(BASE)" || { echo "same-images: give BASE=path/to/another/render" >&2; exit 2; }
	@python3 renderer/bench/same_images.py $(BASE) $(BUILD)/render $(if $(SPP),--spp $(SPP),)

VALGRIND := /usr/bin/valgrind
# Same-run A/B throughput against another build: make bench-ab BASE=old/render
# (INSTRUCTIONS=1: instructions of the render passes under callgrind instead
# of timings; it installs valgrind with apt-get when missing).
bench-ab: $(BUILD)/render $(if $(INSTRUCTIONS),$(VALGRIND))
	@test -x "$(BASE)" || { echo "bench-ab: give BASE=path/to/another/render" >&2; exit 2; }
	@python3 renderer/bench/ab.py $(BASE) $(BUILD)/render $(if $(ROUNDS),--rounds $(ROUNDS),) \
		$(if $(INSTRUCTIONS),--instructions $(if $(SPP),--spp $(SPP),),)

$(VALGRIND):
	@echo "installing valgrind with apt-get (make bench-ab INSTRUCTIONS=1)" >&2
	@apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq valgrind >/dev/null
	@test -x $@ || { echo "bench-ab: valgrind did not install $@" >&2; exit 1; }

fuzz:
	@JOBS=$(JOBS) renderer/fuzz/run.sh $(or $(FUZZ_SECONDS),60)

# Independent-renderer check against Mitsuba 3 (own venv): the lampshade with
# light sampling, then the lampshade with a third-party mesh from a binary PLY
# (configs/scenes/lampshade_mesh.yaml) with each of CROSSCHECK_STRATEGIES,
# then the lampshade with an 80-triangle sphere as a mesh light
# (tests/configs/good/mesh_light_sphere.yaml) with each of
# CROSSCHECK_MESH_LIGHT_STRATEGIES, then the night White Room at 128x72
# (light and antishadow_exact with its auto portals, antishadow_exact with
# the hand portals); each scene against one set of Mitsuba
# renders. Every run is made; the target fails if any disagrees. About 11
# minutes on 2 busy cores. tools/crosscheck/README.md.
CROSSCHECK_STRATEGIES ?= light portal antishadow antishadow_exact
CROSSCHECK_MESH_LIGHT_STRATEGIES ?= light portal antishadow_exact
CROSSCHECK_OUT := results/tmp/crosscheck
crosscheck: $(BUILD)/render
	@test -x .venv-xcheck/bin/python || python3 -m venv .venv-xcheck
	@.venv-xcheck/bin/pip install -q mitsuba pytest -e harness
	@rc=0; \
	.venv-xcheck/bin/python tools/crosscheck/mitsuba_lampshade.py --renderer $(BUILD)/render || rc=1; \
	for s in $(CROSSCHECK_STRATEGIES); do \
	  .venv-xcheck/bin/python tools/crosscheck/mitsuba_lampshade.py --renderer $(BUILD)/render \
	    --scene configs/scenes/lampshade_mesh.yaml --strategy $$s \
	    --mitsuba-cache $(CROSSCHECK_OUT)/lampshade_mesh/mitsuba.npz \
	    --out $(CROSSCHECK_OUT)/lampshade_mesh/direct_$$s || rc=1; \
	done; \
	for s in $(CROSSCHECK_MESH_LIGHT_STRATEGIES); do \
	  .venv-xcheck/bin/python tools/crosscheck/mitsuba_lampshade.py --renderer $(BUILD)/render \
	    --scene tests/configs/good/mesh_light_sphere.yaml --strategy $$s \
	    --mitsuba-cache $(CROSSCHECK_OUT)/mesh_light_sphere/mitsuba.npz \
	    --out $(CROSSCHECK_OUT)/mesh_light_sphere/direct_$$s || rc=1; \
	done; \
	for v in light:white_room_night antishadow_exact:white_room_night antishadow_exact:white_room_night_hand; do \
	  .venv-xcheck/bin/python tools/crosscheck/mitsuba_lampshade.py --renderer $(BUILD)/render \
	    --scene configs/scenes/$${v#*:}.yaml --strategy $${v%%:*} --set film.width=128 --set film.height=72 \
	    --ours-spp 256 --mitsuba-spp 256 --mitsuba-runs 16 \
	    --mitsuba-cache $(CROSSCHECK_OUT)/white_room/mitsuba_direct.npz \
	    --out $(CROSSCHECK_OUT)/white_room/direct_$${v%%:*}_$${v#*:} || rc=1; \
	done; exit $$rc

clean:
	rm -rf renderer/build renderer/build-san $(FUZZ_BUILD)

-include $(OBJS:.o=.d) $(BUILD)/obj/cli/main.d $(TEST_BINS:=.d) $(TEST_SUPPORT_OBJS:.o=.d) $(BENCH_BINS:=.d) $(TOOL_BINS:=.d) $(BUILD)/fuzz/fuzz_config.d \
  $(BUILD)/fuzz/fuzz_mesh.d $(BUILD)/fuzz/fuzz_portals.d $(BUILD)/fuzz/replay.d

# Kill-loop stress (issue 5): each kill loop of tests/renderer/test_faults.c
# (kills at random moments, inside snapshot and final writes too) run
# STRESS_ITERATIONS times (default 500); every EXR left must open.
.PHONY: stress
stress: $(BUILD)/render $(BUILD)/tests/test_faults
	PORTAL_LIGHTS_KILL_ITERATIONS=$(or $(STRESS_ITERATIONS),500) $(BUILD)/tests/test_faults kill_loop
