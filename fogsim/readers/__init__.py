"""Dataset adapters: each turns a dataset on disk into a list of :class:`Sample`.

Adapters only read; outputs are written by :mod:`fogsim.fog.batch` under ``--out``, mirroring
each sample's ``key`` (its path relative to the dataset root, without suffix).
"""
from fogsim.readers.base import DepthSpec, Sample  # noqa: F401
