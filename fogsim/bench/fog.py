"""Fog engine speed on one 1920×1280 frame, one core, against baselines measured in the same run.

Prints ms per frame per level (medians of interleaved repeats) for:
  baseline   a straightforward numpy float64 transcription of Eq. 2
  standard   fogsim's Koschmieder blend (Fogger: float32, shared per-image work)
  extended   fogsim's extended form (box 19, separable, border-normalised)
  scatter    the scatter model (:mod:`fogsim.fog.scatter`, shipped parameters, sRGB and linear
             blending) against Koschmieder in the same blend space
then all five paper levels of a frame including the planar→ray conversion, and the speedup
of the extended form over a literal per-pixel transcription of the reference's windowed
accumulation on a 128×128 crop. Targets (``docs/speed.md``): standard ≥ 3× faster than baseline;
extended ≤ 1.5× standard; scatter ≤ 3× standard per level (sRGB; linear against linear
Koschmieder); five levels ≤ 150 ms.

    fogsim bench fog [--repeat 15] [--size 1920x1280]
"""
from __future__ import annotations

import cv2
import numpy as np

from fogsim.bench.timing import median_ms
from fogsim.camera import clear_ray_cache, planar_to_ray
from fogsim.fog.engine import FogSettings
from fogsim.fog.levels import load_preset
from fogsim.fog.model import PAPER_KERNEL, Fogger, koschmieder_extended
from fogsim.fog.synthetic import demo_scene

FOGGY = (0.03, 0.06, 0.09, 0.12)
#: the frame size the targets are stated for (width, height)
SIZE = (1920, 1280)
#: scatter may cost at most this many times Koschmieder per level (issue 19)
SCATTER_MAX_RATIO = 3.0


def baseline_eq2(image, distance, beta, airlight=255.0):
    """Eq. 2 as one would first write it: float64 throughout, then clip and round."""
    t = np.exp(-beta * distance.astype(np.float64))[:, :, None]
    out = image.astype(np.float64) * t + airlight * (1.0 - t)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def reference_loop(img, distance, beta, k=19, airlight=255.0):
    """The reference's per-pixel windowed accumulation (uniform weights), transcribed literally."""
    r = k // 2
    t = np.exp(-beta * distance)
    out = np.zeros(img.shape)
    for m in range(r, img.shape[0] - r):
        for n in range(r, img.shape[1] - r):
            win = (slice(m - r, m + r + 1), slice(n - r, n + r + 1))
            out[win] += img[win] * (t[m, n] / k**2) + airlight * (1 - t[m, n]) / k**2
    return out.astype(np.uint8)


