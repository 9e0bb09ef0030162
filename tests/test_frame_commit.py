"""``fogsim.render.frame.commit_frame`` without Blender: fabricated render passes for a real scene
description, every written file checked against computations made here by hand."""
import json

import numpy as np
import OpenEXR
import pytest

import fogsim.render.frame as frame_mod
from conftest import expected_yolo_lines
from fogsim.camera import Intrinsics, decode_disparity_png
from fogsim.dataset.layout import DatasetLayout
from fogsim.io.depth_files import read_depth_file, read_uint16_map
from fogsim.io.images import read_image
from fogsim.render.frame import DescribedFrame, FramePasses, commit_frame, describe_frame, frame_name, scene_meshes
from fogsim.render.preset import load_render_preset
from fogsim.render.silhouette import silhouette_areas
from fogsim.scene.classes import CLASS_ID, LABELLED

W, H = 96, 64
SKY_ROWS = 8


@pytest.fixture(scope="module")
def scene():
    config = load_render_preset("default", frames=1, resolution=f"{W}x{H}")
    desc = describe_frame(config, 0)
    meshes = scene_meshes(desc)
    K = Intrinsics.from_dict(desc["camera"]["intrinsics"])
    labelled = {o["id"]: [(v, f) for v, f, _ in meshes[o["id"]]] for o in desc["objects"] if o["class"] in LABELLED}
    sil = silhouette_areas(labelled, K, np.asarray(desc["camera"]["world_to_camera"]))
    return config, desc, meshes, K, sil


def hand_ray(depth: np.ndarray, K: Intrinsics) -> np.ndarray:
    """Planar Z → ray distance, float64: Z·sqrt(1 + ((u − cx)/fx)² + ((v − cy)/fy)²), pixel centres at integers."""
    v, u = np.mgrid[0:depth.shape[0], 0:depth.shape[1]].astype(np.float64)
    return depth.astype(np.float64) * np.sqrt(1 + ((u - K.cx) / K.fx) ** 2 + ((v - K.cy) / K.fy) ** 2)


def hand_transmission(beta: float, ray: np.ndarray) -> np.ndarray:
    """exp(−β·ℓ), H×W×1; β = 0 is clear air everywhere (also at ℓ = inf)."""
    return (np.exp(-beta * ray) if beta > 0 else np.ones_like(ray))[..., None]


def hand_srgb8(linear: np.ndarray, exposure: float) -> np.ndarray:
    x = np.clip(linear.astype(np.float64) * exposure, 0, 1)
    s = np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)
    return np.floor(s * 255 + 0.5)


def pick_objects(desc, sil):
    """Labelled objects to paint: two that stay labels, one too occluded, one too small;
    and a building (not labelled)."""
    labelled = [o for o in desc["objects"] if o["class"] in LABELLED]
    by_area = sorted(labelled, key=lambda o: -sil[o["id"]]["pixels_in_image"])
    occluded = by_area[0]  # 30 painted pixels of a large silhouette: under 10 % visible
    assert sil[occluded["id"]]["pixels_in_image"] > 300, "the scene has no large object any more"
    kept = [o for o in by_area if 25 <= sil[o["id"]]["pixels_in_image"] <= 160][:2]  # fully painted
    assert len(kept) == 2, "the scene has no two mid-sized objects any more"
    small = next(o for o in labelled if o not in kept and o is not occluded)
    building = next(o for o in desc["objects"] if o["class"] == "building")
    return kept, occluded, small, building


def passes(desc, sil, K, seed=3):
    """rgb_linear (values above 1 too), planar depth (sky rows inf), and an instance mask painting
    rectangles: kept[0] [2,18)×[40,50), kept[1] on the right border [80,96)×[30,40), the occluded
    object [30,35)×[12,18), the small one [50,53)×[50,53), a building [40,60)×[0,8)."""
    rng = np.random.default_rng(seed)
    kept, occluded, small, building = pick_objects(desc, sil)
    rgb = rng.uniform(0, 1.3, (H, W, 3)).astype(np.float32)
    depth = rng.uniform(3, 150, (H, W)).astype(np.float32)
    depth[:SKY_ROWS] = np.inf
    mask = np.zeros((H, W), np.uint16)
    rects = {kept[0]["id"]: (2, 40, 18, 50), kept[1]["id"]: (80, 30, 96, 40), occluded["id"]: (30, 12, 35, 18),
             small["id"]: (50, 50, 53, 53), building["id"]: (40, 0, 60, 8)}
    for i, (oid, (x0, y0, x1, y1)) in enumerate(rects.items()):
        mask[y0:y1, x0:x1] = oid
        if oid != building["id"]:
            depth[y0:y1, x0:x1] = 10.0 + 5 * i  # a flat object facing the camera
    return rgb, depth, mask, rects, (kept, occluded, small, building)


