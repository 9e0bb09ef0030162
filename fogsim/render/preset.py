"""Dataset presets for the renderer: one JSON file naming a style, camera, quality and fog levels.

``presets/<name>.json`` refers to components by name — ``presets/styles/<style>.json``,
``presets/cameras/<camera>.json``, ``presets/quality/<quality>.json``, ``presets/fog/<fog>.json``
(or an inline list of β) — so a preset is short and its parts are shared. Command-line
overrides (frames, seed, resolution, samples, levels) are applied on top.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from fogsim import presets
from fogsim.errors import InputError
from fogsim.fileio import read_json
from fogsim.fog.levels import FogLevel, parse_levels
from fogsim.presets import preset_path

KEYS = {"name", "description", "version", "style", "camera", "resolution", "quality", "fog",
        "fog_model", "labels", "exposure", "frames", "seed", "stereo", "train_fraction"}


@dataclass(frozen=True)
class RenderConfig:
    name: str
    source: str
    style: dict
    camera: dict
    resolution: tuple[int, int]
    quality: dict
    levels: tuple[FogLevel, ...]
    fog_model: dict = field(default_factory=dict)
    labels: dict = field(default_factory=dict)
    exposure: float = 1.0
    frames: int = 8
    seed: int = 0
    stereo_baseline: float | None = None  # metres; None = no right camera
    train_fraction: float = 0.8  # share of frames in the train split (fogsim.dataset_writer's rule)

    def to_dict(self) -> dict:
        return {"name": self.name, "source": self.source, "style": self.style, "camera": self.camera,
                "resolution": list(self.resolution), "quality": self.quality,
                "levels": [lv.to_dict() for lv in self.levels], "fog_model": self.fog_model,
                "labels": self.labels, "exposure": self.exposure, "frames": self.frames, "seed": self.seed,
                "stereo_baseline_m": self.stereo_baseline, "train_fraction": self.train_fraction}


def _component(kind: str, value, source: Path) -> dict:
    """An inline component (a dict) or the bundled one of that name."""
    if isinstance(value, dict):
        return value
    return read_json(presets.component_path(kind, value, source))


def _stereo_baseline(spec, camera: dict, override: bool | None, source: Path) -> float | None:
    """Baseline in metres from the preset's ``stereo`` ({"baseline_m": …} or true = the
    camera's ``stereo_baseline_m``, else Cityscapes' 0.209 m); ``override`` forces it on/off."""
    on = bool(spec) if override is None else override
    if not on:
        return None
    b = spec.get("baseline_m") if isinstance(spec, dict) else None
    b = float(b if b is not None else camera.get("stereo_baseline_m", 0.209))
    if not b > 0:
        raise InputError(source, f"stereo baseline must be > 0 m, got {b}")
    return b


def _positive(value, name: str) -> float:
    v = float(value)
    if not v > 0:
        raise ValueError(f"{name} must be > 0, got {value}")
    return v


def _resolution(value) -> tuple[int, int]:
    w, h = (int(v) for v in value)
    if w < 8 or h < 8:
        raise ValueError(f"resolution must be at least 8×8 pixels, got {w}×{h}")
    return w, h


def parse_resolution(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise ValueError(f"--resolution must look like 640x426, got {text!r}") from None
    if w < 8 or h < 8:
        raise ValueError(f"--resolution {text}: at least 8×8 pixels")
    return w, h


def load_render_preset(name_or_path: str | None = None, *, frames: int | None = None,
                       seed: int | None = None, resolution: str | None = None,
                       samples: int | None = None, levels: str | None = None,
                       stereo: bool | None = None, train_fraction: float | None = None) -> RenderConfig:
    """Read a dataset preset and apply overrides; every problem names the preset file."""
    path = preset_path(name_or_path)
    if not path.is_file():
        raise InputError(path, "preset not found")
    d = read_json(path)
    if not isinstance(d, dict):
        raise InputError(path, "a preset must be a JSON object")
    unknown = set(d) - KEYS
    if unknown:
        raise InputError(path, f"unknown preset keys {sorted(unknown)} (allowed: {sorted(KEYS)})")
    for key in ("style", "camera", "quality"):
        if key not in d:
            raise InputError(path, f"preset lacks {key!r}")
    # command-line overrides: their errors are usage errors, not the preset's
    res_override = parse_resolution(resolution) if resolution else None
    if samples is not None and samples < 1:
        raise ValueError(f"--samples must be ≥ 1, got {samples}")
    lv_override = parse_levels(levels) if levels is not None else None
    if train_fraction is not None and not 0 < train_fraction < 1:
        raise ValueError(f"--train-fraction must be between 0 and 1, got {train_fraction}")
    try:
        quality = dict(_component("quality", d["quality"], path))
        if samples is not None:
            quality["samples"] = samples
        camera = _component("cameras", d["camera"], path)
        res = res_override or _resolution(d.get("resolution") or (camera["width"], camera["height"]))
        fog = d.get("fog", "paper")
        baseline = _stereo_baseline(d.get("stereo"), camera, stereo, path)
        lv = lv_override or parse_levels(",".join(str(x) for x in fog) if isinstance(fog, list) else str(fog))
        cfg = RenderConfig(
            name=str(d.get("name", path.stem)), source=str(path),
            style=_component("styles", d["style"], path), camera=camera,
            resolution=(int(res[0]), int(res[1])), quality=quality, levels=tuple(lv),
            fog_model=dict(d.get("fog_model", {})), labels=dict(d.get("labels", {})),
            exposure=_positive(d.get("exposure", 1.0), "exposure"),
            frames=int(frames if frames is not None else d.get("frames", 8)),
            seed=int(seed if seed is not None else d.get("seed", 0)), stereo_baseline=baseline,
            train_fraction=float(train_fraction if train_fraction is not None else d.get("train_fraction", 0.8)))
        if not 0 < cfg.train_fraction < 1:
            raise ValueError(f"train_fraction must be between 0 and 1, got {cfg.train_fraction}")
        fog_settings(cfg)  # fail now, naming the preset, not after the first render
        _check_labels(cfg.labels)
        if any(lv.key == "all" for lv in cfg.levels):
            raise ValueError("a fog level may not be keyed 'all' (the name of the mixed split)")
    except (TypeError, KeyError, IndexError, ValueError) as exc:
        raise InputError(path, f"malformed preset ({exc})") from None
    if cfg.frames < 1:
        raise ValueError(f"--frames must be ≥ 1, got {cfg.frames}")
    return cfg


def fog_settings(config: RenderConfig) -> dict:
    """The preset's ``fog_model`` as Fogger arguments: airlight (8-bit units), blend space, kernel."""
    from fogsim.fog.model import SPACES, Kernel, airlight_rgb

    m = config.fog_model
    unknown = set(m) - {"extended", "kernel", "kernel_size", "sigma", "eps", "airlight", "space"}
    if unknown:
        raise ValueError(f"unknown fog_model keys {sorted(unknown)}")
    kernel = None
    if m.get("extended"):
        kernel = Kernel(m.get("kernel", "box"), int(m.get("kernel_size", 19)), float(m.get("sigma", 5.0)),
                        float(m.get("eps", 1e-3)))
    airlight = m.get("airlight", 255)
    airlight_rgb(airlight)  # validates: a number or R,G,B in [0, 255]
    space = m.get("space", "srgb")
    if space not in SPACES:
        raise ValueError(f"fog_model.space must be one of {', '.join(SPACES)}, got {space!r}")
    return {"airlight": airlight, "space": space, "kernel": kernel}


def _check_labels(labels: dict) -> None:
    unknown = set(labels) - {"min_pixels", "min_visible_fraction"}
    if unknown:
        raise ValueError(f"unknown labels keys {sorted(unknown)}")
    if int(labels.get("min_pixels", 25)) < 1 or not 0 <= float(labels.get("min_visible_fraction", 0.1)) <= 1:
        raise ValueError("labels: min_pixels must be ≥ 1 and min_visible_fraction in [0, 1]")
