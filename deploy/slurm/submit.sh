#!/bin/bash
# Submits the batch array over SHARDS tasks and the summary job that waits for it.
#
#   SCANATLAS_INPUT=/scans/incoming SCANATLAS_OUT=/scans/atlas SHARDS=8 ./submit.sh
#
# The summary depends on the array with `afterany` by default: `scanatlas batch` exits 1 when a
# model failed, and with `afterok` the summary would then never run, just when it is most
# wanted. DEPENDENCY=afterok runs it only after a fully successful array.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
: "${SCANATLAS_INPUT:?set SCANATLAS_INPUT to a folder of models or a manifest}"
: "${SCANATLAS_OUT:?set SCANATLAS_OUT to the output folder (shared by all tasks)}"
shards=${SHARDS:-4}
dependency=${DEPENDENCY:-afterany}
mkdir -p "$SCANATLAS_OUT"
array=$(sbatch --parsable --export=ALL --array="0-$((shards - 1))" "$here/batch-array.sh")
summary=$(sbatch --parsable --export=ALL --kill-on-invalid-dep=yes \
  --dependency="$dependency:${array%%;*}" "$here/batch-summary.sh")
echo "array job ${array%%;*} ($shards tasks), summary job ${summary%%;*} ($dependency)"
