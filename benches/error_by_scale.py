#!/usr/bin/env python3
"""Where one denoiser's error exceeds another's, by spatial scale.

Usage: python3 benches/error_by_scale.py DATA A_DIR B_DIR [--radii 1,2,4,8] [--border 8]
Needs `pip install OpenEXR numpy`.

DATA is a dataset made by `rtd datagen` (its views' `reference` layer is the target); A_DIR and
B_DIR hold one denoised EXR per validation view, named as the view (`rtd bench validation
--save-images A_DIR` writes rtd's; `benches/oidn_compare.py DATA B_DIR` writes OIDN's). Each
image goes through the display transform the validation PSNR uses (clamp to [0, 1], sRGB). The
error image (output − reference) is then box-filtered with radius r (a (2r+1)² mean, edges
repeated), which keeps the error's content at scales of about 2r+1 pixels and above, and the
MSE is taken inside a --border (default 8 px, as `rtd bench validation` crops). For the
unfiltered error and each radius the script prints the mean over views of A's MSE ÷ B's, the
ratio of their sums, and the share of each one's unfiltered MSE that survives the filter. A
ratio that grows with the radius means A's extra error lies more in low frequencies (blotches)
than in fine detail.
"""
import argparse, glob, json, os, sys

import numpy as np
import OpenEXR


def rgb(path, layer=None):
    """A layer's R, G, B (or the file's own R, G, B) as an H×W×3 array."""
    with OpenEXR.File(path, separate_channels=True) as f:
        ch = {k: np.asarray(v.pixels, dtype=np.float64) for p in f.parts for k, v in p.channels.items()}
    prefix = f"{layer}." if layer else ""
    return np.stack([ch[prefix + c] for c in "RGB"], axis=-1)


def display(x):
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def box(e, r):
    """Mean over a (2r+1)² window, edges repeated, by running sums along each axis."""
    for axis in (0, 1):
        pad = [(0, 0)] * e.ndim
        pad[axis] = (r + 1, r)
        c = np.cumsum(np.pad(e, pad, mode="edge"), axis=axis)
        n = e.shape[axis]
        e = (np.take(c, range(2 * r + 1, 2 * r + 1 + n), axis=axis) - np.take(c, range(n), axis=axis)) / (2 * r + 1)
    return e


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("data")
    ap.add_argument("a")
    ap.add_argument("b")
    ap.add_argument("--radii", default="1,2,4,8")
    ap.add_argument("--border", type=int, default=8)
    args = ap.parse_args()
    radii = [0] + [int(r) for r in args.radii.split(",") if int(r) > 0]
    inside = (slice(args.border, -args.border or None),) * 2
    mse = []  # views × radii × (A, B)
    for view in sorted(glob.glob(os.path.join(args.data, "views", "*.exr"))):
        name = os.path.basename(view)
        a_path, b_path = os.path.join(args.a, name), os.path.join(args.b, name)
        if not (os.path.exists(a_path) and os.path.exists(b_path)):
            continue
        ref = display(rgb(view, "reference"))
        errors = [display(rgb(a_path)) - ref, display(rgb(b_path)) - ref]
        mse.append([[np.mean(((box(e, r) if r else e)[inside]) ** 2) for e in errors] for r in radii])
    if not mse:
        sys.exit(f"no view of {args.data} has an output in both {args.a} and {args.b}")
    mse = np.array(mse)
    rows = []
    for i, r in enumerate(radii):
        a, b = mse[:, i, 0], mse[:, i, 1]
        rows.append({
            "radius": r,
            "mean_ratio": float(np.mean(a / b)),
            "sum_ratio": float(a.sum() / b.sum()),
            "a_share": float(a.sum() / mse[:, 0, 0].sum()),
            "b_share": float(b.sum() / mse[:, 0, 1].sum()),
        })
    print(f"{len(mse)} views")
    print("| box radius (px) | A ÷ B, mean of views | A ÷ B, sums | share of A's MSE | share of B's MSE |")
    print("|---|---|---|---|---|")
    for row in rows:
        print("| {radius} | {mean_ratio:.3f} | {sum_ratio:.3f} | {a_share:.3f} | {b_share:.3f} |".format(**row))
    print(json.dumps({"views": len(mse), "rows": rows}))


if __name__ == "__main__":
    main()
