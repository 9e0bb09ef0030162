"""From a sample's depth file to the ray distance the fog model needs."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fogsim.camera import NO_HIT_DEPTH, Intrinsics, planar_to_ray
from fogsim.errors import InputError
from fogsim.fog.fill import HolesError, fill_holes, hole_mask
from fogsim.readers.base import Sample

NO_INTRINSICS = ("planar depth needs the camera intrinsics to become ray distance: "
                 "give --intrinsics FILE.json or --hfov DEG, or --depth-kind ray")


class SetupError(InputError):
    """A problem of the whole run (missing depth or intrinsics, intrinsics for another image
    shape), not of one sample: found before the output folder is claimed, exit 2."""


def check_sample(sample: Sample) -> None:
    """What can be checked without reading a file: the sample has depth, and planar depth has
    a camera (its own intrinsics, or a depth format that brings them, like Cityscapes')."""
    spec = sample.depth
    if spec is None:
        raise SetupError(sample.source, "this dataset has no depth; give depth maps (--depth / --depth-dir) "
                                        "or --depth-from ila:CHECKPOINT for it")
    if not spec.is_ray_distance and sample.intrinsics is None and spec.encoding != "disparity":
        raise SetupError(spec.path or sample.source, NO_INTRINSICS)


def check_aspect(K: Intrinsics, width: int, height: int, source: str) -> None:
    """Intrinsics may be scaled to the image, but not to another aspect ratio."""
    if abs(K.height * width / K.width - height) > 1.0:
        raise SetupError(source, f"the intrinsics are for {K.width}×{K.height}, another aspect ratio "
                                 f"than the {width}×{height} image")


@dataclass
class Distance:
    """Ray distance ℓ in metres (H×W float32, +inf = no hit) and how it was obtained."""

    ray: np.ndarray
    record: dict


def sample_distance(sample: Sample, width: int, height: int, fill: str = "none",
                    image: np.ndarray | None = None) -> Distance:
    """Read, validate, hole-fill and convert a sample's depth to ray distance.

    A depth reader's own per-image record (:meth:`DepthSpec.read_with_record`, e.g. the LiDAR
    points and coverage) goes into the record under ``depth_record``.
    Raises :class:`InputError` naming the depth file for missing depth, size mismatch,
    NaN or negative values, unfilled holes, or planar depth without intrinsics.
    """
    check_sample(sample)
    spec = sample.depth
    if image is not None:
        depth, file_K, reader_record = spec.read_with_record(image)
    else:
        (depth, file_K), reader_record = spec.read(width, height), {}
    src = spec.path
    if depth.shape != (height, width):
        raise InputError(src, f"depth is {depth.shape[1]}×{depth.shape[0]} but the image "
                              f"{sample.source} is {width}×{height}")
    if np.isnan(depth).any():
        raise InputError(src, f"depth has {int(np.isnan(depth).sum())} NaN pixels")
    if (depth < 0).any():
        raise InputError(src, f"depth has {int((depth < 0).sum())} negative pixels")
    depth = np.where(depth >= NO_HIT_DEPTH, np.float32(np.inf), depth)
    holes = float(hole_mask(depth).mean())
    try:
        depth = fill_holes(depth, fill, image)
    except HolesError as exc:
        raise InputError(src, str(exc)) from None
    record = {"depth_file": src, "encoding": spec.decoded_by, "fill": fill,
              "hole_fraction": round(holes, 6)} | ({"depth_record": reader_record} if reader_record else {})
    if spec.is_ray_distance:
        record["distance"] = "ray (as stored)"
        return Distance(depth, record)
    K: Intrinsics | None = sample.intrinsics or file_K
    if K is None:
        raise SetupError(src, NO_INTRINSICS)
    if (K.width, K.height) != (width, height):
        check_aspect(K, width, height, sample.source)
        K = K.scaled(width, height)
    record["distance"] = "planar→ray"
    record["intrinsics"] = K.to_dict()
    return Distance(planar_to_ray(depth, K), record)
