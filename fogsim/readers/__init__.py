"""Dataset adapters: each turns a dataset on disk into a list of :class:`Sample`.

Adapters only read; outputs are written by :mod:`fogsim.fog.batch` under ``--out``, mirroring
each sample's ``key`` (its path relative to the dataset root, without suffix). The entry points:
:func:`fogsim.readers.folder.folder_samples` (image + depth folders),
:func:`fogsim.readers.cityscapes.cityscapes_samples` and :func:`fogsim.readers.waymo.waymo_samples`
(v1 TFRecord or v2 parquet; the :mod:`fogsim.readers.waymo` package). They are not imported here,
so that importing the sample record (:mod:`fogsim.readers.base`) does not load every reader.
"""
from fogsim.readers.base import DepthSpec, Labels, Sample

__all__ = ["DepthSpec", "Labels", "Sample"]
