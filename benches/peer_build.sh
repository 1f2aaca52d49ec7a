#!/usr/bin/env bash
# scanatlas build against MeshLab's "parameterization + texturing from registered rasters" on the same synthetic captures: wall time, peak RSS and `scanatlas rig-score`'s figures (PSNR against the true colour, seam jump, texel density, UV defects) side by side, with ratios.
#
# Usage:
#   benches/peer_build.sh [options] [SHAPE ...]
#
# SHAPE is blob, terrain, torus or multi (default: blob terrain torus). For every shape and every
# photo count, `scanatlas synth-rig` writes a capture (undistorted photos, --k1 0, since the
# MeshLab project cannot carry COLMAP's lens model), `scanatlas build` textures it from the COLMAP
# cameras, peer_raster_texture.sh textures it from rig.mlp, and `scanatlas rig-score` measures
# every output with the same code. Options (defaults in brackets):
#   --photos "K ..."   photo counts                                 ["12 64"]
#   --faces N          faces of the synthetic mesh                  [20000]
#   --width W --height H   photo size                               [1024 768]
#   --sizes "S ..."    MeshLab texture sides: numbers, or `match` = the square whose area is
#                      scanatlas' texel count (rounded up to 64)    ["2048 match"]
#   --tools DIR        the shared measuring tools                   [../shared/tools]
#   --bin FILE         the scanatlas binary                         [target/release/scanatlas; built if missing]
#   --work DIR         scratch folder                               [/tmp/scanatlas-peer-build]
#   --out FILE         also write the markdown tables to FILE
#   -- ARGS...         extra arguments for `scanatlas build`
#
# Installs what it lacks by itself (peer_raster_texture.sh installs xvfb and a venv with pymeshlab
# on first use). Every program runs under /usr/bin/time -v (wall clock, and the maximum resident
# set size of the largest process of the tree) and `nice -n 10`, one program at a time.
set -euo pipefail

REPO=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd)
TOOLS=$REPO/../shared/tools
BIN=$REPO/target/release/scanatlas
WORK=/tmp/scanatlas-peer-build
OUTFILE=
PHOTOS="12 64"
FACES=20000
WIDTH=1024
HEIGHT=768
SIZES="2048 match"
SHAPES=()
BUILD_ARGS=()

while [[ $# -gt 0 ]]; do
    case $1 in
        --photos) PHOTOS=$2; shift 2;;
        --faces) FACES=$2; shift 2;;
        --width) WIDTH=$2; shift 2;;
        --height) HEIGHT=$2; shift 2;;
        --sizes) SIZES=$2; shift 2;;
        --tools) TOOLS=$2; shift 2;;
        --bin) BIN=$2; shift 2;;
        --work) WORK=$2; shift 2;;
        --out) OUTFILE=$2; shift 2;;
        --) shift; BUILD_ARGS=("$@"); break;;
        -h|--help) sed -n '3,26p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; exit 0;;
        -*) echo "unknown option $1" >&2; exit 2;;
        *) SHAPES+=("$1"); shift;;
    esac
