"""The scatter fog model: Koschmieder's law plus forward scattering, an airlight that varies with
viewing elevation, and glow around light sources — an image-space fog calibrated on Cycles'
path-traced fog (``fogsim fit-fog``; parameters shipped in ``scatter_params.json``).

Per pixel x with ray distance ℓ (m), extinction β (1/m), optical depth T = βℓ:

    I_fog = m·I·t  +  PSF ⊛ [ m·I·(t_f − t) + G·s·m·I·(1 − t) ]  +  a·e^(−λβ)·A·e^(c·sin θ)·(1 − t_f)

The parameters come in five blocks (:class:`ScatterParams`, declared once in :mod:`fogsim.schema.scatter`,
with ranges, defaults and what the fit searches):

* t = e^(−βℓ): the light that reaches the camera unscattered (Koschmieder's transmission);
* ``psf`` (k ``psf.forward``, ρ ``psf.spread``): t_f = e^(−β(1−k)ℓ) is the light that is unscattered *or*
  scattered into the forward peak of the droplets' phase function — the delta-scaling approximation
  (Joseph et al. 1976, δ-Eddington: a share k ≈ g² of scattering is treated as not deflected). The part
  t_f − t is the image-forming light that still arrives, but spread by the atmospheric point-spread
  function: a Gaussian in angle whose variance grows linearly with optical depth, σ_θ² = ρ·T (the
  small-angle diffusion limit of forward-peaked multiple scattering, the regime Narasimhan & Nayar's
  APSF covers for T ≲ 1–2), splatted from each source pixel with *its own* width (energy conserving:
  every source pixel's light is spread, not gathered);
* ``direct`` (μ ``direct.illumination``, κ ``direct.exposure_key``, f ``direct.flatten``): m = g·e^(−μβ):
  objects in fog are lit by the fog's diffuse light, not by the clear sky: g (:func:`exposure_gain`, off
  when κ = 0) maps the clear image's median luminance to κ·A, so the direct term no longer depends on
  how the clear image was lit or exposed, and e^(−μβ) lets that light fade as the fog thickens; I
  itself has its sun and shadow flattened by a share f, I → r·(I/r)^(1−f) around the median r;
* ``airlight`` (a ``airlight.level``, λ ``airlight.fade``, c ``airlight.elevation``, ν ``airlight.sky_exponent``):
  a·e^(−λβ)·(Ω/Ω₀)^(−ν)·A·e^(c·sin θ), the airlight in units of the horizon radiance A (the
  ``airlight`` argument: what the camera's exposure puts at the lowest sky) — a level a (the fog
  between camera and scene is not the sky seen through all of it) that fades with β as the fog layer's
  light from above is itself attenuated (λ, m; empirical), and brightens with the viewing elevation θ,
  as the path to the top of the fog layer, which is lit from above, gets shorter; Ω is the share of sky
  in view (Ω₀ = :data:`SKY_REFERENCE`): in Cycles' fog the street's airlight relative to the lowest
  visible sky falls as the view opens up (empirical, ν fitted);
* ``glow`` (G ``glow.gain``, ``glow.threshold``, ρ_g ``glow.spread``, w ``glow.tail``, ``glow.max_area``):
  pixels that are saturated in the clear image (linear luminance above the threshold, s ∈ [0, 1]) stand
  for sources far brighter than white; their light is scattered by a PSF of the same form with a gain
  G — a share w by the scene's wide PSF ρ (the APSF's wings), the rest by its own narrow ρ_g (its core)
  — so lamps and headlights glow; a saturated region larger than ``max_area`` of the image is a lit
  surface, not a lamp;
* ``night`` (Y_g ``night.luminance``): the model's day/night switch, the night weight
  1/(1 + (median Y/Y_g)^8) of the clear image (:func:`night_weight`; 0 = off): the glow is a night rule
  (by day white surfaces saturate too), κ, c and ν are day rules (at night lamps, not the fog's light
  from above, light the scene and the fog).

With k = μ = λ = c = G = κ = ν = f = 0 and a = 1 the model is Koschmieder's law exactly (the same blend as
:class:`fogsim.fog.model.Fogger`). ``space="linear"`` (the default here, physically right)
blends linear light; ``"srgb"`` blends the stored values as the paper does. Distances as in
:mod:`fogsim.fog.model` (ray distance, +inf = sky), airlight in 8-bit units, images uint8 /
uint16 / float RGB, returned in their dtype. The PSF is computed on a copy of the image reduced
to about :data:`WORK_WIDTH` pixels wide (the blur is wide; the direct term stays at full size).

    >>> from fogsim.fog.scatter import scatter
    >>> foggy = scatter(image, distance, 0.06)          # shipped parameters, A = 255, linear light
"""
from __future__ import annotations

