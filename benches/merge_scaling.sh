#!/usr/bin/env bash
# How the merge scales with threads: runs `scanatlas defrag` on each model with --threads 1 and
# with every count given, and prints the merge's work, span and settling (report: merge.timings),
# the speed-up they predict, and the speed-up measured, for the merge and the whole run.
#
# Usage:
#   benches/merge_scaling.sh [options] MODEL ...
#
# MODEL is a path to a model file, or `venus`/`meshroom`/`plane` for the shared real models.
# Options:
#   --bin FILE       the scanatlas binary            (target/release/scanatlas; built if missing)
#   --data DIR       folder of the real models       (../shared/data/real; never copied)
#   --work DIR       scratch folder                  (/tmp/scanatlas-scaling)
#   --threads "N.."  thread counts besides 1         ("2")
#   --repeat K       runs per thread count, alternating; medians reported (1)
#   --out FILE       also write the markdown table to FILE
#   -- ARGS...       extra arguments for `scanatlas defrag` (e.g. --merge-only)
#
# The prediction: a judgement reads two charts and a commit writes two, so on N engines the
# queue takes at least its span S and at least its work W over N; and the master settles every
# operation in queue order itself, so it takes at least the settling time s. The speed-up
# predicted from the one-thread run is W / max(S, s, W / N).
set -euo pipefail

REPO=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd)
DATA=$REPO/../shared/data/real
BIN=$REPO/target/release/scanatlas
WORK=/tmp/scanatlas-scaling
THREADS="2"
REPEAT=1
OUTFILE=
MODELS=()
ARGS=()
while [[ $# -gt 0 ]]; do
    case $1 in
        --bin) BIN=$2; shift 2;;
        --data) DATA=$2; shift 2;;
        --work) WORK=$2; shift 2;;
        --threads) THREADS=$2; shift 2;;
        --repeat) REPEAT=$2; shift 2;;
        --out) OUTFILE=$2; shift 2;;
        --) shift; ARGS=("$@"); break;;
        -h|--help) sed -n '2,22p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; exit 0;;
        -*) echo "unknown option $1" >&2; exit 2;;
        *) MODELS+=("$1"); shift;;
    esac
done
[[ ${#MODELS[@]} -gt 0 ]] || { echo "give at least one model (see --help)" >&2; exit 2; }
[[ -x /usr/bin/time ]] || { echo "needs GNU time at /usr/bin/time (Debian package 'time')" >&2; exit 2; }
[[ -x $BIN ]] || (cd "$REPO" && cargo build --release -p scanatlas-cli)

# shellcheck source=models.sh
source "$REPO/benches/models.sh"

mkdir -p "$WORK"
RUNS=()
for m in "${MODELS[@]}"; do
    IN=$(model_path "$m")
    [[ -f $IN ]] || { echo "model not found: $IN" >&2; exit 2; }
    name=$(basename -- "$(dirname -- "$IN")")-$(basename -- "${IN%.*}")
    for ((k = 1; k <= REPEAT; k++)); do
        for n in 1 $THREADS; do
            D=$WORK/$name/t$n-r$k
            rm -rf "$D"; mkdir -p "$D"
            echo "[merge_scaling] $name --threads $n (run $k of $REPEAT)" >&2
            /usr/bin/time -v -o "$D/time" "$BIN" -q defrag "$IN" -o "$D/out/out.obj" \
                --report "$D/report.json" --threads "$n" "${ARGS[@]}" >"$D/log" 2>&1 ||
                { echo "failed: see $D/log" >&2; exit 1; }
            RUNS+=("$name|$n|$D")
        done
    done
    # The outputs must not depend on the thread count.
    for n in $THREADS; do
        if ! diff -rq "$WORK/$name/t1-r1/out" "$WORK/$name/t$n-r1/out" >/dev/null; then
            echo "[merge_scaling] $name: output with --threads $n differs from --threads 1" >&2
            exit 1
        fi
    done
done

python3 - "$OUTFILE" "${RUNS[@]}" <<'PYEOF'
import json, statistics, sys
from collections import defaultdict

out, runs = sys.argv[1], sys.argv[2:]
by = defaultdict(list)
for r in runs:
    name, n, d = r.split("|")
    rep = json.load(open(f"{d}/report.json"))
    wall = None
    for line in open(f"{d}/time"):
        if "Elapsed (wall clock)" in line:
            parts = [float(x) for x in line.strip().rsplit(" ", 1)[1].split(":")]
            wall = sum(p * 60 ** i for i, p in enumerate(reversed(parts)))
    by[(name, int(n))].append((rep, wall))

med = lambda xs: statistics.median(xs)
lines = ["| model | threads | merge s | whole run s | work s | span s | settle s | work/span | "
         "merge speed-up measured | predicted | whole-run speed-up |",
         "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|"]
for name in sorted({k[0] for k in by}):
    one = by[(name, 1)]
    t = lambda rs, f: med([f(r) for r in rs])
    m1 = t(one, lambda r: r[0]["merge"]["timings"]["total_ms"] / 1e3)
    w1 = t(one, lambda r: r[1])
    work = t(one, lambda r: r[0]["merge"]["timings"]["work_ms"] / 1e3)
    span = t(one, lambda r: r[0]["merge"]["timings"]["span_ms"] / 1e3)
    settle = t(one, lambda r: r[0]["merge"]["timings"]["settle_ms"] / 1e3)
    for n in sorted(k[1] for k in by if k[0] == name):
        rs = by[(name, n)]
        mn = t(rs, lambda r: r[0]["merge"]["timings"]["total_ms"] / 1e3)
        wn = t(rs, lambda r: r[1])
        pred = work / max(span, settle, work / n) if span > 0 else float("nan")
        lines.append(f"| {name} | {n} | {mn:.2f} | {wn:.2f} | {work:.2f} | {span:.2f} | "
                     f"{settle:.2f} | {work / span:.1f} | {m1 / mn:.2f}× | {pred:.2f}× | "
                     f"{w1 / wn:.2f}× |")
text = "\n".join(lines)
print(text)
if out:
    open(out, "w").write(text + "\n")
PYEOF
