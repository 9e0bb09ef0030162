"""The albumentations front end: :class:`Fog`, physical fog from each sample's depth.

    import albumentations as A
    import fogsim.augment
    aug = A.Compose([fogsim.augment.Fog(beta=(0, 0.12))], additional_targets={"depth": "mask"},
                    bbox_params=A.BboxParams(format="pascal_voc", label_fields=["labels"]), seed=0)
    out = aug(image=rgb, depth=distance_m, bboxes=boxes, labels=labels)

``depth`` is registered as a *mask* target so that geometric transforms before or after Fog
resize, crop and flip it with the image (nearest-neighbour); Fog itself reads it and changes
only the image — depth, masks, boxes and keypoints pass through untouched. The β used is in
``transform.get_applied_params()["beta"]`` (and in ``applied_transforms`` with Compose's
``save_applied_params=True``). Seeding: Compose's ``seed`` (albumentations' own generator).
Needs albumentations (the ``augment`` extra); importing this module without it raises
:class:`~fogsim.errors.MissingDependency` with the install line.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from fogsim.augment.checks import check_numpy_depth, check_numpy_image
from fogsim.augment.spec import FogSpec, apply_fog
from fogsim.deps import require

A = require("albumentations", "augment")


class Fog(A.ImageOnlyTransform):
    """Physical fog with β drawn per call: every keyword of :class:`fogsim.augment.spec.FogSpec`
    (``beta``, ``model``, ``scatter_params``, ``space``, …) is the spec's, forwarded as it is;
    ``depth_key`` names the depth target (H×W or H×W×1 metres, ray distance unless
    ``depth="planar"``). ``p``: probability of applying it."""

    def __init__(self, beta=(0.0, 0.12), depth_key: str = "depth", p: float = 1.0, **spec: Any):
        super().__init__(p=p)
        self.spec = FogSpec(beta=beta, **spec)
        self.depth_key = depth_key

    @property
    def targets_as_params(self) -> list[str]:
        return [self.depth_key]

    def get_params_dependent_on_data(self, params: dict[str, Any], data: dict[str, Any]) -> dict[str, Any]:
        if self.depth_key not in data:
            raise ValueError(f"Fog needs the depth target {self.depth_key!r} (metres): pass it to the call and "
                             f"register it, additional_targets={{{self.depth_key!r}: 'mask'}}")
        image = check_numpy_image(data["image"])
        depth = check_numpy_depth(data[self.depth_key], image.shape[:2], self.depth_key)
        draw = self.spec.draw(self.random_generator, image.shape[:2])
        self._depth = depth  # read by apply (kept out of params: they are saved per call)
        return {"beta": draw.beta, "airlight": draw.airlight, "draw": draw}

    def apply(self, img: np.ndarray, draw=None, **params: Any) -> np.ndarray:
        return apply_fog(img, self._depth, draw, self.spec)

    def get_transform_init_args_names(self) -> tuple[str, ...]:
        return ()
