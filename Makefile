# The two entry points of the README. Both run the idempotent setup first (Debian packages,
# CMake configure, build), so each works on a fresh machine.
BUILD_DIR ?= build
JOBS ?= $(shell nproc)
SHARED ?= $(abspath ../shared)
DEMO_DIR ?= $(BUILD_DIR)/demo
FFLOC := $(BUILD_DIR)/bin/ffloc

.PHONY: setup build demo test bench clean

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

clean:
	rm -rf $(BUILD_DIR)
