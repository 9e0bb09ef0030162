"""The options of a render job, as records the CLI, the add-on panel and the batch script share
(pure Python: checked before Blender starts).

* :class:`RunOptions` — *how* a job runs, whatever it renders: its shard, resume, GPU, quiet.
* :class:`SceneOptions` — *what* scene mode renders of a user's scene: camera, frame range, class
  map, fog levels, samples, resolution, seed, the fog model (``--fog``, ``--fog-medium``,
  ``--fog-scale``), a LiDAR (``--lidar``) and the pixel bound. :meth:`SceneOptions.check` refuses a bad flag (a
  ``ValueError`` naming it) before any ``.blend`` is opened.

Frame numbers are Blender's (inclusive ranges, as its timeline): Blender keeps frames in
[−:data:`MAX_FRAME`, :data:`MAX_FRAME`]; a range outside that is refused, not clamped.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from fogsim.io.pixel_bound import MAX_PIXELS
from fogsim.render.scene_classes import ClassMap

#: Blender's largest frame number (MAXFRAME in its source: 1 048 574); frames are in ±MAX_FRAME
MAX_FRAME = 1_048_574


@dataclass(frozen=True)
class RunOptions:
    """How a render job runs: ``shard`` (i, N) renders every N-th frame from i, ``resume`` skips
    committed frames, ``gpu`` renders on a GPU when one is found, ``quiet`` shows Blender's errors only."""

    shard: tuple[int, int] = (0, 1)
    resume: bool = True
    gpu: bool = False
    quiet: bool = False

    def frames(self, count: int) -> range:
        """This shard's frame indices of ``count`` (a range: no list of a huge run is made)."""
        i, n = self.shard
        return range(i, count, n)


def parse_frame_range(text: str) -> tuple[int, int, int]:
    """``--frame-range S:E[:STEP]`` (inclusive) → (start, end, step), refused (a ValueError naming the
    flag) unless END ≥ START, STEP ≥ 1 and both ends lie in Blender's frames (±:data:`MAX_FRAME`)."""
    usage = f"--frame-range must look like START:END or START:END:STEP with END ≥ START and STEP ≥ 1, got {text!r}"
    parts = text.split(":")
    if len(parts) not in (2, 3) or any(len(p.strip()) > 9 for p in parts):  # 9 digits: beyond any frame
        raise ValueError(usage if len(parts) not in (2, 3) else
                         f"--frame-range {text}: Blender's frames are -{MAX_FRAME}…{MAX_FRAME}")
    try:
        start, end, step = ([int(v) for v in parts] + [1])[:3]
    except ValueError:
        raise ValueError(usage) from None
    if step < 1 or end < start:
        raise ValueError(usage)
    check_frames(start, end, "--frame-range")
    return start, end, step


def check_frames(start: int, end: int, where: str) -> None:
    """Refuse frames outside Blender's range (``where`` names the flag or the scene setting)."""
    if not (-MAX_FRAME <= start and end <= MAX_FRAME):
        raise ValueError(f"{where} {start}:{end}: Blender's frames are -{MAX_FRAME}…{MAX_FRAME}")


@dataclass(frozen=True)
class SceneOptions:
    """What scene mode renders of a user's scene (the flags of ``fogsim render --scene``; the panel's
    *Source: current scene*). ``source``: what messages name (None: the ``.blend``'s path);
    ``levels``: a ``--levels`` string, or FogLevel objects (the panel's visibilities), None = the
    paper's five; ``fog_model``: a preset-style ``fog_model`` block the flags are applied to."""

    source: str | None = None
    camera: str | None = None
    frame_range: str | None = None
    class_map: ClassMap = field(default_factory=ClassMap)
    levels: str | tuple | None = None
    samples: int | None = None
    resolution: str | None = None
    seed: int = 0
    max_pixels: int = MAX_PIXELS
    fog: str | None = None
    fog_medium: str | None = None
    fog_scale: float | None = None
    fog_model: dict | None = None
    lidar: str | None = None  # a LiDAR sensor (bundled name or .json); the scene's fogsim_lidar object places it
    radar: str | None = None  # a radar sensor (bundled name or .json); the scene's fogsim_radar object places it

    def check(self) -> "SceneOptions":
        """Every flag checked (a ValueError naming it); returns self."""
        from fogsim.fog.levels import parse_levels
        from fogsim.render.preset import check_overrides, check_size, parse_resolution

        check_overrides(seed=self.seed, samples=self.samples, max_pixels=self.max_pixels, fog=self.fog,
                        fog_medium=self.fog_medium, fog_scale=self.fog_scale)
        if self.frame_range:
            parse_frame_range(self.frame_range)
        if self.resolution:
            w, h = parse_resolution(self.resolution)
            if why := check_size(w, h, self.max_pixels):
                raise ValueError(f"--resolution {why}")
        if isinstance(self.levels, str):
            parse_levels(self.levels)
        if self.lidar is not None:
            self.lidar_block()
        if self.radar is not None:
            self.radar_block()
        return self

    def lidar_block(self) -> dict:
        """The checked LiDAR sensor block of ``lidar`` ({} without one)."""
        from fogsim.render.preset import lidar_block

        return lidar_block(self.lidar) if self.lidar is not None else {}

    def radar_block(self) -> dict:
        """The checked radar sensor block of ``radar`` ({} without one)."""
        from fogsim.render.preset import radar_block

        return radar_block(self.radar) if self.radar is not None else {}
