"""A camera that is not a perfect pinhole: lens distortion, vignetting, exposure, sensor noise,
JPEG — applied to an 8-bit sRGB image after the fog (numpy + OpenCV; no Blender).

The camera sees the fogged scene, so :func:`apply_sensor` runs on each fog level's image, in the
order light takes: lens (radial distortion, then vignetting), exposure, the sensor (shot + read
noise, in linear light), the 8-bit sRGB encoding, JPEG. Depth and the instance mask are
*resampled* through the same distortion by nearest neighbour (:func:`distort_nearest`): their
values stay exact and line up with the image, so boxes from the distorted mask match it.

Models (pixels: OpenCV convention, integer coordinates are pixel centres; K the pinhole
intrinsics the scene was rendered with):

* **Radial distortion**, OpenCV's model with coefficients ``[k1, k2, p1, p2, k3]``: a ray through
  normalised point (x, y) = ((u − cx)/fx, (v − cy)/fy), r² = x² + y², lands at
  x_d = x·(1 + k1 r² + k2 r⁴ + k3 r⁶) + 2 p1 x y + p2 (r² + 2x²) (y_d likewise), pixel
  (fx x_d + cx, fy y_d + cy). The distorted image samples the rendered one where
  OpenCV's iterative point undistortion maps each of its pixels; a pixel seeing outside the render is black
  (mask 0, depth +inf).
* **Vignetting**, the cos⁴ law generalised: gain(u, v) = cos(θ)^a, cos θ = 1/√(1 + x² + y²)
  (θ the angle off the optical axis), a = ``vignetting`` (4 = natural vignetting; 0 = off).
* **Exposure**: linear light × 2^EV (``exposure_ev``).
* **Noise**: signal in electrons e = linear · ``full_well_e`` (white = full well); shot noise
  Poisson(e), read noise Normal(0, ``read_noise_e``²); back to linear ÷ full well, so the
  variance at linear value s is s / full_well + (read_noise / full_well)². Seeded: one
  ``numpy.random.Generator`` per image.
* **JPEG**: encoded at ``jpeg_quality`` (1–100) with OpenCV and decoded (the file written stays a
  lossless PNG that holds the JPEG's artefacts).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from fogsim.camera import Intrinsics
from fogsim.colour import linear_to_srgb8, srgb_to_linear
from fogsim.schema.base import check
from fogsim.schema.presets import SensorSpec

__all__ = ["Sensor", "apply_sensor", "distort_nearest", "distortion_maps", "distort_points", "jpeg",
           "shot_read_noise", "vignette_gain"]


@dataclass(frozen=True)
class Sensor:
    """The camera model of a preset's ``sensor`` block (:class:`fogsim.schema.presets.SensorSpec`)."""

    exposure_ev: float = 0.0
    vignetting: float = 0.0
    distortion: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)  # OpenCV k1, k2, p1, p2, k3
    full_well_e: float | None = None  # None = no noise
    read_noise_e: float = 0.0
    jpeg_quality: int | None = None  # None = no JPEG

    @classmethod
    def from_dict(cls, d: dict) -> "Sensor":
        """The model of a preset's ``sensor`` object, checked (a bad one is a ValueError); the
        defaults are :class:`~fogsim.schema.presets.SensorSpec`'s."""
        spec = check(d, SensorSpec, prefix="sensor")
        dist = list(spec.distortion or [])
        return cls(exposure_ev=spec.exposure_ev, vignetting=spec.vignetting,
                   distortion=tuple(dist + [0.0] * (5 - len(dist))),
                   full_well_e=None if spec.noise is None else spec.noise.full_well_e,
                   read_noise_e=0.0 if spec.noise is None else spec.noise.read_noise_e,
                   jpeg_quality=spec.jpeg_quality)

    @property
    def distorts(self) -> bool:
        return any(v != 0 for v in self.distortion)


def _matrix(K: Intrinsics) -> np.ndarray:
    return np.array([[K.fx, 0, K.cx], [0, K.fy, K.cy], [0, 0, 1]], np.float64)


