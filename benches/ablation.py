#!/usr/bin/env python3
"""Ablation study of the paper's Table 1 on the real models: runs `scanatlas defrag` with each
preset (default, alpha 2.5 and 10, NoRetry, NoBC, NoSB, Random; optionally solver variants),
evaluates every output with the independent evaluator, and prints a table of time, resampled
area, vertex replication, texture size, solidity and charts, with relative changes against the
default run of each model.

Usage:
  benches/ablation.py DATA_DIR [--models meshroom,venus] [--presets default,alpha-2.5,...]
      [--bin target/release/scanatlas] [--evaluate .../evaluate.py] [--python VENV/bin/python]
      [--work /tmp/scanatlas-ablation]

DATA_DIR is the folder of the real models (shared/data/real); nothing is copied from it. The
evaluator needs a Python with numpy and Pillow (`--python`).
"""

import argparse
import json
import os
import subprocess
import sys
import time

MODELS = {
    "meshroom": "meshroom-esp32cam/texturedMesh.obj",
    "venus": "venus-realitycapture/venus.nodraco.gltf",
    "plane": "sketchfab-plane-meal/scene.gltf",
}

# Each preset is the list of extra `defrag` flags (the paper's ablations, Table 1).
PRESETS = {
    "default": [],
    "alpha-2.5": ["--alpha", "2.5"],
    "alpha-10": ["--alpha", "10"],
    "no-retry": ["--no-retry"],
    "no-bc": ["--scorer", "no-benefit-cost"],
    "no-sb": ["--scorer", "no-size-bonus"],
    "random": ["--scorer", "random"],
    "slim": ["--solver", "slim"],
    "slim-arap": ["--solver", "slim,arap"],
}
TABLE1 = ["default", "alpha-2.5", "alpha-10", "no-retry", "no-bc", "no-sb", "random"]


def run(args, model, preset, out_dir):
    src = os.path.join(args.data, MODELS[model])
    out = os.path.join(out_dir, "out.obj")
    report = os.path.join(out_dir, "report.json")
    cmd = [args.bin, "-q", "defrag", src, "-o", out, "--report", report] + PRESETS[preset]
    t = time.time()
    subprocess.run(cmd, check=True)
    wall = time.time() - t
    ev_json = os.path.join(out_dir, "evaluate.json")
    subprocess.run(
        [args.python, args.evaluate, src, out, "--json", ev_json, "--no-color"],
        check=True,
        stdout=subprocess.DEVNULL,
    )
    with open(report) as f:
        rep = json.load(f)
    with open(ev_json) as f:
        ev = json.load(f)
    o, c = ev["output"], ev["comparison"]
    gp = (c.get("grid_preserved") or {}).get("area3d_fraction_of_all_input")
    return {
        "model": model,
        "preset": preset,
        "wall_s": wall,
        "merge_s": rep["times"]["merge_ms"] / 1e3,
        "resampled": None if gp is None else 1.0 - gp,
        "replication": o["vertex_replication"],
        "texels": o["total_texels"],
        "solidity": o["atlas_solidity"],
        "charts": o["charts_edge"],
        "faces_in": ev["input"]["faces"],
        "faces_out": o["faces"],
        "new_flips": c.get("new_flipped_faces"),
        "new_overlap_pairs": (c.get("overlap") or {}).get("new_overlap_face_pairs"),
        "accepted": rep["merge"]["accepted"],
        "attempted": rep["merge"]["attempted"],
    }


def rel(x, base):
    if x is None or base in (None, 0):
        return ""
    return f"({100.0 * (x - base) / base:+.0f}%)"


def table(rows):
    cols = [
        ("time s", "wall_s", "{:.1f}"),
        ("merge s", "merge_s", "{:.1f}"),
        ("resampled", "resampled", "{:.3f}"),
        ("vert repl", "replication", "{:.3f}"),
        ("Mtexels", "texels", "{:.2f}"),
        ("solidity", "solidity", "{:.4f}"),
        ("charts", "charts", "{:d}"),
    ]
    head = f"| model | preset | " + " | ".join(c[0] for c in cols) + " | new flips | new overlaps | merges |"
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    base = {r["model"]: r for r in rows if r["preset"] == "default"}
    for r in rows:
        b = base.get(r["model"], {})
        cells = []
        for _, key, fmt in cols:
            x = r[key]
            if key == "texels" and x is not None:
                x = x / 1e6
            bx = b.get(key)
            if key == "texels" and bx is not None:
                bx = bx / 1e6
            s = "-" if x is None else fmt.format(x)
            if r["preset"] != "default":
                s += " " + rel(x, bx)
            cells.append(s)
        lines.append(
            f"| {r['model']} | {r['preset']} | " + " | ".join(cells)
            + f" | {r['new_flips']} | {r['new_overlap_pairs']} | {r['accepted']}/{r['attempted']} |"
        )
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("data", help="folder of the real models (shared/data/real)")
    ap.add_argument("--models", default="meshroom,venus")
    ap.add_argument("--presets", default=",".join(TABLE1))
    ap.add_argument("--bin", default="target/release/scanatlas")
    ap.add_argument("--evaluate", default=os.path.join(os.path.dirname(__file__), "../../shared/tools/evaluate.py"))
    ap.add_argument("--python", default=sys.executable)
    ap.add_argument("--work", default="/tmp/scanatlas-ablation")
    ap.add_argument("--json", help="also write the rows as JSON to this file")
    args = ap.parse_args()
    rows = []
    for model in args.models.split(","):
        if model not in MODELS:
            sys.exit(f"unknown model {model}; known: {', '.join(MODELS)}")
        for preset in args.presets.split(","):
            if preset not in PRESETS:
                sys.exit(f"unknown preset {preset}; known: {', '.join(PRESETS)}")
            out_dir = os.path.join(args.work, model, preset)
            os.makedirs(out_dir, exist_ok=True)
            print(f"{model} {preset} ...", file=sys.stderr, flush=True)
            rows.append(run(args, model, preset, out_dir))
            if args.json:
                with open(args.json, "w") as f:
                    json.dump(rows, f, indent=1)
    print(table(rows))


if __name__ == "__main__":
    main()
