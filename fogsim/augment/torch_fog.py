"""The torch front ends: :func:`fog_batch` (a batch, per-sample β, CPU or CUDA) and
:class:`FogV2`, a torchvision v2 transform.

:func:`fog_batch` computes what :func:`fogsim.augment.spec.apply_fog` does, on tensors:
I·t + A·(1 − t) with t = exp(−β·ℓ) per sample (ℓ = +inf → t = 0 for β > 0; β = 0 returns the
image), in sRGB or linear light, standard law or the extended form with a ``box`` kernel
(``avg_pool2d`` without the padding: the same border-normalised mean as OpenCV's
``boxFilter`` path). Integer images are rounded half up and clipped, so results equal the
NumPy reference to 1 LSB (OpenCV's rounding of exact halves differs). Heterogeneity and the
Gaussian / guided kernels are NumPy-only (a ValueError here).

:class:`FogV2` takes the sample's depth as a **floating-point** ``tv_tensors.Mask`` (1×H×W,
metres): v2's geometric transforms resize and crop it with the image (nearest), and it tells
the depth apart from integer instance / semantic masks. Only the image is changed.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from fogsim.augment.spec import FogSpec
from fogsim.camera import ray_factor
from fogsim.deps import require

torch = require("torch", "augment")
F = require("torch.nn.functional", "augment")

_SCALE = {torch.uint8: 255.0, torch.uint16: 65535.0}


def draw_batch(n: int, rng: np.random.Generator, spec: FogSpec = FogSpec()) -> tuple[np.ndarray, np.ndarray]:
    """``n`` draws of :meth:`FogSpec.draw` from ``rng``: (β (n,) in 1/m, airlight (n, 3) 8-bit units)."""
    draws = [spec.draw(rng) for _ in range(n)]
    return (np.array([d.beta for d in draws], np.float64), np.array([d.airlight for d in draws], np.float64))


def _srgb_to_linear(x):
    return torch.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def _linear_to_srgb(x):
    x = x.clamp(min=0.0)
    return torch.where(x <= 0.0031308, x * 12.92, 1.055 * x ** (1 / 2.4) - 0.055)


def _per_sample(value, n: int, width: int, like) -> Any:
    """A number, (n,) or (n, width) → an (n, width, 1, 1) float32 tensor on ``like``'s device."""
    v = torch.as_tensor(value, dtype=torch.float32, device=like.device)
    if v.ndim == 0:
        v = v.expand(n)
    if v.ndim == 1:
        v = v[:, None].expand(n, width) if v.shape[0] == n else v[None, :].expand(n, width)
    if v.shape != (n, width):
        raise ValueError(f"expected a number, ({n},) or ({n}, {width}) values, got shape {tuple(v.shape)}")
    return v.reshape(n, width, 1, 1)


def ray_distance(depth, spec: FogSpec):
    """B×1×H×W ray distance (metres) from the depth as ``spec`` describes it."""
    if spec.depth == "planar":
        h, w = depth.shape[-2:]
        return depth * torch.tensor(ray_factor(spec.camera(h, w)), device=depth.device)
    return depth


