"""How far is Koschmieder from path-traced fog: the comparison, from arrays (numpy, no Blender).

Per frame the inputs are the clear render in linear light (H×W×3 float, scene-linear), its
distance (ray distance ℓ in metres, +inf = sky; convert planar Z with
:func:`fogsim.camera.planar_to_ray` or pass ``intrinsics``), the instance mask (H×W, 0 =
background/sky), and per β two path-traced renders of the same frame made with independent
seeds (linear, float). The method (``docs/fog-physics.md``):

* **Koschmieder models** (:class:`fogsim.fog.model.Fogger`, airlight A = white): the clear
  image as the dataset stores it (clipped at white, sRGB-encoded, float so no 8-bit rounding)
  blended in ``srgb`` (the paper's and Foggy Cityscapes' way) or ``linear``, with the standard
  law and with each extended kernel given (default: the paper's box 19). Every model image is
  brought back to linear light for the comparison.
* **Exposure**: ``raw`` compares the path-traced image as rendered (A = white = 1.0);
  ``normalised`` scales it by s = 1 / Y(A_h), the scalar a camera's auto-exposure would apply,
  so that the horizon radiance A_h becomes A. A_h = mean RGB of the *horizon* pixels: the sky
  pixels (ℓ = inf, index 0) in the lowest :data:`HORIZON_FRACTION` of the sky by image row
  (the sky nearest the horizon line; for a level camera the horizon itself). No sky → no
  normalisation (None). ``far`` scales it instead so that the median luminance of the pixels
  beyond the visibility V = ln(20)/β (:func:`far_luminance`, sky included: where Koschmieder
  is all airlight) becomes A — in a street canyon, where the lowest sky lies at the end of the
  street and the far field is seen at higher elevations, the two differ.
* **Interior mask**: a pixel counts only when all 8 neighbours have the same object index and
  a distance within 5 % of its own (both sky is equal), so mixed (anti-aliased) edge pixels —
  whose depth comes from one sample and whose colour from all — are not counted as model error.
* **Errors** E_i = s·F_i − K (per pixel and channel, linear light, in units of A), over
  interior pixels per distance bin (:data:`BINS`; ``sky`` and ``all`` = every non-sky bin):
  ``bias`` = mean((E₁ + E₂)/2) and the noise-free ``rms`` = √max(0, mean(E₁·E₂)) — the noise
  of two independent seeds is uncorrelated, so it cancels in the product; ``rms_with_noise``
  = √mean(((E₁ + E₂)/2)²) for comparison, and ``noise`` = √(mean((F₁ − F₂)²)/2)·s, the
  per-render noise.
* **Per object** (mask ids): mean luminance Y over its interior pixels; contrast against the
  airlight C = (Y(A) − Y_obj)/Y(A) in the path-traced image (A = its horizon radiance) and in
  each model image (A = white), the clear contrast C0 = 1 − Y_clear (against white), and
  t = exp(−β·d) at its median ray distance d. Koschmieder in linear light gives C_K = C0·t
  exactly; ``ratio`` = C_PT / C_K per model (None where |C_K| < 1e-3).

Frames accumulate (:class:`Comparison`): sums per bin over all frames, each frame normalised
by its own horizon. :meth:`Comparison.result` → a JSON-ready dict; :mod:`fogsim.bench.fog_physics_report`
(``markdown``, ``write_report``) turns it into a table, PNG panels (:mod:`fogsim.viz`) and files.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from fogsim.camera import Intrinsics, planar_to_ray
from fogsim.colour import linear_to_srgb, linear_to_srgb8, luminance, srgb_to_linear
from fogsim.fog.engine import FogSettings
from fogsim.fog.levels import visibility_from_beta
from fogsim.fog.model import PAPER_KERNEL, Kernel
from fogsim.fog.scatter import ScatterParams
from fogsim.fog.visibility import transmission_at

#: distance bins in metres: [lo, hi)
BINS = ((0.0, 10.0), (10.0, 20.0), (20.0, 40.0), (40.0, 80.0), (80.0, math.inf))
HORIZON_FRACTION = 0.1
#: the "far" exposure: pixels with exp(−βℓ) below this (beyond the visibility ln 20 / β; sky included)
EXPOSURES = ("raw", "normalised", "far")
DEPTH_TOLERANCE = 0.05
MIN_CONTRAST = 1e-3


def bin_name(lo: float, hi: float) -> str:
    return f"{lo:g}+ m" if not math.isfinite(hi) else f"{lo:g}-{hi:g} m"


BIN_NAMES = tuple(bin_name(lo, hi) for lo, hi in BINS)


def koschmieder_model(space: str, kernel: Kernel | None = None) -> FogSettings:
    """A Koschmieder variant of the comparison: blend ``space`` and ``kernel`` (None = the standard law)."""
    return FogSettings("koschmieder", 255.0, space, kernel)


def default_models(kernels=(PAPER_KERNEL,), scatter: ScatterParams | bool = True) -> tuple[FogSettings, ...]:
    """sRGB and linear blending, standard and with each extended kernel; then the scatter model
    in linear light (``scatter``: True = the shipped parameters, False = none, or the parameters)."""
    models = tuple(koschmieder_model(space, k) for k in (None, *kernels) for space in ("srgb", "linear"))
    if scatter is not False:
        models += (scatter_model(None if scatter is True else scatter),)
    return models


def scatter_model(params: ScatterParams | None = None, space: str = "linear") -> FogSettings:
    """The scatter model as a fog record (``params`` None: the shipped parameters)."""
    return FogSettings("scatter", 255.0, space, scatter=params)


# ----------------------------------------------------------------------------- pieces
def interior_mask(distance: np.ndarray, mask: np.ndarray, tolerance: float = DEPTH_TOLERANCE) -> np.ndarray:
    """True where all 8 neighbours have the same index and a distance within ``tolerance`` of the
    pixel's own (relative; two sky pixels, both +inf, agree). Pixels on the image border compare
    with the neighbours that exist."""
    h, w = mask.shape
    d = np.asarray(distance, np.float64)
    pd = np.pad(d, 1, mode="edge")
    pm = np.pad(mask, 1, mode="edge")
    ok = np.ones((h, w), bool)
    inf = np.isinf(d)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if dy == dx == 0:
                continue
            nd = pd[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]
            nm = pm[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]
            n_inf = np.isinf(nd)
            with np.errstate(invalid="ignore"):
                close = np.where(inf | n_inf, inf & n_inf, np.abs(nd - d) <= tolerance * d)
            ok &= (nm == mask) & close
    return ok


def far_luminance(image_linear: np.ndarray, distance: np.ndarray, beta: float) -> float | None:
    """Median linear luminance of the pixels beyond the visibility V = ln(20)/β (ray distance in
    metres, sky included): the airlight a fogged render shows; None when no pixel is that far."""
    far = distance >= visibility_from_beta(beta)
    return float(np.median(luminance(image_linear)[far])) if far.any() else None


def horizon_radiance(image: np.ndarray, distance: np.ndarray, mask: np.ndarray,
                     fraction: float = HORIZON_FRACTION) -> dict | None:
    """The horizon: mean RGB of the lowest ``fraction`` of sky pixels by row, with the sky's
    mean luminance over it and a profile (mean luminance per sky row band, top → bottom)."""
    sky = np.isinf(distance) & (mask == 0)
    if not sky.any():
        return None
    rows = np.nonzero(sky)[0]
    cut = np.quantile(rows, 1.0 - fraction)
    horizon = sky & (np.arange(sky.shape[0])[:, None] >= cut)
    rgb = image[horizon].mean(axis=0)
    y_h = float(luminance(rgb[None, None])[0, 0])
    lum = luminance(image)
    bands = np.array_split(np.unique(rows), min(8, len(np.unique(rows))))
    profile = [float(lum[np.isin(np.arange(sky.shape[0]), b)[:, None] & sky].mean()) for b in bands]
    return {"rgb": [float(v) for v in rgb], "luminance": y_h, "pixels": int(horizon.sum()),
            "rows": [int(math.ceil(cut)), int(rows.max())],
            "mean_sky_over_horizon": float(lum[sky].mean()) / max(y_h, 1e-12),
            "profile_top_to_bottom": profile}


def koschmieder_linear(clear_linear: np.ndarray, distance: np.ndarray, beta: float, model: FogSettings,
                       camera: Intrinsics | None = None, up=None) -> np.ndarray:
    """The model's fogged image in linear light, float32, from the clear render (clipped at
    white and sRGB-encoded as the dataset stores it, but in float). ``camera`` and ``up`` (world
    up in camera coordinates) give the scatter model its elevation map and PSF width; its image
    is not clipped at white (the path-traced one is not either: normalised, the fog above the
    horizon is brighter than A — a float or HDR output keeps that, an 8-bit one clips it)."""
    srgb = linear_to_srgb(np.clip(clear_linear, 0.0, 1.0))
    fogger = model.fogger(srgb, distance, camera, up)
    if model.kind == "scatter":  # not clipped at white: its airlight exceeds A above the horizon, as the fog's does
        out = fogger.blend(beta)
        return out if model.blend_space == "linear" else srgb_to_linear(np.clip(out, 0.0, None))
    return srgb_to_linear(np.clip(fogger(beta), 0.0, 1.0))


@dataclass
class _Sums:
    """Running sums of one (β, model, exposure, bin): Σ(E₁+E₂)/2, ΣE₁E₂, Σ((E₁+E₂)/2)², Σ|ΔF|²/2, n."""

    mean: float = 0.0
    cross: float = 0.0
    square: float = 0.0
    noise: float = 0.0
    n: int = 0

    def add(self, e1: np.ndarray, e2: np.ndarray, df: np.ndarray) -> None:
        m = 0.5 * (e1 + e2)
        self.mean += float(m.sum())
        self.cross += float((e1 * e2).sum())
        self.square += float((m * m).sum())
        self.noise += float((df * df).sum()) / 2.0
        self.n += int(e1.size)

    def result(self) -> dict:
        if self.n == 0:
            return {"bias": None, "rms": None, "rms_with_noise": None, "noise": None, "values": 0}
        cross = self.cross / self.n
        return {"bias": self.mean / self.n, "rms": math.sqrt(max(cross, 0.0)),
                "rms_with_noise": math.sqrt(self.square / self.n), "noise": math.sqrt(self.noise / self.n),
                "cross_mean": cross, "values": self.n}


@dataclass
class Comparison:
    """Koschmieder models against path-traced renders, accumulated over frames (see the module)."""

    models: tuple[FogSettings, ...] = field(default_factory=default_models)
    bins: tuple = BINS
    panels: dict = field(default_factory=dict)   # frame → RGB uint8 panel image
    max_panels: int = 4

    def __post_init__(self):
        self._sums: dict = {}
        self._objects: dict = {}
        self._horizon: dict = {}
        self._far: dict = {}
        self._interior = [0, 0]
        self._glow: dict = {}
        self.frames: list[str] = []

    def _sum(self, beta, model, exposure, where) -> _Sums:
        return self._sums.setdefault((beta, model, exposure, where), _Sums())

    def add_frame(self, name: str, clear_linear: np.ndarray, distance: np.ndarray, mask: np.ndarray,
                  renders: dict[float, tuple[np.ndarray, np.ndarray]], intrinsics: Intrinsics | None = None,
                  classes: dict[int, str] | None = None, camera: Intrinsics | None = None, up=None,
                  night: bool = False) -> None:
        """One frame: ``distance`` is ray distance (or planar Z when ``intrinsics`` is given);
        ``renders``: β → (seed-0 render, seed-1 render), linear float H×W×3; ``classes``:
        mask id → class name: the objects of the object table (None: every id in the mask);
        ``camera`` / ``up``: the camera's intrinsics and world up in camera coordinates (the
        scatter model's elevation and PSF width; default ``intrinsics``, a level camera);
        ``night``: measure the glow around the lamps (:func:`lamps`)."""
        camera = camera or intrinsics
        clear_linear = np.asarray(clear_linear, np.float32)
        if clear_linear.ndim != 3 or clear_linear.shape[2] != 3:
            raise ValueError(f"{name}: the clear render must be H×W×3, got {clear_linear.shape}")
        h, w = clear_linear.shape[:2]
        ray = planar_to_ray(distance, intrinsics) if intrinsics is not None else np.asarray(distance, np.float32)
        if ray.shape != (h, w) or mask.shape != (h, w):
            raise ValueError(f"{name}: distance {ray.shape} and mask {mask.shape} must be {(h, w)}")
        inner = interior_mask(ray, mask)
        self._interior[0] += int(inner.sum())
        self._interior[1] += inner.size
        sky = np.isinf(ray) & (mask == 0)
        where = {"sky": inner & sky, "all": inner & ~sky}
        for (lo, hi), key in zip(self.bins, BIN_NAMES):
            where[key] = inner & ~sky & (ray >= lo) & (ray < hi)
        ids = [int(i) for i in np.unique(mask) if i != 0 and (classes is None or int(i) in classes)]
        obj_px = {i: inner & (mask == i) for i in ids}
        obj_px = {i: m for i, m in obj_px.items() if m.any()}
        obj_d = {i: float(np.median(ray[mask == i][np.isfinite(ray[mask == i])]))
                 if np.isfinite(ray[mask == i]).any() else math.nan for i in obj_px}
        y_clear = luminance(np.clip(clear_linear, 0.0, 1.0))
        panel_rows = []
        for beta, (f1, f2) in sorted(renders.items()):
            f1, f2 = np.asarray(f1, np.float32), np.asarray(f2, np.float32)
            if f1.shape != clear_linear.shape or f2.shape != clear_linear.shape:
                raise ValueError(f"{name}: the β = {beta:g} renders must be {w}×{h}×3")
            hz = horizon_radiance(0.5 * (f1 + f2), ray, mask)
            self._horizon.setdefault(beta, []).append({"frame": name, **(hz or {"luminance": None})})
            exposures = {"raw": 1.0}
            if hz is not None and hz["luminance"] > 0:
                exposures["normalised"] = 1.0 / hz["luminance"]
            fmean = 0.5 * (f1 + f2)
            y_pt = luminance(fmean)
            y_far = far_luminance(fmean, ray, beta) or 0.0
            if y_far > 0:
                exposures["far"] = 1.0 / y_far
            self._far.setdefault(beta, []).append(y_far if y_far > 0 else None)
            kimgs = {}
            for model in self.models:
                k = koschmieder_linear(clear_linear, ray, beta, model, camera, up)
                kimgs[model.name] = k
                for exposure, s in exposures.items():
                    e1, e2, df = s * f1 - k, s * f2 - k, s * (f1 - f2)
                    for key, m in where.items():
                        if m.any():
                            self._sum(beta, model.name, exposure, key).add(e1[m], e2[m], df[m])
            y_k = {n: luminance(k) for n, k in kimgs.items()}
            a_pt = hz["luminance"] if hz is not None else None
            for i, px in obj_px.items():
                d = obj_d[i]
                c0 = 1.0 - float(y_clear[px].mean())
                c_pt = None if not a_pt else (a_pt - float(y_pt[px].mean())) / a_pt
                c_k = {n: 1.0 - float(y[px].mean()) for n, y in y_k.items()}
                ratio = {n: (None if c_pt is None or abs(c) < MIN_CONTRAST else c_pt / c) for n, c in c_k.items()}
                self._objects.setdefault(beta, []).append({
                    "frame": name, "id": i, "class": (classes or {}).get(i), "pixels": int(px.sum()),
                    "distance_m": None if math.isnan(d) else d,
                    "transmission": None if math.isnan(d) else transmission_at(d, beta),
                    "contrast_clear": c0, "contrast_pt": c_pt, "contrast_k": c_k, "ratio_pt_k": ratio})
            if night:
                s = exposures.get("normalised", 1.0)
                for lamp in lamps(clear_linear, ray):
                    self._glow.setdefault(beta, []).append({
                        "frame": name, **lamp, "pt": radial_profile(luminance(s * fmean), lamp["centre"]),
                        "models": {n: radial_profile(y, lamp["centre"]) for n, y in y_k.items()}})
            if len(self.panels) < self.max_panels:
                panel_rows.append(self._panel_row(beta, clear_linear, fmean, exposures, kimgs, inner))
        self.frames.append(name)
        if panel_rows:
            self.panels[name] = _stack(panel_rows)

    def _panel_row(self, beta, clear, fmean, exposures, kimgs, inner) -> np.ndarray:
        from fogsim.viz import strip

        s = exposures.get("normalised", 1.0)
        lin = kimgs.get("linear", next(iter(kimgs.values())))
        srgb = kimgs.get("srgb", lin)
        err = luminance(s * fmean - lin)
        tiles = [linear_to_srgb8(clear), linear_to_srgb8(lin), linear_to_srgb8(srgb)]
        caps = [f"b={beta:g} clear", "K lin", "K srgb"]
        if "scatter" in kimgs:
            tiles.append(linear_to_srgb8(kimgs["scatter"]))
            caps.append("scatter")
        tiles += [linear_to_srgb8(fmean, s), linear_to_srgb8(fmean), signed_map(err, 0.25)]
        caps += [f"PT x{s:.2f}", "PT raw", "PT-K lin +-.25"]
        if "scatter" in kimgs:
            tiles.append(signed_map(luminance(s * fmean - kimgs["scatter"]), 0.25))
            caps.append("PT-scatter")
        tiles.append((inner[..., None] * 255).repeat(3, 2).astype(np.uint8))
        caps.append("interior")
        return strip(tiles, caps, width=max(160, clear.shape[1]))

    def result(self) -> dict:
        """The JSON-ready summary of every frame added so far."""
        per_beta = {}
        betas = sorted({k[0] for k in self._sums} | set(self._horizon))
        for beta in betas:
            models = {}
            for model in self.models:
                models[model.name] = {}
                for exposure in EXPOSURES:
                    keys = ("all", *BIN_NAMES, "sky")
                    if any((beta, model.name, exposure, key) in self._sums for key in keys):
                        models[model.name][exposure] = {
                            key: self._sums.get((beta, model.name, exposure, key), _Sums()).result() for key in keys}
            hz = [h for h in self._horizon.get(beta, []) if h.get("luminance") is not None]
            per_beta[f"{beta:g}"] = {
                "beta": beta,
                "horizon": {"luminance_mean": _mean([h["luminance"] for h in hz]),
                            "rgb_mean": [_mean([h["rgb"][c] for h in hz]) for c in range(3)] if hz else None,
                            "mean_sky_over_horizon": _mean([h["mean_sky_over_horizon"] for h in hz]),
                            "frames": self._horizon.get(beta, [])},
                "far_luminance_mean": _mean(self._far.get(beta, [])),
                "models": models, "objects": self._objects.get(beta, []),
                "objects_summary": _object_summary(self._objects.get(beta, []), [m.name for m in self.models]),
                "glow": _glow_summary(self._glow.get(beta, []), [m.name for m in self.models])}
        return {"frames": self.frames, "bins_m": [[lo, hi if math.isfinite(hi) else None] for lo, hi in self.bins],
                "interior_fraction": self._interior[0] / self._interior[1] if self._interior[1] else None,
                "models": [m.name for m in self.models], "units": "linear light, A = white = 1.0",
                "estimator": "bias = mean((E1+E2)/2); rms = sqrt(max(0, mean(E1*E2))) (noise-free, two seeds)",
                "per_beta": per_beta}


#: objects in the per-β summary: those that keep at least this transmission (some contrast to measure)
SUMMARY_MIN_TRANSMISSION = 0.05


def _object_summary(objects: list[dict], names: list[str]) -> dict:
    """Per model: the median of PT/K over objects with t ≥ :data:`SUMMARY_MIN_TRANSMISSION`."""
    out = {}
    for n in names:
        r = [o["ratio_pt_k"][n] for o in objects if (o["transmission"] or 0) >= SUMMARY_MIN_TRANSMISSION
             and o["ratio_pt_k"].get(n) is not None]
        out[n] = {"median_ratio_pt_k": float(np.median(r)) if r else None, "objects": len(r)}
    return out


#: glow rings around a lamp's centre: [lo, hi) pixels
GLOW_RINGS = ((0, 2), (2, 4), (4, 8), (8, 16), (16, 32))
#: a lamp: a connected region of the clear image at least this bright (linear luminance), not sky,
#: of at most LAMP_MAX_FRACTION of the image
LAMP_LUMINANCE = 0.9
LAMP_MAX_FRACTION = 0.01
MAX_LAMPS = 12


def lamps(clear_linear: np.ndarray, distance: np.ndarray) -> list[dict]:
    """The light sources of a (night) clear render: connected regions of linear luminance ≥
    :data:`LAMP_LUMINANCE` that are not sky and cover ≤ :data:`LAMP_MAX_FRACTION` of the image,
    the :data:`MAX_LAMPS` largest, as ``{"centre": [x, y], "pixels", "distance_m"}``."""
    import cv2

    y = luminance(np.clip(clear_linear, 0.0, None))
    bright = ((y >= LAMP_LUMINANCE) & np.isfinite(distance)).astype(np.uint8)
    n, labels, stats, cents = cv2.connectedComponentsWithStats(bright, connectivity=8)
    found = []
    for i in range(1, n):
        area = int(stats[i, cv2.CC_STAT_AREA])
        if area <= LAMP_MAX_FRACTION * y.size:
            found.append({"centre": [float(cents[i][0]), float(cents[i][1])], "pixels": area,
                          "distance_m": float(np.median(distance[labels == i]))})
    return sorted(found, key=lambda d: -d["pixels"])[:MAX_LAMPS]


def radial_profile(y: np.ndarray, centre, rings=GLOW_RINGS) -> list[float | None]:
    """Mean of ``y`` (H×W) in each ring [lo, hi) px around ``centre`` (x, y); None for an empty ring."""
    h, w = y.shape
    r = np.hypot(np.arange(w)[None, :] + 0.0 - centre[0], np.arange(h)[:, None] + 0.0 - centre[1])
    return [float(y[(r >= lo) & (r < hi)].mean()) if ((r >= lo) & (r < hi)).any() else None for lo, hi in rings]


def _glow_summary(found: list[dict], names: list[str]) -> dict | None:
    """Per ring: the median over lamps of the path-traced and each model's mean luminance."""
    if not found:
        return None

    def med(rows):
        return [_median([r[i] for r in rows]) for i in range(len(GLOW_RINGS))]
    return {"lamps": len(found), "rings_px": [list(r) for r in GLOW_RINGS], "pt": med([f["pt"] for f in found]),
            "models": {n: med([f["models"][n] for f in found]) for n in names}}


