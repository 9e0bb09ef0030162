"""KITTI object detection (camera + Velodyne) and Seeing Through Fog, read as fogsim samples.

Modules: :mod:`.calib` (calibration files, the projection P2·R0_rect·Tr_velo_to_cam, STF's ROS files),
:mod:`.labels` (``label_2`` lines → records; the one line formatter), :mod:`.boxes` (label boxes in the
LiDAR frame), :mod:`.samples` (:func:`kitti_samples`, :func:`stf_samples`, the points source).
"""
from fogsim.readers.kitti.calib import KittiCalib, read_kitti_calib, stf_calib_from_tf
from fogsim.readers.kitti.labels import KITTI_CLASSES, STF_CLASSES, KittiLabels
from fogsim.readers.kitti.samples import KittiPoints, kitti_samples, stf_samples

__all__ = ["KITTI_CLASSES", "KittiCalib", "KittiLabels", "KittiPoints", "STF_CLASSES", "kitti_samples",
           "read_kitti_calib", "stf_calib_from_tf", "stf_samples"]
