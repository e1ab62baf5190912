#!/usr/bin/env bash
# One shard of a `coif batch` manifest per Slurm array task. Submit with the number of shards
# as the array size (any MIN works; a step such as 0-63:2 does not):
#   sbatch --array=0-63 scripts/slurm-array.sh jobs.jsonl [coif batch options, e.g. --backend cpu]
# Task SLURM_ARRAY_TASK_ID runs shard (ID - SLURM_ARRAY_TASK_MIN) of SLURM_ARRAY_TASK_COUNT:
# the jobs k (from 0, manifest order) with k mod COUNT equal to it. Each task writes
# <manifest>.shard-I-of-N.summary.json; --resume lets a requeued or resubmitted task skip
# the jobs it finished. The task's exit code is coif batch's (0, or the first failing job's).
# COIF=/path/to/coif picks the binary (default: coif on PATH).
#SBATCH --job-name=coif-batch
#SBATCH --cpus-per-task=4
#SBATCH --mem=8G
#SBATCH --time=04:00:00
#SBATCH --output=coif-batch-%A_%a.log
#SBATCH --requeue
set -euo pipefail
manifest=${1:?usage: sbatch --array=0-63 scripts/slurm-array.sh jobs.jsonl [coif batch options]}
shift
: "${SLURM_ARRAY_TASK_ID:?not an array task: submit with sbatch --array=0-N}"
# Headless Vulkan loaders want a valid runtime folder.
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-$(mktemp -d)}"
# Use the CPUs Slurm gave the task, not every CPU of the node.
if [ -n "${SLURM_CPUS_PER_TASK:-}" ]; then
    export RAYON_NUM_THREADS="$SLURM_CPUS_PER_TASK"
fi
exec "${COIF:-coif}" batch "$manifest" --resume "$@"