def test_commit_frame_writes_every_file_as_computed_by_hand(scene, tmp_path, monkeypatch):
    config, desc, meshes, K, sil = scene
    rgb, depth, mask, rects, (kept, occluded, small, building) = passes(desc, sil, K)
    layout = DatasetLayout(tmp_path / "ds")
    name = frame_name(0)
    levels = [lv.key for lv in config.levels]
    others = ([layout.image(lv, name) for lv in levels] + [layout.label(lv, name) for lv in levels]
              + [layout.depth(name), layout.mask(name)])

    calls = []
    real_write_json = frame_mod.write_json

    def watched_write_json(path, obj):
        if path == layout.meta(name):  # the meta comes last: every other file is complete by then
            calls.append(("meta", [p.is_file() for p in others]))
        real_write_json(path, obj)

    monkeypatch.setattr(frame_mod, "write_json", watched_write_json)
    for fn in ("write_image", "write_depth", "write_frame_labels"):
        real = getattr(frame_mod, fn)
        monkeypatch.setattr(frame_mod, fn, lambda *a, _real=real, _fn=fn, **kw: (calls.append((_fn, None)),
                                                                                   _real(*a, **kw))[1])
    meta = commit_frame(layout, config, DescribedFrame(0, desc, meshes), FramePasses(rgb, depth, mask),
                        timings={"render": 1.5}, render_info={"engine": "fake"})

    # meta/<frame>.json: written last, so its presence marks the frame done
    assert calls[-1] == ("meta", [True] * len(others)) and sum(c[0] == "meta" for c in calls) == 1
    assert layout.frame_done(name) and layout.done_frames() == [name]
    stored = json.loads(layout.meta(name).read_text())
    assert stored == json.loads(json.dumps(meta))
    assert (stored["frame"], stored["index"], stored["width"], stored["height"]) == (name, 0, W, H)
    assert stored["scene"] == json.loads(json.dumps(desc)) and stored["render"] == {"engine": "fake"}
    assert stored["timings_s"]["render"] == 1.5 and {"ground_truth", "fog", "write"} <= set(stored["timings_s"])
    assert [lv["beta"] for lv in stored["fog"]["levels"]] == [lv.beta for lv in config.levels]
    assert stored["depth"]["file"] == f"depth/{name}.exr" and stored["stereo"] is None

    # object records: the painted labelled objects only, filters applied, in scene order
    records = {r["id"]: r for r in stored["objects"]}
    assert set(records) == {kept[0]["id"], kept[1]["id"], occluded["id"], small["id"]}  # no building
    assert [r["id"] for r in stored["objects"]] == [o["id"] for o in desc["objects"] if o["id"] in records]
    ray = hand_ray(depth, K)
    for oid, (x0, y0, x1, y1) in rects.items():
        if oid not in records:
            continue
        r, n = records[oid], (x1 - x0) * (y1 - y0)
        assert r["bbox"] == [x0, y0, x1, y1] and r["pixels"] == n
        assert r["class_id"] == CLASS_ID[r["class"]]
        assert r["distance_m"] == pytest.approx(np.median(ray[y0:y1, x0:x1]), abs=1e-3)
        assert r["visible_fraction"] == pytest.approx(min(1.0, n / sil[oid]["pixels_in_image"]), abs=1e-4)
        assert r["truncated"] == (x1 == W)
    assert [records[o["id"]]["kept"] for o in kept] == [True, True]
    assert (records[occluded["id"]]["kept"], records[occluded["id"]]["reason"]) == (False, "too occluded")
    assert (records[small["id"]]["kept"], records[small["id"]]["reason"]) == (False, "too few pixels")

    # YOLO labels, identical at every level: the kept rectangles, normalised pixel-edge boxes
    by_hand = []
    for o in desc["objects"]:
        if o in kept:
            x0, y0, x1, y1 = rects[o["id"]]
            by_hand.append(f"{CLASS_ID[o['class']]} {(x0 + x1) / 2 / W:.6f} {(y0 + y1) / 2 / H:.6f} "
                           f"{(x1 - x0) / W:.6f} {(y1 - y0) / H:.6f}")
    assert len(by_hand) == 2
    visible = {oid: min(1.0, int((mask == oid).sum()) / max(sil[oid]["pixels_in_image"], 1)) for oid in records}
    assert expected_yolo_lines(mask, desc["objects"], visible, 25, 0.1) == by_hand
    for lv in levels:
        assert layout.label(lv, name).read_text() == "".join(line + "\n" for line in by_hand)

    # depth EXR and mask PNG round-trip exactly (also through the OpenEXR library)
    assert np.array_equal(read_depth_file(layout.depth(name)), depth)
    with OpenEXR.File(str(layout.depth(name))) as exr:
        assert np.array_equal(exr.channels()["Y"].pixels, depth)
    got_mask = read_uint16_map(layout.mask(name))
    assert got_mask.dtype == np.uint16 and np.array_equal(got_mask, mask)

    # images: sRGB of the linear render, then Koschmieder on the ray distance at each level
    clear = read_image(layout.image("clear", name))
    srgb = hand_srgb8(rgb, config.exposure)
    assert clear.dtype == np.uint8 and clear.shape == (H, W, 3)
    assert np.abs(clear - srgb).max() <= 1 and np.mean(clear == srgb) > 0.999
    for lv in config.levels:
        got = read_image(layout.image(lv.key, name))
        t = hand_transmission(lv.beta, ray)
        for base, tol in ((clear, 0.5 + 1e-3), (srgb, 1.0 + 1e-3)):
            ref = base * t + 255.0 * (1 - t)
            assert np.abs(got - ref).max() <= tol, lv.key
        if lv.beta > 0:
            assert (got[:SKY_ROWS] == 255).all()  # sky: airlight
            assert got.astype(int).sum() > clear.astype(int).sum()


