"""Decoded fields of Waymo input files (crafted or damaged ones included), checked with
:func:`fogsim.schema.base.check` where they are decoded, each failure one line naming the file and
row (``FILE#row N: [CameraBoxComponent].type: must be an integer (got nan)``).

What guards what (``docs/safety.md``, Schemas): the *kind* of every v2 column is declared in
:data:`fogsim.readers.waymo.images.V2_COLUMN_KINDS` and checked when a file is opened; the values a
column kind admits but a field does not (a NaN in a float column of codes) are checked per row by
the models here; v1 protobuf fields by the typed accessors of :mod:`fogsim.readers.waymo.protobuf_wire`
(the wire type) and the value checks of the readers.
"""
from __future__ import annotations

from pydantic import Field

from fogsim.schema.base import Int, Open

__all__ = ["V2BoxCodes"]


class V2BoxCodes(Open):
    """The integer codes of a v2 box row (``camera_box``, ``projected_lidar_box``): ``type``
    (``Label.Type``) and ``difficulty_level.detection``. Parquet may store them as floats: 3.0 is
    3; NaN, 2.5 and null are refused."""

    type: Int
    difficulty: Int | None = Field(None, alias="difficulty_level.detection")
