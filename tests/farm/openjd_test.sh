#!/bin/bash
# Runs the Open Job Description example (farm/openjd/still.template.yaml) locally with the `openjd` CLI
# (PyPI's openjd-cli): its Render step's tasks render sample chunks, its Merge step merges them, and the merged
# EXR and PNG must equal a single-process render byte for byte.
#
#   tests/farm/openjd_test.sh [NIMBUS_BINARY]      (default: $CARGO_TARGET_DIR or target, then debug/nimbus)
#
# It installs nothing: without `openjd` (on the PATH, or named by $OPENJD) it skips with a message, unless
# NIMBUS_REQUIRE_OPENJD=1 (as .ci/run sets, after installing openjd-cli in a virtual environment).
set -euo pipefail
# Reproducible headers (a fixed capDate, no render time), so that merged and single renders compare byte for
# byte: the pixels always do, and with this the whole files do.
export SOURCE_DATE_EPOCH=0

repo=$(cd "$(dirname "$0")/../.." && pwd)
nimbus=${1:-${CARGO_TARGET_DIR:-$repo/target}/debug/nimbus}
openjd=${OPENJD:-$(command -v openjd || true)}
if [ -z "$openjd" ] || [ ! -x "$openjd" ]; then
    if [ "${NIMBUS_REQUIRE_OPENJD:-0}" = 1 ]; then
        echo "openjd test: FAILED: no openjd CLI (pip install openjd-cli) (NIMBUS_REQUIRE_OPENJD=1)" >&2
        exit 1
    fi
    echo "openjd test: SKIP: no openjd CLI (pip install openjd-cli, or set OPENJD)"
    exit 0
fi
[ -x "$nimbus" ] || { echo "openjd test: FAILED: no nimbus binary at $nimbus (cargo build first)" >&2; exit 1; }
bin=$(cd "$(dirname "$nimbus")" && pwd)
nimbus=$bin/$(basename "$nimbus")
openjd=$(cd "$(dirname "$openjd")" && pwd)/$(basename "$openjd")

dir=$(mktemp -d /tmp/nimbus-openjd.XXXXXX)
trap 'rm -rf "$dir"' EXIT
cd "$dir"
start=$(date +%s)
if ! PATH=$bin:$PATH "$openjd" run "$repo/farm/openjd/still.template.yaml" --step Merge --run-dependencies \
    --job-param SceneFile="$repo/assets/cloud.gltf" --job-param OutputDir="$dir/out" \
    --job-param Chunks=3 --job-param Spp=12 --job-param Width=40 --job-param Height=30 \
    --job-param Seed=3 >"$dir/openjd.log" 2>&1; then
    tail -n 40 "$dir/openjd.log" >&2
    echo "openjd test: FAILED: the job did not complete" >&2
    exit 1
fi
"$nimbus" render "$repo/assets/cloud.gltf" --spp 12 --width 40 --height 30 --seed 3 -o single.exr 2>single.log
for file in exr png; do
    if ! cmp "out/shot.$file" "single.$file"; then
        echo "openjd test: FAILED: the merged shot.$file differs from the single-process render" >&2
        exit 1
    fi
done
echo "openjd test: $(ls out/parts | wc -l) chunk tasks and the merge ran in $(($(date +%s) - start)) s; merged EXR and PNG equal the single render byte for byte"
echo "test result: ok. 1 passed; 0 failed; 0 ignored (Open Job Description job, merged bit for bit)"
