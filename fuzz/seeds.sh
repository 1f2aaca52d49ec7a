#!/usr/bin/env bash
# Writes the seed corpora of every fuzz target into corpus/<target>/ with a scanatlas binary
# (argument 1, default: the workspace's release build): small synthetic scans in every model
# format, their sheets in every image format, a synthetic rig's COLMAP and Bundler files, and
# config files.
set -euo pipefail
cd "$(dirname "$0")"
B=${1:-../target/release/scanatlas}
SEP='@@FILE@@'
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
mkdir -p corpus/{obj,ply,gltf,image,colmap,bundler,config}

"$B" synth "$T/o" --faces 100 --sheet-size 64 --cameras 2 -q
"$B" synth "$T/s" --faces 100 --sheet-size 64 --cameras 1 -q
for m in o s; do
  { cat "$T/$m/scan.obj"; printf '%s' "$SEP"; cat "$T/$m/scan.mtl"; printf '%s' "$SEP"; cat "$T/$m/sheet_0.png"; } > "corpus/obj/$m"
done
# A star polygon and a quad, with relative indices.
printf 'mtllib scan.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 0.2 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0.5 0.2\nusemtl m\nf 1/1 5/5 2/2 3/3 4/4\nf -4/-4 -3/-3 -2/-2 -1/-1\n%snewmtl m\nmap_Kd t.png\n%s' "$SEP" "$SEP" > corpus/obj/poly
cat "$T/s/sheet_0.png" >> corpus/obj/poly

for f in ply gltf glb; do
  "$B" synth "$T/$f" --faces 100 --sheet-size 64 --cameras 1 --format "$f" -q
done
{ cat "$T/ply/scan.ply"; printf '%s' "$SEP"; cat "$T/ply/sheet_0.png"; } > corpus/ply/synth
"$B" convert "$T/o/scan.obj" -o "$T/pa/a.ply" -q 2>/dev/null || true
for p in "$T"/pa/*.ply; do [ -e "$p" ] && cp "$p" corpus/ply/converted; done
cp "$T/glb/scan.glb" corpus/gltf/glb
for g in "$T"/gltf/*.gltf; do
  bin=$(ls "$T"/gltf/*.bin 2>/dev/null | head -1 || true)
  { cat "$g"; printf '%s' "$SEP"; [ -n "$bin" ] && cat "$bin"; printf '%s' "$SEP"; cat "$T/gltf/sheet_0.png" 2>/dev/null || true; } > corpus/gltf/gltf
done

cp "$T/o/sheet_0.png" corpus/image/png
for fmt in jpg tiff exr; do
  "$B" convert "$T/s/scan.obj" -o "$T/c$fmt/c.obj" --texture-format "$fmt" -q
  cp "$T"/c$fmt/c_0.* "corpus/image/$fmt"
done

"$B" synth-rig "$T/rig" --faces 100 --photos 2 --width 16 --height 16 -q
find "$T/rig" -maxdepth 3 | sed "s|$T/rig||" > /dev/null
txt=$(dirname "$(find "$T/rig" -name cameras.txt | head -1)")
bin=$(dirname "$(find "$T/rig" -name cameras.bin | head -1)")
{ printf '\x00'; cat "$txt/cameras.txt"; printf '%s' "$SEP"; cat "$txt/images.txt"; printf '%s' "$SEP"; cat "$txt/points3D.txt" 2>/dev/null || true; } > corpus/colmap/text
{ printf '\x01'; cat "$bin/cameras.bin"; printf '%s' "$SEP"; cat "$bin/images.bin"; printf '%s' "$SEP"; cat "$bin/points3D.bin" 2>/dev/null || true; } > corpus/colmap/binary
bundle=$(find "$T/rig" -name bundle.out | head -1)
# The fuzz target's photo folder holds one photo, p.png: the seed's list names it.
n=$(awk 'NR==2 {print $1}' "$bundle" 2>/dev/null || echo 1)
{ cat "$bundle"; printf '%s' "$SEP"; for _ in $(seq 1 "${n:-1}"); do echo p.png; done; } > corpus/bundler/synth

printf 'time-limit = 30\nalpha = 0.5\nsolver = "slim"\npadding = 2\nmax-sheet-size = "2048"\n' > corpus/config/flat
printf '[solver]\nuse = "slim,arap"\n[solver.slim]\nmax-iterations = 10\n[packer.horizon]\nseed = 3\n' > corpus/config/tables
echo "seeds: $(find corpus -type f | wc -l) files"
