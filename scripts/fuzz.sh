#!/usr/bin/env bash
# Runs each libFuzzer target of a fuzz build for a while (make fuzz).
#   scripts/fuzz.sh BUILD_DIR SECONDS_PER_TARGET [TARGET...]
# New inputs go to BUILD_DIR/fuzz-corpus/<target> (seeded from the committed
# tests/fuzz/corpus/<target>, which is never written); crashes to
# BUILD_DIR/crashes/<target>/. Exit 1 if any target crashed: minimise the
# input (fuzz_<t> -minimize_crash=1 FILE), fix the bug, and commit the input
# under tests/fuzz/regressions/<target>/ (replayed by test_fuzz_corpus).
set -euo pipefail
build=${1:?build dir}
secs=${2:-60}
shift 2 || true
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=(las ros_messages ini)
src=$(cd "$(dirname "$0")/.." && pwd)
failed=0
for t in "${targets[@]}"; do
	bin="$build/fuzz/fuzz_$t"
	work="$build/fuzz-corpus/$t"
	crashes="$build/crashes/$t"
	mkdir -p "$work" "$crashes"
	echo "== fuzz_$t: $secs s"
	if ! "$bin" -max_total_time="$secs" -timeout=10 -rss_limit_mb=2048 \
		-print_final_stats=1 -artifact_prefix="$crashes/" \
		"$work" "$src/tests/fuzz/corpus/$t" 2>"$build/fuzz_$t.log"; then
		echo "fuzz_$t: FAILED, see $build/fuzz_$t.log and $crashes/"
		failed=1
	fi
	grep -E "stat::number_of_executed_units|stat::new_units_added" \
		"$build/fuzz_$t.log" || true
done
exit $failed
