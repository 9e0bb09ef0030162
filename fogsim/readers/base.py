"""The sample record every dataset adapter produces, and depth decoding by name.

A :class:`Sample` is cheap and picklable (it holds paths and small numbers, never pixels),
so shards and worker processes can pass samples around; pixels are read on demand.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Protocol

import numpy as np

from fogsim.camera import Intrinsics
from fogsim.errors import InputError
from fogsim.io.depth_files import read_depth_file
from fogsim.readers.cityscapes_files import read_cityscapes_depth
from fogsim.readers.paper import read_paper_8bit

#: How a depth file is turned into metres (see :class:`DepthSpec`).
DEPTH_ENCODINGS = ("metric", "disparity", "paper-8bit")

#: A depth source computed from the image (see :attr:`DepthSpec.reader`): RGB uint8 H×W×3 →
#: (depth in metres, H×W, 0 = hole, inf = no hit; the intrinsics it implies or None).
DepthReader = Callable[[np.ndarray], "tuple[np.ndarray, Intrinsics | None]"]


@dataclass(frozen=True)
class DepthSpec:
    """Where a sample's depth comes from and how to decode it.

    ``encoding``:
      * ``metric`` — EXR/.npy in metres, or 16-bit PNG × ``png_scale`` metres per unit.
      * ``disparity`` — Cityscapes 16-bit disparity (p = 256·d + 1, 0 = invalid) decoded with
        the stereo camera JSON at ``camera_path`` into planar depth Z = baseline·fx/d
        (:func:`fogsim.readers.cityscapes.read_cityscapes_depth`).
      * ``paper-8bit`` — the paper's 8-bit ILA predictions decoded with its constant
        (:func:`fogsim.readers.paper.paper_distance_from_8bit`); already a distance, no ray step.
    ``kind``: ``planar`` (Z along the optical axis; needs intrinsics) or ``ray`` (distance).
    ``reader``: a picklable callable that computes the depth from the image instead of
    decoding a file (e.g. :class:`fogsim.depth.ila.ILADepth`, a model's prediction); when
    given, ``encoding`` is not used, ``path`` names the source in messages, and the reader's
    ``name`` attribute is what the fog sidecars record as the encoding (:attr:`decoded_by`).
    A reader may also report on each image: a ``read_with_record(image) -> (depth, intrinsics,
    record dict)`` method (e.g. :class:`fogsim.depth.lidar_source.LidarDepth`: points used,
    coverage) is used by :meth:`read_with_record`, and the fog sidecars keep that record.
    """

    path: str
    encoding: str = "metric"
    kind: str = "planar"
    png_scale: float | None = None
    camera_path: str | None = None
    reader: DepthReader | None = None

    @property
    def is_ray_distance(self) -> bool:
        """True when the decoded values are already ray distances (no planar→ray step)."""
        return self.kind == "ray" or self.encoding == "paper-8bit"

    @property
    def decoded_by(self) -> str:
        """How the depth is obtained, as recorded: the reader's ``name`` or the encoding."""
        if self.reader is None:
            return self.encoding
        return getattr(self.reader, "name", type(self.reader).__name__)

    def read_for_image(self, image: np.ndarray) -> tuple[np.ndarray, Intrinsics | None]:
        """Like :meth:`read`, for the image ``image`` (which a :attr:`reader` computes from)."""
        if self.reader is not None:
            return self.reader(image)
        return self.read(image.shape[1], image.shape[0])

    def read_with_record(self, image: np.ndarray) -> tuple[np.ndarray, Intrinsics | None, dict]:
        """:meth:`read_for_image` and what the :attr:`reader` reports about this image ({} for
        files and for readers without a ``read_with_record`` method)."""
        with_record = getattr(self.reader, "read_with_record", None)
        if with_record is not None:
            return with_record(image)
        return (*self.read_for_image(image), {})

    def read(self, width: int, height: int) -> tuple[np.ndarray, Intrinsics | None]:
        """Depth in metres (0 = hole, inf = no hit) and the intrinsics the file implies."""
        if self.reader is not None:
            raise ValueError(f"{self.path}: depth from {self.decoded_by} is computed from the image; "
                             "read it with read_for_image")
        if self.encoding == "metric":
            return read_depth_file(self.path, self.png_scale), None
        if self.encoding == "disparity":
            depth, camera = read_cityscapes_depth(self.path, self.camera_path)
            return depth, camera.intrinsics
        if self.encoding == "paper-8bit":
            return read_paper_8bit(self.path), None
        raise InputError(self.path, f"unknown depth encoding {self.encoding!r} "
                                    f"(use one of {', '.join(DEPTH_ENCODINGS)})")


@dataclass(frozen=True)
class Labels:
    """A real image's annotations, in the record format of rendered frames (``meta["objects"]``).

    ``classes``: the dataset's own class list (YOLO ids index it; COCO ids are index + 1),
    e.g. ``("vehicle", "pedestrian", "cyclist")`` for Waymo. ``objects``: one dict per
    annotation with at least

    * ``class`` (a name in ``classes``), ``class_id`` (its index),
    * ``bbox`` ``[x0, y0, x1, y1)`` in pixel-edge coordinates, clamped to the image,
    * ``pixels`` (instance-mask pixel count, or the box area where only a box exists),
    * ``kept`` (False → an ignore region: COCO ``iscrowd = 1``, not in YOLO) and ``reason``,
    * ``distance_m`` (ray distance camera centre → object in metres, or None = unknown) and
      ``distance_source`` (how it was obtained, e.g. ``"laser box centre (association)"``,
      ``"lidar points in box (near cluster)"``, ``"valid disparity (median)"``, ``"unknown"``),

    plus whatever the dataset adds (``difficulty``, the dataset's own ``object_id``, …; these
    reach the COCO files, see :data:`fogsim.dataset.coco.COCO_EXTRA_FIELDS`).
    """

    classes: tuple[str, ...]
    objects: list[dict]


#: A picklable callable giving a sample's :class:`Labels` (read on demand, like the image).
LabelReader = Callable[[], Labels]


@dataclass(frozen=True)
class Sample:
    """One image to fog.

    ``key``: output path relative to the output level folder, POSIX, without suffix
    (e.g. ``frankfurt/frankfurt_000000_000294_leftImg8bit``). ``source``: what to name in
    messages. ``read_image``: a picklable callable returning H×W×3 RGB. ``depth``: where
    the depth is (None when the dataset has none). ``intrinsics``: camera of the image,
    when the dataset knows it (needed to turn planar depth into ray distance). ``labels``:
    the dataset's annotations of this image (None when it has none), see :class:`Labels`.
    """

    key: str
    source: str
    read_image: Callable[[], np.ndarray]
    depth: DepthSpec | None = None
    intrinsics: Intrinsics | None = None
    meta: dict = field(default_factory=dict, compare=False)
    labels: LabelReader | None = None


#: the key of :attr:`Sample.meta` that holds a sample's LiDAR scan source (:class:`ScanSource`)
SCAN_SOURCE = "lidar_points"


class ScanSource(Protocol):
    """A sample's LiDAR scan, as ``fogsim fog --lidar`` fogs it (``Sample.meta[SCAN_SOURCE]``; picklable):
    :class:`fogsim.readers.kitti.samples.KittiPoints` (KITTI, STF),
    :class:`fogsim.readers.waymo.lidar_cloud.WaymoScan`.

    * ``key``: the LiDAR frame's name (a relative POSIX path: file names and seeds derive from it);
    * ``fmt``: the point format its fogged levels are written in (:data:`fogsim.lidar.formats.FORMATS`);
    * ``return_mode``: the scan's return mode when the data says it (STF's ``last`` folder), else None;
    * ``cloud()``: the scan (:class:`fogsim.lidar.points.PointCloud`, sensor frame);
    * ``sensor(base)``: its sensor (:class:`fogsim.lidar.sensors.LidarSensor`) — ``base`` (a name or a
      file) or the format's usual one, completed from the data (Waymo: the frame's beams and mount);
    * ``image_uv(cloud)``: each point's pixel-edge coordinates in the sample's image (N×2, NaN where the
      camera does not see it), for the camera's patchy-fog field along each ray;
    * ``boxes(records)``: each label record's 3D box in the sensor frame
      (:class:`fogsim.lidar.boxes.Box3D`, None where it has none);
    * ``kitti_calib()``: the frame's :class:`fogsim.readers.kitti.calib.KittiCalib` for a KITTI tree of
      its levels, or None (not a KITTI-style source);
    * ``camera_view()``: the camera a cropped scan covers (:class:`fogsim.lidar.rays.CameraView`), or None
      (a full sweep, or unknown): the empty rays of a cropped scan are those inside it;
    * ``describe()``: a JSON-able record of where the scan was read (``meta["lidar"]["input"]``).
    """

    key: str
    fmt: str
    return_mode: str | None

    def cloud(self): ...

    def sensor(self, base=None): ...

    def image_uv(self, cloud) -> np.ndarray: ...

    def boxes(self, records: list[dict]) -> list: ...

    def kitti_calib(self): ...

    def camera_view(self): ...

    def describe(self) -> dict: ...
