#!/bin/bash
# scanatlas batch as a Slurm job array: every task runs `scanatlas batch` on the same input and
# output folder and takes its share of the sorted model list from SLURM_ARRAY_TASK_ID and
# SLURM_ARRAY_TASK_COUNT. Submit it with submit.sh, or directly:
#
#   SCANATLAS_INPUT=/scans/incoming SCANATLAS_OUT=/scans/atlas sbatch --array=0-7 batch-array.sh
#
# The task's threads follow --cpus-per-task (scanatlas reads SLURM_CPUS_PER_TASK, its CPU
# affinity and its cgroup), and its memory budget the cgroup's limit where Slurm sets one.
#SBATCH --job-name=scanatlas-batch
#SBATCH --cpus-per-task=4
#SBATCH --mem=16G
#SBATCH --time=04:00:00
# SIGTERM two minutes before the time limit: the model in progress is stopped, logged
# `interrupted`, and redone by the next run; the ones already done are skipped then.
#SBATCH --signal=B:TERM@120
#SBATCH --output=scanatlas-batch-%A_%a.out
set -euo pipefail
: "${SCANATLAS_INPUT:?set SCANATLAS_INPUT to a folder of models or a manifest}"
: "${SCANATLAS_OUT:?set SCANATLAS_OUT to the output folder (shared by all tasks)}"
# Extra arguments (batch options, then defrag options), split on spaces on purpose.
# shellcheck disable=SC2086
exec "${SCANATLAS:-scanatlas}" batch "$SCANATLAS_INPUT" -o "$SCANATLAS_OUT" ${SCANATLAS_ARGS:-}
