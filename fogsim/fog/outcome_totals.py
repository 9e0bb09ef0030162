"""The end of ``fogsim fog --points``: each level's outcome totals over the scans (or radar sweeps) of the run —
LiDAR points kept, attenuated, lost and replaced by fog clutter (and the clutter the fog adds on rays that
returned nothing); radar detections kept and lost — summed from the
sidecars (:class:`~fogsim.schema.documents.PointsSidecar`) of every item of this shard that is done, so a
resumed run counts what it found done too."""
from __future__ import annotations

from collections import Counter

from fogsim.schema.base import load_json
from fogsim.schema.documents import PointsSidecar

__all__ = ["EMPTY_RAYS", "outcome_totals", "totals_lines"]


EMPTY_RAYS = "empty-ray clutter"  # a LiDAR's fog clutter on rays that returned nothing in clear air (no input point)


def outcome_totals(job, items) -> dict[str, Counter]:
    """Level key → outcome → count over ``items`` that ``job`` has done (``job.paths(item, level)[2]``: the
    sidecar): each input point's (detection's) outcome, and a LiDAR's :data:`EMPTY_RAYS` (points the fog
    added on rays without an input point)."""
    totals = {lv.key: Counter() for lv in job.levels}
    for item in items:
        if not job.done(item):
            continue
        for lv in job.levels:
            sidecar = load_json(job.paths(item, lv)[2], PointsSidecar)
            totals[lv.key].update(sidecar.outcomes)
            totals[lv.key][EMPTY_RAYS] += sidecar.empty_ray_clutter
    return totals


def totals_lines(totals: dict[str, Counter], what: str, unit: str = "scans") -> list[str]:
    """``"  beta0.06: kept 80 (66.7 %), attenuated 30 (25.0 %), lost 0 (0.0 %), clutter 10 (8.3 %) + 12 on empty
    rays"``, one per level under a heading naming ``what`` ("points", "detections") and the ``unit`` summed
    ("scans", "sweeps"): shares of the input."""
    width = max((len(k) for k in totals), default=0)
    lines = [f"outcomes per level ({what} of the {unit} done):"]
    for key, counts in totals.items():
        extra = counts.get(EMPTY_RAYS, 0)
        n = sum(v for k, v in counts.items() if k != EMPTY_RAYS)
        parts = [f"{k} {v} ({100 * v / max(n, 1):.1f} %)" for k, v in counts.items() if k != EMPTY_RAYS]
        text = ", ".join(parts) + (f" + {extra} on empty rays" if extra else "") if n else "none done"
        lines.append(f"  {key + ':':<{width + 1}} {text}")
    return lines
