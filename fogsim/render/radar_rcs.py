"""Radar cross sections of a rendered scene's objects at 77 GHz, by class and aspect (pure Python).

An object's RCS σ(θ) (m², reported in dBsm = 10·log10 σ) depends on its class and on the aspect angle θ
between the object's heading and the line of sight from the radar (θ = 0: seen head-on or from behind,
90°: broadside). Between the class's head-on and broadside values the power interpolates as
σ(θ) = σ_front·cos²θ + σ_side·sin²θ (a smooth stand-in for the measured lobes; no specular spikes).
Typical values (dBsm; head-on, broadside), with their sources:

* car / van: 10, 14 — Matsunami, Nakamura, Kajiwara, "RCS measurements for vehicles and pedestrian at
  26 and 79 GHz", ICSPCS 2012 (doi:10.1109/ICSPCS.2012.6508004): passenger cars ≈ 10 dBsm front/rear,
  higher broadside; trucks and buses larger (the same trend, values stated here: 15, 20);
* pedestrian: −8, −8 — Fortuny-Guasch & Chareau, "Radar cross section measurements of pedestrian dummies
  and humans in the 24/77 GHz frequency bands", JRC report EUR 25762 EN (2013), and Matsunami et al.:
  adults ≈ −10 … −5 dBsm, nearly independent of aspect;
* cyclist: −5, 0 — Belgiovane & Chen, "Bicycles and human riders backscattering at 77 GHz for automotive
  radar", EuCAP 2014: a bicycle with rider ≈ −5 dBsm head-on, a few dB more from the side (the frame);
* traffic light, traffic sign, pole (steel): 5, 5 / 10, 10 / 5, 5 — stated here (typical of flat plates and
  cylinders of their size off normal incidence), not measured;
* building, tree: per resolution cell γ·A (the constant-γ clutter model, A the area the cell's rays see
  face-on) with γ = −20 dB (walls, mostly seen at grazing angles along a street) and −15 dB (trees), stated.

Ground (road, sidewalk, lane marking, curb) is not an object: it returns **clutter**, a resolution cell's
σ = σ⁰·A_cell with σ⁰ = :data:`GROUND_SIGMA0_DB` (asphalt at 77 GHz and grazing incidence: −20 … −30 dB,
Sarabandi, Li, Nashashibi, "Modeling and measurements of scattering from road surfaces at millimeter-wave
frequencies", IEEE TAP 45(11), 1997).
"""
from __future__ import annotations

import math

import numpy as np

#: (head-on, broadside) RCS in dBsm by object class (the module docstring's table and sources)
CLASS_RCS_DBSM = {"car": (10.0, 14.0), "van": (10.0, 14.0), "truck": (15.0, 20.0), "bus": (15.0, 20.0),
                  "pedestrian": (-8.0, -8.0), "cyclist": (-5.0, 0.0), "traffic_light": (5.0, 5.0),
                  "traffic_sign": (10.0, 10.0), "pole": (5.0, 5.0)}
#: classes whose detections are areas (σ⁰ in dB times the resolution cell's area), not point targets
AREA_SIGMA0_DB = {"building": -20.0, "tree": -15.0}
#: the ground's classes (clutter, not objects) and its σ⁰ in dB
GROUND_CLASSES = ("road", "lane_marking", "sidewalk", "curb")
GROUND_SIGMA0_DB = -25.0
#: the RCS of an object of a class the table lacks (a user's scene), dBsm
DEFAULT_RCS_DBSM = 0.0

__all__ = ["AREA_SIGMA0_DB", "CLASS_RCS_DBSM", "DEFAULT_RCS_DBSM", "GROUND_CLASSES", "GROUND_SIGMA0_DB",
           "aspect_rad", "object_rcs_dbsm"]


def aspect_rad(heading_xy, line_of_sight_xy) -> float:
    """The aspect angle θ ∈ [0, π/2] between an object's heading and the line of sight (both horizontal
    vectors, any length): 0 head-on or from behind, π/2 broadside."""
    h = np.asarray(heading_xy, np.float64)[:2]
    s = np.asarray(line_of_sight_xy, np.float64)[:2]
    n = float(np.linalg.norm(h) * np.linalg.norm(s))
    if n == 0.0:
        return 0.0
    return math.acos(min(1.0, abs(float(h @ s)) / n))


def object_rcs_dbsm(cls: str, aspect: float) -> float:
    """σ(θ) in dBsm of a point-target class at aspect ``aspect`` (radians): the module docstring's model."""
    front, side = CLASS_RCS_DBSM.get(cls, (DEFAULT_RCS_DBSM, DEFAULT_RCS_DBSM))
    c2 = math.cos(aspect) ** 2
    return 10.0 * math.log10(10 ** (front / 10) * c2 + 10 ** (side / 10) * (1.0 - c2))
