"""The study folder's format, one owner: every path under a ``fogsim study`` OUT (what
:class:`fogsim.dataset.layout.DatasetLayout` is to a dataset).

Layout under the root::

    study.json                          dataset, levels, training configuration (a rerun with
                                        other parameters is refused)
    yolo/                               training view of the dataset (symlinks, split lists, data YAMLs)
    ultralytics_config/                 Ultralytics' settings folder (kept out of the user's home)
    runs/<model>/                       the model's Ultralytics run; fogsim_done.json, written last,
                                        marks it trained; weights/best.pt
    predictions/<model>/<level>.json    COCO results on the level's validation images
    report/                             cross_density.{json,csv,md}, heatmaps, fog_level.json,
                                        fog_level_<estimator>.png, distance_policy.json, report.md
    sim_to_real/study/                  the rendered dataset's own study (a study folder itself)
    sim_to_real/predictions/<model>/<level>.json   its models on this dataset's validation images
    yolo_scatter/                       training view of the scatter-fogged render (--scatter-dataset)
    path_traced/predictions/<model>/<level>.json   every model on the path-traced render's
                                        validation images (--eval-dataset)

Models are named by fog level key, and :data:`~fogsim.dataset.layout.MIXED_MODEL` for the model
trained on every level.
"""
from __future__ import annotations

from pathlib import Path

#: written last into a model's run folder: its presence marks the model trained
DONE_FILE = "fogsim_done.json"


class StudyLayout:
    """Every path of the study folder ``root`` (see the module docstring)."""

    def __init__(self, root: str | Path):
        self.root = Path(root)

    def study_file(self) -> Path:
        return self.root / "study.json"

    def training_view(self) -> Path:
        return self.root / "yolo"

    def config_dir(self) -> Path:
        return self.root / "ultralytics_config"

    def run(self, model: str) -> Path:
        """The model's Ultralytics run folder."""
        return self.root / "runs" / model

    def run_done(self, model: str) -> Path:
        return self.run(model) / DONE_FILE

    def weights(self, model: str) -> Path:
        return self.run(model) / "weights" / "best.pt"

    def predictions(self, model: str) -> Path:
        return self.root / "predictions" / model

    def prediction(self, model: str, level: str) -> Path:
        return self.predictions(model) / f"{level}.json"

    def report(self, name: str = "") -> Path:
        """The report folder, or the file ``name`` in it."""
        return self.root / "report" / name if name else self.root / "report"

    def sim_study(self) -> Path:
        """The root of the sim-to-real study of the rendered dataset (a study folder itself)."""
        return self.root / "sim_to_real" / "study"

    def sim_prediction(self, model: str, level: str) -> Path:
        """Detections of the sim study's model ``model`` on this study's dataset, level ``level``."""
        return self.root / "sim_to_real" / "predictions" / model / f"{level}.json"

    def scatter_view(self) -> Path:
        """The training view of the scatter-fogged render (``--scatter-dataset``)."""
        return self.root / "yolo_scatter"

    def eval_predictions(self, model: str) -> Path:
        return self.root / "path_traced" / "predictions" / model

    def eval_prediction(self, model: str, level: str) -> Path:
        """Detections of model ``model`` on the path-traced render's (``--eval-dataset``) level ``level``."""
        return self.eval_predictions(model) / f"{level}.json"
