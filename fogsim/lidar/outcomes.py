"""The outcome of each input point of a fogged scan — one vocabulary for every LiDAR fog model
(:mod:`fogsim.lidar.fog` and the published models, :mod:`fogsim.lidar.hahner2021`, :mod:`fogsim.lidar.stf2020`):
``kept`` (reported unchanged), ``attenuated`` (reported, dimmer and/or moved by range noise), ``lost`` (not
reported), ``clutter`` (the fog's echo reported instead, on the same ray), ``no-return`` (a row that stands for
a firing without a return — :func:`fogsim.lidar.rays.no_returns` — and still returns nothing: written as it
was); codes 0–4 in this order."""
from __future__ import annotations

__all__ = ["ATTENUATED", "CLUTTER", "EMPTY_RAY_INDEX", "KEPT", "LOST", "NO_RETURN", "OUTCOMES"]

OUTCOMES = ("kept", "attenuated", "lost", "clutter", "no-return")
KEPT, ATTENUATED, LOST, CLUTTER, NO_RETURN = range(5)
#: the ``index`` of a fogged scan's rows that no input point made (the empty rays' clutter points, and the
#: points a model adds: stf2020's random scatter)
EMPTY_RAY_INDEX = -1