def test_commit_frame_without_objects_writes_empty_labels(scene, tmp_path):
    config, desc, meshes, K, sil = scene
    layout = DatasetLayout(tmp_path / "ds")
    rgb = np.full((H, W, 3), 0.2, np.float32)
    depth = np.full((H, W), 20.0, np.float32)
    meta = commit_frame(layout, config, DescribedFrame(3, desc, meshes),
                        FramePasses(rgb, depth, np.zeros((H, W), np.uint16)))
    assert meta["objects"] == [] and meta["frame"] == "000003" and layout.done_frames() == ["000003"]
    for lv in config.levels:
        assert layout.label(lv.key, "000003").read_text() == ""  # background image
        img = read_image(layout.image(lv.key, "000003"))
        t = hand_transmission(lv.beta, hand_ray(depth, K))
        assert np.abs(img - (hand_srgb8(rgb, 1.0) * t + 255 * (1 - t))).max() <= 1 + 1e-3


def test_commit_frame_stereo_pair_in_cityscapes_layout(scene, tmp_path):
    """A right view that is the left one moved 4 px: SGBM finds disparity 4 and the pair, disparity
    and camera land in Cityscapes' tree under the frame's split."""
    _, desc, meshes, K, sil = scene
    config = load_render_preset("default", frames=1, resolution=f"{W}x{H}", stereo=True)
    rng = np.random.default_rng(0)
    wide = rng.uniform(0, 1, (H, W + 4, 3)).astype(np.float32)
    left, right = wide[:, :W], wide[:, 4:]  # right(x) = left(x + 4): disparity 4 px
    depth = np.full((H, W), 30.0, np.float32)
    layout = DatasetLayout(tmp_path / "ds")
    meta = commit_frame(layout, config, DescribedFrame(0, desc, meshes),
                        FramePasses(left, depth, np.zeros((H, W), np.uint16), right_linear=right))
    st = meta["stereo"]
    assert st["baseline_m"] == config.stereo_baseline and st["split"] in ("train", "val")
    disp = decode_disparity_png(read_uint16_map(layout.cityscapes("disparity", "000000", st["split"])))
    valid = disp > 0
    assert st["hole_fraction"] == pytest.approx(1 - valid.mean(), abs=1e-6)
    assert valid.mean() > 0.5 and np.median(np.abs(disp[valid] - 4.0)) < 0.25
    assert np.array_equal(read_image(layout.cityscapes("leftImg8bit", "000000", st["split"])),
                          read_image(layout.image("clear", "000000")))
    assert np.abs(read_image(layout.cityscapes("rightImg8bit", "000000", st["split"])).astype(int)
                  - hand_srgb8(right, 1.0)).max() <= 1
    cam = json.loads(layout.cityscapes("camera", "000000", st["split"]).read_text())
    assert cam["extrinsic"]["baseline"] == pytest.approx(config.stereo_baseline)
    assert cam["intrinsic"]["fx"] == pytest.approx(K.fx) and cam["intrinsic"]["u0"] == pytest.approx(K.cx)
