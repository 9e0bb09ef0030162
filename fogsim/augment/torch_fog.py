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

from fogsim.augment.checks import FLOAT_DTYPES, check_image_dtype, check_size, check_unit_range, dtype_name
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


def _per_sample(value, n: int, width: int, like, name: str) -> Any:
    """A number, (n,) or (n, width) → an (n, width, 1, 1) float32 tensor on ``like``'s device; anything
    else is a TypeError / ValueError naming ``name`` (``beta``, ``airlight``)."""
    forms = f"a number or {n} values" if width == 1 else f"a number, {n} values (one per sample), {width} (R, G, B) " \
        f"or {n}×{width}"
    if isinstance(value, (str, bytes)) or value is None or (isinstance(value, torch.Tensor) and
                                                          (value.dtype == torch.bool or value.is_complex())):
        raise TypeError(f"{name} must be {forms}, got {type(value).__name__} {value!r}"[:200])
    try:
        v = torch.as_tensor(value, dtype=torch.float32, device=like.device)
    except (TypeError, ValueError, RuntimeError):
        raise TypeError(f"{name} must be {forms}, got {type(value).__name__} {value!r}"[:200]) from None
    if v.ndim == 1 and v.shape[0] in (n, width):
        v = v[:, None].expand(n, width) if v.shape[0] == n else v[None, :].expand(n, width)
    elif v.ndim == 0:
        v = v.expand(n, width)
    if v.shape != (n, width):
        raise ValueError(f"{name} must be {forms} for this batch of {n}, got shape {tuple(v.shape)}")
    return v.reshape(n, width, 1, 1)


def check_tensor_image(images, batched: bool = True, name: str = "images") -> tuple[int, int, int]:
    """(B, H, W) of a B×3×H×W (``batched``) or 3×H×W tensor the fog supports (:mod:`fogsim.augment.checks`)."""
    shape = "B×3×H×W" if batched else "3×H×W"
    if not isinstance(images, torch.Tensor):
        hint = " (torch.from_numpy(x).permute(0, 3, 1, 2) turns B×H×W×3 NumPy images into one)" \
            if isinstance(images, np.ndarray) else ""
        raise TypeError(f"{name} must be a torch.Tensor {shape}, got {type(images).__name__}{hint}")
    if images.ndim != (4 if batched else 3) or images.shape[-3] != 3:
        extra = "; FogV2 transforms one image — for a batch use fog_batch" if not batched and images.ndim == 4 else ""
        raise ValueError(f"{name} must be {shape}, got shape {tuple(images.shape)}{extra}")
    kind = check_image_dtype(images.dtype, name)
    h, w = images.shape[-2:]
    check_size(h, w, name)
    if kind in FLOAT_DTYPES:
        lo, hi = torch.aminmax(images.detach().float())
        check_unit_range(float(lo), float(hi), name)
    return (images.shape[0] if batched else 1), h, w


def _check_depth_tensor(depth, shape: tuple, name: str = "depth") -> None:
    if not isinstance(depth, torch.Tensor):
        raise TypeError(f"{name} must be a torch.Tensor B×1×H×W of distances (metres), got {type(depth).__name__}")
    if depth.dtype == torch.bool or depth.is_complex():
        raise TypeError(f"{name} must hold real numbers (metres), got dtype {dtype_name(depth.dtype)}")
    if tuple(depth.shape) != shape:
        raise ValueError(f"{name} must be B×1×H×W = {shape}, got {tuple(depth.shape)}")


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
    n, h, w = check_tensor_image(images)
    _check_depth_tensor(depth, (n, 1, h, w))
    if not isinstance(spec, FogSpec):
        raise TypeError(f"spec must be a fogsim.augment.FogSpec, got {type(spec).__name__}")
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
    b = _per_sample(beta, n, 1, images, "beta")
    if (b < 0).any() or not torch.isfinite(b).all():
        raise ValueError("beta must be finite and ≥ 0 (1/m)")
    a = _per_sample(airlight, n, 3, images, "airlight")
    if not (torch.isfinite(a).all() and (a >= 0).all() and (a <= 255).all()):
        raise ValueError("airlight must be finite and in [0, 255] (8-bit units)")
    clear = b == 0
    # β·ℓ capped at 80: exp(−80) ≈ 2e−35 is 0 to any pixel depth, and keeps exp out of float32's
    # denormal range (arithmetic on denormals is ~10× slower on CPUs)
    t = torch.where(clear, torch.ones_like(distance), torch.exp(-(b * distance).clamp_(max=80.0)))
    if spec.kernel is not None:
        k = spec.kernel.size
        t = F.avg_pool2d(t, k, stride=1, padding=k // 2, count_include_pad=False)
    scale = _SCALE.get(images.dtype, 1.0)
    a = a * (scale / 255.0)
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


def __getattr__(name: str):
    """``FogV2`` is made on first use: only it needs torchvision (a torch-only user has fog_batch)."""
    if name == "FogV2":
        cls = globals()["FogV2"] = _fog_v2()
        return cls
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _fog_v2():
    v2 = require("torchvision.transforms.v2", "augment")
    tv_tensors = require("torchvision.tv_tensors", "augment")

    class FogV2(v2.Transform):
        """Koschmieder fog as a torchvision v2 transform; parameters as :class:`FogSpec`, ``seed``
        seeds its own generator (deterministic draws). The β of the last call is ``last_beta``.

            t = v2.Compose([v2.RandomHorizontalFlip(), FogV2(beta=(0, 0.12), seed=0)])
            image, depth, boxes = t(tv_tensors.Image(rgb), tv_tensors.Mask(depth_m), boxes)

        One image per call (C×H×W, with its depth 1×H×W or H×W); a batch is :func:`fog_batch`'s.
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
            image = inpt.as_subclass(torch.Tensor)
            _, h, w = check_tensor_image(image, batched=False, name="image")
            depth = params["depth"].as_subclass(torch.Tensor)
            if depth.shape[-2:] != (h, w) or depth.numel() != h * w:
                raise ValueError(f"the depth Mask must be 1×H×W = 1×{h}×{w} like the image, got "
                                 f"{tuple(depth.shape)}")
            depth = depth.reshape(1, 1, h, w)
            out = fog_batch(image[None], depth, params["beta"], params["airlight"], self.spec)[0]
            return tv_tensors.wrap(out, like=inpt) if isinstance(inpt, tv_tensors.Image) else out

    FogV2.__module__ = __name__
    return FogV2
