"""What the study and YOLO tests share: the synthetic dataset they train on, the study's script
entry (``scripts/train_per_density.py`` = ``fogsim study``) and the tiny training flags."""
from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

from synthetic_dataset import make_dataset

ROOT = Path(__file__).resolve().parents[1]
LEVELS = ["clear", "beta0.03", "beta0.06", "beta0.09", "beta0.12"]
#: the smallest real training: one epoch on CPU at 64 px
TINY = ("--epochs", "1", "--imgsz", "64", "--batch", "4", "--workers", "0", "--device", "cpu", "--no-plots",
        "--quiet")


def study_dataset(tmp_path_factory) -> Path:
    """16 synthetic frames at the five paper levels, half of them in train."""
    return make_dataset(tmp_path_factory.mktemp("synthetic") / "ds", frames=16, train_fraction=0.5)


def driver(*args, **kw) -> subprocess.CompletedProcess:
    """``scripts/train_per_density.py ARGS`` (the study's command) in a fresh Python."""
    return subprocess.run([sys.executable, str(ROOT / "scripts" / "train_per_density.py"), *map(str, args)],
                          capture_output=True, text=True, cwd=ROOT, **kw)


def need_detect_extra() -> None:
    # not imported here: Ultralytics writes settings on import
    if importlib.util.find_spec("ultralytics") is None or importlib.util.find_spec("pycocotools") is None:
        pytest.skip("the 'detect' extra (Ultralytics, pycocotools) is not installed")
