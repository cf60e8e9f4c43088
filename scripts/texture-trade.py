#!/usr/bin/env python3
"""Frame time and error against spp for the textured satellite, with and without the
mip-map (docs/tradeoff.md, "Textured satellite"). Standard library only.

    scripts/texture-trade.py [--hilcam target/release/hilcam] [--width 256]
                             [--spp 1,2,4,16,64] [--reference-spp 1024] [--repeat 5]

Renders scenes/textured_satellite.toml at depth 1 (direct sunlight: what texture
filtering changes) with every pixel given exactly `spp` samples, once with
`texture_filter = "mip"` and once with `"bilinear"`, each `--repeat` times (the median
time, after one warm-up frame), and reports the relative RMSE over the lit pixels against
a mip-mapped reference at `--reference-spp` (both filters converge to the same image),
the same samples in both rows (so the rows differ only on textured pixels).
"""
import argparse
import re
import struct
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def read_pfm(path):
    data = path.read_bytes()
    parts = data.split(b"\n", 3)
    w, h = map(int, parts[1].split())
    scale = float(parts[2])
    fmt = "<" if scale < 0 else ">"
    return struct.unpack(f"{fmt}{w * h}f", parts[3][: 4 * w * h])


def render(hilcam, scene, out, width, spp, repeat):
    cmd = [hilcam, "--log", "warn", "render", str(scene), "--out", str(out), "--width", str(width),
           "--spp", str(spp), "--no-adaptive", "--depth", "1", "--repeat", str(repeat), "--warm-up", "1"]
    text = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    m = re.search(r"median ([0-9.]+) (m?s)", text) or re.search(r": ([0-9.]+) (s),", text)
    if not m:
        sys.exit(f"no time in: {text}")
    return float(m.group(1)) * (1e-3 if m.group(2) == "ms" else 1.0)


def rel_rmse(img, ref, mask):
    idx = [i for i, r in enumerate(ref) if r > 0 and mask[i]]
    mean = sum(ref[i] for i in idx) / len(idx)
    return (sum((img[i] - ref[i]) ** 2 for i in idx) / len(idx)) ** 0.5 / mean


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--hilcam", default=str(ROOT / "target/release/hilcam"))
    ap.add_argument("--width", type=int, default=256)
    ap.add_argument("--spp", default="1,2,4,16,64")
    ap.add_argument("--reference-spp", type=int, default=1024)
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args()
    base = (ROOT / "scenes/textured_satellite.toml").read_text()
    with tempfile.TemporaryDirectory(dir=ROOT / "scenes") as tmp:
        tmp = Path(tmp)
        scenes = {}
        for f in ["mip", "bilinear"]:
            text = base.replace('obj = "textured_satellite/', 'obj = "../textured_satellite/')
            text = text.replace('camera_file = "../', 'camera_file = "../../')
            scenes[f] = tmp / f"{f}.toml"
            scenes[f].write_text(text + f'texture_filter = "{f}"\n')
        ref_path = tmp / "ref.pfm"
        render(a.hilcam, scenes["mip"], ref_path, a.width, a.reference_spp, 1)
        ref = read_pfm(ref_path)
        lit = [r > 0 for r in ref]
        print(f"textured satellite, {a.width} px wide, depth 1, reference {a.reference_spp} spp (mip)")
        print("| spp | filter | frame time | rel. RMSE, lit pixels |")
        print("|---:|---|---:|---:|")
        for spp in a.spp.split(","):
            for f in ["mip", "bilinear"]:
                out = tmp / f"{f}_{spp}.pfm"
                t = render(a.hilcam, scenes[f], out, a.width, spp, a.repeat)
                e = rel_rmse(read_pfm(out), ref, lit)
                print(f"| {spp} | {f} | {t * 1000:.1f} ms | {100 * e:.2f} % |")


if __name__ == "__main__":
    main()
