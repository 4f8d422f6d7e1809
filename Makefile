# The two README commands: `make demo` and `make test`. Both install missing
# Debian packages, configure and build (Release, -j2) first.
BUILD_DIR ?= build
JOBS ?= 2
DEMO_DIR ?= $(BUILD_DIR)/demo

.PHONY: all deps configure build test demo bench format clean

all: build

deps:
	@bash scripts/install-deps.sh

$(BUILD_DIR)/CMakeCache.txt: | deps
	cmake -S . -B $(BUILD_DIR) -DCMAKE_BUILD_TYPE=Release

configure: deps $(BUILD_DIR)/CMakeCache.txt

build: configure
	cmake --build $(BUILD_DIR) -j $(JOBS)

test: build
	@mkdir -p $(BUILD_DIR)/test-tmp && find $(BUILD_DIR)/test-tmp -mindepth 1 -delete
	cd $(BUILD_DIR) && ctest --output-on-failure -j $(JOBS) --timeout 900

demo: build
	bash scripts/demo.sh $(BUILD_DIR) $(DEMO_DIR)

bench: build
	bash scripts/bench.sh $(BUILD_DIR)

format:
	find apps libs rawlog_tools tests -name '*.cpp' -o -name '*.h' | xargs clang-format -i

clean:
	rm -rf $(BUILD_DIR)
