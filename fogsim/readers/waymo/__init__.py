"""The Waymo Open Dataset (v1 TFRecord, v2 parquet) as fogsim samples, with 2D labels and LiDAR,
without TensorFlow or the waymo package.

The entry points are :func:`waymo_samples` (v1 or v2, by what the path holds),
:func:`waymo_v1_samples` and :func:`waymo_v2_samples` (:mod:`.samples`). The modules, bottom up
(each imports only those before it):

* the formats: :mod:`.protobuf_wire` (protobuf wire format), :mod:`.tfrecord` (TFRecord framing and
  CRCs), :mod:`.matrix` (MatrixFloat / MatrixInt32 protos);
* :mod:`.sensors` (camera and lidar names, camera calibration), :mod:`.address` (where a frame is:
  :class:`~.address.V1Record`, :class:`~.address.V2Frame`), :mod:`.images` (the image readers and
  the parquet opener);
* LiDAR: :mod:`.lidar_frame`, :mod:`.lidar_v1`, :mod:`.lidar_v2`, :mod:`.lidar_geometry`, :mod:`.lidar`;
* labels: :mod:`.labels` (what they are, the records), :mod:`.label_distance`, :mod:`.labels_v1`,
  :mod:`.labels_v2`;
* :mod:`.samples`, which puts them together.
"""
from fogsim.readers.waymo.samples import waymo_samples, waymo_v1_samples, waymo_v2_samples

__all__ = ["waymo_samples", "waymo_v1_samples", "waymo_v2_samples"]
