"""A real tiny render (bpy module, 96×64, 8 samples, Koschmieder): every object's visibility at every
level is in meta and COCO, and matches contrast recomputed here from the written images and mask
(erosion and ring by hand with array shifts, sRGB decoding and Rec. 709 weights written out)."""
import importlib.util
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fogsim.io.depth_files import read_uint16_map
from fogsim.io.images import read_image

pytestmark = pytest.mark.blender
ROOT = Path(__file__).resolve().parents[1]


def shifted_any(m: np.ndarray, r: int, pad_value: bool) -> np.ndarray:
    """Chebyshev dilation by r (pad_value False) or, on ~m, erosion (via the caller)."""
    h, w = m.shape
    p = np.pad(m, r, constant_values=pad_value)
    out = np.zeros_like(m)
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            out |= p[r + dy:r + dy + h, r + dx:r + dx + w]
    return out


def luminance8(img):
    x = img.astype(np.float64) / 255
    lin = np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)
    return lin @ np.array([0.2126, 0.7152, 0.0722])


def by_hand(lum, obj):
    h, w = obj.shape
    p = np.pad(obj, 1, mode="edge")
    interior = np.ones_like(obj)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            interior &= p[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]
    if not interior.any():
        interior = obj
    ring = shifted_any(obj, 4, False) & ~shifted_any(obj, 1, False)
    bg = lum[ring].mean()
    return abs(lum[interior].mean() - bg) / max(bg, 1e-3)


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    if importlib.util.find_spec("bpy") is None:
        pytest.skip("the bpy module is not installed (the 'blender' extra)")
    out = tmp_path_factory.mktemp("vis") / "ds"
    cmd = [sys.executable, "-m", "fogsim", "render", "--out", str(out), "--preset", "default", "--frames", "1",
           "--seed", "3", "--resolution", "96x64", "--samples", "8", "--levels", "clear,0.06,0.12", "--quiet"]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert res.returncode == 0, res.stderr[-3000:]
    return out


def test_every_object_has_visibility_per_level_as_measured(rendered):
    meta = json.loads((rendered / "meta" / "000000.json").read_text())
    mask = read_uint16_map(rendered / "masks" / "000000.png")
    levels = {lv["key"]: lv["beta"] for lv in meta["fog"]["levels"]}
    assert meta["objects"] and set(levels) == {"clear", "beta0.06", "beta0.12"}
    lum = {k: luminance8(read_image(rendered / "images" / k / "000000.png")) for k in levels}
    for rec in meta["objects"]:
        obj = mask == rec["id"]
        assert set(rec["visibility"]) == set(levels)
        for key, beta in levels.items():
            v = rec["visibility"][key]
            c = by_hand(lum[key], obj)
            assert v["method"] == "mask" and v["contrast"] == pytest.approx(c, abs=2e-5, rel=1e-4), (rec["id"], key)
            assert v["contrast_clear"] == pytest.approx(by_hand(lum["clear"], obj), abs=2e-5, rel=1e-4)
            assert v["transmission"] == pytest.approx(math.exp(-beta * rec["distance_m"]), abs=1e-5)
            assert v["visible"] == (v["contrast"] >= 0.05)
    # fog takes contrast away: at 0.12/m (V = 25 m) nothing beyond 2·V keeps 5 %
    far = [r for r in meta["objects"] if r["distance_m"] > 50]
    assert far and not any(r["visibility"]["beta0.12"]["visible"] for r in far)
    assert any(r["visibility"]["clear"]["visible"] for r in far)
    coco = json.loads((rendered / "coco" / "beta0.12.json").read_text())
    assert len(coco["annotations"]) == len(meta["objects"])
    for ann, rec in zip(coco["annotations"], meta["objects"]):
        assert {k: ann[k] for k in ("transmission", "contrast", "visible")} == \
            {k: rec["visibility"]["beta0.12"][k] for k in ("transmission", "contrast", "visible")}