def run(repeat: int = 15, size: tuple[int, int] = SIZE) -> int:
    """Measure and print the table (numpy's elementwise work is single-threaded; OpenCV is set to 1);
    ``size`` (width, height) other than :data:`SIZE` is for quick checks (the targets are for SIZE)."""
    cv2.setNumThreads(1)
    width, height = size
    rgb, depth, K = demo_scene(np.random.default_rng(0), width, height)
    ray = planar_to_ray(depth, K)
    ray_finite = np.where(np.isfinite(ray), ray, 1e4).astype(np.float32)  # the baseline gets no inf
    levels = [lv.beta for lv in load_preset("paper")]

    def standard_levels():
        f = Fogger(rgb, ray)
        return [f(b) for b in FOGGY]

    def extended_levels():
        f = Fogger(rgb, ray, kernel=PAPER_KERNEL)
        return [f(b) for b in FOGGY]

    def per_model(make):
        def levels():
            f = make()
            return [f(b) for b in FOGGY]
        return levels

    def five_levels(kernel):
        def run():
            clear_ray_cache() if cold else None
            f = Fogger(rgb, planar_to_ray(depth, K), kernel=kernel)
            return [f(b) for b in levels]
        return run

    per_level = median_ms({
        "baseline": lambda: [baseline_eq2(rgb, ray_finite, b) for b in FOGGY],
        "standard": standard_levels,
        "extended": extended_levels,
        "scatter": per_model(lambda: FogSettings("scatter", space="srgb").fogger(rgb, ray, K)),
        "linear": per_model(lambda: Fogger(rgb, ray, space="linear")),
        "scatter linear": per_model(lambda: FogSettings("scatter").fogger(rgb, ray, K)),
    }, repeat)
    per_level = {k: v / len(FOGGY) for k, v in per_level.items()}
    cold = False
    five = median_ms({"standard": five_levels(None), "extended": five_levels(PAPER_KERNEL)}, repeat)
    cold = True
    five_cold = median_ms({"standard": five_levels(None)}, max(3, repeat // 3))

    c = min(128, height // 2, width // 2)  # a 128×128 crop at the full size
    y0, x0 = (height - c) // 2, (width - c) // 2
    crop = (slice(y0, y0 + c), slice(x0, x0 + c))
    img_c, ray_c = rgb[crop].astype(np.float64), ray_finite[crop].astype(np.float64)
    loop = median_ms({"reference loop": lambda: reference_loop(img_c, ray_c, 0.06)}, 3)["reference loop"]
    ours_c = median_ms({"ours": lambda: koschmieder_extended(rgb[crop], ray[crop], 0.06)}, 25)["ours"]

    print(f"fog benchmark: {width}×{height} RGB uint8, one core, medians of {repeat} interleaved repeats")
    print(f"{'per level (ms/frame)':<34}{'ms':>9}{'vs baseline':>13}")
    for name in ("baseline", "standard", "extended"):
        print(f"  {name:<32}{per_level[name]:9.1f}{per_level['baseline'] / per_level[name]:12.2f}×")
    ratio = {"srgb": per_level["scatter"] / per_level["standard"],
             "linear": per_level["scatter linear"] / per_level["linear"]}
    print(f"{'scatter model, per level':<34}{'ms':>9}{'vs Koschmieder':>16}")
    print(f"  {'Koschmieder, linear blend':<32}{per_level['linear']:9.1f}")
    print(f"  {'scatter, sRGB blend':<32}{per_level['scatter']:9.1f}{ratio['srgb']:15.2f}×")
    print(f"  {'scatter, linear blend':<32}{per_level['scatter linear']:9.1f}{ratio['linear']:15.2f}×")
    print(f"{'all five paper levels + planar→ray':<34}{'ms':>9}")
    print(f"  {'standard':<32}{five['standard']:9.1f}")
    print(f"  {'standard, ray map not cached':<32}{five_cold['standard']:9.1f}")
    print(f"  {'extended (box 19)':<32}{five['extended']:9.1f}")
    print(f"extended vs literal reference loop, {c}×{c} crop: {loop:.0f} ms vs {ours_c:.2f} ms "
          f"= {loop / ours_c:,.0f}× faster")
    checks = [
        ("standard ≥ 3× faster than baseline", per_level["baseline"] / per_level["standard"] >= 3),
        ("extended ≤ 1.5× standard", per_level["extended"] / per_level["standard"] <= 1.5),
        (f"scatter ≤ {SCATTER_MAX_RATIO:g}× Koschmieder (sRGB)", ratio["srgb"] <= SCATTER_MAX_RATIO),
        (f"scatter ≤ {SCATTER_MAX_RATIO:g}× Koschmieder (linear)", ratio["linear"] <= SCATTER_MAX_RATIO),
        ("five levels (standard) ≤ 150 ms", five["standard"] <= 150),
        ("five levels (extended) ≤ 150 ms", five["extended"] <= 150),
    ]
    for text, ok in checks:
        print(f"  [{'ok' if ok else 'MISSED'}] {text}")
    print(f"bench fog: {per_level['standard']:.1f} ms per level = {per_level['baseline'] / per_level['standard']:.2f}× "
          f"faster than Eq. 2 in float64; five paper levels {five['standard']:.0f} ms (extended {five['extended']:.0f} "
          f"ms); scatter {ratio['srgb']:.2f}× Koschmieder per level (sRGB, linear {ratio['linear']:.2f}×); "
          f"{sum(ok for _, ok in checks)}/{len(checks)} targets met")  # the summary line (--quiet)
    return 0