def distort_points(uv: np.ndarray, K: Intrinsics, coeffs) -> np.ndarray:
    """Pinhole pixels (N×2) → where the distorting lens puts them (OpenCV's forward model)."""
    uv = np.asarray(uv, np.float64).reshape(-1, 2)
    pts = np.column_stack([(uv[:, 0] - K.cx) / K.fx, (uv[:, 1] - K.cy) / K.fy, np.ones(len(uv))])
    out, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), _matrix(K), np.asarray(coeffs, np.float64))
    return out.reshape(-1, 2)


def undistort_points(points: np.ndarray, camera: np.ndarray, coeffs) -> np.ndarray:
    """Pinhole pixels (N×1×2) of distorted pixels ``points`` (N×1×2) for the 3×3 ``camera`` and
    OpenCV ``coeffs``, iterated to convergence (50 iterations, 1e-9): ``cv2.undistortPointsIter`` in
    OpenCV 4, ``cv2.undistortPoints`` with a termination criterion in OpenCV 5 (which dropped Iter)."""
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-9)
    coeffs = np.asarray(coeffs, np.float64)
    if hasattr(cv2, "undistortPointsIter"):
        return cv2.undistortPointsIter(points, camera, coeffs, None, camera, criteria)
    return cv2.undistortPoints(points, camera, coeffs, R=None, P=camera, criteria=criteria)


@lru_cache(maxsize=8)
def _maps(fx, fy, cx, cy, w, h, coeffs: tuple) -> tuple[np.ndarray, np.ndarray]:
    K = Intrinsics(fx, fy, cx, cy, w, h)
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    grid = np.stack([u.ravel(), v.ravel()], axis=1).reshape(-1, 1, 2)
    src = undistort_points(grid, _matrix(K), coeffs)
    src = src.reshape(h, w, 2)
    src = np.where(np.abs(src) < 1e7, src, np.nan).astype(np.float32)  # a diverged inverse: no source pixel
    return np.ascontiguousarray(src[..., 0]), np.ascontiguousarray(src[..., 1])


def distortion_maps(K: Intrinsics, coeffs) -> tuple[np.ndarray, np.ndarray]:
    """For every pixel of the distorted image, the pinhole pixel it sees (map_x, map_y for
    ``cv2.remap``), from :func:`undistort_points`."""
    return _maps(K.fx, K.fy, K.cx, K.cy, K.width, K.height, tuple(float(c) for c in coeffs))


def distortion_problem(K: Intrinsics, coeffs) -> str | None:
    """Why the OpenCV ``coeffs`` make nonsense of camera ``K``'s image, or None. Coefficients inside
    the schema's range can still fold the lens mapping over the image (a black ring, the image
    repeated mirrored beyond it): every pixel of the distorted image must see one ray — the
    inverse map found by :func:`undistort_points` must map back onto the pixel (within 0.05 px) —
    and the radial mapping r_d = r·(1 + k1 r² + k2 r⁴ + k3 r⁶) must rise monotonically out to the
    farthest ray any pixel sees (dr_d/dr > 0)."""
    c = tuple(float(x) for x in coeffs) + (0.0,) * (5 - len(coeffs))
    k1, k2, k3 = c[0], c[1], c[4]
    mx, my = distortion_maps(K, c)
    seen = np.stack([mx.ravel(), my.ravel()], axis=1).astype(np.float64)
    where = f"at this camera ({K.width}×{K.height}, fx {K.fx:.4g} px)"
    if not np.isfinite(seen).all():
        return f"folds the image {where}: some pixels see no ray (the lens mapping has no inverse there)"
    v, u = np.mgrid[0:K.height, 0:K.width]
    back = distort_points(seen, K, c)
    miss = np.hypot(back[:, 0] - u.ravel(), back[:, 1] - v.ravel())
    if not miss.max() <= 0.05:
        worst = int(np.argmax(miss))
        return (f"folds the image {where}: the lens mapping is not one-to-one over it (pixel "
                f"({worst % K.width}, {worst // K.width}) sees no ray; a black ring and the image repeated "
                "beyond it); use smaller coefficients")
    r = np.linspace(0.0, float(np.hypot((seen[:, 0] - K.cx) / K.fx, (seen[:, 1] - K.cy) / K.fy).max()), 4097)
    slope = 1 + 3 * k1 * r**2 + 5 * k2 * r**4 + 7 * k3 * r**6
    if not (slope > 0).all():
        return (f"folds the image {where}: the radial mapping r·(1 + k1 r² + k2 r⁴ + k3 r⁶) stops rising at "
                f"r = {r[np.argmax(slope <= 0)]:.3g}, inside the image (rays beyond it land back inside); use "
                "smaller coefficients")
    return None


