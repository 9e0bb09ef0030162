"""Hostile arguments to the Python API of ``fogsim.augment`` (issue 31, class 4: U7, U8, U9; item 5).

Every front end — the NumPy reference (``apply_fog``, ``random_fog``, ``FogSpec``), albumentations'
``Fog``, the batched torch ``fog_batch`` and torchvision's ``FogV2`` — raises a ``TypeError`` (a
type or dtype it does not take) or a ``ValueError`` (a shape or range) whose message names the
argument, for anything it does not support; never an OpenCV assertion, a torch broadcast error,
an AttributeError, and never an image computed from garbage (an int32 or 0–255 float image read
as 0–1, a NaN airlight). The inputs are left as they were. The rules: :mod:`fogsim.augment.checks`.
"""
from __future__ import annotations

import subprocess
import sys
from dataclasses import dataclass
from typing import Callable

import numpy as np
import pytest

from fogsim.augment import Draw, FogSpec, apply_fog, random_fog

H, W = 4, 6
IMG = np.full((H, W, 3), 90, np.uint8)
DEPTH = np.full((H, W), 40.0, np.float32)


def rng():
    return np.random.default_rng(0)


@dataclass
class Call:
    """``call(inputs)`` must raise ``error`` with every string of ``says`` in its message; ``inputs``
    (built fresh per case) must be unchanged afterwards. ``needs``: the module that must import."""

    id: str
    call: Callable
    error: type
    says: tuple[str, ...]
    needs: str = ""


def np_case(id, f, error, *says):
    return Call(id, f, error, says)


