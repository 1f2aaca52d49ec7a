#!/usr/bin/env bash
# Two scanatlas binaries on the same synthetic scans of every shape, size, camera count and
# sheet count: the evaluator's figures of each output against its input, side by side.
#
# Usage:
#   benches/synth_sweep.sh OLD_BIN NEW_BIN [WORK_DIR] [EVALUATE_PY] [PYTHON]
#
# WORK_DIR (default /tmp/scanatlas-sweep) receives the scans, the outputs, the evaluator's JSON and
# table.md. EVALUATE_PY defaults to ../shared/tools/evaluate.py next to the repository, PYTHON to
# python3 (it needs numpy and Pillow). Each scan is written by NEW_BIN's `synth`, then both
# binaries run `defrag` with default options on it, one at a time.
set -euo pipefail
REPO=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd)
OLD=$1
NEW=$2
WORK=${3:-/tmp/scanatlas-sweep}
EVAL=${4:-$REPO/../shared/tools/evaluate.py}
PY=${5:-python3}
mkdir -p "$WORK"

# shape faces cameras sheets sheet-size seed [floating specks]
CONFIGS=()
for shape in blob terrain torus multi; do
    CONFIGS+=("$shape 5000 6 1 1024 1" "$shape 20000 12 1 2048 2" "$shape 20000 24 2 1024 3"
        "$shape 60000 32 4 1024 4" "$shape 40000 8 1 4096 5" "$shape 10000 48 3 512 6"
        "$shape 20000 16 2 1024 7 60")
done

for cfg in "${CONFIGS[@]}"; do
    read -r shape faces cams sheets size seed specks <<<"$cfg"
    specks=${specks:-0}
    name="$shape-$faces-c$cams-s$sheets-$size"
    [[ $specks != 0 ]] && name="$name-k$specks"
    dir="$WORK/$name"
    if [[ ! -f "$dir/scan/scan.obj" ]]; then
        "$NEW" -q synth "$dir/scan" --shape "$shape" --faces "$faces" --cameras "$cams" \
            --sheets "$sheets" --sheet-size "$size" --seed "$seed" --specks "$specks"
    fi
    model=$(ls "$dir"/scan/*.obj | head -1)
    for side in old new; do
        bin=$OLD
        [[ $side == new ]] && bin=$NEW
        rm -rf "$dir/$side"
        "$bin" -q defrag "$model" -o "$dir/$side/out.obj" --report "$dir/$side/report.json"
        "$PY" "$EVAL" "$model" "$dir/$side/out.obj" --json "$dir/$side/eval.json" >/dev/null 2>&1
    done
    echo "$name done" >&2
done

"$PY" - "$WORK" <<'PYEOF' | tee "$WORK/table.md"
import json, os, sys
work = sys.argv[1]
rows = []
def fig(e, r):
    c, o, i = e["comparison"], e["output"], e["input"]
    # Specks made point faces on purpose are the only degenerate faces a run may add.
    specks = ((r.get("pack") or {}).get("palette") or {}).get("speck_faces", 0)
    col = c.get("color", {})
    p = lambda k: (col.get(k) or {}).get("psnr_db")
    return dict(charts=o["charts_edge_with_area"], sol=o["atlas_solidity"],
                texels=o["total_texels"] / i["total_texels"], arap=c["distortion_arap"]["mean"],
                grid=c["grid_preserved"]["area3d_fraction"] or 0.0, psnr=p("all"),
                pres=p("grid_preserved"), defects=c["new_flipped_faces"]
                + max(c["new_degenerate_faces"] - specks, 0) + c["overlap"]["new_overlap_face_pairs"],
                specks=specks, sheets=o["texture_sheets"])
print("| scan | charts with area | solidity | texels / input | mean ARAP | grid-preserved | PSNR dB | preserved PSNR dB | new defects | speck faces | sheets |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
tot = {"old": [], "new": []}
for name in sorted(os.listdir(work)):
    d = os.path.join(work, name)
    try:
        a, b = (fig(json.load(open(os.path.join(d, s, "eval.json"))),
                    json.load(open(os.path.join(d, s, "report.json")))) for s in ("old", "new"))
    except (FileNotFoundError, NotADirectoryError):
        continue
    tot["old"].append(a); tot["new"].append(b)
    f = lambda k, fmt: f"{fmt.format(a[k]) if a[k] is not None else '-'} → {fmt.format(b[k]) if b[k] is not None else '-'}"
    print(f"| {name} | {f('charts','{}')} | {f('sol','{:.4f}')} | {f('texels','{:.3f}')} | {f('arap','{:.5f}')} | {f('grid','{:.1%}')} | {f('psnr','{:.2f}')} | {f('pres','{:.2f}')} | {f('defects','{}')} | {f('specks','{}')} | {f('sheets','{}')} |")
n = len(tot["new"])
if n:
    m = lambda s, k: sum(x[k] for x in tot[s] if x[k] is not None) / n
    print(f"| **mean of {n}** | {m('old','charts'):.1f} → {m('new','charts'):.1f} | {m('old','sol'):.4f} → {m('new','sol'):.4f} | {m('old','texels'):.3f} → {m('new','texels'):.3f} | {m('old','arap'):.5f} → {m('new','arap'):.5f} | {m('old','grid'):.1%} → {m('new','grid'):.1%} | {m('old','psnr'):.2f} → {m('new','psnr'):.2f} | | {sum(x['defects'] for x in tot['old'])} → {sum(x['defects'] for x in tot['new'])} | {sum(x['specks'] for x in tot['old'])} → {sum(x['specks'] for x in tot['new'])} | |")
    over = lambda s: sum(1 for x in tot[s] if x["arap"] > 0.025)
    print(f"\nOutputs over the budget g = 0.025: {over('old')} → {over('new')} of {n}.")
PYEOF