def fog_batch(images, depth, beta, airlight=255.0, spec: FogSpec = FogSpec()):
    """Fog a batch: ``images`` B×3×H×W (uint8, uint16 or float 0–1), ``depth`` B×1×H×W metres
    (ray distance unless ``spec.depth == "planar"``; +inf = sky, 0 = hole → no fog), ``beta``
    a number or (B,) in 1/m, ``airlight`` a number, (B,) or (B, 3) in 8-bit units. Same dtype
    and device back. ``spec`` supplies depth convention, camera, blend space and kernel."""
    if images.ndim != 4 or images.shape[1] != 3:
        raise ValueError(f"images must be B×3×H×W, got shape {tuple(images.shape)}")
    n, _, h, w = images.shape
    if depth.shape != (n, 1, h, w):
        raise ValueError(f"depth must be B×1×H×W = {(n, 1, h, w)}, got {tuple(depth.shape)}")
    if spec.heterogeneity:
        raise ValueError("heterogeneity is NumPy-only (fogsim.augment.apply_fog)")
    if spec.model != "koschmieder":
        raise ValueError(f"the torch path has Koschmieder's law only, got model {spec.model!r} "
                         "(fogsim.augment.apply_fog has the scatter model)")
    if spec.kernel is not None and spec.kernel.kind != "box":
        raise ValueError(f"the torch path has the box kernel only, got {spec.kernel.kind!r}")
    distance = ray_distance(depth.to(torch.float32), spec)
    if torch.isnan(distance).any() or (distance < 0).any():
        raise ValueError("depth has NaN or negative values")
    b = _per_sample(beta, n, 1, images)
    if (b < 0).any() or not torch.isfinite(b).all():
        raise ValueError("β must be finite and ≥ 0 (1/m)")
    clear = b == 0
    # β·ℓ capped at 80: exp(−80) ≈ 2e−35 is 0 to any pixel depth, and keeps exp out of float32's
    # denormal range (arithmetic on denormals is ~10× slower on CPUs)
    t = torch.where(clear, torch.ones_like(distance), torch.exp(-(b * distance).clamp_(max=80.0)))
    if spec.kernel is not None:
        k = spec.kernel.size
        t = F.avg_pool2d(t, k, stride=1, padding=k // 2, count_include_pad=False)
    scale = _SCALE.get(images.dtype, 1.0)
    a = _per_sample(airlight, n, 3, images) * (scale / 255.0)
    x = images.to(torch.float32)
    if spec.space == "linear":
        a, x = _srgb_to_linear(a / scale), _srgb_to_linear(x / scale)
    out = a + (x - a) * t
    if spec.space == "linear":
        out = _linear_to_srgb(out) * (scale if images.dtype in _SCALE else 1.0)
    if images.dtype in _SCALE:
        out = torch.floor(out + 0.5).clamp_(0.0, scale)
    out = out.to(images.dtype)
    return torch.where(clear, images, out)


def batch_timer(image: np.ndarray, distance: np.ndarray, n: int, device: str, rng: np.random.Generator,
                spec: FogSpec = FogSpec()):
    """A function fogging ``n`` copies of ``image`` (H×W×3 uint8) over ``distance`` as one batch on
    ``device`` with fresh draws, synchronised on CUDA (what ``fogsim bench augment`` times);
    ``device="cpu"`` runs on one thread."""
    if device == "cpu":
        torch.set_num_threads(1)
    x = torch.from_numpy(image).permute(2, 0, 1)[None].repeat(n, 1, 1, 1).to(device)
    z = torch.from_numpy(np.ascontiguousarray(distance))[None, None].repeat(n, 1, 1, 1).to(device)

    def run():
        beta, air = draw_batch(n, rng, spec)
        fog_batch(x, z, torch.from_numpy(beta), torch.from_numpy(air), spec)
        if device != "cpu":
            torch.cuda.synchronize()
    run()  # warm-up (CUDA context, kernels)
    return run


def cuda_available() -> bool:
    return bool(torch.cuda.is_available())


v2 = require("torchvision.transforms.v2", "augment")
tv_tensors = require("torchvision.tv_tensors", "augment")


class FogV2(v2.Transform):
    """Koschmieder fog as a torchvision v2 transform; parameters as :class:`FogSpec`, ``seed``
    seeds its own generator (deterministic draws). The β of the last call is ``last_beta``.

        t = v2.Compose([v2.RandomHorizontalFlip(), FogV2(beta=(0, 0.12), seed=0)])
        image, depth, boxes = t(tv_tensors.Image(rgb), tv_tensors.Mask(depth_m), boxes)
    """

    def __init__(self, beta=(0.0, 0.12), seed: int | None = None, **spec: Any):
        super().__init__()
        self.spec = FogSpec(beta=beta, **spec)
        self.rng = np.random.default_rng(seed)
        self.last_beta: float | None = None

    def make_params(self, flat_inputs: list[Any]) -> dict[str, Any]:
        depths = [x for x in flat_inputs if isinstance(x, tv_tensors.Mask) and x.is_floating_point()]
        if len(depths) != 1:
            raise ValueError(f"FogV2 needs exactly one floating-point tv_tensors.Mask (the depth, metres); "
                             f"got {len(depths)}")
        beta, airlight = draw_batch(1, self.rng, self.spec)
        self.last_beta = float(beta[0])
        return {"depth": depths[0], "beta": beta, "airlight": airlight}

    def transform(self, inpt: Any, params: dict[str, Any]) -> Any:
        if isinstance(inpt, tv_tensors.Mask) or not (isinstance(inpt, tv_tensors.Image) or
                                                      type(inpt) is torch.Tensor):
            return inpt
        depth = params["depth"].as_subclass(torch.Tensor)
        depth = depth.reshape(1, 1, *depth.shape[-2:])
        image = inpt.as_subclass(torch.Tensor)
        out = fog_batch(image[None], depth, params["beta"], params["airlight"], self.spec)[0]
        return tv_tensors.wrap(out, like=inpt) if isinstance(inpt, tv_tensors.Image) else out
