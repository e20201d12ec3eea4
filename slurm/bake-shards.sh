#!/usr/bin/env bash
# Submits a sharded bake to Slurm: an array job with one `prt-gpu bake … --shard I/N` per task,
# then a merge job that starts once every shard has succeeded (afterok). Each shard writes its
# part atomically, so the merge never reads a half-written one; a shard that failed is rerun
# alone with SHARDS=I (the merge is submitted again behind it).
#
#   usage: slurm/bake-shards.sh N OUTPUT.glb [MESH] [bake options...]
#   e.g.   slurm/bake-shards.sh 16 city.prt.glb city.glb --mode interreflected --bands 4
#
# Environment:
#   PRT_GPU      the prt-gpu binary the jobs run (default: prt-gpu on PATH)
#   PARTS_DIR    where parts and logs go (default: OUTPUT.parts); on a filesystem every node sees
#   SHARDS       which shards to submit, as sbatch's --array takes them (default: 0-(N-1))
#   SBATCH_ARGS  more sbatch options for both jobs, e.g. "--partition=gpu --gres=gpu:1"
# Prints the array job's id and the merge job's id.
set -euo pipefail

if [ $# -lt 2 ] || ! [[ $1 =~ ^[1-9][0-9]*$ ]]; then
    echo "usage: $0 N OUTPUT.glb [MESH] [bake options...]" >&2
    exit 2
fi
count=$1
output=$2
shift 2
here=$(cd "$(dirname "$0")" && pwd)
parts=${PARTS_DIR:-$output.parts}
mkdir -p "$parts/logs"
read -r -a extra <<<"${SBATCH_ARGS:-}"

array=$(sbatch --parsable "${extra[@]}" --array="${SHARDS:-0-$((count - 1))}" \
    --job-name=prt-gpu-shard --output="$parts/logs/shard-%a.out" \
    "$here/shard.sbatch" "$count" "$parts" "$@")
array=${array%%;*}
merge=$(sbatch --parsable "${extra[@]}" --dependency="afterok:$array" \
    --job-name=prt-gpu-merge --output="$parts/logs/merge.out" \
    "$here/merge.sbatch" "$count" "$parts" "$output")
echo "$array ${merge%%;*}"
