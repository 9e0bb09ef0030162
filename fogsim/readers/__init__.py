"""Dataset adapters: each turns a dataset on disk into a list of :class:`Sample`.

Adapters only read; outputs are written by :mod:`fogsim.fog.batch` under ``--out``, mirroring
each sample's ``key`` (its path relative to the dataset root, without suffix). The entry points:
:func:`folder_samples` (image + depth folders), :func:`cityscapes_samples` and
:func:`waymo_samples` (v1 TFRecord or v2 parquet; the :mod:`fogsim.readers.waymo` package).
"""
from fogsim.readers.base import DepthSpec, Labels, Sample
from fogsim.readers.cityscapes import cityscapes_samples
from fogsim.readers.folder import folder_samples
from fogsim.readers.waymo import waymo_samples, waymo_v1_samples, waymo_v2_samples

__all__ = ["DepthSpec", "Labels", "Sample", "cityscapes_samples", "folder_samples", "waymo_samples",
           "waymo_v1_samples", "waymo_v2_samples"]
