# The two README commands: `make demo` and `make test`. Both install missing
# Debian packages, configure and build (Release, -j2) first.
BUILD_DIR ?= build
JOBS ?= 2
DEMO_DIR ?= $(BUILD_DIR)/demo

.PHONY: all deps configure build test demo bench format clean test-asan test-tsan fuzz

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

# The test suite under AddressSanitizer + UndefinedBehaviorSanitizer (-O1 -g)
# in its own build folder (doc/reliability.md). ASAN_CTEST_ARGS passes ctest
# options, e.g. ASAN_CTEST_ARGS="-LE sim" to leave the simulator e2e tests out.
ASAN_DIR ?= build-asan
ASAN_CTEST_ARGS ?=
LAUNCHER := $(shell command -v ccache >/dev/null && echo -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
test-asan: deps
	cmake -S . -B $(ASAN_DIR) -DCMAKE_BUILD_TYPE=Release -DFOREST_SLAM_SANITIZE=address $(LAUNCHER)
	cmake --build $(ASAN_DIR) -j $(JOBS)
	cd $(ASAN_DIR) && ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:detect_stack_use_after_return=0 \
	  LSAN_OPTIONS=suppressions=$(CURDIR)/tests/sanitizer/lsan.supp \
	  UBSAN_OPTIONS=print_stacktrace=1:suppressions=$(CURDIR)/tests/sanitizer/ubsan.supp \
	  ctest --output-on-failure -j $(JOBS) --timeout 3600 $(ASAN_CTEST_ARGS)

# ThreadSanitizer (-O1 -g, build-tsan) on the tests whose code runs worker
# threads: SerialWorker (local map, CForestMap inserter, output collector),
# the parallel correspondence search, the loop-closure back-end, the online
# grabber and recorder, and the whole app end to end (doc/reliability.md).
TSAN_DIR ?= build-tsan
TSAN_TESTS ?= test_core test_odometry test_loop test_pipeline test_outputs \
  test_map test_trees test_online test_forest_slam_app
empty :=
space := $(empty) $(empty)
test-tsan: deps
	cmake -S . -B $(TSAN_DIR) -DCMAKE_BUILD_TYPE=Release -DFOREST_SLAM_SANITIZE=thread $(LAUNCHER)
	cmake --build $(TSAN_DIR) -j $(JOBS) --target $(TSAN_TESTS)
	cd $(TSAN_DIR) && TSAN_OPTIONS=halt_on_error=1:second_deadlock_stack=1:suppressions=$(CURDIR)/tests/sanitizer/tsan.supp \
	  ctest --output-on-failure -j $(JOBS) --timeout 3600 -R '^($(subst $(space),|,$(strip $(TSAN_TESTS))))$$'

# libFuzzer on the LAS reader, the ROS message decoders and the INI loader,
# FUZZ_SECONDS each (clang, build-fuzz); crashes land in build-fuzz/crashes.
FUZZ_DIR ?= build-fuzz
FUZZ_SECONDS ?= 60
fuzz: deps
	cmake -S . -B $(FUZZ_DIR) -DCMAKE_BUILD_TYPE=Release -DCMAKE_C_COMPILER=clang \
	  -DCMAKE_CXX_COMPILER=clang++ -DFOREST_SLAM_SANITIZE=fuzzer $(LAUNCHER)
	cmake --build $(FUZZ_DIR) -j $(JOBS) --target fuzz_las fuzz_ros_messages fuzz_ini
	bash scripts/fuzz.sh $(FUZZ_DIR) $(FUZZ_SECONDS)

bench: build
	bash scripts/bench.sh $(BUILD_DIR)

format:
	find apps libs rawlog_tools tests -name '*.cpp' -o -name '*.h' | xargs clang-format -i

clean:
	rm -rf $(BUILD_DIR)
