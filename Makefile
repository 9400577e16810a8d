# Entry points. `make demo` and `make test` work on a fresh Debian 12 machine:
# both install the dependencies first (deploy/install-deps.sh, idempotent).
# `make demo` installs and builds only what the demo runs (the three binaries);
# `make test` adds the test-only packages and builds every suite and benchmark.
BUILD_DIR ?= build
JOBS ?= $(shell nproc)
CMAKE_FLAGS ?=
# A new build directory uses Ninja: it compiles a library's files while the
# libraries it links are still building (Make's generator waits for them),
# which keeps both cores busy in a unity build. An existing build directory
# keeps the generator it was made with.
GENERATOR ?= $(if $(wildcard $(BUILD_DIR)/CMakeCache.txt),,-G Ninja)

.PHONY: deps test-deps configure binaries build demo test bench clean

deps:
	bash deploy/install-deps.sh

test-deps:
	bash deploy/install-deps.sh --test

configure: deps
	cmake -S . -B $(BUILD_DIR) -DCMAKE_BUILD_TYPE=Release $(GENERATOR) $(CMAKE_FLAGS)

# The CLI, the coordinator and the worker, without the suites.
binaries: configure
	cmake --build $(BUILD_DIR) -j $(JOBS) --target totalgrad totalgrad-coordinator totalgrad-worker

build: configure
	cmake --build $(BUILD_DIR) -j $(JOBS)

demo: binaries
	bash deploy/demo.sh $(BUILD_DIR)

test: test-deps build
	ctest --test-dir $(BUILD_DIR) --output-on-failure -j $(JOBS) --timeout 900

clean:
	rm -rf $(BUILD_DIR)
