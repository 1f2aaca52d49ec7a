#!/usr/bin/env bash
# scanatlas defrag against the reference (MeshLab's texture defragmentation through pymeshlab, headless) on the same models: wall time, peak RSS and the evaluator's quality figures side by side, with ratios.
#
# Usage:
#   benches/peer_compare.sh [options] [MODEL ...]
#
# MODEL is a name of the real-model catalogue (venus, meshroom, plane) or a path to a model
# file; default: venus meshroom. Options (defaults relative to the repository):
#   --data DIR      folder of the real models          (../shared/data/real; never copied)
#   --tools DIR     the shared measuring tools          (../shared/tools: peer_defrag.sh, evaluate.py)
#   --bin FILE      the scanatlas binary                (target/release/scanatlas; built if missing)
#   --work DIR      scratch folder for outputs and the evaluator's venv (/tmp/scanatlas-peer)
#   --python PY     interpreter for the evaluator's venv (python3)
#   --out FILE      also write the markdown tables to FILE
#   --repeat N      run both programs N times each, alternating, and report the medians of the
#                   wall and stage times and the largest peak RSS (1; the outputs of the last runs
#                   are evaluated)
#   -- ARGS...      extra arguments for `scanatlas defrag`
#
# Installs what it lacks by itself: the reference (peer_defrag.sh installs xvfb and a venv with
# pymeshlab on first use) and a venv with numpy and Pillow for the evaluator, in --work.
# Both programs run under /usr/bin/time -v (wall clock, and the maximum resident set size of the
# largest process of the tree). Everything runs under `nice -n 19`, one program at a time.
set -euo pipefail

REPO=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd)
DATA=$REPO/../shared/data/real
TOOLS=$REPO/../shared/tools
BIN=$REPO/target/release/scanatlas
WORK=/tmp/scanatlas-peer
PY=python3
OUTFILE=
REPEAT=1
MODELS=()
DEFRAG_ARGS=()

while [[ $# -gt 0 ]]; do
    case $1 in
        --data) DATA=$2; shift 2;;
        --tools) TOOLS=$2; shift 2;;
        --bin) BIN=$2; shift 2;;
        --work) WORK=$2; shift 2;;
        --python) PY=$2; shift 2;;
        --out) OUTFILE=$2; shift 2;;
        --repeat) REPEAT=$2; shift 2;;
        --) shift; DEFRAG_ARGS=("$@"); break;;
        -h|--help) sed -n '3,20p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; exit 0;;
        -*) echo "unknown option $1" >&2; exit 2;;
        *) MODELS+=("$1"); shift;;
    esac
