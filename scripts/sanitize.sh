#!/usr/bin/env bash
# The tests that exercise `unsafe` code under a memory checker (issue 17).
#
#   scripts/sanitize.sh [asan|memcheck|all]     (default: all)
#
# What has `unsafe`: the sample storage (a raw pointer into a Vec or a file
# map, madvise), the SIMD intrinsics and unchecked lane loads (simd.rs,
# volume/, transfer.rs, accel/skip.rs), the object renderer's shared film,
# and vol_gen's libc calls (fallocate, signals, positioned writes). The test
# binaries below cover each of them (the unit tests of `raycaster` and
# `vol_gen`, which test every intrinsic against its portable twin, and the
# end-to-end suites that render through every renderer, layout and ISA).
#
# asan:     AddressSanitizer (`-Zsanitizer=address`, nightly), its own
#           target directory (target/asan); skipped without nightly.
# memcheck: valgrind memcheck on the ordinary release test binaries (no
#           second build); skipped without valgrind.
#
# Exit status 1 when any checker reports an error.
set -uo pipefail
cd "$(dirname "$0")/.."
MODE=${1:-all}
status=0

# The end-to-end suites that reach the unsafe code (every renderer, layout,
# sample type and ISA; mapped files; hostile inputs).
SUITES=(parallel_renderers render_skipping render_iso_exact vol_format hostile_inputs fuzz_regressions)

run_asan() {
    if ! cargo +nightly --version >/dev/null 2>&1; then
        echo "asan: SKIPPED (no nightly toolchain)"
        return
    fi
    local host
    host=$(rustc -vV | sed -n 's/^host: //p')
    local tests=()
    for s in "${SUITES[@]}"; do tests+=(--test "$s"); done
    echo "== asan: raycaster and vol_gen unit tests, vol_gen CLI tests, ${SUITES[*]}"
    # detect_leaks=0: the test harness's threads and rayon's pool live to
    # the end of the process on purpose.
    export ASAN_OPTIONS=detect_leaks=0:abort_on_error=0
    export RUSTFLAGS="-Zsanitizer=address -Cforce-frame-pointers=yes"
    export RUSTDOCFLAGS="-Zsanitizer=address"
    local common=(+nightly test --release --target "$host" --target-dir target/asan)
    cargo "${common[@]}" -p raycaster --lib || status=1
    cargo "${common[@]}" -p vol_gen || status=1
    cargo "${common[@]}" -p raycaster-suite "${tests[@]}" || status=1
    unset RUSTFLAGS RUSTDOCFLAGS
}

run_memcheck() {
    if ! command -v valgrind >/dev/null; then
        echo "memcheck: SKIPPED (no valgrind: apt-get install valgrind)"
        return
    fi
    echo "== memcheck: building the release test binaries"
    local tests=()
    for s in "${SUITES[@]}"; do tests+=(--test "$s"); done
    local bins
    bins=$( (cargo test --release --no-run --message-format=json -p raycaster --lib;
             cargo test --release --no-run --message-format=json -p raycaster-suite "${tests[@]}") \
        | grep -o '"executable":"[^"]*"' | cut -d'"' -f4)
    for b in $bins; do
        echo "== memcheck: $(basename "$b")"
        # The SIMD paths are chosen at run time; valgrind runs the AVX2 ones.
        # valgrind runs one thread at a time, so a test that cancels a frame
        # from another thread after 10 % of its time cannot work under it.
        if ! valgrind --quiet --error-exitcode=99 --leak-check=no "$b" --test-threads=2 -q \
            --skip cancellation_stops_a_frame_in_progress \
            >"target/memcheck-$(basename "$b").log" 2>&1; then
            status=1
            echo "   errors or failures: target/memcheck-$(basename "$b").log"
            grep -E "^==[0-9]+== (Invalid|Conditional|Use of|Mismatched|Source and)" \
                "target/memcheck-$(basename "$b").log" | sort | uniq -c | head
        else
            echo "   clean"
        fi
    done
}

case "$MODE" in
    asan) run_asan ;;
    memcheck) run_memcheck ;;
    all) run_memcheck; run_asan ;;
    *) echo "usage: scripts/sanitize.sh [asan|memcheck|all]"; exit 2 ;;
esac
[ $status -eq 0 ] && echo "sanitize: clean" || echo "sanitize: REPORTS (see above)"
exit $status