# ----------------------------------------------------------------------------- NumPy reference
NUMPY = [
    np_case("random-fog-0x0", lambda: random_fog(np.zeros((0, 0, 3), np.uint8), np.zeros((0, 0), np.float32), rng(),
                                                  FogSpec(beta=0.05)), ValueError, "image is 0×0", "nothing to fog"),
    np_case("random-fog-0-wide", lambda: random_fog(np.zeros((5, 0, 3), np.uint8), np.zeros((5, 0), np.float32),
                                                     rng()), ValueError, "image is 0×5"),
    np_case("scatter-0x0", lambda: random_fog(np.zeros((0, 0, 3), np.uint8), np.zeros((0, 0), np.float32), rng(),
                                              FogSpec(beta=0.05, model="scatter")), ValueError, "image is 0×0"),
    np_case("scatter-1x1", lambda: random_fog(np.zeros((1, 1, 3), np.uint8), np.ones((1, 1), np.float32), rng(),
                                              FogSpec(beta=0.05, model="scatter")), ValueError, "image is 1×1",
            "at least 2 pixels"),
    np_case("image-int32", lambda: random_fog(IMG.astype(np.int32), DEPTH, rng()), TypeError, "image", "int32"),
    np_case("image-int64", lambda: random_fog(IMG.astype(np.int64), DEPTH, rng()), TypeError, "image", "int64"),
    np_case("image-bool", lambda: random_fog(IMG > 50, DEPTH, rng()), TypeError, "image", "bool"),
    np_case("image-float-0-255", lambda: random_fog(IMG.astype(np.float32), DEPTH, rng()), ValueError,
            "image is floating point", "divide it by 255"),
    np_case("image-float-negative", lambda: random_fog(IMG.astype(np.float32) / -255, DEPTH, rng()), ValueError,
            "image is floating point", "[0, 1]"),
    np_case("image-float-nan", lambda: apply_fog(np.full((H, W, 3), np.nan, np.float32), DEPTH,
                                                 Draw(0.05, (255.0,) * 3)), ValueError, "image holds NaN"),
    np_case("image-grey", lambda: random_fog(IMG[..., 0], DEPTH, rng()), ValueError, "image must be H×W×3"),
    np_case("image-none", lambda: random_fog(None, DEPTH, rng()), TypeError, "image must be a NumPy array", "NoneType"),
    np_case("image-list", lambda: apply_fog(IMG.tolist(), DEPTH, Draw(0.05, (255.0,) * 3)), TypeError,
            "image must be a NumPy array"),
    np_case("rng-none", lambda: random_fog(IMG, DEPTH, None), TypeError, "rng must be a numpy.random.Generator"),
    np_case("rng-seed-int", lambda: random_fog(IMG, DEPTH, 0), TypeError, "rng must be"),
    np_case("depth-string", lambda: random_fog(IMG, "deep", rng()), TypeError, "depth must be"),
    np_case("depth-bool", lambda: random_fog(IMG, DEPTH > 0, rng()), TypeError, "depth must hold real numbers"),
    np_case("depth-other-size", lambda: random_fog(IMG, DEPTH[:2], rng()), ValueError, "depth must be H×W",
            "4×6"),
    np_case("depth-nan", lambda: random_fog(IMG, DEPTH * np.nan, rng()), ValueError, "NaN"),
    np_case("depth-negative", lambda: random_fog(IMG, -DEPTH, rng()), ValueError, "negative"),
    np_case("draw-not-a-draw", lambda: apply_fog(IMG, DEPTH, 0.05), TypeError, "draw must be a fogsim.augment.Draw"),
    np_case("draw-airlight-nan", lambda: apply_fog(IMG, DEPTH, Draw(0.05, (float("nan"),) * 3)), ValueError,
            "draw.airlight"),
    np_case("draw-airlight-negative", lambda: apply_fog(IMG, DEPTH, Draw(0.05, (-5.0,) * 3)), ValueError,
            "draw.airlight"),
    np_case("draw-beta-nan", lambda: apply_fog(IMG, DEPTH, Draw(float("nan"), (255.0,) * 3)), ValueError, "draw.beta"),
    np_case("draw-beta-string", lambda: apply_fog(IMG, DEPTH, Draw("0.1", (255.0,) * 3)), TypeError, "draw.beta"),
    np_case("spec-not-a-spec", lambda: apply_fog(IMG, DEPTH, Draw(0.05, (255.0,) * 3), {"beta": 1}), TypeError,
            "spec must be a fogsim.augment.FogSpec"),
    np_case("spec-beta-string-12", lambda: FogSpec(beta="12"), TypeError, "beta must be", "'12'"),
    np_case("spec-beta-string-decimal", lambda: FogSpec(beta="0.1"), TypeError, "beta must be", "'0.1'"),
    np_case("spec-beta-bool", lambda: FogSpec(beta=True), TypeError, "beta must be"),
    np_case("spec-beta-strings-in-list", lambda: FogSpec(beta=["0.1", "0.2"]), TypeError, "beta must hold numbers"),
    np_case("spec-beta-none", lambda: FogSpec(beta=None), TypeError, "beta must be"),
    np_case("spec-beta-negative", lambda: FogSpec(beta=-0.1), ValueError, "β must be finite values ≥ 0"),
    np_case("spec-beta-inf", lambda: FogSpec(beta=(0, float("inf"))), ValueError, "β must be finite"),
    np_case("spec-airlight-nan", lambda: FogSpec(airlight=float("nan")), ValueError, "airlight"),
    np_case("spec-airlight-string", lambda: FogSpec(airlight="white"), TypeError, "airlight must be a number"),
    np_case("spec-airlight-too-bright", lambda: FogSpec(airlight=300), ValueError, "airlight"),
    np_case("spec-heterogeneity-scale-tiny", lambda: FogSpec(heterogeneity=0.3, heterogeneity_scale=1e-9),
            ValueError, "heterogeneity scale"),
]


# ----------------------------------------------------------------------------- albumentations
def _albu(image, check_shapes: bool = True, **targets):
    import albumentations as A

    from fogsim.augment import Fog

    return A.Compose([Fog(beta=0.05)], additional_targets={"depth": "mask"}, seed=0,
                     is_check_shapes=check_shapes)(image=image, **targets)


def albu_case(id, f, error, *says):
    return Call(id, f, error, says, "albumentations")


