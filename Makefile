# The two entry points of the README. Both run the idempotent setup first (Debian packages,
# CMake configure, build), so each works on a fresh machine.
BUILD_DIR ?= build
JOBS ?= $(shell nproc)
SHARED ?= $(abspath ../shared)
FUZZ_BUILD_DIR ?= build-fuzz
FUZZ_SECONDS ?= 60
DEMO_DIR ?= $(BUILD_DIR)/demo
FFLOC := $(BUILD_DIR)/bin/ffloc

.PHONY: setup build demo test bench fuzz fuzz-seeds clean

setup:
	BUILD_DIR=$(BUILD_DIR) ./scripts/setup.sh

build:
	cmake --build $(BUILD_DIR) -j $(JOBS)

demo: setup
	./scripts/demo.sh $(FFLOC) $(DEMO_DIR) $(SHARED)

test: setup
	cd $(BUILD_DIR) && FFLOC_SHARED_DIR=$(SHARED) ctest --output-on-failure -j $(JOBS)

bench: setup
	./scripts/bench.sh $(BUILD_DIR) $(SHARED)

# Every parser under libFuzzer with ASan and UBSan (clang), FUZZ_SECONDS each, one at a time;
# prints executions, coverage and findings per target. docs/fuzzing.md.
fuzz:
	./fuzz/run_fuzzers.sh --build-dir $(FUZZ_BUILD_DIR) --seconds $(FUZZ_SECONDS) $(FUZZ_TARGETS)

# Writes the seed corpora in fuzz/corpus/ again from our own writers.
fuzz-seeds:
	./fuzz/run_fuzzers.sh --build-dir $(FUZZ_BUILD_DIR) --write-seeds

clean:
	rm -rf $(BUILD_DIR)
