#!/usr/bin/env python3
"""Where one denoiser's error exceeds another's, by spatial scale and by region.

Usage: python3 benches/error_by_scale.py DATA A_DIR B_DIR [--radii 1,2,4,8] [--border 8]
       [--edge-radius 1]
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

By region: the pixels within --edge-radius of a geometric edge (a step of more than 0.3 in the
view's normal between neighbours), of a material edge (more than 0.1 in its albedo), and the
rest. For each, its share of the pixels, its share of A's squared error in excess of B's (sums
over views), and A's MSE ÷ B's there.
"""
import argparse, glob, json, os, sys

import numpy as np
import OpenEXR


def rgb(path, layer=None, names="RGB"):
    """A layer's R, G, B (or the file's own R, G, B; or the channels `names`) as an H×W×3 array."""
    with OpenEXR.File(path, separate_channels=True) as f:
        ch = {k: np.asarray(v.pixels, dtype=np.float64) for p in f.parts for k, v in p.channels.items()}
    prefix = f"{layer}." if layer else ""
    return np.stack([ch[prefix + c] for c in names], axis=-1)


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


def edges(albedo, normal, radius=1):
    """Pixels within `radius` of a step of more than 0.1 in albedo or 0.3 in normal between
    neighbours (H×W×3 arrays; pass zeros to leave one out)."""
    step = np.zeros(albedo.shape[:2], bool)
    for img, t in ((albedo, 0.1), (normal, 0.3)):
        dy, dx = np.abs(np.diff(img, axis=0)).sum(-1) > t, np.abs(np.diff(img, axis=1)).sum(-1) > t
        step[:-1] |= dy
        step[1:] |= dy
        step[:, :-1] |= dx
        step[:, 1:] |= dx
    near = step.copy()
    for oy in range(-radius, radius + 1):
        for ox in range(-radius, radius + 1):
            near |= np.roll(np.roll(step, oy, 0), ox, 1)
    return near


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("data")
    ap.add_argument("a")
    ap.add_argument("b")
    ap.add_argument("--radii", default="1,2,4,8")
    ap.add_argument("--border", type=int, default=8)
    ap.add_argument("--edge-radius", type=int, default=1)
    args = ap.parse_args()
    radii = [0] + [int(r) for r in args.radii.split(",") if int(r) > 0]
    inside = (slice(args.border, -args.border or None),) * 2
    mse = []  # views × radii × (A, B)
    regions = {name: [0.0, 0.0, 0] for name in ("geometric edges", "material edges", "rest", "all")}
    for view in sorted(glob.glob(os.path.join(args.data, "views", "*.exr"))):
        name = os.path.basename(view)
        a_path, b_path = os.path.join(args.a, name), os.path.join(args.b, name)
        if not (os.path.exists(a_path) and os.path.exists(b_path)):
            continue
        ref = display(rgb(view, "reference"))
        errors = [display(rgb(a_path)) - ref, display(rgb(b_path)) - ref]
        mse.append([[np.mean(((box(e, r) if r else e)[inside]) ** 2) for e in errors] for r in radii])
        albedo, normal = rgb(view, "albedo"), rgb(view, "normal", "XYZ")
        geometric = edges(np.zeros_like(albedo), normal, args.edge_radius)[inside]
        material = edges(albedo, np.zeros_like(normal), args.edge_radius)[inside]
        sq = [(e[inside] ** 2).mean(-1) for e in errors]
        rest = ~(geometric | material)
        for name, m in (("geometric edges", geometric), ("material edges", material), ("rest", rest), ("all", np.ones_like(rest))):
            regions[name][0] += sq[0][m].sum()
            regions[name][1] += sq[1][m].sum()
            regions[name][2] += m.sum()
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
    total = regions.pop("all")
    # Geometric and material edges overlap, so their shares may sum past 1; "rest" is neither.
    print(f"\n| region (within {args.edge_radius} px) | share of pixels | share of A's excess over B | A ÷ B MSE |")
    print("|---|---|---|---|")
    by_region = {}
    for name, (a, b, n) in regions.items():
        by_region[name] = {
            "pixel_share": n / total[2],
            "excess_share": (a - b) / (total[0] - total[1]),
            "ratio": a / b,
        }
        print("| {} | {pixel_share:.3f} | {excess_share:.3f} | {ratio:.2f} |".format(name, **by_region[name]))
    print(json.dumps({"views": len(mse), "rows": rows, "regions": by_region}))


if __name__ == "__main__":
    main()
