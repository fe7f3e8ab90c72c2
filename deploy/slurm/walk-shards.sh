#!/usr/bin/env bash
# A long walkthrough on a Slurm cluster: one array task per shard of the camera path, then a
# merge that runs once every task has finished.
#
#   sbatch deploy/slurm/walk-shards.sh            # submits the shards; the merge follows
#
# FRAMES, SHARDS, OUT and the walk options below are the knobs; OUT must be on a file system
# every node sees.
#SBATCH --job-name=sightline-walk
#SBATCH --array=0-7
#SBATCH --cpus-per-task=2
#SBATCH --time=01:00:00
#SBATCH --output=sightline-walk-%A_%a.log
set -euo pipefail

SIGHTLINE=${SIGHTLINE:-sightline}
FRAMES=${FRAMES:-2400}
SHARDS=${SHARDS:-8}            # keep equal to the size of --array above
OUT=${OUT:-$PWD/walk}
WALK_OPTS=(--scene city --method all --verify --size 1280x720)

mkdir -p "$OUT/shards"
# The path is written once, by the first task; the others wait for it.
if [[ ! -s "$OUT/path.json" ]]; then
  if [[ "${SLURM_ARRAY_TASK_ID:-0}" == 0 ]]; then
    "$SIGHTLINE" path --kind street --frames "$FRAMES" --out "$OUT/path.json.tmp"
    mv "$OUT/path.json.tmp" "$OUT/path.json"
  else
    while [[ ! -s "$OUT/path.json" ]]; do sleep 2; done
  fi
fi

if [[ -n "${SLURM_ARRAY_TASK_ID:-}" ]]; then
  # One shard: frames [a, b) of the path.
  i=$SLURM_ARRAY_TASK_ID
  per=$(((FRAMES + SHARDS - 1) / SHARDS))
  a=$((i * per))
  b=$((a + per < FRAMES ? a + per : FRAMES))
  if ((a < b)); then
    "$SIGHTLINE" walk "${WALK_OPTS[@]}" --path "$OUT/path.json" --threads "${SLURM_CPUS_PER_TASK:-2}" \
      --frame-range "$a..$b" --out "$OUT/shards/$(printf %04d "$i")"
  fi
  # The first task queues the merge behind the whole array.
  if [[ "$i" == 0 ]]; then
    sbatch --dependency="afterok:${SLURM_ARRAY_JOB_ID}" --job-name=sightline-merge \
      --output="sightline-merge-%j.log" --wrap="'$SIGHTLINE' merge --out '$OUT/merged' '$OUT'/shards/*"
  fi
fi
