"""Waymo camera images, read on demand: the picklable readers of v1 (TFRecord) and v2 (parquet)
images, and the one parquet opener of the Waymo readers.

* v1: :class:`TFRecordImage`, one camera's ``CameraImage.image`` (JPEG) of a ``Frame`` record,
  parsed with :mod:`.protobuf_wire` using the field numbers below (``dataset.proto``).
* v2: :class:`ParquetImage`, the ``[CameraImageComponent].image`` of one row of a
  ``camera_image/*.parquet`` file (read with pyarrow, the ``waymo`` extra).

Images decode to RGB uint8 H×W×3 (:func:`fogsim.io.images.decode_image`).
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
from fogsim.io.images import decode_image
from fogsim.readers.waymo import protobuf_wire as pw
from fogsim.readers.waymo.address import V1Record

# v1 field numbers (dataset.proto): Frame.images, CameraImage.name / .image
FRAME_IMAGES = 4
IMAGE_NAME, IMAGE_DATA = 1, 2

# v2 column (v2/perception/camera_image.py; v2/component.py names it)
V2_IMAGE = "[CameraImageComponent].image"


#: The declared kind of the v2 columns fogsim reads, by name (exact) or by the end of the name:
#: what :func:`open_parquet` checks before any value is read (a list where a key belongs, a
#: string where a box coordinate does, is refused naming the file and the column). Sensor keys
#: are integers or strings (some real files store "FRONT" or "1"); values that the column kind
#: admits but the field does not (a NaN box type) are checked per row where they are decoded.
V2_COLUMN_KINDS = {
    "key.segment_context_name": ("string",), "key.frame_timestamp_micros": ("integer",),
    "key.camera_name": ("integer", "string"), "key.laser_name": ("integer", "string"),
    "key.camera_object_id": ("string",), "key.laser_object_id": ("string",),
    V2_IMAGE: ("binary",),
}
V2_COLUMN_KIND_ENDINGS = {
    **{f".box.{a}": ("number",) for a in ("center.x", "center.y", "center.z", "size.x", "size.y", "size.z",
                                          "heading")},
    ".type": ("number",), ".width": ("number",), ".height": ("number",), ".transform": ("list",),
    ".values": ("list",), ".shape": ("list",),
}
_KIND_WORDS = {"string": "a string", "integer": "an integer", "number": "a number", "binary": "a binary",
               "list": "a list"}


def _kind_of(arrow_type) -> set[str]:
    import pyarrow as pa

    t = arrow_type
    if pa.types.is_dictionary(t):
        t = t.value_type
    kinds = set()
    if pa.types.is_string(t) or pa.types.is_large_string(t):
        kinds.add("string")
    if pa.types.is_integer(t):
        kinds |= {"integer", "number"}
    if pa.types.is_floating(t):
        kinds.add("number")
    if pa.types.is_binary(t) or pa.types.is_large_binary(t):
        kinds.add("binary")
    if pa.types.is_list(t) or pa.types.is_large_list(t) or pa.types.is_fixed_size_list(t):
        kinds.add("list")
    return kinds


def declared_kinds(column: str) -> tuple[str, ...] | None:
    """The kinds :data:`V2_COLUMN_KINDS` declares for ``column`` (None: not declared)."""
    if column in V2_COLUMN_KINDS:
        return V2_COLUMN_KINDS[column]
    return next((k for end, k in V2_COLUMN_KIND_ENDINGS.items() if column.endswith(end)), None)


def open_parquet(file: Path, columns: Iterable[str], optional: Iterable[str] = ()):
    """A ``pyarrow.parquet.ParquetFile`` known to hold ``columns``, each of its declared kind
    (:data:`V2_COLUMN_KINDS`).

    Raises :class:`~fogsim.errors.MissingDependency` without pyarrow (the ``waymo`` extra) and
    :class:`~fogsim.errors.InputError` naming ``file`` when it is unreadable, lacks a column or
    holds one of another kind (``optional`` columns are checked where the file has them)."""
    pq = require("pyarrow.parquet", "waymo")
    try:
        pf = pq.ParquetFile(file)
    except (OSError, ValueError) as exc:  # pyarrow's ArrowInvalid is a ValueError
        raise InputError(file, f"not a readable parquet file ({exc})") from None
    columns = list(columns)
    missing = [c for c in columns if c not in pf.schema_arrow.names]
    if missing:
        raise InputError(file, f"missing column(s) {', '.join(missing)} (not a Waymo v2 file?)")
    schema = pf.schema_arrow
    for column in [*columns, *(c for c in optional if c in schema.names)]:
        want = declared_kinds(column)
        arrow_type = schema.field(column).type
        if want and not set(want) & _kind_of(arrow_type):
            raise InputError(file, f"column {column} holds {arrow_type} values, expected "
                                   f"{' or '.join(_KIND_WORDS[k] for k in want)} column")
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
