"""Which fog, said once: :class:`FogSettings`, the fog-model record every reader shares, and the
one factory that builds the fogger it names.

One record describes the fog a run applies — the model (:data:`~fogsim.schema.vocabulary.FOG_KINDS`),
the airlight, the blend space, Koschmieder's extended kernel, the heterogeneity of the density,
the scatter model's parameters — whoever applies it: ``fogsim fog`` (:mod:`fogsim.fog.batch`), a
render's post-process fog (:mod:`fogsim.render.frame`), the Koschmieder-vs-path-tracing comparison
(:mod:`fogsim.fog.physics`), ``fogsim fit-fog``, the training augmentation (:mod:`fogsim.augment`).
The fog's density β comes from the run's levels, not from here, so one record fogs every level — and
every sensor: the camera through :meth:`FogSettings.fogger`; the next sensor (the LiDAR) reads the
same record and the same β, and so does the radar (:meth:`FogSettings.radar_fogger`).

:meth:`FogSettings.record` is what every document fogsim writes says of the fog (``model`` one of
the vocabulary's words; an older document's words are read by :func:`~fogsim.schema.vocabulary.model_word`).

Units: airlight in 8-bit units [0, 255] (a number, [R, G, B], or ``"estimate"``: the dark-channel
estimate of each image), distances ray distance in metres (+inf = sky), heterogeneity patches in pixels.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fogsim.camera import Intrinsics, pixel_index
from fogsim.fog.model import Fogger, Kernel, airlight_rgb, check_heterogeneity, density_field, estimate_airlight
from fogsim.fog.scatter import ScatterFogger, ScatterParams, load_params
from fogsim.lidar.fog import LidarFogger, lidar_fog_spec
from fogsim.lidar.points import PointCloud
from fogsim.radar.detections import RadarScan
from fogsim.radar.fog import RadarFogger, radar_fog_spec
from fogsim.schema.lidar import LidarFogSpec
from fogsim.schema.radar import RadarFogSpec
from fogsim.schema.vocabulary import FOG_KINDS, POST_PROCESS_KINDS, SPACES

#: the blend space of each model when the record does not say (scatter: where it was fitted)
DEFAULT_SPACE = {"koschmieder": "srgb", "scatter": "linear", "volumetric": "linear"}
ESTIMATE = "estimate"


@dataclass(frozen=True)
class Heterogeneity:
    """Patchy fog: β × a smooth density field with mean 1 and values in [1 − a, 1 + a]
    (:func:`fogsim.fog.model.density_field`); ``amplitude`` a ∈ [0, 1), patches of ``scale_px`` pixels."""

    amplitude: float
    scale_px: float = 64.0

    def __post_init__(self):
        check_heterogeneity(self.amplitude, self.scale_px)

    def field(self, shape: tuple[int, int], rng: np.random.Generator) -> np.ndarray:
        """The H×W density field drawn from ``rng``."""
        return density_field(shape, rng, self.amplitude, self.scale_px)

    def to_dict(self) -> dict:
        return {"amplitude": self.amplitude, "scale_px": self.scale_px}


@dataclass(frozen=True)
class FogSettings:
    """The fog a run applies, at every level and for every sensor (see the module docstring).

    ``kind``: one of :data:`~fogsim.schema.vocabulary.FOG_KINDS` (``volumetric`` is rendered by
    Cycles: it has no fogger here). ``airlight``: 8-bit units, a number, RGB, or ``"estimate"``.
    ``space``: the blend space (None: :data:`DEFAULT_SPACE` of the kind). ``kernel``: Koschmieder's
    extended form (None: the standard law). ``heterogeneity``: patchy fog (Koschmieder only).
    ``scatter_file``: the scatter model's parameter file (None: the shipped, fitted one);
    ``scatter``: the parameters themselves (a fit's candidate; they win over the file).
    ``lidar``: the LiDAR's part of the same fog (:class:`~fogsim.schema.lidar.LidarFogSpec`: its
    model, backscatter, extinction ratio at 905 nm; None = the defaults) — the LiDAR takes the level's
    β and the heterogeneity's field from this record too (:meth:`lidar_fogger`, :meth:`point_betas`).
    ``radar``: the radar's part (:class:`~fogsim.schema.radar.RadarFogSpec`: the visibility–liquid-water
    relation, the fog's temperature; None = the defaults) — the radar takes the level's β too
    (:meth:`radar_fogger`).
    """

    kind: str = "koschmieder"
    airlight: float | tuple[float, float, float] | str = 255.0
    space: str | None = None
    kernel: Kernel | None = None
    heterogeneity: Heterogeneity | None = None
    scatter_file: str | None = None
    scatter: ScatterParams | None = None
    lidar: LidarFogSpec | None = None
    radar: RadarFogSpec | None = None

    def __post_init__(self):
        if self.kind not in FOG_KINDS:
            raise ValueError(f"fog model must be one of {', '.join(FOG_KINDS)}, got {self.kind!r}")
        if self.space is not None and self.space not in SPACES:
            raise ValueError(f"blend space must be one of {', '.join(SPACES)}, got {self.space!r}")
        if self.kind != "koschmieder" and (self.kernel is not None or self.heterogeneity is not None):
            raise ValueError(f"the {self.kind} model has no extended kernel or heterogeneity (Koschmieder only)")
        if self.kind != "scatter" and (self.scatter_file is not None or self.scatter is not None):
            raise ValueError("scatter parameters need the scatter model")
        if self.kernel is not None and not isinstance(self.kernel, Kernel):
            raise TypeError(f"kernel must be a fogsim.fog.model.Kernel or None, got {type(self.kernel).__name__}")
        if self.lidar is not None and not isinstance(self.lidar, LidarFogSpec):
            object.__setattr__(self, "lidar", lidar_fog_spec(self.lidar))  # a dict: checked, one line naming the key
        if self.radar is not None and not isinstance(self.radar, RadarFogSpec):
            object.__setattr__(self, "radar", radar_fog_spec(self.radar))
        if self.heterogeneity is not None and not self.heterogeneity.amplitude:
            object.__setattr__(self, "heterogeneity", None)  # amplitude 0 is homogeneous fog
        if not (isinstance(self.airlight, str) and self.airlight == ESTIMATE):
            airlight_rgb(self.airlight)  # the range, checked once (ValueError naming the airlight)
            if not isinstance(self.airlight, (int, float)):
                object.__setattr__(self, "airlight", tuple(float(a) for a in self.airlight))

    @classmethod
    def from_preset(cls, m) -> "FogSettings":
        """The record of a render preset's checked ``fog_model`` block (:class:`fogsim.schema.presets.FogModel`):
        the scatter model always blends linear light there (where it was fitted), ``space`` is Koschmieder's."""
        kernel = Kernel(m.kernel, m.kernel_size, float(m.sigma), float(m.eps)) if m.extended else None
        airlight = tuple(m.airlight) if isinstance(m.airlight, list) else m.airlight
        space = {"scatter": "linear", "koschmieder": m.space}.get(m.kind)
        return cls(m.kind, airlight, space, kernel if m.kind == "koschmieder" else None,
                   scatter_file=m.scatter_params if m.kind == "scatter" else None,
                   lidar=m.lidar if "lidar" in m.model_fields_set else None,
                   radar=m.radar if "radar" in m.model_fields_set else None)

    # ------------------------------------------------------------------ what it resolves to
    @property
    def blend_space(self) -> str:
        """The blend space used (``space``, or the kind's default)."""
        return self.space or DEFAULT_SPACE[self.kind]

    @property
    def params(self) -> ScatterParams | None:
        """The scatter model's parameters (read once per file, cached), None for the other models."""
        if self.kind != "scatter":
            return None
        return self.scatter if self.scatter is not None else load_params(self.scatter_file)

    def airlight_for(self, image: np.ndarray) -> np.ndarray:
        """The airlight used on ``image``: RGB float64 in 8-bit units (the dark-channel estimate for
        ``"estimate"``)."""
        if isinstance(self.airlight, str):
            return estimate_airlight(image)
        return np.broadcast_to(np.asarray(self.airlight, np.float64), (3,)).copy()

    def density(self, shape: tuple[int, int], rng: np.random.Generator) -> np.ndarray | None:
        """The density field of one image (None: homogeneous fog), drawn from ``rng``."""
        return None if self.heterogeneity is None else self.heterogeneity.field(shape, rng)

    # ------------------------------------------------------------------ the factory
    def fogger(self, image: np.ndarray, distance: np.ndarray, intrinsics: Intrinsics | None = None, up=None,
               density: np.ndarray | None = None, airlight=None):
        """The fogger of one image: ``fogger(β)`` is the fogged image in the image's dtype (β in 1/m;
        the β-independent work is shared between levels). ``distance``: ray distance in metres
        (+inf = sky); ``intrinsics`` and ``up`` (world up in camera coordinates) give the scatter
        model its elevation map and PSF width; ``density``: the heterogeneity's field of this image;
        ``airlight``: this image's airlight (8-bit units), overriding the record's (a drawn one)."""
        if self.kind not in POST_PROCESS_KINDS:
            raise ValueError(f"{self.kind} fog is rendered, not applied to an image: it has no fogger")
        a = self.airlight_for(image) if airlight is None else airlight
        if self.kind == "scatter":
            return ScatterFogger(image, distance, a, self.blend_space, self.params, intrinsics, up)
        return Fogger(image, distance, a, self.blend_space, self.kernel, density)

    def lidar_fogger(self, scan: PointCloud, sensor) -> LidarFogger:
        """The LiDAR's fogger of one scan in this fog: ``fogger(β, rng)`` with the level's β (the camera's;
        :meth:`point_betas` for patchy fog) gives the scan the sensor reports and every point's outcome."""
        return LidarFogger(scan, sensor, self.lidar)

    def radar_fogger(self, scan: RadarScan, sensor) -> RadarFogger:
        """The radar's fogger of one sweep in this fog: ``fogger(β)`` with the level's β (the camera's; one
        per detection for patchy fog) gives the sweep the radar reports and every detection's outcome."""
        return RadarFogger(scan, sensor, self.radar)

    def point_betas(self, beta: float, density: np.ndarray | None, uv: np.ndarray | None = None):
        """β along each LiDAR ray, from the camera's β and density field: β × m at the pixel a point's
        ``uv`` (N×2 pixel-edge coordinates in the camera image) falls in, β for the points outside the
        image (the field's mean) — the camera and the LiDAR see one patchy fog. Homogeneous fog: β."""
        if density is None or uv is None or beta == 0:
            return beta
        row, col, inside = pixel_index(uv, density.shape[1], density.shape[0])
        return np.where(inside, beta * density[row, col].astype(np.float64), float(beta))  # float64: β exact

    # ------------------------------------------------------------------ what documents say
    def record(self) -> dict:
        """What every document fogsim writes says of the fog: ``model``, ``airlight`` (8-bit units,
        or "estimate"), ``blend_space``; Koschmieder: ``kernel`` (None = the standard law) and
        ``heterogeneity`` (None = homogeneous); scatter: ``scatter_params`` (the values) and
        ``scatter_params_file`` (None = the shipped file)."""
        airlight = self.airlight if isinstance(self.airlight, (str, int, float)) else list(self.airlight)
        out = {"model": self.kind, "airlight": airlight, "blend_space": self.blend_space}
        if self.kind == "koschmieder":
            out["kernel"] = self.kernel.to_dict() if self.kernel else None
            out["heterogeneity"] = self.heterogeneity.to_dict() if self.heterogeneity else None
        elif self.kind == "scatter":
            out["scatter_params"] = self.params.to_dict()
            out["scatter_params_file"] = self.scatter_file
        if self.lidar is not None:
            out["lidar_fog"] = self.lidar.model_dump()
        if self.radar is not None:
            out["radar_fog"] = self.radar.model_dump()
        return out

    @property
    def name(self) -> str:
        """A short name of the variant, for tables: ``srgb``, ``linear+box19``, ``scatter`` …"""
        if self.kind == "scatter":
            return "scatter" if self.blend_space == "linear" else f"scatter-{self.blend_space}"
        if self.kernel is None:
            return self.blend_space
        k = self.kernel
        extra = f",s{k.sigma:g}" if k.kind == "gaussian" else ""
        return f"{self.blend_space}+{k.kind}{k.size}{extra}"


__all__ = ["DEFAULT_SPACE", "ESTIMATE", "FogSettings", "Heterogeneity"]