ALBU = [
    albu_case("albu-0x0", lambda: _albu(np.zeros((0, 0, 3), np.uint8), depth=np.zeros((0, 0), np.float32)),
              ValueError, "image is 0×0"),
    albu_case("albu-depth-string", lambda: _albu(IMG, depth="abc"), TypeError, "depth"),
    albu_case("albu-depth-missing", lambda: _albu(IMG), ValueError, "Fog", "'depth'"),  # albumentations' words
    albu_case("albu-depth-other-size", lambda: _albu(IMG, False, depth=DEPTH[:2]), ValueError, "depth must be H×W"),
    albu_case("albu-image-float-0-255", lambda: _albu(IMG.astype(np.float32), depth=DEPTH), ValueError,
              "image is floating point", "divide it by 255"),
    albu_case("albu-image-int32", lambda: _albu(IMG.astype(np.int32), depth=DEPTH), TypeError, "image", "int32"),
    albu_case("albu-beta-string", lambda: __import__("fogsim.augment", fromlist=["Fog"]).Fog(beta="12"), TypeError,
              "beta must be"),
]


# ----------------------------------------------------------------------------- torch and torchvision
def _t(x):
    import torch

    return torch.from_numpy(np.ascontiguousarray(x))


def _timg(n=2, dtype="uint8"):
    import torch

    return torch.full((n, 3, H, W), 90, dtype=getattr(torch, dtype))


def _tdepth(n=2):
    import torch

    return torch.full((n, 1, H, W), 40.0)


def _fog_batch(*a, **k):
    from fogsim.augment import fog_batch

    return fog_batch(*a, **k)


def _fogv2(image, depth):
    from torchvision import tv_tensors

    from fogsim.augment import FogV2

    return FogV2(beta=0.05, seed=0)(tv_tensors.Image(image), tv_tensors.Mask(depth))


def torch_case(id, f, error, *says, needs="torch"):
    return Call(id, f, error, says, needs)


TORCH = [
    torch_case("batch-int32", lambda: _fog_batch(_timg(dtype="int32"), _tdepth(), 0.05), TypeError, "images", "int32"),
    torch_case("batch-int64", lambda: _fog_batch(_timg(dtype="int64"), _tdepth(), 0.05), TypeError, "images", "int64"),
    torch_case("batch-bool", lambda: _fog_batch(_timg() > 50, _tdepth(), 0.05), TypeError, "images", "bool"),
    torch_case("batch-float-0-255", lambda: _fog_batch(_timg(dtype="float32"), _tdepth(), 0.05), ValueError,
               "images is floating point", "divide it by 255"),
    torch_case("batch-airlight-nan", lambda: _fog_batch(_timg(), _tdepth(), 0.05, airlight=float("nan")), ValueError,
               "airlight must be finite"),
    torch_case("batch-airlight-negative", lambda: _fog_batch(_timg(), _tdepth(), 0.05, airlight=-1.0), ValueError,
               "airlight must be finite and in [0, 255]"),
    torch_case("batch-airlight-four-values", lambda: _fog_batch(_timg(), _tdepth(), 0.05, airlight=[1, 2, 3, 4]),
               ValueError, "airlight must be", "batch of 2"),
    torch_case("batch-beta-three-for-two", lambda: _fog_batch(_timg(), _tdepth(), _t(np.array([0.1, 0.2, 0.3]))),
               ValueError, "beta must be a number or 2 values", "got shape (3,)"),
    torch_case("batch-beta-string", lambda: _fog_batch(_timg(), _tdepth(), "0.1"), TypeError, "beta must be"),
    torch_case("batch-beta-negative", lambda: _fog_batch(_timg(), _tdepth(), -0.1), ValueError, "beta must be finite"),
    torch_case("batch-numpy-images", lambda: _fog_batch(_timg().numpy(), _tdepth().numpy(), 0.05), TypeError,
               "images must be a torch.Tensor", "torch.from_numpy"),
    torch_case("batch-numpy-depth", lambda: _fog_batch(_timg(), _tdepth().numpy(), 0.05), TypeError,
               "depth must be a torch.Tensor"),
    torch_case("batch-0x0", lambda: _fog_batch(_timg()[:, :, :0, :0], _tdepth()[:, :, :0, :0], 0.05), ValueError,
               "images is 0×0"),
    torch_case("batch-hwc", lambda: _fog_batch(_timg().permute(0, 2, 3, 1), _tdepth(), 0.05), ValueError,
               "images must be B×3×H×W"),
    torch_case("batch-depth-other-size", lambda: _fog_batch(_timg(), _tdepth()[:, :, :2], 0.05), ValueError,
               "depth must be B×1×H×W"),
    torch_case("batch-depth-bool", lambda: _fog_batch(_timg(), _tdepth() > 0, 0.05), TypeError,
               "depth must hold real numbers"),
    torch_case("batch-depth-nan", lambda: _fog_batch(_timg(), _tdepth() * float("nan"), 0.05), ValueError, "NaN"),
    torch_case("v2-on-a-batch", lambda: _fogv2(_timg(), _tdepth()), ValueError, "image must be 3×H×W",
               "for a batch use fog_batch", needs="torchvision"),
    torch_case("v2-depth-other-size", lambda: _fogv2(_timg(1)[0], _tdepth(1)[0][:, :2]), ValueError,
               "the depth Mask must be 1×H×W", needs="torchvision"),
    torch_case("v2-int32-image", lambda: _fogv2(_timg(1, "int32")[0], _tdepth(1)[0]), TypeError, "image", "int32",
               needs="torchvision"),
]

