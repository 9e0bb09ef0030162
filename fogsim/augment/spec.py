"""What a fog augmentation draws per sample, and the NumPy reference that applies it.

:class:`FogSpec` holds the configuration shared by every front end (albumentations, torchvision,
the batched torch function, the Ultralytics training hook): the range or list β is drawn from,
uniform in β or in visibility, the airlight and its jitter, the depth convention, the blend
space, the extended kernel and heterogeneity. :meth:`FogSpec.draw` draws one sample's
parameters from a NumPy ``Generator`` (seeded by the caller: the same seed gives the same
draws); :func:`apply_fog` is the reference every other path is tested against — the fog record's
fogger (:class:`fogsim.fog.engine.FogSettings`, as ``fogsim fog`` and a render apply it) with the
depth converted.

Depth requirements (docs/augment.md): metres; **ray distance** from the camera centre by
default, or planar Z along the optical axis with ``depth="planar"`` and the camera's
intrinsics (or horizontal field of view); +inf = sky (pure airlight when β > 0); 0 = a hole,
which gets *no* fog (t = 1) — fill holes first (:mod:`fogsim.fog.fill`) where they matter; NaN
or negative depth is a ValueError.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from fogsim.augment.checks import check_airlight, check_beta, check_numpy_depth, check_numpy_image, is_number
from fogsim.camera import Intrinsics, planar_to_ray
from fogsim.fog.engine import FogSettings, Heterogeneity
from fogsim.fog.levels import beta_from_visibility, visibility_from_beta
from fogsim.fog.model import Kernel, check_heterogeneity
from fogsim.schema.vocabulary import POST_PROCESS_KINDS

DEPTH_KINDS = ("ray", "planar")
SAMPLING = ("beta", "visibility")


@dataclass(frozen=True)
class Draw:
    """One sample's fog: β in 1/m, airlight RGB in 8-bit units, optional density field."""

    beta: float
    airlight: tuple[float, float, float]
    density: np.ndarray | None = field(default=None, compare=False, repr=False)


