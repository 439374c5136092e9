#!/usr/bin/env python3
"""Runs Intel OIDN (pip install pyoidn OpenEXR) on a dataset's validation views, for
`rtd bench validation --external oidn=DIR`, and times OIDN against `rtd denoise` on one image.

Usage:
  python3 benches/oidn_compare.py DATASET OUTDIR [--spp 8] [--quality balanced]
  python3 benches/oidn_compare.py --time NOISY.exr   # OIDN fast/balanced seconds on rtd's layers

OIDN gets the same noisy colour and rtd's albedo and normal layers (from the guide pass).
"""
import json, os, sys, time
import numpy as np
import OpenEXR
import pyoidn


def read(path):
    with OpenEXR.File(path, separate_channels=True) as f:
        ch = f.channels()
        return {k: np.asarray(v.pixels, dtype=np.float32) for k, v in ch.items()}


def rgb(ch, prefix, names="RGB"):
    p = f"{prefix}." if prefix else ""
    return np.stack([ch[p + n] for n in names], axis=-1).astype(np.float32)


def write(path, img):
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    channels = {"R": img[..., 0].copy(), "G": img[..., 1].copy(), "B": img[..., 2].copy()}
    with OpenEXR.File(header, channels) as f:
        f.write(path)


def main():
    args = sys.argv[1:]
    if args and args[0] == "--time":
        ch = read(args[1])
        color = rgb(ch, "noisy") if "noisy.R" in ch else rgb(ch, "")
        albedo, normal = rgb(ch, "albedo"), rgb(ch, "normal", "XYZ")
        out = {}
        for q in ["fast", "balanced"]:
            pyoidn.denoise(color, albedo, normal, hdr=True, quality=q)  # warm-up
            ts = []
            for _ in range(3):
                t = time.time()
                pyoidn.denoise(color, albedo, normal, hdr=True, quality=q)
                ts.append(time.time() - t)
            out[q] = sorted(ts)[1]
        print(json.dumps(out))
        return
    data, outdir = args[0], args[1]
    spp = int(args[args.index("--spp") + 1]) if "--spp" in args else 8
    quality = args[args.index("--quality") + 1] if "--quality" in args else "balanced"
    os.makedirs(outdir, exist_ok=True)
    manifest = json.load(open(os.path.join(data, "manifest.json")))
    for v in manifest["views"]:
        if not v["validation"]:
            continue
        ch = read(os.path.join(data, v["file"]))
        out = pyoidn.denoise(rgb(ch, f"noisy{spp}"), rgb(ch, "albedo"), rgb(ch, "normal", "XYZ"), hdr=True, quality=quality)
        stem = os.path.splitext(os.path.basename(v["file"]))[0]
        write(os.path.join(outdir, stem + ".exr"), np.asarray(out, dtype=np.float32))
        print(stem)


if __name__ == "__main__":
    main()
