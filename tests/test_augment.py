"""fogsim.augment: the NumPy reference against koschmieder, β sampling, the albumentations and
torch front ends against the reference (1 LSB), and the Ultralytics dataset that fogs on load."""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fogsim.augment import Draw, FogSpec, apply_fog, random_fog
from fogsim.augment.spec import parse_augment
from fogsim.camera import Intrinsics, planar_to_ray
from fogsim.fog.levels import visibility_from_beta
from fogsim.fog.model import Kernel, koschmieder, koschmieder_extended
from fogsim.fog.synthetic import demo_scene


def scene(seed=0, n=None, h=48, w=72):
    """Random RGB and ray distance (sky rows = inf, a hole row = 0), one sample or ``n``."""
    rng = np.random.default_rng(seed)
    shape = (h, w) if n is None else (n, h, w)
    img = rng.integers(0, 256, (*shape, 3), dtype=np.uint8)
    d = rng.uniform(0.5, 250.0, shape).astype(np.float32)
    d[..., :4, :] = np.inf
    d[..., -1, :] = 0.0
    return img, d


def test_reference_is_koschmieder_and_extended():
    img, d = scene()
    for beta in (0.0, 0.03, 0.12):
        draw = Draw(beta, (255.0, 255.0, 255.0))
        assert np.array_equal(apply_fog(img, d, draw), koschmieder(img, d, beta))
        spec = FogSpec(kernel=Kernel("box", 7), space="linear")
        assert np.array_equal(apply_fog(img, d, draw, spec), koschmieder_extended(img, d, beta, Kernel("box", 7),
                                                                                  space="linear"))
    fogged = apply_fog(img, d, Draw(0.1, (255.0,) * 3))
    assert (fogged[:4] == 255).all()  # sky: pure airlight
    assert np.array_equal(fogged[-1], img[-1])  # a hole (0 m): no fog


def test_planar_depth_with_intrinsics_or_fov():
    img, d = scene()
    d[d == 0] = 1.0
    K = Intrinsics.from_hfov(70.0, 72, 48)
    draw = Draw(0.05, (240.0,) * 3)
    want = koschmieder(img, planar_to_ray(d, K), 0.05, 240.0)
    assert np.array_equal(apply_fog(img, d, draw, FogSpec(depth="planar", hfov=70.0)), want)
    assert np.array_equal(apply_fog(img, d, draw, FogSpec(depth="planar", intrinsics=K)), want)
    big = Intrinsics.from_hfov(70.0, 144, 96)  # intrinsics of the full-size camera: scaled to the image
    assert np.abs(apply_fog(img, d, draw, FogSpec(depth="planar", intrinsics=big)).astype(int) - want).max() <= 1
    assert not np.array_equal(apply_fog(img, d, draw), want)  # ray ≠ planar off the axis


def test_sampling_range_list_visibility_seeded():
    img, d = scene()
    a, beta_a = random_fog(img, d, np.random.default_rng(7))
    b, beta_b = random_fog(img, d, np.random.default_rng(7))
    assert beta_a == beta_b and np.array_equal(a, b) and 0 <= beta_a <= 0.12
    assert np.array_equal(a, koschmieder(img, d, beta_a))
    rng = np.random.default_rng(0)
    betas = np.array([FogSpec(beta=(0.01, 0.12)).draw_beta(rng) for _ in range(4000)])
    assert betas.min() >= 0.01 and betas.max() <= 0.12 and abs(betas.mean() - 0.065) < 0.003
    vis = np.array([visibility_from_beta(FogSpec(beta=(0.01, 0.12), sample="visibility").draw_beta(rng))
                    for _ in range(4000)])
    lo, hi = visibility_from_beta(0.12), visibility_from_beta(0.01)
    assert vis.min() >= lo - 1e-9 and vis.max() <= hi + 1e-9 and abs(vis.mean() - (lo + hi) / 2) < 4.0
    picks = {FogSpec(beta=[0.0, 0.06, 0.12]).draw_beta(rng) for _ in range(200)}
    assert picks == {0.0, 0.06, 0.12}
    jit = {FogSpec(airlight=230, airlight_jitter=20).draw(rng).airlight for _ in range(50)}
    assert all(210 <= a[0] <= 250 and a[0] == a[1] == a[2] for a in jit) and len(jit) > 1
    het = FogSpec(heterogeneity=0.3).draw(rng, (48, 72)).density
    assert het.shape == (48, 72) and abs(float(het.mean()) - 1) < 1e-5


