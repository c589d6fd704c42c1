"""`tessera render --denoise` as a compositor reads it: layer names and header entries,
checked with the reference OpenEXR reader."""

import subprocess
from pathlib import Path

import numpy as np
import OpenEXR

ROOT = Path(__file__).resolve().parents[2]


def test_denoised_layers_and_header(tmp_path):
    exr = tmp_path / "denoised.exr"
    cmd = ["cargo", "run", "--release", "-q", "-p", "tessera", "--", "render", str(ROOT / "fixtures" / "cornell_box.usda"), "--res", "64x48", "--spp", "8"]
    subprocess.run(cmd + ["--aov", "diffuse", "--denoise", "-o", str(exr)], cwd=ROOT, check=True, capture_output=True)
    f = OpenEXR.InputFile(str(exr))
    header = f.header()
    channels = set(header["channels"])
    # The raw beauty stays; the denoised one is a layer beside it, as are the guides.
    assert {"R", "G", "B", "A"} <= channels
    assert {f"beauty_denoised.{c}" for c in "RGBA"} <= channels
    assert {f"diffuse_denoised.{c}" for c in "RGB"} <= channels
    assert {"albedo.R", "normal.X"} <= channels
    assert b"Open Image Denoise" in header["tessera/denoised"]
    assert header["tessera/plan"].split(b",")[-1] == b"denoise"
    raw = np.frombuffer(f.channel("R"), dtype=np.float32)
    denoised = np.frombuffer(f.channel("beauty_denoised.R"), dtype=np.float32)
    assert np.isfinite(denoised).all() and not np.array_equal(raw, denoised)