def _median(values) -> float | None:
    values = [v for v in values if v is not None]
    return float(np.median(values)) if values else None


def _mean(values) -> float | None:
    values = [v for v in values if v is not None]
    return float(np.mean(values)) if values else None


def _stack(rows: list[np.ndarray]) -> np.ndarray:
    width = max(r.shape[1] for r in rows)
    return np.vstack([np.pad(r, ((0, 4), (0, width - r.shape[1]), (0, 0)), constant_values=255) for r in rows])


def signed_map(x: np.ndarray, scale: float) -> np.ndarray:
    """Signed values → RGB uint8: blue negative, white 0, red positive, saturating at ±``scale``."""
    v = np.clip(np.asarray(x, np.float32) / scale, -1.0, 1.0)
    out = np.empty(v.shape + (3,), np.float32)
    out[..., 0] = np.where(v > 0, 1.0, 1.0 + v)
    out[..., 1] = 1.0 - np.abs(v)
    out[..., 2] = np.where(v < 0, 1.0, 1.0 - v)
    return (out * 255 + 0.5).astype(np.uint8)


def noisy_render(image: np.ndarray, sigma: float, rng: np.random.Generator) -> np.ndarray:
    """``image`` plus independent Gaussian noise of std ``sigma`` (relative to the value, as Monte
    Carlo noise is), float32 — a stand-in path-traced render for tests and dry runs."""
    return (image * (1.0 + rng.normal(0.0, sigma, image.shape))).astype(np.float32)


__all__ = ["BINS", "BIN_NAMES", "GLOW_RINGS", "Comparison", "default_models", "far_luminance", "horizon_radiance",
           "interior_mask", "koschmieder_linear", "koschmieder_model", "lamps", "noisy_render", "radial_profile",
           "scatter_model", "signed_map"]
