"""Where one Waymo frame is: the small picklable addresses that the image, label and LiDAR readers
hold (never pixels, labels or points), so samples can be passed to worker processes.

* v1: :class:`V1Record`, one ``Frame`` record of a .tfrecord file (its byte offset and data length,
  from :func:`~fogsim.readers.waymo.tfrecord.index_tfrecord`).
* v2: :class:`V2Frame`, one frame of a split folder (the folder, the segment context name and the
  timestamp in µs: the key the v2 tables share).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from fogsim.readers.waymo.tfrecord import read_record


@dataclass(frozen=True)
class V1Record:
    """The ``Frame`` record of ``length`` data bytes at byte ``offset`` of the .tfrecord file ``path``;
    ``verify``: check its data CRC on every read."""

    path: str
    offset: int
    length: int
    verify: bool = True

    def read(self, source: str) -> bytes:
        """The record's data bytes (``source`` names it in errors)."""
        return read_record(self.path, self.offset, self.length, source, self.verify)


@dataclass(frozen=True)
class V2Frame:
    """A frame of the v2 split folder ``root`` (e.g. ``.../training``): segment ``context`` name and
    ``timestamp`` (µs)."""

    root: str
    context: str
    timestamp: int

    def table(self, tag: str) -> Path:
        """The segment's table ``<root>/<tag>/<context>.parquet`` (which may not exist)."""
        return Path(self.root) / tag / f"{self.context}.parquet"