@dataclass(frozen=True)
class FogSpec:
    """How fog is drawn and applied per sample.

    ``beta``: a ``(low, high)`` tuple is a range in 1/m; a list (or a tuple of another length)
    is a set of values, one picked uniformly; a number is that β always.
    ``sample``: for a range, ``"beta"`` draws β uniformly, ``"visibility"`` draws the visibility
    V = ln 20 / β uniformly between V(high) and V(low) (needs low > 0: V(0) is infinite).
    ``airlight``: 8-bit units (255 = white); ``airlight_jitter``: ± that many units, uniform,
    the same for R, G, B (grey fog). ``depth``: ``"ray"`` (default) or ``"planar"``, which needs
    ``intrinsics`` (scaled to the image's size when it differs) or ``hfov`` in degrees.
    ``kernel``: None = standard law, a :class:`~fogsim.fog.model.Kernel` = extended form.
    ``heterogeneity``: amplitude a of a smooth density field (0 = homogeneous), patches of
    ``heterogeneity_scale`` pixels (:func:`~fogsim.fog.model.density_field`).
    ``model``: ``"koschmieder"`` (default) or ``"scatter"`` — :func:`fogsim.fog.scatter.scatter`
    (forward scatter, elevation airlight, glow; NumPy and albumentations only, no kernel or
    heterogeneity), with the parameter file ``scatter_params`` (None = the shipped fitted one).
    ``space`` None is the model's own: sRGB for Koschmieder (the paper's), linear light for scatter
    (where it was fitted). :attr:`fog` is the fog record all this applies
    (:class:`fogsim.fog.engine.FogSettings`, the one every fogsim fog is made by; its airlight is
    drawn per sample).
    """

    beta: tuple[float, float] | tuple[float, ...] = (0.0, 0.12)
    sample: str = "beta"
    airlight: float = 255.0
    airlight_jitter: float = 0.0
    depth: str = "ray"
    intrinsics: Intrinsics | None = None
    hfov: float | None = None
    space: str | None = None
    kernel: Kernel | None = None
    heterogeneity: float = 0.0
    heterogeneity_scale: float = 64.0
    model: str = "koschmieder"
    scatter_params: str | None = None
    is_list: bool = False  # set by __post_init__: beta is a list of values (not a range)
    #: the fog record (set by __post_init__; the scatter model's parameters are read once, not per sample)
    fog: FogSettings = field(default=None, init=False, repr=False, compare=False)

    def __post_init__(self):
        beta = self.beta
        if is_number(beta):
            beta = (float(beta), float(beta))
        elif not isinstance(beta, (tuple, list, np.ndarray)):
            raise TypeError(f"beta must be a number, a (low, high) tuple or a list of numbers in 1/m, got "
                            f"{type(beta).__name__} {beta!r}")
        if not all(is_number(b) for b in beta):
            raise TypeError(f"beta must hold numbers in 1/m, got {self.beta!r}")
        beta = tuple(float(b) for b in beta)
        is_list = isinstance(self.beta, list) or len(beta) != 2
        if not beta or not all(math.isfinite(b) and b >= 0 for b in beta):
            raise ValueError(f"β must be finite values ≥ 0 (1/m), got {self.beta}")
        if not is_list and beta[0] > beta[1]:
            raise ValueError(f"β range must be (low, high) with low ≤ high, got {self.beta}")
        if self.sample not in SAMPLING:
            raise ValueError(f"sample must be one of {', '.join(SAMPLING)}, got {self.sample!r}")
        if self.sample == "visibility" and not is_list and beta[0] == 0:
            raise ValueError("uniform in visibility needs a β range with low > 0 (visibility is infinite at β = 0)")
        for name in ("airlight", "airlight_jitter"):
            if not is_number(getattr(self, name)):
                raise TypeError(f"{name} must be a number (8-bit units), got {getattr(self, name)!r}")
        if not (0 <= self.airlight - self.airlight_jitter and self.airlight + self.airlight_jitter <= 255):
            raise ValueError(f"airlight ± jitter must stay in [0, 255], got {self.airlight} ± {self.airlight_jitter}")
        if self.depth not in DEPTH_KINDS:
            raise ValueError(f"depth must be one of {', '.join(DEPTH_KINDS)}, got {self.depth!r}")
        if self.depth == "planar" and self.intrinsics is None and self.hfov is None:
            raise ValueError("planar depth needs the camera: intrinsics or hfov (degrees)")
        if self.hfov is not None and not 0 < self.hfov < 180:
            raise ValueError(f"hfov must be in (0, 180) degrees, got {self.hfov}")
        if self.model not in POST_PROCESS_KINDS:
            raise ValueError(f"model must be one of {', '.join(POST_PROCESS_KINDS)}, got {self.model!r}")
        if self.heterogeneity:
            check_heterogeneity(self.heterogeneity, self.heterogeneity_scale)
        fog = FogSettings(self.model, self.airlight, self.space, self.kernel,
                          Heterogeneity(self.heterogeneity, self.heterogeneity_scale) if self.heterogeneity else None,
                          self.scatter_params)
        fog.params  # a scatter parameter file is read (and checked) here, once
        object.__setattr__(self, "beta", beta)
        object.__setattr__(self, "is_list", is_list)
        object.__setattr__(self, "space", fog.blend_space)
        object.__setattr__(self, "fog", fog)

    def draw_beta(self, rng: np.random.Generator) -> float:
        """One β (1/m) from the range or list."""
        if self.is_list:
            return self.beta[int(rng.integers(len(self.beta)))]
        low, high = self.beta
        if self.sample == "beta":
            return float(rng.uniform(low, high))
        v = rng.uniform(visibility_from_beta(high), visibility_from_beta(low))
        return beta_from_visibility(float(v))

    def draw(self, rng: np.random.Generator, shape: tuple[int, int] | None = None) -> Draw:
        """One sample's parameters (β, airlight, density field for an H×W ``shape``)."""
        beta = self.draw_beta(rng)
        a = self.airlight
        if self.airlight_jitter:
            a = float(a + rng.uniform(-self.airlight_jitter, self.airlight_jitter))
        density = None
        if self.heterogeneity and shape is not None:
            density = self.fog.density(shape, rng)
        return Draw(beta, (a, a, a), density)

    def camera(self, height: int, width: int) -> Intrinsics:
        """The camera of an image of this size (for planar depth)."""
        if self.intrinsics is not None:
            K = self.intrinsics
            return K if (K.width, K.height) == (width, height) else K.scaled(width, height)
        return Intrinsics.from_hfov(self.hfov, width, height)

    def ray_distance(self, depth: np.ndarray) -> np.ndarray:
        """H×W ray distance in metres from the depth as given (H×W or H×W×1)."""
        depth = np.asarray(depth)
        if depth.ndim == 3 and depth.shape[2] == 1:
            depth = depth[:, :, 0]
        depth = depth.astype(np.float32, copy=False)
        if self.depth == "planar":
            return planar_to_ray(depth, self.camera(*depth.shape))
        return depth


