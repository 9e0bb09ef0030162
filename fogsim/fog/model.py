"""Koschmieder fog: the standard law and the extended (smoothed-transmission) form.

Standard (paper Eq. 2):   I_fog = I·t + A·(1 − t),   t = exp(−β·ℓ)
Extended (the paper's "matrix-based" form): every pixel y spreads I(x)·t(y) + A·(1 − t(y))
over the k×k window around it with weights w(x − y); summed, this is Koschmieder's law with
a smoothed transmission, I_fog(x) = I(x)·(w∗t)(x) + A·(1 − (w∗t)(x)). Here w∗t is a separable
filter, normalised by the weight that falls inside the image, so the border is not darkened
(the reference loop leaves a dark frame there).

Units and conventions: ℓ is the *ray distance* from the camera in metres (convert planar
depth with :func:`fogsim.camera.planar_to_ray`); +inf (no hit, sky) gives t = 0, i.e. pure
airlight. β in 1/m. A in 8-bit units (255 = white) whatever the image dtype. Images are
uint8, uint16 or float (0–1) RGB and come back in the same dtype, rounded and clipped.
``space="srgb"`` blends the stored (gamma-encoded) values as the paper and Foggy Cityscapes
do; ``space="linear"`` blends in linear light, which is physically right.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from functools import lru_cache

import cv2
import numpy as np

from fogsim.colour import from_float, full_scale, linear_to_srgb, srgb_to_linear
from fogsim.schema.presets import MAX_KERNEL_SIZE
from fogsim.schema.vocabulary import KERNELS, SPACES


@dataclass(frozen=True)
class Kernel:
    """Weights w of the extended form.

    ``box``: uniform 1/k² over k×k (what the paper's reference run used, k = 19).
    ``gaussian``: normalised Gaussian, k×k, std ``sigma`` pixels (reference: 19, σ = 5).
    ``guided``: edge-aware — a guided filter of radius k//2 steered by the image, so the
    transmission of a near object does not bleed into the sky around it.
    """

    kind: str = "box"
    size: int = 19
    sigma: float = 5.0
    eps: float = 1e-3

    def __post_init__(self):
        if self.kind not in KERNELS:
            raise ValueError(f"kernel must be one of {', '.join(KERNELS)}, got {self.kind!r}")
        if self.size < 1 or self.size % 2 == 0 or self.size > MAX_KERNEL_SIZE:
            raise ValueError(f"kernel size must be a positive odd number ≤ {MAX_KERNEL_SIZE}, got {self.size}")
        if self.kind == "gaussian" and not self.sigma > 0:
            raise ValueError(f"Gaussian sigma must be > 0, got {self.sigma}")
        if self.kind == "guided" and not self.eps > 0:
            raise ValueError(f"guided-filter eps must be > 0, got {self.eps}")

    def weights_1d(self) -> np.ndarray:
        """The separable 1-D weights (sum 1) for box and Gaussian kernels."""
        if self.kind == "box":
            return np.full(self.size, 1.0 / self.size)
        r = np.arange(self.size) - self.size // 2
        g = np.exp(-(r ** 2) / (2.0 * self.sigma ** 2))
        return g / g.sum()

    def to_dict(self) -> dict:
        d = asdict(self)
        if self.kind != "gaussian":
            d.pop("sigma")
        if self.kind != "guided":
            d.pop("eps")
        return d


PAPER_KERNEL = Kernel("box", 19)


# ----------------------------------------------------------------------------- transmission
def check_distance(distance: np.ndarray, shape: tuple[int, int] | None = None) -> None:
    """Raise ValueError unless ``distance`` is an H×W map of values in [0, +inf]."""
    if distance.ndim != 2:
        raise ValueError(f"distance must be an H×W map, got shape {distance.shape}")
    if shape is not None and distance.shape != tuple(shape):
        raise ValueError(f"distance is {distance.shape[1]}×{distance.shape[0]} but the image is "
                         f"{shape[1]}×{shape[0]}")
    if np.isnan(distance).any():
        raise ValueError(f"distance has {int(np.isnan(distance).sum())} NaN pixels")
    if (distance < 0).any():
        raise ValueError(f"distance has {int((distance < 0).sum())} negative pixels")


def check_beta(beta: float) -> None:
    if not (np.isfinite(beta) and beta >= 0):
        raise ValueError(f"β must be a finite number ≥ 0 (1/m), got {beta}")


def transmission(distance: np.ndarray, beta: float) -> np.ndarray:
    """t = exp(−β·ℓ) as H×W float32; ℓ = +inf → 0."""
    check_beta(beta)
    if beta == 0:  # 0·inf would be NaN; clear air transmits everything, sky included
        return np.ones(distance.shape, np.float32)
    t = np.multiply(distance, np.float32(-beta), dtype=np.float32)
    return np.exp(t, out=t)


@lru_cache(maxsize=8)
def _border_weight(height: int, width: int, kernel: Kernel) -> np.ndarray:
    """1 / (weight of the kernel that falls inside the image), per pixel (1 in the interior)."""
    w, r = kernel.weights_1d(), kernel.size // 2
    wy = np.convolve(np.ones(height), w, mode="full")[r:r + height]
    wx = np.convolve(np.ones(width), w, mode="full")[r:r + width]
    inv = (1.0 / np.outer(wy, wx)).astype(np.float32)
    inv.flags.writeable = False
    return inv


def smooth_transmission(t: np.ndarray, kernel: Kernel, guide: np.ndarray | None = None) -> np.ndarray:
    """(w∗t) normalised at the border; ``guide`` (H×W float 0–1) is needed for ``guided``.

    Pixels outside the image contribute nothing, and each output is divided by the weight
    that fell inside, so a uniform t stays uniform up to the edge. Only the border bands
    (k//2 wide) need that division; the interior already has full weight.
    """
    if kernel.kind == "guided":
        if guide is None:
            raise ValueError("the guided kernel needs the image as a guide")
        from fogsim.deps import require_contrib
        require_contrib("guidedFilter")  # opencv-python installed over the contrib build removes it
        out = cv2.ximgproc.guidedFilter(guide.astype(np.float32), t, kernel.size // 2, kernel.eps)
        return np.clip(out, 0.0, 1.0, out=out)
    k = kernel.size
    if kernel.kind == "box":  # running sums: cost independent of k
        out = cv2.boxFilter(t, cv2.CV_32F, (k, k), normalize=True, borderType=cv2.BORDER_CONSTANT)
    else:
        w = kernel.weights_1d().astype(np.float32)
        out = cv2.sepFilter2D(t, cv2.CV_32F, w, w, borderType=cv2.BORDER_CONSTANT)
    inv, r = _border_weight(t.shape[0], t.shape[1], kernel), k // 2
    if 2 * r >= min(t.shape):  # bands would overlap: correct every pixel
        return np.multiply(out, inv, out=out)
    if r:
        for band in (np.s_[:r], np.s_[-r:], np.s_[r:-r, :r], np.s_[r:-r, -r:]):
            out[band] *= inv[band]
    return out


# ----------------------------------------------------------------------------- airlight
def airlight_rgb(airlight, dtype=np.uint8, name: str = "airlight") -> np.ndarray:
    """Airlight (scalar or RGB, 8-bit units) → float32 RGB in the scale of ``dtype``; a value
    outside [0, 255] is a ValueError naming ``name`` (the caller's word for it, e.g. a flag)."""
    a = np.broadcast_to(np.asarray(airlight, dtype=np.float64), (3,))
    if not np.all(np.isfinite(a)) or (a < 0).any() or (a > 255).any():
        raise ValueError(f"{name} must lie in [0, 255] (8-bit units), got {airlight}")
    return (a * (full_scale(dtype) / 255.0)).astype(np.float32)


def dark_channel(image: np.ndarray, patch: int = 15) -> np.ndarray:
    """He et al.'s dark channel of an H×W×3 image: the minimum over RGB and a ``patch``×``patch``
    window, H×W in the image's own scale and dtype (pass float32)."""
    return cv2.erode(image.min(axis=2), cv2.getStructuringElement(cv2.MORPH_RECT, (patch, patch)))


def estimate_airlight(image: np.ndarray, patch: int = 15, top_fraction: float = 0.001) -> np.ndarray:
    """Atmospheric light from the dark channel (He et al.; as Foggy Cityscapes uses it).

    Takes the ``top_fraction`` of pixels with the brightest :func:`dark_channel` and returns
    the per-channel median of the image there, as float RGB in 8-bit units.
    """
    img = image.astype(np.float32) * np.float32(255.0 / full_scale(image.dtype))
    dark = dark_channel(img, patch)
    n = max(1, int(round(dark.size * top_fraction)))
    idx = np.argpartition(dark.ravel(), dark.size - n)[-n:]
    return np.median(img.reshape(-1, 3)[idx], axis=0)


# ----------------------------------------------------------------------------- heterogeneous fog
def check_heterogeneity(amplitude: float, scale_px: float,
                        names: tuple[str, str] = ("heterogeneity amplitude", "heterogeneity scale")) -> None:
    """The range of :func:`density_field`'s parameters: 0 ≤ ``amplitude`` < 1 and ``scale_px`` ≥ 1
    pixel (finite: the random grid has one cell per ``scale_px`` pixels, so a smaller patch would be
    an allocation, not a pattern); a ValueError names the parameter by ``names`` (the caller's words)."""
    if not 0 <= amplitude < 1:
        raise ValueError(f"{names[0]} must be in [0, 1), got {amplitude}")
    if not 1 <= scale_px < float("inf"):
        raise ValueError(f"{names[1]} must be a finite number ≥ 1 pixel, got {scale_px}")


def density_field(shape: tuple[int, int], rng: np.random.Generator, amplitude: float = 0.3,
                  scale_px: float = 64.0) -> np.ndarray:
    """A smooth random field m(x) with mean exactly 1 and values in [1 − a, 1 + a].

    Multiplying β by m makes patchy fog with the same mean density. ``scale_px`` is the
    size of the patches in pixels; ``rng`` makes it reproducible (pass one seeded Generator).
    """
    check_heterogeneity(amplitude, scale_px)
    h, w = shape
    gh, gw = max(2, int(np.ceil(h / scale_px)) + 1), max(2, int(np.ceil(w / scale_px)) + 1)
    coarse = rng.standard_normal((gh, gw)).astype(np.float32)
    field = cv2.resize(coarse, (w, h), interpolation=cv2.INTER_CUBIC)
    field -= field.mean()
    peak = float(np.abs(field).max())
    if peak > 0 and amplitude > 0:
        field *= amplitude / peak
    else:
        field[...] = 0.0
    field += 1.0
    return field


# ----------------------------------------------------------------------------- the blend
class Fogger:
    """Fog one image at many densities, sharing the work that does not depend on β.

    >>> fogger = Fogger(image, distance, airlight=255, space="srgb", kernel=None)
    >>> foggy = [fogger(beta) for beta in (0.03, 0.06)]

    ``distance``: ray distance ℓ in metres (H×W, ≥ 0, +inf = sky). ``kernel=None`` is the
    standard law; a :class:`Kernel` gives the extended form. ``density`` (optional H×W field
    with mean 1, see :func:`density_field`) scales β per pixel.

    The blend I·t + A·(1 − t) is computed as A + (I − A)·t on contiguous float32 colour
    planes; for uint8 sRGB images OpenCV rounds and saturates in the same pass.
    """

    def __init__(self, image: np.ndarray, distance: np.ndarray, airlight=255.0, space: str = "srgb",
                 kernel: Kernel | None = None, density: np.ndarray | None = None):
        if image.ndim != 3 or image.shape[2] != 3:
            raise ValueError(f"image must be H×W×3 RGB, got shape {image.shape}")
        if space not in SPACES:
            raise ValueError(f"blend space must be one of {', '.join(SPACES)}, got {space!r}")
        check_distance(distance, image.shape[:2])
        self.image, self.dtype, self.space, self.kernel = image, image.dtype, space, kernel
        scale = np.float32(full_scale(image.dtype))
        a = airlight_rgb(airlight, image.dtype)
        self.distance = distance.astype(np.float32, copy=False)
        if density is not None:
            check_distance(density, image.shape[:2])
            self.distance = self.distance * density
        planes = [np.ascontiguousarray(image[:, :, c], dtype=np.float32) for c in range(3)]
        if space == "linear":
            a = srgb_to_linear(a / scale)
            planes = [srgb_to_linear(p / scale) for p in planes]
        self._a = a
        self._diff = [p - a[c] for c, p in enumerate(planes)]  # I − A per colour plane
        self._fast_u8 = self.dtype == np.uint8 and space == "srgb"
        self._guide = None
        if kernel is not None and kernel.kind == "guided":
            self._guide = sum(planes) / np.float32(3 * (1 if space == "linear" else scale))

    def transmission(self, beta: float) -> np.ndarray:
        """The transmission used for β: exp(−β·ℓ), smoothed by the kernel if there is one."""
        t = transmission(self.distance, beta)
        if self.kernel is not None:
            t = smooth_transmission(t, self.kernel, self._guide)
        return t

    def __call__(self, beta: float) -> np.ndarray:
        if beta == 0:
            return self.image.copy()
        t = self.transmission(beta)
        if self._fast_u8:  # A + (I − A)·t, rounded to nearest and saturated by OpenCV
            return cv2.merge([cv2.convertScaleAbs(cv2.multiply(d, t), alpha=1.0, beta=float(a))
                              for d, a in zip(self._diff, self._a)])
        out = np.stack([d * t + a for d, a in zip(self._diff, self._a)], axis=-1)
        if self.space == "linear":
            out = linear_to_srgb(out)
            if self.dtype.kind != "f":
                out *= np.float32(full_scale(self.dtype))
        return from_float(out, self.dtype)


def koschmieder(image: np.ndarray, distance: np.ndarray, beta: float, airlight=255.0,
                space: str = "srgb", density: np.ndarray | None = None) -> np.ndarray:
    """Standard Koschmieder fog: I·t + A·(1 − t), t = exp(−β·ℓ). See the module docstring."""
    check_beta(beta)
    return Fogger(image, distance, airlight, space, None, density)(beta)


def koschmieder_extended(image: np.ndarray, distance: np.ndarray, beta: float,
                         kernel: Kernel = PAPER_KERNEL, airlight=255.0, space: str = "srgb",
                         density: np.ndarray | None = None) -> np.ndarray:
    """Extended form: Koschmieder's law with the transmission smoothed by ``kernel``."""
    check_beta(beta)
    return Fogger(image, distance, airlight, space, kernel, density)(beta)
