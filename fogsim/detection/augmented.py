"""Ultralytics training with on-the-fly fog: the study's ``augmented`` model.

:func:`fog_trainer` returns a subclass of Ultralytics' ``DetectionTrainer`` whose training set
is a :class:`FoggyDataset` — a documented subclass of ``ultralytics.data.YOLODataset`` that fogs
every image it loads (``get_image_and_label``, also used by Mosaic and MixUp for their extra
images) with β drawn per sample by a :class:`fogsim.augment.FogSpec`, from the frame's ray
distance (the dataset's ``depth/<frame>.exr`` + camera, :func:`fogsim.dataset.reader.read_distance`,
resized nearest-neighbour to the loaded image). It is handed to ``YOLO(...).train(trainer=…)``,
Ultralytics' own hook for a custom trainer: no internals are patched. Validation during training
uses Ultralytics' plain dataset (the images on disk).

Images are fogged in Ultralytics' BGR order: the airlight is grey, so channel order does not
matter. Draws are seeded by (seed, image index, how often this process loaded that image), so a
run with the same seed and workers repeats its fog.
"""
from __future__ import annotations

from collections import Counter
from functools import lru_cache
from pathlib import Path

import cv2
import numpy as np

from fogsim.augment.spec import FogSpec, apply_fog
from fogsim.dataset.layout import DatasetLayout
from fogsim.dataset.reader import read_distance

DEPTH_CACHE = 256  # frames of ray distance kept per process


def foggy_dataset(dataset: Path, spec: FogSpec, seed: int = 0):
    """The :class:`FoggyDataset` class for ``dataset`` (the fogsim dataset whose frames the
    training images are) and ``spec``; it takes ``YOLODataset``'s arguments."""
    from ultralytics.data import YOLODataset

    layout = DatasetLayout(dataset)

    @lru_cache(maxsize=DEPTH_CACHE)
    def distance(frame: str) -> np.ndarray:
        return read_distance(layout, frame)

    class FoggyDataset(YOLODataset):
        """YOLODataset whose every loaded image is fogged from its frame's depth; ``last_beta``
        maps an index to the β (1/m) of its latest load."""

        def __init__(self, *args, **kwargs):
            self.loads, self.last_beta = Counter(), {}
            super().__init__(*args, **kwargs)

        def get_image_and_label(self, index: int):
            label = super().get_image_and_label(index)
            image = label["img"]
            d = cv2.resize(distance(Path(self.im_files[index]).stem), (image.shape[1], image.shape[0]),
                           interpolation=cv2.INTER_NEAREST)
            self.loads[index] += 1
            draw = spec.draw(np.random.default_rng([seed, index, self.loads[index]]), image.shape[:2])
            label["img"] = apply_fog(image, d, draw, spec)
            self.last_beta[index] = draw.beta
            return label

    return FoggyDataset


def fog_trainer(ultralytics, dataset: Path, spec: FogSpec, seed: int = 0):
    """A ``DetectionTrainer`` subclass that trains on :func:`foggy_dataset`'s class (see the
    module docstring); ``ultralytics`` is the module set up by
    :func:`fogsim.detection.yolo.load_ultralytics`."""
    from ultralytics.data.utils import get_split_fraction
    from ultralytics.models.yolo.detect import DetectionTrainer
    from ultralytics.utils import colorstr
    from ultralytics.utils.torch_utils import unwrap_model

    FoggyDataset = foggy_dataset(dataset, spec, seed)

    class FogTrainer(DetectionTrainer):
        """DetectionTrainer whose training set is a FoggyDataset (the arguments Ultralytics'
        ``build_yolo_dataset`` gives a detection YOLODataset in train mode)."""

        def build_dataset(self, img_path, mode="train", batch=None):
            if mode != "train":
                return super().build_dataset(img_path, mode, batch)
            cfg = self.args
            return FoggyDataset(
                img_path=img_path, imgsz=cfg.imgsz, batch_size=batch, augment=True, hyp=cfg, rect=cfg.rect,
                cache=cfg.cache or None, single_cls=cfg.single_cls or False,
                stride=max(int(unwrap_model(self.model).stride.max()), 32), pad=0.0, prefix=colorstr("train: "),
                task=cfg.task, classes=cfg.classes, data=self.data,
                fraction=get_split_fraction(cfg.fraction, "train"))

    return FogTrainer


def training_datasets(dataset: Path, level: str, spec: FogSpec, names: dict[int, str], imgsz: int = 640,
                      seed: int = 0) -> tuple:
    """(Ultralytics' ``YOLODataset``, the :func:`foggy_dataset` one) over ``images/<level>`` of a
    fogsim dataset, both with Ultralytics' default training augmentation (mosaic, perspective,
    HSV, flip) at ``imgsz`` — the pair ``fogsim bench augment`` times. Call
    :func:`fogsim.detection.yolo.load_ultralytics` first."""
    from ultralytics.cfg import get_cfg
    from ultralytics.data import YOLODataset

    kw = dict(img_path=str(DatasetLayout(dataset).images_dir(level)), imgsz=imgsz, augment=True, hyp=get_cfg(),
              data={"names": names, "channels": 3})
    return YOLODataset(**kw), foggy_dataset(dataset, spec, seed)(**kw)
