#!/usr/bin/env bash
# Coverage-guided fuzzing of every input the library reads (issue 17).
#
#   scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET...]
#
# Builds the targets of fuzz/ with cargo-fuzz on the nightly toolchain
# (libFuzzer; installs cargo-fuzz with `cargo install` when missing) and runs
# each for SECONDS_PER_TARGET (default 60) with an RSS limit of 2 GB and a
# 10 s per-input timeout, starting from fuzz/seeds/<target>/ and the working
# corpus fuzz/corpus/<target>/ (kept between runs, not committed), with the
# target's dictionary from fuzz/dicts/ when there is one.
#
# Every crash, timeout or out-of-memory input libFuzzer writes is minimised
# and copied into fuzz/regressions/<target>/, where tests/fuzz_regressions.rs
# replays it in the normal test suite; the script then exits 1. At the end it
# prints, per target, the executions and the coverage (libFuzzer's `cov`
# edges and `ft` features) from its last status line.
#
# Without a nightly toolchain the script says so and exits 0: fuzzing is an
# extra, never a requirement of the default build.
set -uo pipefail
cd "$(dirname "$0")/.."

SECONDS_PER_TARGET=${1:-60}
shift || true
ALL=(vol nrrd nhdr nifti nifti_gz dicom dicom_series raw tf_json vseq points)
TARGETS=("${@:-${ALL[@]}}")
[ ${#TARGETS[@]} -eq 0 ] && TARGETS=("${ALL[@]}")

if ! cargo +nightly --version >/dev/null 2>&1; then
    echo "fuzz.sh: SKIPPED: no nightly toolchain (rustup toolchain install nightly)"
    exit 0
fi
if ! cargo +nightly fuzz --version >/dev/null 2>&1; then
    echo "fuzz.sh: installing cargo-fuzz from crates.io"
    cargo install cargo-fuzz || { echo "fuzz.sh: SKIPPED: cargo-fuzz did not install"; exit 0; }
fi

# The fuzz crate has its own workspace; start from the main lock file so it
# builds the same dependency versions.
[ -f fuzz/Cargo.lock ] || cp Cargo.lock fuzz/Cargo.lock
echo "== build (cargo +nightly fuzz build -O)"
(cd fuzz && cargo +nightly fuzz build -O) || exit 1

LOGS=fuzz/logs
mkdir -p "$LOGS"
status=0
for t in "${TARGETS[@]}"; do
    mkdir -p "fuzz/corpus/$t" "fuzz/artifacts/$t"
    dict=()
    [ -f "fuzz/dicts/$t.dict" ] && dict=("-dict=dicts/$t.dict")
    echo "== $t: ${SECONDS_PER_TARGET} s"
    (cd fuzz && cargo +nightly fuzz run -O "$t" "corpus/$t" "seeds/$t" -- \
        -max_total_time="$SECONDS_PER_TARGET" -rss_limit_mb=2048 -timeout=10 \
        -max_len=65536 -print_final_stats=1 "${dict[@]}") >"$LOGS/$t.log" 2>&1
    rc=$?
    found=$(ls "fuzz/artifacts/$t" 2>/dev/null | grep -E '^(crash|timeout|oom|leak)-' || true)
    if [ -n "$found" ]; then
        status=1
        mkdir -p "fuzz/regressions/$t"
        for a in $found; do
            min="fuzz/artifacts/$t/min-$a"
            # Bounded: minimising a timeout re-runs inputs that each take up
            # to the 10 s limit, so -runs alone could take hours.
            (cd fuzz && timeout 900 cargo +nightly fuzz tmin -O "$t" "artifacts/$t/$a" -- -runs=2000 \
                -max_total_time=300 -exact_artifact_path="artifacts/$t/min-$a") >/dev/null 2>&1
            [ -s "$min" ] || cp "fuzz/artifacts/$t/$a" "$min"
            cp "$min" "fuzz/regressions/$t/$a"
            mv "fuzz/artifacts/$t/$a" "fuzz/artifacts/$t/done-$a"
            echo "   FOUND $a -> fuzz/regressions/$t/$a (log: $LOGS/$t.log)"
        done
    elif [ $rc -ne 0 ]; then
        status=1
        echo "   libFuzzer exited $rc without an artifact (log: $LOGS/$t.log)"
    fi
done

echo "== summary (target: executions, coverage from the last status line)"
for t in "${TARGETS[@]}"; do
    runs=$(grep -E '^stat::number_of_executed_units' "$LOGS/$t.log" | awk '{print $2}')
    last=$(grep -E '#[0-9]+.*(cov|ft):' "$LOGS/$t.log" | tail -1 | grep -oE 'cov: [0-9]+ ft: [0-9]+ corp: [0-9/]+[a-zA-Z]*' || true)
    echo "$t: ${runs:-?} execs, ${last:-no status line}"
done
exit $status
