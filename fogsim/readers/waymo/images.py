"""Waymo camera images, read on demand: the picklable readers of v1 (TFRecord) and v2 (parquet)
images, and the one parquet opener of the Waymo readers.

* v1: :class:`TFRecordImage`, one camera's ``CameraImage.image`` (JPEG) of a ``Frame`` record,
  parsed with :mod:`.protobuf_wire` using the field numbers below (``dataset.proto``).
* v2: :class:`ParquetImage`, the ``[CameraImageComponent].image`` of one row of a
  ``camera_image/*.parquet`` file (read with pyarrow, the ``waymo`` extra).

Images decode to RGB uint8 H×W×3 (:func:`fogsim.fileio.decode_image`).
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Iterable

import numpy as np

from fogsim.deps import require
from fogsim.errors import InputError
from fogsim.fileio import decode_image
from fogsim.readers.waymo import protobuf_wire as pw
from fogsim.readers.waymo.address import V1Record

# v1 field numbers (dataset.proto): Frame.images, CameraImage.name / .image
FRAME_IMAGES = 4
IMAGE_NAME, IMAGE_DATA = 1, 2

# v2 column (v2/perception/camera_image.py; v2/component.py names it)
V2_IMAGE = "[CameraImageComponent].image"


def open_parquet(file: Path, columns: Iterable[str]):
    """A ``pyarrow.parquet.ParquetFile`` known to hold ``columns``.

    Raises :class:`~fogsim.errors.MissingDependency` without pyarrow (the ``waymo`` extra) and
    :class:`~fogsim.errors.InputError` naming ``file`` when it is unreadable or lacks a column."""
    pq = require("pyarrow.parquet", "waymo")
    try:
        pf = pq.ParquetFile(file)
    except (OSError, ValueError) as exc:  # pyarrow's ArrowInvalid is a ValueError
        raise InputError(file, f"not a readable parquet file ({exc})") from None
    missing = [c for c in columns if c not in pf.schema_arrow.names]
    if missing:
        raise InputError(file, f"missing column(s) {', '.join(missing)} (not a Waymo v2 file?)")
    return pf


@dataclass(frozen=True)
class TFRecordImage:
    """Picklable reader: the image of camera ``camera`` (CameraName enum value) in the Frame at
    ``record``; ``source`` names it in messages."""

    record: V1Record
    camera: int
    source: str

    def __call__(self) -> np.ndarray:
        frame = pw.decode_fields(self.record.read(self.source), self.source)
        for image in pw.submessages(frame, FRAME_IMAGES, self.source):
            if pw.integer(image, IMAGE_NAME, 0, self.source) == self.camera:
                return decode_image(pw.blob(image, IMAGE_DATA, self.source) or b"", self.source)
        raise InputError(self.source, "camera image not in the frame (file changed since "
                                      "indexing?)")


@lru_cache(maxsize=1)
def _image_column(path: str, row_group: int, stamp: tuple[int, int]):
    """One row group's image column, cached (keyed by ``stamp`` = mtime, size too) so reading
    the images of one row group in turn decodes the column once."""
    pf = open_parquet(Path(path), [V2_IMAGE])
    return pf.read_row_group(row_group, columns=[V2_IMAGE]).column(0)


@dataclass(frozen=True)
class ParquetImage:
    """Picklable reader: the image in row ``row`` of row group ``row_group`` of a v2 file."""

    path: str
    row_group: int
    row: int
    source: str

    def __call__(self) -> np.ndarray:
        try:
            stat = os.stat(self.path)
            column = _image_column(self.path, self.row_group, (stat.st_mtime_ns, stat.st_size))
            data = column[self.row].as_py()
        except (OSError, ValueError, IndexError) as exc:
            raise InputError(self.source, f"cannot read the image ({exc})") from None
        return decode_image(data or b"", self.source)