done
[[ ${#MODELS[@]} -gt 0 ]] || MODELS=(venus meshroom)

log() { echo "[peer_compare] $*" >&2; }

# shellcheck source=models.sh
source "$REPO/benches/models.sh"

for t in peer_defrag.sh evaluate.py; do
    [[ -f $TOOLS/$t ]] || { echo "missing $TOOLS/$t (use --tools)" >&2; exit 2; }
done
[[ -x /usr/bin/time ]] || { echo "needs GNU time at /usr/bin/time (Debian package 'time')" >&2; exit 2; }
mkdir -p "$WORK"
WORK=$(cd -- "$WORK" && pwd)

# -- the scanatlas binary --------------------------------------------------------------------
if [[ ! -x $BIN ]]; then
    log "building $BIN"
    (cd "$REPO" && nice -n 19 cargo build --release -p scanatlas-cli)
fi

# -- a venv with numpy and Pillow for the evaluator ------------------------------------------
EVAL_PY=$WORK/venv/bin/python
if ! "$EVAL_PY" -c "import numpy, PIL" >/dev/null 2>&1; then
    log "creating $WORK/venv with numpy and Pillow"
    "$PY" -m venv "$WORK/venv"
    "$EVAL_PY" -m pip install -q --disable-pip-version-check numpy pillow >&2
fi

# -- the reference: install once (a minute or two on first use) ------------------------------
PEER_SETUP_ONLY=1 "$TOOLS/peer_defrag.sh"

# Runs "$@" under /usr/bin/time -v, niced; stdout+stderr to $1.log, time's report to $1.time.
timed() {
    local tag=$1; shift
    nice -n 19 /usr/bin/time -v -o "$tag.time" "$@" >"$tag.log" 2>&1 || {
        log "failed ($?): $* (see $tag.log)"; tail -n 20 "$tag.log" >&2; return 1; }
}

RESULTS=()
for m in "${MODELS[@]}"; do
    IN=$(model_path "$m")
    [[ -f $IN ]] || { echo "model not found: $IN (use --data)" >&2; exit 2; }
    name=$(basename -- "${m%.*}")
    D=$WORK/$name
    rm -rf "$D"; mkdir -p "$D/ref" "$D/ours"

    for ((k = 1; k <= REPEAT; k++)); do
        log "$name: reference (MeshLab through pymeshlab) on $IN (run $k of $REPEAT)"
        timed "$D/ref/run$k" "$TOOLS/peer_defrag.sh" "$IN" "$D/ref/out.obj"
        log "$name: scanatlas defrag (run $k of $REPEAT)"
        timed "$D/ours/run$k" "$BIN" -q defrag "$IN" -o "$D/ours/out.obj" \
            --report "$D/ours/report$k.json" "${DEFRAG_ARGS[@]}"
    done
    for side in ref ours; do
        log "$name: evaluating the $side output"
        nice -n 19 "$EVAL_PY" "$TOOLS/evaluate.py" "$IN" "$D/$side/out.obj" \
            --json "$D/$side/eval.json" >/dev/null 2>"$D/$side/eval.log" ||
            { log "evaluator failed on $D/$side/out.obj"; tail -n 20 "$D/$side/eval.log" >&2; exit 1; }
    done
    RESULTS+=("$name=$D")
done

"$EVAL_PY" - "$OUTFILE" "$REPEAT" "${RESULTS[@]}" <<'PYEOF'
import json, re, statistics, sys

def time_v(path):
    """Wall seconds and peak RSS in bytes from a GNU `time -v` report."""
    wall = rss = None
    for line in open(path):
        line = line.strip()
        if line.startswith("Elapsed (wall clock) time"):
            parts = [float(x) for x in line.rsplit(" ", 1)[1].split(":")]
            wall = sum(p * 60 ** i for i, p in enumerate(reversed(parts)))
        elif line.startswith("Maximum resident set size"):
            rss = int(line.rsplit(" ", 1)[1]) * 1024
    return wall, rss

def peer_stage(path):
    m = re.search(r"defrag_s=([0-9.]+)", open(path).read())
    return float(m.group(1)) if m else None

def figures(d, side):
    e = json.load(open(f"{d}/{side}/eval.json"))
    i, o, c = e["input"], e["output"], e["comparison"]
    runs = range(1, int(sys.argv[2]) + 1)
    timed = [time_v(f"{d}/{side}/run{k}.time") for k in runs]
    walls = [w for w, _ in timed if w is not None]
    wall = statistics.median(walls) if walls else None
    rss = max((r for _, r in timed if r is not None), default=None)
    if side == "ref":
        stages = [peer_stage(f"{d}/ref/run{k}.log") for k in runs]
    else:
        stages = []
        for k in runs:
            t = json.load(open(f"{d}/ours/report{k}.json"))["times"]
            stages.append((t["prepare_ms"] + t["merge_ms"] + t["pack_ms"] + t["textures_ms"]) / 1e3)
    stages = [x for x in stages if x is not None]
    stage = statistics.median(stages) if stages else None
    all_walls[side] = walls
    col = c.get("color") or {}
    fig = {
        "wall time (s)": wall,
        "defrag stage alone (s)": stage,
        "peak RSS (MB)": rss / 1e6 if rss else None,
        "charts": o["charts_edge"],
        "atlas solidity": o["atlas_solidity"],
        "vertex replication": o["vertex_replication"],
        "texels (M)": o["total_texels"] / 1e6,
        "grid-preserved area": (c.get("grid_preserved") or {}).get("area3d_fraction_of_all_input"),
        "PSNR vs input (dB)": (col.get("all") or {}).get("psnr_db"),
        "new flipped faces": c.get("new_flipped_faces"),
        "new overlapping face pairs": (c.get("overlap") or {}).get("new_overlap_face_pairs"),
        "dropped faces": i["faces"] - o["faces"],
    }
    inp = {
        "charts": i["charts_edge"],
        "atlas solidity": i["atlas_solidity"],
        "vertex replication": i["vertex_replication"],
        "texels (M)": i["total_texels"] / 1e6,
    }
    return fig, inp, i["faces"]

def fmt(k, v):
    if v is None:
        return "—"
    if isinstance(v, int):
        return f"{v:,}"
    if k == "grid-preserved area":
        return f"{100 * v:.1f}%"
    if k == "atlas solidity":
        return f"{v:.4f}"
    if k == "vertex replication":
        return f"{v:.3f}"
    return f"{v:.1f}" if abs(v) >= 10 else f"{v:.2f}"

def ratio(a, b):
    if a is None or b is None or a == 0:
        return "—"
    return f"{b / a:.2f}"

out = []
all_walls = {}
for arg in sys.argv[3:]:
    name, d = arg.split("=", 1)
    ref, inp, faces = figures(d, "ref")
    ours, _, _ = figures(d, "ours")
    out.append(f"**{name}** ({faces:,} faces)\n")
    if int(sys.argv[2]) > 1:
        runs = "; ".join(f"{side} " + ", ".join(f"{w:.2f}" for w in all_walls[side]) for side in ("ref", "ours"))
        out.append(f"Wall times of the {sys.argv[2]} runs (s): {runs}. Times below are medians, peak RSS the largest.\n")
    out.append("| figure | input | reference | scanatlas | ratio scanatlas / reference |")
    out.append("|---|--:|--:|--:|--:|")
    for k in ref:
        out.append(f"| {k} | {fmt(k, inp.get(k))} | {fmt(k, ref[k])} | {fmt(k, ours[k])} | {ratio(ref[k], ours[k])} |")
    out.append("")
text = "\n".join(out)
print(text)
if sys.argv[1]:
    open(sys.argv[1], "w").write(text + "\n")
PYEOF