@pytest.mark.parametrize("kw, message", [({"beta": (0.1, 0.05)}, "low ≤ high"), ({"beta": (-1, 0.1)}, "≥ 0"),
                                         ({"sample": "visibility"}, "low > 0"), ({"depth": "planar"}, "hfov"),
                                         ({"airlight": 250, "airlight_jitter": 10}, "[0, 255]")])
def test_spec_refuses(kw, message):
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]")):
        FogSpec(**kw)


def test_parse_augment():
    assert parse_augment("continuous").beta == (0.0, 0.12)
    spec = parse_augment("continuous:0.01-0.2:visibility")
    assert spec.beta == (0.01, 0.2) and spec.sample == "visibility"
    for bad in ("discrete", "continuous:abc", "continuous:0.2-0.1"):
        with pytest.raises(ValueError):
            parse_augment(bad)


# ----------------------------------------------------------------------------- albumentations
def test_albumentations_compose_fogs_image_leaves_boxes_masks_depth():
    A = pytest.importorskip("albumentations")
    import fogsim.augment

    img, d = scene(3)
    mask = (np.arange(48 * 72).reshape(48, 72) % 5).astype(np.uint8)
    boxes = [[2.0, 3.0, 30.0, 40.0], [10.0, 12.0, 70.0, 47.0]]
    aug = A.Compose([fogsim.augment.Fog(beta=(0, 0.12))], additional_targets={"depth": "mask"},
                    bbox_params=A.BboxParams(format="pascal_voc", label_fields=["labels"]), seed=0)
    out = aug(image=img, depth=d, mask=mask, bboxes=boxes, labels=[1, 2])
    beta = aug.transforms[0].get_applied_params()["beta"]
    assert 0 < beta <= 0.12
    assert np.array_equal(out["image"], koschmieder(img, d, beta)) and not np.array_equal(out["image"], img)
    assert np.allclose(out["bboxes"], boxes, atol=1e-4) and list(out["labels"]) == [1, 2]
    assert np.array_equal(out["depth"], d) and np.array_equal(out["mask"], mask)
    again = A.Compose([fogsim.augment.Fog(beta=(0, 0.12))], additional_targets={"depth": "mask"}, seed=0)
    assert np.array_equal(again(image=img, depth=d)["image"], out["image"])  # Compose's seed: same draw
    # a geometric transform before Fog moves the depth with the image (it is a mask target)
    flip = A.Compose([A.HorizontalFlip(p=1), fogsim.augment.Fog(beta=[0.08])], additional_targets={"depth": "mask"})
    assert np.array_equal(flip(image=img, depth=d)["image"], koschmieder(img[:, ::-1], d[:, ::-1], 0.08))
    loose = A.Compose([fogsim.augment.Fog()], additional_targets={"depth": "mask"}, is_check_shapes=False)
    with pytest.raises(ValueError, match=r"depth must be H×W \(or H×W×1\) = 48×72 like the image, got shape \(10, "):
        loose(image=img, depth=d[:10])