import math
import os
from functools import lru_cache
from importlib import resources
from pathlib import Path

import cv2
import numpy as np

from fogsim.camera import Intrinsics
from fogsim.colour import (
    LUMINANCE_WEIGHTS,
    decode_codes,
    from_float,
    full_scale,
    linear_to_srgb,
    srgb_luminance,
    srgb_to_linear,
)
from fogsim.fog.model import airlight_rgb, check_beta, check_distance
from fogsim.fog.scatter_optics import (
    focal_px,
    psf_sigma_rad,
    reduce_points,
    smooth_elevation_sine,
    splat,
)
from fogsim.schema.base import load_json
from fogsim.schema.scatter import ScatterParameters, ScatterParamsFile
from fogsim.schema.vocabulary import SPACES

#: the shipped parameter file (fitted by ``fogsim fit-fog``)
PARAMS_FILE = "scatter_params.json"
#: the width (px) of the reduced copy the PSF is computed on
WORK_WIDTH = 240
#: the exposure gain's bounds (a black or a blown-out clear image is not scaled without limit)
EXPOSURE_GAIN_RANGE = (0.125, 8.0)
#: a gain g in linear light is g^(1/SRGB_GAMMA) on sRGB-encoded values (the power-law part of sRGB)
SRGB_GAMMA = 2.2
#: the median luminance is taken on a copy about this many pixels wide
EXPOSURE_WIDTH = 160
#: the share of sky in view the airlight's level ``a`` refers to, and the least share counted
SKY_REFERENCE = 0.15
#: how sharply the glow fades between night and day images (:func:`night_weight`)
GLOW_DARK_POWER = 8
SKY_MIN = 0.02


#: The model's parameters: the schema's record, declared once in :mod:`fogsim.schema.scatter` (blocks
#: ``psf``, ``direct``, ``airlight``, ``glow``, ``night``; every default switches its term off).
ScatterParams = ScatterParameters
KOSCHMIEDER = ScatterParams()


@lru_cache(maxsize=4)
def _code_table(dtype) -> np.ndarray:
    """Linear light of every code value of an integer dtype (the table :func:`decode_codes` uses)."""
    top = int(full_scale(dtype))
    return decode_codes(np.arange(top + 1, dtype=np.uint8 if top == 255 else np.uint16))


def shipped_params_path() -> Path:
    return Path(str(resources.files("fogsim.fog").joinpath(PARAMS_FILE)))


def load_params_file(path: str | Path | None = None) -> ScatterParamsFile:
    """The parameter file (default: the shipped one), checked: a malformed file is an
    :class:`~fogsim.errors.InputError` naming it and the key."""
    return load_json(shipped_params_path() if path is None else path, ScatterParamsFile)


@lru_cache(maxsize=1)
def _shipped() -> ScatterParams:
    return load_params_file().parameters