def apply_fog(image: np.ndarray, depth: np.ndarray, draw: Draw, spec: FogSpec = FogSpec()) -> np.ndarray:
    """The reference: fog ``image`` (H×W×3 uint8/uint16/float in [0, 1]) with ``draw`` over ``depth``
    (see the module docstring) by the spec's fog record; same dtype back. Channel order does not
    matter for grey airlight. An argument it does not support is a TypeError / ValueError naming it
    (:mod:`fogsim.augment.checks`)."""
    check_numpy_image(image)
    depth = check_numpy_depth(depth, image.shape[:2])
    if not isinstance(draw, Draw):
        raise TypeError(f"draw must be a fogsim.augment.Draw (FogSpec.draw(rng)), got {type(draw).__name__}")
    check_beta(draw.beta, "draw.beta")
    check_airlight(draw.airlight, "draw.airlight")
    if not isinstance(spec, FogSpec):
        raise TypeError(f"spec must be a fogsim.augment.FogSpec, got {type(spec).__name__}")
    distance = spec.ray_distance(depth)
    camera = spec.camera(*distance.shape) if spec.intrinsics is not None or spec.hfov is not None else None
    return spec.fog.fogger(image, distance, camera, density=draw.density, airlight=draw.airlight)(draw.beta)


def random_fog(image: np.ndarray, depth: np.ndarray, rng: np.random.Generator,
               spec: FogSpec = FogSpec()) -> tuple[np.ndarray, float]:
    """Draw one sample's fog from ``rng`` and apply it: (fogged image, β used in 1/m)."""
    check_numpy_image(image)
    check_numpy_depth(depth, image.shape[:2])
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator (np.random.default_rng(seed)), got "
                        f"{type(rng).__name__}")
    draw = spec.draw(rng, image.shape[:2])
    return apply_fog(image, depth, draw, spec), draw.beta


def parse_augment(text: str) -> FogSpec:
    """``continuous`` or ``continuous:LOW-HIGH`` (β in 1/m; default 0–0.12, the paper's levels'
    span), optionally ``…:visibility`` to draw uniformly in visibility → the study's FogSpec."""
    parts = text.split(":")
    if parts[0] != "continuous" or len(parts) > 3:
        raise ValueError(f"--augment must be continuous[:LOW-HIGH][:visibility], got {text!r}")
    beta, sample = (0.0, 0.12), "beta"
    for part in parts[1:]:
        if part in SAMPLING:
            sample = part
            continue
        try:
            low, high = (float(v) for v in part.split("-"))
        except ValueError:
            raise ValueError(f"--augment range must be LOW-HIGH in 1/m (e.g. 0-0.12), got {part!r}") from None
        beta = (low, high)
    try:
        return FogSpec(beta=beta, sample=sample)
    except ValueError as exc:  # a range FogSpec refuses: say which flag gave it
        raise ValueError(f"--augment {text}: {exc}") from None