done
[[ ${#SHAPES[@]} -gt 0 ]] || SHAPES=(blob terrain torus)

log() { echo "[peer_build] $*" >&2; }

[[ -f $TOOLS/peer_raster_texture.sh ]] || { echo "missing $TOOLS/peer_raster_texture.sh (use --tools)" >&2; exit 2; }
[[ -x /usr/bin/time ]] || { echo "needs GNU time at /usr/bin/time (Debian package 'time')" >&2; exit 2; }
command -v python3 >/dev/null || { echo "needs python3 (standard library only) for the tables" >&2; exit 2; }
mkdir -p "$WORK"
WORK=$(cd -- "$WORK" && pwd)

# -- the scanatlas binary --------------------------------------------------------------------
if [[ ! -x $BIN ]]; then
    log "building $BIN"
    (cd "$REPO" && nice -n 10 cargo build --release -p scanatlas-cli)
fi

# Runs "$@" under /usr/bin/time -v, niced; stdout+stderr to $1.log, time's report to $1.time.
timed() {
    local tag=$1; shift
    nice -n 10 /usr/bin/time -v -o "$tag.time" "$@" >"$tag.log" 2>&1 || {
        log "failed ($?): $* (see $tag.log)"; tail -n 20 "$tag.log" >&2; return 1; }
}

RESULTS=()
for shape in "${SHAPES[@]}"; do
    for k in $PHOTOS; do
        name=$shape-$k
        D=$WORK/$name
        rm -rf "$D"; mkdir -p "$D/ours"
        log "$name: synth-rig ($FACES faces, $k photos of ${WIDTH}x$HEIGHT)"
        nice -n 10 "$BIN" -q synth-rig "$D/rig" --shape "$shape" --faces "$FACES" --photos "$k" \
            --width "$WIDTH" --height "$HEIGHT" --k1 0
        log "$name: scanatlas build"
        timed "$D/ours/run" "$BIN" -q build --mesh "$D/rig/mesh.obj" --cameras "$D/rig/sparse" \
            --images "$D/rig/images" -o "$D/ours/out.obj" --report "$D/ours/report.json" \
            "${BUILD_ARGS[@]}"
        nice -n 10 "$BIN" -q rig-score --rig "$D/rig" "$D/ours/out.obj" --json >"$D/ours/score.json"
        ours_texels=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['texels'])" "$D/ours/score.json")
        sides=(ours)
        for s in $SIZES; do
            if [[ $s == match ]]; then
                s=$(python3 -c "import math,sys; print(max(64, 64 * math.ceil(math.sqrt(int(sys.argv[1])) / 64)))" "$ours_texels")
            fi
            side=meshlab-$s
            [[ -d $D/$side ]] && continue
            mkdir -p "$D/$side"
            log "$name: MeshLab raster texturing, one ${s}x$s texture"
            timed "$D/$side/run" "$TOOLS/peer_raster_texture.sh" "$D/rig/rig.mlp" "$D/$side/out.obj" "$s"
            nice -n 10 "$BIN" -q rig-score --rig "$D/rig" "$D/$side/out.obj" --json >"$D/$side/score.json"
            sides+=("$side")
        done
        RESULTS+=("$name=$D=$(IFS=,; echo "${sides[*]}")")
    done
done

python3 - "$OUTFILE" "$FACES" "$WIDTH" "$HEIGHT" "${RESULTS[@]}" <<'PYEOF'
import json, sys

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

def figures(d, side):
    s = json.load(open(f"{d}/{side}/score.json"))
    wall, rss = time_v(f"{d}/{side}/run.time")
    return {
        "wall time (s)": wall,
        "peak RSS (MB)": rss / 1e6 if rss else None,
        "PSNR vs true colour (dB)": s["psnr_db"],
        "seam colour jump (0-255)": s["seam_jump"],
        "  the true colour's own step there": s["seam_jump_true"],
        "  seam excess (texture step − true step)": s["seam_jump_excess"],
        "  the same measure inside charts": s["interior_jump"],
        "texel density (median; 1 = photos')": s["texel_density"],
        "texel density p10 / p90": (s["texel_density_p10"], s["texel_density_p90"]),
        "flipped UV faces": s["uv_flipped_faces"],
        "overlapping face pairs": s["overlap_face_pairs"],
        "dropped faces": s["faces_dropped"],
        "zero-area UV faces (unseen)": s["zero_area_uv_faces"],
        "charts": s["charts"],
        "texels (M)": s["texels"] / 1e6,
    }

def fmt(v):
    if v is None:
        return "—"
    if isinstance(v, tuple):
        return " / ".join(fmt(x) for x in v)
    if isinstance(v, int):
        return f"{v:,}"
    return f"{v:.1f}" if abs(v) >= 100 else f"{v:.2f}" if abs(v) >= 1 else f"{v:.3f}"

def ratio(a, b):
    if a is None or b is None or isinstance(a, tuple) or a == 0:
        return "—"
    return f"{b / a:.2f}"

outfile, faces, w, h = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4]
out = []
for arg in sys.argv[5:]:
    name, d, sides = arg.split("=", 2)
    sides = sides.split(",")
    figs = {s: figures(d, s) for s in sides}
    peers = [s for s in sides if s != "ours"]
    shape, k = name.rsplit("-", 1)
    out.append(f"**{shape}**, {faces:,} faces, {k} photos of {w}×{h}\n")
    head = "| figure | " + " | ".join(f"MeshLab {p.split('-')[1]}²" for p in peers) + " | scanatlas | " + \
        " | ".join(f"ratio vs MeshLab {p.split('-')[1]}²" for p in peers) + " |"
    out.append(head)
    out.append("|---|" + "--:|" * (2 * len(peers) + 1))
    for key in figs["ours"]:
        row = [fmt(figs[p][key]) for p in peers] + [fmt(figs["ours"][key])]
        row += [ratio(figs[p][key], figs["ours"][key]) for p in peers]
        out.append(f"| {key} | " + " | ".join(row) + " |")
    out.append("")
text = "\n".join(out)
print(text)
if outfile:
    open(outfile, "w").write(text + "\n")
PYEOF
