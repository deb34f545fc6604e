#!/usr/bin/env bash
# Soak test (issue 17): open, render and close volumes of every format in a
# loop through the viewer's loading path and the renderer front, with random
# options, for SECONDS (default 180), then check that RSS and the thread
# count are back at their baseline. See tests/soak.rs.
#
#   scripts/soak.sh [SECONDS]
set -euo pipefail
cd "$(dirname "$0")/.."
SOAK_SECONDS=${1:-180} cargo test --release --test soak -- --ignored --nocapture