def test_fog_without_albumentations_names_the_extra():
    code = ("import sys; sys.modules['albumentations'] = None\n"
            "import fogsim.augment\n"
            "from fogsim.errors import MissingDependency\n"
            "try:\n    fogsim.augment.Fog\nexcept MissingDependency as e:\n    print(e)\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0 and "fogsim[augment]" in r.stdout, r.stderr


# ----------------------------------------------------------------------------- torch
def devices():
    torch = pytest.importorskip("torch")
    return ["cpu", *(["cuda"] if torch.cuda.is_available() else [])]


@pytest.mark.torch
@pytest.mark.parametrize("spec", [FogSpec(), FogSpec(space="linear"), FogSpec(kernel=Kernel("box", 7)),
                                  FogSpec(depth="planar", hfov=60.0), FogSpec(airlight=200, airlight_jitter=40)],
                         ids=["srgb", "linear", "box7", "planar", "jitter"])
def test_torch_batch_equals_numpy_to_1_lsb(spec):
    torch = pytest.importorskip("torch")
    from fogsim.augment import draw_batch, fog_batch

    img, d = scene(5, n=6)
    rng = np.random.default_rng(1)
    beta, air = draw_batch(6, rng, spec)
    beta[0] = 0.0
    ref = np.stack([apply_fog(img[i], d[i], Draw(beta[i], tuple(air[i])), spec) for i in range(6)])
    ref_f = np.stack([apply_fog(img[i] / np.float32(255), d[i], Draw(beta[i], tuple(air[i])), spec)
                      for i in range(6)])
    for device in devices():
        x = torch.from_numpy(img).permute(0, 3, 1, 2).to(device)
        z = torch.from_numpy(d)[:, None].to(device)
        out = fog_batch(x, z, torch.tensor(beta), torch.tensor(air), spec)
        assert out.dtype == torch.uint8 and out.device.type == device
        diff = np.abs(out.permute(0, 2, 3, 1).cpu().numpy().astype(int) - ref)
        assert diff.max() <= 1, (device, diff.max())
        assert np.array_equal(out[0].permute(1, 2, 0).cpu().numpy(), img[0])  # β = 0: the image itself
        out_f = fog_batch(x.float() / 255, z, beta, air, spec)
        assert np.abs(out_f.permute(0, 2, 3, 1).cpu().numpy() - ref_f).max() < 1 / 255


@pytest.mark.torch
def test_torch_refuses_what_it_does_not_do():
    torch = pytest.importorskip("torch")
    from fogsim.augment import fog_batch

    x, z = torch.zeros(2, 3, 8, 8, dtype=torch.uint8), torch.ones(2, 1, 8, 8)
    with pytest.raises(ValueError, match="box kernel"):
        fog_batch(x, z, 0.1, spec=FogSpec(kernel=Kernel("gaussian", 5)))
    with pytest.raises(ValueError, match="B×1×H×W"):
        fog_batch(x, z[:, :, :4], 0.1)
    with pytest.raises(ValueError, match="NaN or negative"):
        fog_batch(x, -z, 0.1)
    with pytest.raises(ValueError, match="Koschmieder's law only"):
        fog_batch(x, z, 0.1, spec=FogSpec(model="scatter"))


@pytest.mark.torch
def test_torchvision_v2_transform_moves_depth_with_the_image():
    torch = pytest.importorskip("torch")
    pytest.importorskip("torchvision")
    from torchvision import tv_tensors
    from torchvision.transforms import v2

    from fogsim.augment import FogV2

    img, d = scene(9)
    image = tv_tensors.Image(torch.from_numpy(img).permute(2, 0, 1))
    depth = tv_tensors.Mask(torch.from_numpy(d)[None])
    boxes = tv_tensors.BoundingBoxes([[2, 3, 30, 40]], format="XYXY", canvas_size=(48, 72))
    fog = FogV2(beta=(0, 0.12), seed=0)
    out_img, out_depth, out_boxes = v2.Compose([v2.RandomHorizontalFlip(p=1.0), fog])(image, depth, boxes)
    assert isinstance(out_img, tv_tensors.Image) and 0 <= fog.last_beta <= 0.12
    want = koschmieder(np.ascontiguousarray(img[:, ::-1]), np.ascontiguousarray(d[:, ::-1]), fog.last_beta)
    assert np.abs(out_img.permute(1, 2, 0).numpy().astype(int) - want).max() <= 1
    assert torch.equal(out_depth, depth.flip(-1)) and out_boxes.tolist() == [[42, 3, 70, 40]]
    with pytest.raises(ValueError, match="floating-point"):
        fog(image, tv_tensors.Mask(torch.zeros(1, 48, 72, dtype=torch.uint8)))
    a, b = FogV2(seed=3), FogV2(seed=3)
    assert torch.equal(a(image, depth)[0], b(image, depth)[0]) and a.last_beta == b.last_beta
    assert not math.isnan(a.last_beta)


# ----------------------------------------------------------------------------- Ultralytics
@pytest.fixture(scope="module")
def depth_dataset(tmp_path_factory):
    from synthetic_dataset import make_dataset
    return make_dataset(tmp_path_factory.mktemp("synthetic") / "ds", frames=12, train_fraction=0.5, depth=True)


@pytest.mark.detect
def test_foggy_dataset_fogs_each_load_from_the_frame_depth(depth_dataset, tmp_path):
    from study_driver import LEVELS, need_detect_extra
    need_detect_extra()
    import cv2

    from fogsim.dataset.reader import read_distance, read_split
    from fogsim.detection.augmented import foggy_dataset
    from fogsim.detection.yolo import AUGMENTED_MODEL, load_ultralytics, training_view

    load_ultralytics(tmp_path / "config")
    data = training_view(depth_dataset, tmp_path / "view", LEVELS, augmented="clear")
    lines = (data[AUGMENTED_MODEL].parent / "train.txt").read_text().split()
    n = len(read_split(depth_dataset, "clear", "train"))
    assert len(lines) == 5 * n and all("/train/clear/images/" in line for line in lines)  # mixed's images per epoch
    spec = FogSpec(beta=(0.05, 0.12))
    ds = foggy_dataset(depth_dataset, spec, seed=4)(
        img_path=str(data[AUGMENTED_MODEL].parent / "train.txt"), imgsz=64, augment=False,
        data={"names": {i: str(i) for i in range(8)}, "channels": 3})
    assert len(ds) == 5 * n
    clear = ds.load_image(0)[0]
    fogged = ds.get_image_and_label(0)["img"]
    d = read_distance(depth_dataset, Path(ds.im_files[0]).stem)
    d = cv2.resize(d, (clear.shape[1], clear.shape[0]), interpolation=cv2.INTER_NEAREST)
    draw = spec.draw(np.random.default_rng([4, 0, 1]), clear.shape[:2])
    assert draw.beta == ds.last_beta[0] and np.array_equal(fogged, apply_fog(clear, d, draw, spec))
    assert not np.array_equal(fogged, clear)
    assert ds.get_image_and_label(0)["img"].tolist() != fogged.tolist()  # a new β on the next load
    assert np.array_equal(ds.load_image(0)[0], clear)  # the clear image (and its cache) untouched


@pytest.mark.detect
@pytest.mark.slow
def test_study_augment_gives_the_augmented_row(depth_dataset, tmp_path):
    import json

    from study_driver import LEVELS, TINY, driver, need_detect_extra
    need_detect_extra()
    out = tmp_path / "study"
    r = driver("--out", out, "--dataset", depth_dataset, "--augment", "continuous:0-0.12", *TINY)
    assert r.returncode == 0, r.stderr[-3000:]
    table = json.loads((out / "report" / "cross_density.json").read_text())
    assert set(table["augmented"]) == set(LEVELS)
    report = (out / "report" / "report.md").read_text()
    assert "**augmented (β beta-uniform in 0–0.12 1/m) vs mixed vs specialists**" in report
    assert "Levels won by mAP@50: oracle" in report
    done = json.loads((out / "runs" / "augmented" / "fogsim_done.json").read_text())
    assert done["data"].endswith("augmented/data.yaml")
    assert json.loads((out / "study.json").read_text())["parameters"]["augment"] == {"beta": [0.0, 0.12],
                                                                                    "sample": "beta"}
    # a dataset without depth (fogged real data) is refused for --augment, naming the frame's depth file
    from synthetic_dataset import make_dataset
    bare = make_dataset(tmp_path / "bare", frames=4, train_fraction=0.5)
    r = driver("--out", tmp_path / "s2", "--dataset", bare, "--augment", "continuous", *TINY, "--shard", "6/7")
    assert r.returncode == 2 and "no depth for this frame" in r.stderr, r.stderr[-2000:]


@pytest.mark.detect
@pytest.mark.slow
def test_bench_augment_times_an_ultralytics_sample_with_and_without_fog(monkeypatch):
    pytest.importorskip("ultralytics", reason="the detect extra is not installed")
    import fogsim.bench.augment as bench

    monkeypatch.setattr(bench, "ULTRALYTICS_FRAMES", 2)
    ms = bench.ultralytics_ms(1)  # its frames must pass the frame-record schema the reader checks
    assert set(ms) == {"plain", "foggy", "depth read"} and all(v > 0 for v in ms.values())


def test_scatter_model_is_the_scatter_function_and_refused_where_unsupported():
    from fogsim.fog.scatter import scatter

    rgb, depth, K = demo_scene(np.random.default_rng(3), 96, 64)
    ray = planar_to_ray(depth, K)
    spec = FogSpec(beta=0.06, model="scatter", intrinsics=K)
    draw = spec.draw(np.random.default_rng(0), rgb.shape[:2])
    out = apply_fog(rgb, ray, draw, spec)
    assert np.array_equal(out, scatter(rgb, ray, 0.06, draw.airlight, spec.space, intrinsics=K))
    assert not np.array_equal(out, apply_fog(rgb, ray, draw, FogSpec(beta=0.06)))  # not Koschmieder
    assert np.array_equal(apply_fog(rgb, ray, FogSpec(beta=0.0).draw(np.random.default_rng(0)),
                                    FogSpec(beta=0.0, model="scatter")), rgb)
    with pytest.raises(ValueError, match="model must be one of"):
        FogSpec(model="mie")
    with pytest.raises(ValueError, match="no extended kernel or heterogeneity"):
        FogSpec(model="scatter", heterogeneity=0.3)
