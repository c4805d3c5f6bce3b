# portal-lights: one Makefile for set-up, the renderer, its tests, the
# harness venv, the figures and the benchmarks. Results are file targets so
# that make redoes only what changed.

SHELL := /bin/bash
ROOT := $(CURDIR)

CC ?= cc
SANITIZE ?= 0
BUILD := renderer/build
ifeq ($(SANITIZE),1)
BUILD := renderer/build-san
SAN_FLAGS := -fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined
endif

CFLAGS ?= -O2 -g
# ISO C mode also means no contraction into fused multiply-adds, which the
# vectorised samplers rely on to match the one-point code bit for bit.
WARN := -std=c99 -Wall -Wextra -Wpedantic -Wshadow
# Nothing reads errno after a libm call: without the flag every sqrt keeps a
# branch to the library for negative arguments (measured: 3% of a render).
# Nothing reads floating-point exception flags either: without
# -fno-trapping-math GCC will not turn a guarded division into a select,
# and the sampler loops marked `#pragma omp simd` (-fopenmp-simd: the
# pragma only, no OpenMP runtime) would not vectorise.
MATH := -fno-math-errno -fno-trapping-math -fopenmp-simd
CPPFLAGS := -D_POSIX_C_SOURCE=200809L -Irenderer/src -MMD -MP
ALL_CFLAGS := $(WARN) $(MATH) $(CFLAGS) $(SAN_FLAGS) -pthread
# assimp (mesh_file.c): pkg-config --libs assimp gives -lassimp.
LDLIBS := -lembree3 -lOpenEXRCore -lyaml -lassimp -lm -pthread

SRCS := $(filter-out renderer/src/main.c,$(wildcard renderer/src/*.c))
OBJS := $(SRCS:renderer/src/%.c=$(BUILD)/obj/%.o)
TEST_SRCS := $(wildcard tests/renderer/test_*.c)
TEST_BINS := $(TEST_SRCS:tests/renderer/%.c=$(BUILD)/tests/%)
DEPS_STAMP := renderer/build/.deps-installed
VENV := .venv
VENV_STAMP := $(VENV)/.installed

.SECONDARY:
.PHONY: all deps venv test test-c test-c-san test-py figures bench bench-ab fuzz crosscheck clean
.DEFAULT_GOAL := all

all: $(BUILD)/render

# System packages: installed with apt-get when a header is missing.
$(DEPS_STAMP):
	@mkdir -p $(@D)
	@if [ ! -f /usr/include/embree3/rtcore.h ] || [ ! -f /usr/include/OpenEXR/openexr.h ] || \
	    [ ! -f /usr/include/yaml.h ] || [ ! -f /usr/include/assimp/cimport.h ] || \
	    ! command -v pkg-config >/dev/null; then \
	  echo "installing libembree-dev libopenexr-dev libyaml-dev libassimp-dev with apt-get" >&2; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
	    libembree-dev libopenexr-dev libyaml-dev libassimp-dev pkg-config >/dev/null; \
	fi
	@touch $@
deps: $(DEPS_STAMP)

$(BUILD)/obj/%.o: renderer/src/%.c | $(DEPS_STAMP)
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) $(ALL_CFLAGS) -c $< -o $@

$(BUILD)/librender.a: $(OBJS)
	@rm -f $@
	ar rcs $@ $^

$(BUILD)/render: $(BUILD)/obj/main.o $(BUILD)/librender.a
	$(CC) $(ALL_CFLAGS) $^ -o $@ $(LDLIBS)

$(BUILD)/tests/%.o: tests/renderer/%.c | $(DEPS_STAMP)
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) -Itests/renderer $(ALL_CFLAGS) -c $< -o $@

$(BUILD)/tests/%: $(BUILD)/tests/%.o $(BUILD)/librender.a
	$(CC) $(ALL_CFLAGS) $^ -o $@ $(LDLIBS)

# C tests: every tests/renderer/test_*.c is its own executable.
test-c: $(BUILD)/render $(TEST_BINS)
	@tests/run_c_tests.sh $(BUILD)

test-c-san:
	@$(MAKE) --no-print-directory SANITIZE=1 test-c

# Python harness in a local venv.
$(VENV_STAMP): harness/pyproject.toml
	@test -x $(VENV)/bin/python || python3 -m venv $(VENV)
	$(VENV)/bin/pip install -q --upgrade pip
	$(VENV)/bin/pip install -q -e harness[test]
	@touch $@
venv: $(VENV_STAMP)

test-py: $(VENV_STAMP) $(BUILD)/render
	@if [ -d tests/harness ] && ls tests/harness/test_*.py >/dev/null 2>&1; then \
	  $(VENV)/bin/python -m pytest -q tests/harness; fi

test: test-c test-c-san test-py

figures: $(BUILD)/render $(VENV_STAMP)
	$(VENV)/bin/portal-harness sweep configs/experiments/lampshade_ratio$(if $(FULL),_full,).yaml
	$(VENV)/bin/portal-harness figures configs/experiments/lampshade_ratio$(if $(FULL),_full,).yaml

bench: $(BUILD)/render
	@renderer/bench/run.sh $(BUILD)

# Same-run A/B throughput against another build: make bench-ab BASE=old/render
bench-ab: $(BUILD)/render
	@test -x "$(BASE)" || { echo "bench-ab: give BASE=path/to/another/render" >&2; exit 2; }
	@python3 renderer/bench/ab.py $(BASE) $(BUILD)/render $(if $(ROUNDS),--rounds $(ROUNDS),)

fuzz:
	@renderer/fuzz/run.sh $(or $(FUZZ_SECONDS),60)

# Independent-renderer check: the lampshade against Mitsuba 3 (own venv).
crosscheck: $(BUILD)/render
	@test -x .venv-xcheck/bin/python || python3 -m venv .venv-xcheck
	@.venv-xcheck/bin/pip install -q mitsuba numpy openexr PyYAML pytest
	.venv-xcheck/bin/python tools/crosscheck/mitsuba_lampshade.py

clean:
	rm -rf renderer/build renderer/build-san

-include $(OBJS:.o=.d) $(BUILD)/obj/main.d $(TEST_BINS:=.d)

# Kill-loop stress (issue 5): each kill loop of tests/renderer/test_faults.c
# (kills at random moments, inside snapshot and final writes too) run
# STRESS_ITERATIONS times (default 500); every EXR left must open.
.PHONY: stress
stress: $(BUILD)/render $(BUILD)/tests/test_faults
	PORTAL_LIGHTS_KILL_ITERATIONS=$(or $(STRESS_ITERATIONS),500) $(BUILD)/tests/test_faults kill_loop
