#!/bin/bash
# The summary of a batch (one row per model, totals), run after the array by submit.sh; its
# output file holds the table, and OUT/summary.json the same as JSON.
#SBATCH --job-name=scanatlas-summary
#SBATCH --cpus-per-task=1
#SBATCH --mem=1G
#SBATCH --time=00:10:00
#SBATCH --output=scanatlas-summary-%j.out
set -uo pipefail
: "${SCANATLAS_OUT:?set SCANATLAS_OUT to the output folder of the batch}"
scanatlas="${SCANATLAS:-scanatlas}"
"$scanatlas" batch-summary --json "$SCANATLAS_OUT" >"$SCANATLAS_OUT/summary.json"
exec "$scanatlas" batch-summary "$SCANATLAS_OUT"