CASES = NUMPY + ALBU + TORCH


@pytest.mark.parametrize("case", [pytest.param(c, id=c.id, marks=[pytest.mark.torch] if c.needs in ("torch",
                                                                                                     "torchvision")
                                               else []) for c in CASES])
def test_hostile_augment_call(case: Call):
    if case.needs:
        pytest.importorskip(case.needs)
    before = (IMG.copy(), DEPTH.copy())
    with pytest.raises(case.error) as err:
        case.call()
    for text in case.says:
        assert text in str(err.value), str(err.value)
    assert type(err.value) is case.error, f"{type(err.value).__name__}: {err.value}"  # not a subclass's own
    assert (IMG == before[0]).all() and (DEPTH == before[1]).all(), "an input changed"


def test_at_least_sixty_cases():
    assert len(CASES) >= 60 and len({c.id for c in CASES}) == len(CASES)


def test_what_is_supported_still_fogs_by_the_formula():
    """The checks refuse only what is unsupported: uint16, float 0–1 (float16 too) and a 1×1 image
    fog to I·t + A·(1 − t) as before."""
    t = np.exp(-0.05 * 40.0)
    for image, scale in ((IMG, 255), (IMG.astype(np.uint16) * 257, 65535), (IMG / np.float32(255), 1.0),
                         ((IMG / 255).astype(np.float16), 1.0)):
        out = apply_fog(image, DEPTH, Draw(0.05, (255.0,) * 3))
        assert out.dtype == image.dtype
        expected = (90 / 255 * t + (1 - t)) * scale
        assert np.allclose(out.astype(np.float64), expected, atol=max(1.0, scale * 2e-3)), (image.dtype, out[0, 0])
    one = apply_fog(IMG[:1, :1], DEPTH[:1, :1], Draw(0.05, (255.0,) * 3))
    assert one.shape == (1, 1, 3) and abs(int(one[0, 0, 0]) - round(90 * t + 255 * (1 - t))) <= 1


def test_fog_batch_needs_no_torchvision():
    """Item 5: a torch-only user (torchvision absent) has fog_batch; FogV2 alone says what to install."""
    pytest.importorskip("torch")
    code = """
import sys
sys.modules["torchvision"] = None  # as if not installed: every import of it fails
import torch
from fogsim.augment import fog_batch
from fogsim.errors import MissingDependency
out = fog_batch(torch.full((1, 3, 2, 2), 90, dtype=torch.uint8), torch.full((1, 1, 2, 2), 40.0), 0.05)
assert out.dtype == torch.uint8 and int(out[0, 0, 0, 0]) == 233, out
try:
    from fogsim.augment import FogV2
except MissingDependency as exc:
    print("MISSING", exc)
"""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "MISSING" in r.stdout and "torchvision" in r.stdout and "fogsim[augment]" in r.stdout, r.stdout
