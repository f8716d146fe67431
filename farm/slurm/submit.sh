#!/bin/bash
# Renders a still on a Slurm cluster: an array job of CHUNKS sample chunks, then a merge job that runs when
# every chunk has succeeded. Prints the two job ids; the merge's is the last line.
#
#   farm/slurm/submit.sh CHUNKS SCENE OUT_DIR [nimbus render flags, e.g. --spp 1024 --width 1920]
#
# OUT_DIR must be on storage every node sees. Environment: NIMBUS (the nimbus binary, default nimbus on the
# PATH), CPUS_PER_TASK (threads per chunk, default 4), PARTITION (default: the cluster's default).
set -euo pipefail
if [ $# -lt 3 ]; then
    echo "usage: $0 CHUNKS SCENE OUT_DIR [nimbus render flags...]" >&2
    exit 2
fi
chunks=$1 scene=$2 out=$3
shift 3
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$out/parts" "$out/logs"
partition=()
if [ -n "${PARTITION:-}" ]; then partition=(--partition "$PARTITION"); fi
render=$(sbatch --parsable "${partition[@]}" --array="0-$((chunks - 1))" \
    --cpus-per-task="${CPUS_PER_TASK:-4}" --output="$out/logs/render-%A_%a.log" \
    "$here/render.sbatch" "$scene" "$out" "$@")
render=${render%%;*}
merge=$(sbatch --parsable "${partition[@]}" --dependency="afterok:$render" \
    --output="$out/logs/merge-%j.log" "$here/merge.sbatch" "$out")
merge=${merge%%;*}
echo "render array job: $render"
echo "merge job: $merge"