def distort_nearest(array: np.ndarray, K: Intrinsics, coeffs, outside) -> np.ndarray:
    """A mask or depth map resampled into the distorted image by nearest neighbour (values
    exact); pixels that see outside the render get ``outside`` (mask 0, depth +inf)."""
    mx, my = distortion_maps(K, coeffs)
    ui, vi = np.rint(mx).astype(np.int64), np.rint(my).astype(np.int64)
    inside = (ui >= 0) & (ui < K.width) & (vi >= 0) & (vi < K.height)
    out = np.full(array.shape, outside, dtype=array.dtype)
    out[inside] = array[vi[inside], ui[inside]]
    return out


def vignette_gain(K: Intrinsics, a: float) -> np.ndarray:
    """H×W gain cos(θ)^a, θ the angle of the pixel's ray off the optical axis (a = 4: cos⁴ law)."""
    v, u = np.mgrid[0:K.height, 0:K.width].astype(np.float64)
    r2 = ((u - K.cx) / K.fx) ** 2 + ((v - K.cy) / K.fy) ** 2
    return ((1.0 + r2) ** (-a / 2.0)).astype(np.float32)


def shot_read_noise(linear: np.ndarray, full_well_e: float, read_noise_e: float,
                    rng: np.random.Generator) -> np.ndarray:
    """Linear light with shot (Poisson in electrons) and read (Gaussian) noise added."""
    electrons = rng.poisson(np.clip(linear, 0.0, None) * full_well_e).astype(np.float32)
    if read_noise_e > 0:
        electrons += rng.normal(0.0, read_noise_e, linear.shape).astype(np.float32)
    return electrons / np.float32(full_well_e)


def jpeg(image: np.ndarray, quality: int) -> np.ndarray:
    """An 8-bit RGB image through JPEG at ``quality`` (OpenCV's encoder) and back."""
    ok, buf = cv2.imencode(".jpg", np.ascontiguousarray(image[..., ::-1]), [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise RuntimeError("OpenCV could not JPEG-encode the image")
    return np.ascontiguousarray(cv2.imdecode(buf, cv2.IMREAD_COLOR)[..., ::-1])


def apply_sensor(image: np.ndarray, K: Intrinsics, sensor: Sensor, rng: np.random.Generator) -> np.ndarray:
    """An 8-bit sRGB H×W×3 image as this camera records it (lens, exposure, noise, JPEG)."""
    linear = srgb_to_linear(image.astype(np.float32) / np.float32(255.0))
    if sensor.distorts:
        mx, my = distortion_maps(K, sensor.distortion)
        linear = cv2.remap(linear, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    if sensor.vignetting:
        linear *= vignette_gain(K, sensor.vignetting)[..., None]
    if sensor.exposure_ev:
        linear *= np.float32(2.0 ** sensor.exposure_ev)
    if sensor.full_well_e:
        linear = shot_read_noise(linear, sensor.full_well_e, sensor.read_noise_e, rng)
    out = linear_to_srgb8(linear)
    return jpeg(out, sensor.jpeg_quality) if sensor.jpeg_quality else out
