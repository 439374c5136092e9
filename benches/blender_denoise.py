#!/usr/bin/env python3
"""Blender's own EXR through `rtd denoise`, against Intel OIDN on the same file.

Usage: python3 benches/blender_denoise.py OUT_DIR [--rtd target/release/rtd] [--spp 16]
       [--reference-spp 2048] [--size 320x180] [--figure PNG]
Needs `pip install bpy==5.0.1 OpenEXR pyoidn` (and pillow for --figure).

Cycles renders the room of benches/blender_roundtrip.py (all four lights) at --spp with its
denoising data passes, written as Blender writes them: one multi-layer EXR with
`ViewLayer.Combined`, `ViewLayer.Denoising Albedo`, `ViewLayer.Denoising Normal` (half floats,
Blender's default depth). Then:
  rtd denoise --color r.exr --albedo r.exr --normal r.exr -o rtd.exr
and OIDN (balanced, HDR) on the same colour, albedo and normal. Both are scored against a
--reference-spp Cycles render with rtd's metric: PSNR after clamping to [0,1] and sRGB encoding.
Where rtd's error exceeds OIDN's is split between detail (pixels within 2 px of an albedo or
normal edge) and the flat rest; --figure writes the images and both errors side by side.
"""
import argparse, json, os, subprocess, sys, time

import numpy as np
import OpenEXR
import pyoidn

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import blender_roundtrip as rt  # noqa: E402
from error_by_scale import display as srgb, edges  # noqa: E402
import bpy  # noqa: E402


def channels(path):
    """Every channel of every part (Blender writes one part per pass)."""
    with OpenEXR.File(path, separate_channels=True) as f:
        return {k: np.asarray(v.pixels, dtype=np.float32) for p in f.parts for k, v in p.channels.items()}


def rgb(ch, prefix, names="RGB"):
    return np.stack([ch[f"{prefix}.{n}"] for n in names], axis=-1).astype(np.float32)


def psnr(a, b):
    mse = np.mean((srgb(a) - srgb(b)) ** 2)
    return float(10 * np.log10(1.0 / mse))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--rtd", default="target/release/rtd")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--reference-spp", type=int, default=2048)
    ap.add_argument("--size", default="320x180")
    ap.add_argument("--figure", help="write reference, rtd, OIDN, albedo and both errors to this PNG")
    args = ap.parse_args()
    w, h = map(int, args.size.split("x"))
    os.makedirs(args.out, exist_ok=True)
    out = os.path.abspath(args.out)
    sc = rt.build({"point", "spot", "sun", "emissive"})
    sc.view_layers[0].cycles.denoising_store_passes = True
    ref = os.path.join(out, "reference.exr")
    if not os.path.exists(ref):
        rt.render_cycles(sc, w, h, args.reference_spp, ref)
    noisy = os.path.join(out, "cycles.exr")
    rt.render_cycles(sc, w, h, args.spp, os.path.join(out, "beauty.exr"))
    # Blender's multi-layer EXR at its default half-float depth.
    sc.render.image_settings.media_type = "MULTI_LAYER_IMAGE"  # Blender 5's multi-layer EXR
    sc.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
    sc.render.image_settings.color_depth = "16"
    sc.render.filepath = noisy
    bpy.ops.render.render(write_still=True)
    ch = channels(noisy)
    layers = sorted({k.rsplit(".", 1)[0] for k in ch})
    color = rgb(ch, "ViewLayer.Combined")
    albedo = rgb(ch, "ViewLayer.Denoising Albedo")
    normal = rgb(ch, "ViewLayer.Denoising Normal", "XYZ")
    reference = rt.read_exr_rgb(ref).astype(np.float32)
    rtd_out = os.path.join(out, "rtd.exr")
    t = time.time()
    subprocess.run([args.rtd, "denoise", "--color", noisy, "--albedo", noisy, "--normal", noisy, "-o", rtd_out],
                   check=True)
    rtd_s = time.time() - t
    rtd_img = rgb(channels(rtd_out), "ViewLayer.Combined")
    t = time.time()
    oidn_img = np.asarray(pyoidn.denoise(color, albedo, normal, hdr=True, quality="balanced"), dtype=np.float32)
    oidn_s = time.time() - t
    row = {"layers_in_file": layers, "spp": args.spp, "reference_spp": args.reference_spp, "size": [w, h],
           "psnr_noisy": psnr(color, reference), "psnr_rtd": psnr(rtd_img, reference),
           "psnr_oidn_balanced": psnr(oidn_img, reference), "rtd_s": rtd_s, "oidn_s": oidn_s}
    row["rtd_minus_oidn_db"] = row["psnr_rtd"] - row["psnr_oidn_balanced"]
    row.update(excess_by_region(rtd_img, oidn_img, reference, albedo, normal))
    if args.figure:
        figure(args.figure, [reference, rtd_img, oidn_img, albedo], reference,
               ["reference", f"rtd {row['psnr_rtd']:.2f} dB", f"OIDN balanced {row['psnr_oidn_balanced']:.2f} dB",
                "Cycles' Denoising Albedo", "|rtd - reference| x 4", "|OIDN - reference| x 4"])
    print(json.dumps(row, indent=1))
    with open(os.path.join(out, "blender_denoise.json"), "w") as f:
        json.dump(row, f, indent=1)


def excess_by_region(rtd_img, oidn_img, reference, albedo, normal):
    """rtd's squared display error over OIDN's, split between detail and flat pixels."""
    err = lambda x: ((srgb(x) - srgb(reference)) ** 2).mean(-1)
    e_rtd, e_oidn = err(rtd_img), err(oidn_img)
    excess = e_rtd - e_oidn
    detail = edges(albedo, normal, radius=2)
    row = {"detail_area": float(detail.mean())}
    for name, m in (("detail", detail), ("flat", ~detail)):
        row[f"{name}_share_of_excess"] = float(excess[m].sum() / excess.sum())
        row[f"{name}_rtd_over_oidn_mse"] = float(e_rtd[m].mean() / e_oidn[m].mean())
    return row


def figure(path, images, reference, labels):
    """Two rows at 2x: the images (sRGB) above; the albedo, then |x - reference| x 4 of
    images 1 and 2 below; each panel labelled."""
    from PIL import Image, ImageDraw

    def u8(x):
        return (np.clip(x, 0, 1) * 255 + 0.5).astype(np.uint8)

    err = lambda x: np.repeat(np.abs(srgb(x) - srgb(reference)).mean(-1, keepdims=True) * 4, 3, -1)
    top = [u8(srgb(x)) for x in images[:3]]
    bottom = [u8(srgb(images[3])), u8(err(images[1])), u8(err(images[2]))]
    grid = np.concatenate([np.concatenate(top, 1), np.concatenate(bottom, 1)], 0)
    im = Image.fromarray(grid).resize((grid.shape[1] * 2, grid.shape[0] * 2), Image.NEAREST)
    draw = ImageDraw.Draw(im)
    h, w = images[0].shape[0] * 2, images[0].shape[1] * 2
    for i, label in enumerate(labels):
        x, y = (i % 3) * w + 6, (i // 3) * h + 4
        draw.rectangle([x - 3, y - 2, x + 7 * len(label) + 3, y + 12], fill=(0, 0, 0))
        draw.text((x, y), label, fill=(255, 255, 255))
    im.save(path)


if __name__ == "__main__":
    main()