def load_params(path: str | Path | None = None) -> ScatterParams:
    """:class:`ScatterParams` from a parameter file (default: the shipped, fitted one), read once
    per file (cached by its resolved path, modification time and size: an edited file is re-read)."""
    if path is None:
        return _shipped()
    try:
        st = os.stat(path)
    except OSError:
        return load_params_file(path).parameters  # its one-line error
    return _cached_params(str(Path(path).resolve()), st.st_mtime_ns, st.st_size)


@lru_cache(maxsize=16)
def _cached_params(path: str, mtime_ns: int, size: int) -> ScatterParams:
    return load_params_file(path).parameters


def median_luminance(image: np.ndarray, distance: np.ndarray) -> float | None:
    """The median linear luminance of the clear ``image``'s non-sky pixels (finite ``distance``), on a
    copy about :data:`EXPOSURE_WIDTH` px wide; None when every pixel is sky."""
    h, w = image.shape[:2]
    f = max(1, w // EXPOSURE_WIDTH)
    size = (max(1, w // f), max(1, h // f))
    small = cv2.resize(np.ascontiguousarray(image), size, interpolation=cv2.INTER_AREA)
    far = cv2.resize(distance, size, interpolation=cv2.INTER_NEAREST)
    y = srgb_luminance(small)[np.isfinite(far)]
    return float(np.median(y)) if y.size else None


def exposure_gain(median: float, key: float, airlight_linear) -> float:
    """The fog-lit direct term's gain κ·Y_A / median(Y) (:func:`median_luminance`; Y_A the airlight's
    linear luminance), clipped to :data:`EXPOSURE_GAIN_RANGE`: objects in fog are lit by the fog's
    diffuse light, so their radiance relative to the airlight follows their albedo, not how the
    clear image was lit or exposed."""
    y_a = float(np.asarray(airlight_linear, np.float64) @ np.asarray(LUMINANCE_WEIGHTS, np.float64))
    lo, hi = EXPOSURE_GAIN_RANGE
    return float(np.clip(key * y_a / max(median, 1e-6), lo, hi))


def night_weight(median: float, dark: float) -> float:
    """1 / (1 + (median/dark)^8): ≈ 1 for a night image (median luminance well under ``dark``), ≈ 0 by
    day. Measured medians (linear, non-sky): night streets 0.020–0.032, day streets 0.071–0.20."""
    return 1.0 / (1.0 + (median / dark) ** GLOW_DARK_POWER)


def direct_planes(image: np.ndarray, space: str, gain: float = 1.0, flatten: float = 0.0,
                  reference: float = 1.0) -> list[np.ndarray]:
    """The clear image's colour planes as the direct term uses them, in the blend space (0–1,
    float32, contiguous): gain·r·(I/r)^(1−f) with r the ``reference`` (the median luminance in the
    blend space) and f the ``flatten`` share: sun and shadow of the clear image compressed towards
    the even light of fog. 8/16-bit images through one lookup table per image."""
    gamma = 1.0 - flatten
    top = float(full_scale(image.dtype))

    def shape(x):
        if gamma != 1.0:
            x = np.float32(reference) * cv2.pow(np.maximum(x, 0.0) / np.float32(reference), gamma)
        return x * np.float32(gain) if gain != 1.0 else x

    if image.dtype in (np.uint8, np.uint16):
        table = _code_table(np.dtype(image.dtype)) if space == "linear" \
            else np.arange(int(top) + 1, dtype=np.float32) / np.float32(top)
        table = np.ascontiguousarray(shape(table.reshape(1, -1)), np.float32)
        if image.dtype == np.uint8:
            return [cv2.LUT(q, table) for q in cv2.split(image)]
        return [table[0][q] for q in cv2.split(image)]
    planes = [cv2.multiply(q, 1.0 / top, dtype=cv2.CV_32F) for q in _split(image)]
    return [shape(srgb_to_linear(q) if space == "linear" else q) for q in planes]


def sky_gain(distance: np.ndarray, exponent: float) -> float:
    """The airlight's gain (Ω/Ω₀)^(−ν) from the share Ω of sky pixels (+inf distance; counted on every
    4th row and column, at least :data:`SKY_MIN`) against :data:`SKY_REFERENCE`. Empirical: in
    Cycles' fog the street's airlight relative to the lowest visible sky falls as the view opens up
    (urban canyon, Ω ≈ 0.08: 1.05 A; arterial, 0.18: 0.88 A; suburban, 0.23: 0.75 A; ``docs/fog-physics.md``)."""
    omega = max(float(np.isinf(distance[::4, ::4]).mean()), SKY_MIN)
    return float((omega / SKY_REFERENCE) ** (-exponent))


def _split(image: np.ndarray) -> list[np.ndarray]:
    """The colour planes of an H×W×3 image, contiguous (cv2.split for the dtypes OpenCV has)."""
    if image.dtype in (np.uint8, np.uint16, np.float32):
        return list(cv2.split(np.ascontiguousarray(image)))
    return [np.ascontiguousarray(image[:, :, c]) for c in range(3)]


# ----------------------------------------------------------------------------- the model
class ScatterFogger:
    """Fog one image at many densities with the scatter model, sharing the work that does not
    depend on β (colour decoding, the reduced copy, the elevation map).

    ``image`` H×W×3, ``distance`` ray distance in metres (+inf = sky), ``airlight`` the horizon
    radiance in 8-bit units (a number or RGB), ``intrinsics`` for the elevation and the PSF's
    width in pixels (None: :data:`DEFAULT_HFOV_DEG`), ``up`` world up in camera coordinates
    (None: a level camera; :func:`up_from_world_to_camera`), ``params`` None = the shipped
    fitted parameters.
    """

    def __init__(self, image: np.ndarray, distance: np.ndarray, airlight=255.0, space: str = "linear",
                 params: ScatterParams | None = None, intrinsics: Intrinsics | None = None, up=None):
        if image.ndim != 3 or image.shape[2] != 3:
            raise ValueError(f"image must be H×W×3 RGB, got shape {image.shape}")
        if image.shape[0] * image.shape[1] < 2:  # its glow and forward scatter move light between pixels
            raise ValueError(f"image is {image.shape[1]}×{image.shape[0]}: the scatter model needs at least 2 pixels")
        if space not in SPACES:
            raise ValueError(f"blend space must be one of {', '.join(SPACES)}, got {space!r}")
        check_distance(distance, image.shape[:2])
        self.image, self.dtype, self.space = image, image.dtype, space
        self.params = params if params is not None else load_params()
        p = self.params
        d, night = p.direct, p.night.luminance  # night: the day/night switch's luminance (0: off)
        h, w = image.shape[:2]
        scale = np.float32(full_scale(image.dtype))
        self.distance = distance.astype(np.float32, copy=False)
        a = airlight_rgb(airlight, image.dtype) / scale
        a_linear = a if space == "linear" else srgb_to_linear(a)
        if space == "linear":
            a = srgb_to_linear(a)
        self._a = [float(v) for v in a]
        # how much of a night image this is (night.luminance Y_g against the median luminance; 0 = day): the
        # glow is a night rule, the fog-lit objects and the sky-lit airlight are day rules
        y_med = median_luminance(image, self.distance) if d.exposure_key or d.flatten or night else None
        self.glow_weight = 1.0 if not night or y_med is None else night_weight(y_med, night)
        day = 1.0 - self.glow_weight if night else 1.0
        # the airlight's per-image gain from the share of sky in view (1: off)
        self.sky_gain = sky_gain(self.distance, p.airlight.sky_exponent * day) if p.airlight.sky_exponent else 1.0
        # the direct term's per-image gain and flattening (off: 1 and 0), folded into the colour planes
        self.exposure_gain = 1.0
        if d.exposure_key and y_med is not None:  # at night lamps, not the fog's light from above, light it
            self.exposure_gain = exposure_gain(y_med, d.exposure_key, a_linear) ** day
        flatten = d.flatten if y_med is not None else 0.0
        reference = 1.0 if y_med is None else (y_med if space == "linear" else float(linear_to_srgb(y_med)))
        gain = self.exposure_gain if space == "linear" else self.exposure_gain ** (1.0 / SRGB_GAMMA)
        self._planes = direct_planes(image, space, gain, flatten, reference)  # blend space (contiguous planes)
        self._buffers: dict[str, np.ndarray] = {}
        # β-independent parts of the blend: the airlight's gain e^(c·sin θ) (None: 1) and ℓ + μ,
        # so that the direct term's factor m·t = e^(−β(ℓ + μ)) is one exponential
        self._air_gain = self._log_gain = None
        if p.airlight.elevation:
            self._log_gain = np.multiply(smooth_elevation_sine((h, w), intrinsics, up),
                                         np.float32(p.airlight.elevation * day))
            self._air_gain = cv2.exp(self._log_gain)
        self._dist_mu = self.distance + np.float32(d.illumination) if d.illumination else self.distance
        self._scatter = p.psf.forward > 0 or p.glow.gain > 0
        if self._scatter:
            f = max(1, int(math.ceil(w / WORK_WIDTH)))
            self._small = (max(1, w // f), max(1, h // f))
            self._f_small = focal_px((h, w), intrinsics) * self._small[0] / w
            self._rgb_small = cv2.merge([cv2.resize(q, self._small, interpolation=cv2.INTER_AREA)
                                         for q in self._planes])
            self._dist_small = cv2.resize(self.distance, self._small, interpolation=cv2.INTER_NEAREST)
            self._glow_small = None
            if p.glow.gain > 0 and self.glow_weight > 1e-3:
                self._glow_small = self._glow_source(image, p.glow.threshold)
                if self._glow_small is not None and self.glow_weight < 1.0:
                    self._glow_small *= np.float32(self.glow_weight)

    def _glow_source(self, image: np.ndarray, threshold: float) -> np.ndarray | None:
        """The saturated pixels' light, rgb × s with s = clip((Y − thr)/(1 − thr), 0, 1) from the linear
        luminance Y (sky excluded), reduced to the PSF's copy (None: no such pixel). Only pixels whose
        green alone could reach the threshold (Y ≤ G·w_G + w_R + w_B) are decoded: lamps are few."""
        w_r, w_g, w_b = LUMINANCE_WEIGHTS
        g_min = max(0.0, (threshold - w_r - w_b) / w_g)
        green = np.ascontiguousarray(image[:, :, 1])
        if image.dtype in (np.uint8, np.uint16):
            first = int(np.searchsorted(_code_table(np.dtype(image.dtype)), g_min))  # first code ≥ g_min
            candidates = cv2.compare(green, first - 1, cv2.CMP_GT) if first <= full_scale(image.dtype) \
                else np.zeros(green.shape, np.uint8)
        else:
            g = green.astype(np.float32) / np.float32(full_scale(image.dtype))
            candidates = (srgb_to_linear(g) >= g_min).view(np.uint8)
        if not cv2.countNonZero(candidates):
            return None
        ys, xs = np.nonzero(candidates)
        keep = np.isfinite(self.distance[ys, xs])                          # the sky is not a lamp
        ys, xs = ys[keep], xs[keep]
        if not ys.size:
            return None
        px = image[ys, xs]
        lin = _code_table(np.dtype(image.dtype))[px] if image.dtype in (np.uint8, np.uint16) \
            else srgb_to_linear(px.astype(np.float32) / np.float32(full_scale(image.dtype)))
        lum = lin @ np.array(LUMINANCE_WEIGHTS, np.float32)
        sat = np.clip((lum - np.float32(threshold)) / np.float32(max(1e-3, 1.0 - threshold)), 0.0, 1.0)
        if self.params.glow.max_area:
            sat = sat * self._compact(ys, xs, sat > 0, image.shape[:2], self.params.glow.max_area)
            if not sat.any():
                return None
        light = (lin if self.space == "linear" else px.astype(np.float32) / np.float32(full_scale(image.dtype)))
        light = light * sat[:, None]
        return reduce_points(light, ys, xs, image.shape[:2], self._small)

    @staticmethod
    def _compact(ys: np.ndarray, xs: np.ndarray, lit: np.ndarray, shape: tuple[int, int],
                 max_area: float) -> np.ndarray:
        """1 for the ``lit`` pixels (at rows ``ys``, columns ``xs``) whose 8-connected region covers at
        most ``max_area`` of the image (lamps), 0 for the rest (lit surfaces)."""
        mask = np.zeros(shape, np.uint8)
        mask[ys[lit], xs[lit]] = 1
        _, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        small = stats[:, cv2.CC_STAT_AREA] <= max_area * shape[0] * shape[1]
        small[0] = False                                        # the background
        return (small[labels[ys, xs]] & lit).astype(np.float32)

    def _scattered_small(self, beta: float) -> np.ndarray | None:
        p = self.params
        if not self._scatter or beta == 0:
            return None
        m = np.float32(math.exp(-p.direct.illumination * beta))
        d = self._dist_small
        t = np.exp(d * np.float32(-beta))
        tf = np.exp(d * np.float32(-beta * (1.0 - p.psf.forward)))
        wt = (tf - t) * m
        src = cv2.multiply(self._rgb_small, cv2.merge([wt, wt, wt]))  # OpenCV: numpy's broadcast is slower here
        depth = np.where(np.isinf(d), np.float32(0.0), d * np.float32(beta))   # optical depth T = βℓ
        sigma = psf_sigma_rad(depth, p.psf.spread) * self._f_small
        glow = None
        if self._glow_small is not None:
            wg = (1.0 - t) * (m * np.float32(p.glow.gain))
            glow = cv2.multiply(self._glow_small, cv2.merge([wg, wg, wg]))
            if not p.glow.spread or p.glow.spread == p.psf.spread:
                src += glow
                glow = None
            elif p.glow.tail:                                 # the wings: the scene's wide PSF
                src += glow * np.float32(p.glow.tail)
                glow *= np.float32(1.0 - p.glow.tail)
        out = splat(src, sigma)
        if glow is not None:                                  # the core: the lamps' own, narrower PSF
            out += splat(glow, psf_sigma_rad(depth, p.glow.spread) * self._f_small)
        return out

    def _buffer(self, name: str) -> np.ndarray:
        """A full-size float32 work plane kept between calls (fresh 10 MB arrays cost page faults)."""
        buf = self._buffers.get(name)
        if buf is None:
            buf = self._buffers[name] = np.empty(self.image.shape[:2], np.float32)
        return buf

    def _scattered_planes(self, beta: float) -> list[np.ndarray] | None:
        small = self._scattered_small(beta)
        if small is None:
            return None
        h, w = self.image.shape[:2]
        planes = cv2.split(small)
        if (w, h) == self._small:
            return planes
        return [cv2.resize(q, (w, h), dst=self._buffer(f"s{c}"), interpolation=cv2.INTER_LINEAR)
                for c, q in enumerate(planes)]

    def scattered(self, beta: float) -> np.ndarray | None:
        """The PSF term (forward-scattered light and glow) for β, H×W×3 float32 in the blend
        space's scale (0–1), or None when the model has no such term."""
        planes = self._scattered_planes(beta)
        return None if planes is None else cv2.merge(planes)

    def _exp(self, distance: np.ndarray, beta: float, name: str) -> np.ndarray:
        """e^(−β·distance) into the work plane ``name`` (OpenCV's exp: ≈ 2e-7 relative to numpy's)."""
        buf = np.multiply(distance, np.float32(-beta), out=self._buffer(name))
        return cv2.exp(buf, dst=buf)

    def _blend_planes(self, beta: float) -> list[np.ndarray]:
        """The fogged colour planes for β (work buffers: valid until the next call):
        m·t·I + air·A + PSF term, per plane in two passes (add, multiply-accumulate)."""
        p = self.params
        if beta == 0:
            return direct_planes(self.image, self.space)
        mt = self._exp(self._dist_mu, beta, "t")               # m·t
        air = self._buffer("air")          # first e^(c·sin θ)·t_f, then A·e^(c·sin θ)·(1 − t_f)
        gain = self._air_gain
        if p.psf.forward == 0 and not p.direct.illumination:               # t_f = m·t
            gt = mt if gain is None else np.multiply(mt, gain, out=air)
        elif gain is None:
            gt = self._exp(self.distance, beta * (1.0 - p.psf.forward), "air")
        else:                                                   # one exponential: e^(c·sin θ − β(1−k)ℓ)
            gt = cv2.exp(cv2.scaleAdd(self.distance, -beta * (1.0 - p.psf.forward), self._log_gain, dst=air), dst=air)
        level = p.airlight.level * math.exp(-p.airlight.fade * beta) * self.sky_gain   # a·e^(−λβ)·(Ω/Ω₀)^(−ν)
        a = [v * level for v in self._a]
        uniform = a[0] == a[1] == a[2]                          # a grey airlight is folded into the air plane
        unit = a[0] if uniform else 1.0
        if gain is None:
            cv2.addWeighted(gt, -unit, gt, 0.0, unit, dst=air)
        else:
            cv2.addWeighted(gain, unit, gt, -unit, 0.0, dst=air)
        s = self._scattered_planes(beta)
        out = []
        for c, q in enumerate(self._planes):
            o = self._buffer(f"o{c}")
            if uniform:
                if s is not None:
                    cv2.add(air, s[c], dst=o)
                else:
                    o[...] = air
            elif s is not None:
                cv2.scaleAdd(air, a[c], s[c], dst=o)
            else:
                np.multiply(air, np.float32(a[c]), out=o)
            cv2.accumulateProduct(q, mt, o)
            out.append(o)
        return out

    def blend(self, beta: float) -> np.ndarray:
        """The fogged image for β as H×W×3 float32 in the blend space (0–1, not clipped)."""
        return cv2.merge(self._blend_planes(beta))

    def __call__(self, beta: float) -> np.ndarray:
        check_beta(beta)
        if beta == 0:
            return self.image.copy()
        out = self._blend_planes(beta)
        if self.space == "linear":
            out = [linear_to_srgb(q) for q in out]
        if self.dtype == np.uint8:  # scaled, rounded to nearest and saturated by OpenCV (all terms are ≥ 0)
            return cv2.merge([cv2.convertScaleAbs(q, alpha=255.0) for q in out])
        out = np.clip(cv2.merge(out), 0.0, 1.0)
        return from_float(out * np.float32(full_scale(self.dtype)), self.dtype)


def scatter(image: np.ndarray, distance: np.ndarray, beta: float, airlight=255.0, space: str = "linear",
            params: ScatterParams | None = None, intrinsics: Intrinsics | None = None, up=None) -> np.ndarray:
    """Scatter fog at one β (see the module docstring): ``image`` H×W×3 uint8/uint16/float RGB,
    ``distance`` ray distance in metres (+inf = sky), β in 1/m, ``airlight`` the horizon radiance
    in 8-bit units; ``params`` None = the shipped fitted parameters; returns the image's dtype."""
    check_beta(beta)
    return ScatterFogger(image, distance, airlight, space, params, intrinsics, up)(beta)


__all__ = ["KOSCHMIEDER", "PARAMS_FILE", "ScatterFogger", "ScatterParams", "load_params", "load_params_file",
           "scatter", "shipped_params_path"]
