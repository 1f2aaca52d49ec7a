#!/usr/bin/env python3
"""Where the colour error of grid-preserved faces comes from.

Usage: PYTHON benches/preserved_seams.py EVALUATE_PY INPUT OUTPUT [--samples N] [--seed S]

Runs the evaluator's colour sampling (its own code, loaded from EVALUATE_PY) and takes its samples
on grid-preserved faces. For each one it compares the four output texels bilinear sampling reads
with the input texels under the face's grid map: when all four are equal, the sample is exact.
Otherwise each differing texel is put in a class by what covers its centre in the output:

- uncovered: padding (a ring texel the resampler did not copy);
- preserved, other offset: a grid-preserved face under another grid map;
- resampled, near: a resampled face that reads the input within 2 texels of the point the
  preserved face's grid map gives (an input edge the two faces shared);
- resampled, far: a resampled face that reads the input elsewhere (a seam the merge closed, where
  the input had its chart's border and gutter).

Prints each class's share of the samples and of the squared error, and the PSNR of the exact
samples and of the others. Needs numpy and Pillow.
"""
import collections
import sys

import numpy as np

HOOK = '            col["grid_preserved"] = color_stats(ci[g], co[g])\n'


def evaluator_samples(evaluate_py, argv):
    """Runs the evaluator on argv and returns its colour samples on grid-preserved faces."""
    src = open(evaluate_py).read()
    if HOOK not in src:
        sys.exit(f"{evaluate_py}: the colour sampling changed; update HOOK")
    grab = "            GRAB.update(locals())\n"
    ns = {"__name__": "__main__", "GRAB": {}}
    sys.argv = [evaluate_py] + argv + ["--json", "/dev/null"]
    stdout, sys.stdout = sys.stdout, open("/dev/null", "w")
    try:
        exec(compile(src.replace(HOOK, HOOK + grab), evaluate_py, "exec"), ns)
    except SystemExit:
        pass
    finally:
        sys.stdout = stdout
    return ns, ns["GRAB"]


def barycentric(p, T):
    a, b, c = T[:, 0], T[:, 1], T[:, 2]
    v0, v1, v2 = b - a, c - a, p - a
    d = v0[:, 0] * v1[:, 1] - v0[:, 1] * v1[:, 0]
    with np.errstate(all="ignore"):
        l1 = (v2[:, 0] * v1[:, 1] - v2[:, 1] * v1[:, 0]) / d
        l2 = (v0[:, 0] * v2[:, 1] - v0[:, 1] * v2[:, 0]) / d
        return np.stack([1 - l1 - l2, l1, l2], 1)


def main():
    evaluate_py, argv = sys.argv[1], sys.argv[2:]
    ns, v = evaluator_samples(evaluate_py, argv)
    D4 = ns["D4"]
    Mi, Mo, g, k = v["Mi"], v["Mo"], v["g"], v["k"]
    fi, fo, Tin, Tout, which = v["fi"], v["fo"], v["Tin"], v["Tout"], v["which"]
    err = ((v["ci"] - v["co"]) ** 2).sum(1)[g]
    faces = k[g]
    out_sheet = Mo.sheet[fo]
    classes = collections.Counter()
    sse = collections.Counter()
    exact = np.zeros(len(faces), bool)
    for n, (f, uv) in enumerate(zip(faces, v["uvo"][g])):
        img_o, img_i = Mo.sheets[Mo.sheet[fo[f]]].rgb(), Mi.sheets[Mi.sheet[fi[f]]].rgb()
        (ho, wo), (hi, wi) = img_o.shape[:2], img_i.shape[:2]
        x0 = int(np.floor(np.clip(uv[0] * wo - 0.5, 0, wo - 1)))
        y0 = int(np.floor(np.clip((1 - uv[1]) * ho - 0.5, 0, ho - 1)))
        m = D4[which[f]]
        d = Tout[f, 0] - m @ Tin[f, 0]
        kinds = set()
        for xo, yo in {(min(x0 + a, wo - 1), min(y0 + b, ho - 1)) for a in (0, 1) for b in (0, 1)}:
            po = np.array([xo + 0.5, ho - yo - 0.5])
            pi = m.T @ (po - d)
            xi, yi = int(round(pi[0] - 0.5)), int(round(hi - pi[1] - 0.5))
            inside = 0 <= xi < wi and 0 <= yi < hi
            if inside and np.array_equal(img_i[yi, xi], img_o[yo, xo]):
                continue
            kinds.add(cover_class(po, pi, out_sheet == Mo.sheet[fo[f]], Tout, Tin, which, D4, d, m))
        exact[n] = not kinds
        key = ", ".join(sorted(kinds)) or "exact"
        classes[key] += 1
        sse[key] += err[n]
    total = err.sum()
    print(f"{len(faces)} samples on grid-preserved faces, squared error {total:.0f}")
    print("| footprint | samples | share of squared error |")
    print("|---|--:|--:|")
    for key, count in classes.most_common():
        print(f"| {key} | {count} | {sse[key] / total if total else 0:.4f} |")
    for what, sel in (("exact footprints", exact), ("the others", ~exact)):
        mse = err[sel].mean() / 3 if sel.any() else 0
        db = float("inf") if mse == 0 else 10 * np.log10(255 ** 2 / mse)
        print(f"PSNR over {what} ({sel.sum()} samples): {db:.2f} dB")


def cover_class(po, pi, same_sheet, Tout, Tin, which, D4, d, m):
    """What covers output texel centre `po` (its input point under the grid map is `pi`)."""
    cand = np.flatnonzero(same_sheet)
    b = barycentric(np.broadcast_to(po, (len(cand), 2)), Tout[cand])
    hit = np.flatnonzero((b >= -1e-9).all(1))
    if len(hit) == 0:
        return "uncovered"
    f = cand[hit[0]]
    if which[f] >= 0:
        mf = D4[which[f]]
        same = np.allclose(Tout[f, 0] - mf @ Tin[f, 0], d) and np.array_equal(mf, m)
        return "preserved, same offset" if same else "preserved, other offset"
    src = (b[hit[0]][:, None] * Tin[f]).sum(0)
    return "resampled, near" if np.linalg.norm(src - pi) <= 2.0 else "resampled, far"


if __name__ == "__main__":
    main()
