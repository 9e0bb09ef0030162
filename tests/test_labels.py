"""Labels from instance masks, unoccluded silhouettes, and the YOLO/COCO dataset files."""
import json
import math

import numpy as np
import pytest
import trimesh

from fogsim.boxes import boxes_from_mask, median_distance, parse_yolo_line, yolo_line
from fogsim.camera import Intrinsics
from fogsim.dataset.coco import coco_annotation, coco_categories
from fogsim.dataset.layout import DatasetLayout
from fogsim.dataset.writer import contact_sheet, finalize, split_frames, write_frame_labels
from fogsim.fog.levels import FogLevel
from fogsim.io.documents import write_json
from fogsim.io.images import read_image, write_image
from fogsim.render.labels import object_records
from fogsim.render.silhouette import NEAR, clip_near, covered_pixels, project_points, silhouette_areas
from fogsim.rle import box_rle
from fogsim.scene.classes import CLASS_ID, LABELLED


def demo_mask():
    """96×64: two rectangles, an L-shape, a single pixel and a box touching the right border."""
    m = np.zeros((64, 96), np.uint16)
    m[5:15, 10:30] = 1           # 20×10 rectangle
    m[20:24, 40:43] = 2          # 3×4 rectangle
    m[30:50, 5:8] = 3            # L-shape: vertical bar ...
    m[47:50, 8:20] = 3           # ... and foot
    m[40, 60] = 4                # single pixel
    m[50:64, 80:96] = 5          # touches the right and bottom borders
    return m


def test_boxes_exact():
    boxes = boxes_from_mask(demo_mask())
    assert boxes == {
        1: {"bbox": [10, 5, 30, 15], "pixels": 200},
        2: {"bbox": [40, 20, 43, 24], "pixels": 12},
        3: {"bbox": [5, 30, 20, 50], "pixels": 20 * 3 + 3 * 12},
        4: {"bbox": [60, 40, 61, 41], "pixels": 1},
        5: {"bbox": [80, 50, 96, 64], "pixels": 14 * 16},
    }
    assert boxes_from_mask(np.zeros((8, 8), np.uint16)) == {}


def test_boxes_match_brute_force_on_random_mask():
    rng = np.random.default_rng(3)
    mask = rng.integers(0, 40, (50, 70)).astype(np.uint16)
    mask[rng.random(mask.shape) < 0.5] = 0
    boxes = boxes_from_mask(mask)
    assert set(boxes) == set(np.unique(mask)) - {0}
    for i, b in boxes.items():
        ys, xs = np.nonzero(mask == i)
        assert b == {"bbox": [xs.min(), ys.min(), xs.max() + 1, ys.max() + 1], "pixels": xs.size}


def test_median_distance_ignores_inf():
    mask = demo_mask()
    ray = np.full(mask.shape, 50.0, np.float32)
    ray[5:15, 10:20] = 10.0
    ray[5:15, 20:21] = 12.0
    ray[5:15, 21:30] = np.inf                # no hit: ignored
    ray[40, 60] = np.inf                     # object 4 has no finite pixel
    d = median_distance(mask, ray, [1, 2, 4, 99])
    assert d[1] == pytest.approx(np.median([10.0] * 100 + [12.0] * 10))
    assert d[2] == 50.0
    assert math.isnan(d[4]) and math.isnan(d[99])


@pytest.mark.parametrize("width,height", [(96, 64), (1920, 1280)])
def test_yolo_round_trip_exact(width, height):
    rng = np.random.default_rng(width)
    for _ in range(2000):
        x0, x1 = sorted(rng.choice(width + 1, 2, replace=False))
        y0, y1 = sorted(rng.choice(height + 1, 2, replace=False))
        cls = int(rng.integers(len(LABELLED)))
        line = yolo_line({"class_id": cls, "bbox": [x0, y0, x1, y1]}, width, height)
        assert parse_yolo_line(line, width, height) == (cls, [x0, y0, x1, y1])
    assert yolo_line({"class_id": 2, "bbox": [5, 0, 6, 64]}, 96, 64) == "2 0.057292 0.500000 0.010417 1.000000"


def records_for(mask, silhouettes, **kw):
    objects = [{"id": 1, "class": "car"}, {"id": 2, "class": "pedestrian"}, {"id": 3, "class": "building"},
               {"id": 4, "class": "traffic_sign"}, {"id": 5, "class": "bus"}, {"id": 6, "class": "truck"}]
    ray = np.full(mask.shape, 20.0, np.float32)
    return {r["id"]: r for r in object_records(mask, ray, objects, silhouettes, **kw)}


def full_silhouettes(mask):
    return {i: {"pixels_in_image": b["pixels"], "pixels_total": b["pixels"]}
            for i, b in boxes_from_mask(mask).items()}


def test_object_records_fields_and_filters():
    mask = demo_mask()
    sil = full_silhouettes(mask)
    sil[1] = {"pixels_in_image": 800, "pixels_total": 1000}      # occluded and truncated silhouette
    sil[5] = {"pixels_in_image": 224, "pixels_total": 448}       # half outside the image
    recs = records_for(mask, sil, min_pixels=10, min_visible_fraction=0.3)
    assert set(recs) == {1, 2, 4, 5}        # 3 is a building (stuff), 6 is not visible
    car = recs[1]
    assert car["class_id"] == CLASS_ID["car"] and car["bbox"] == [10, 5, 30, 15] and car["pixels"] == 200
    assert car["visible_fraction"] == 0.25 and car["truncation"] == pytest.approx(0.2)
    assert car["distance_m"] == 20.0 and car["distance_stat"] == "median ray distance over visible pixels"
    assert (car["kept"], car["reason"], car["truncated"]) == (False, "too occluded", False)
    assert (recs[2]["kept"], recs[2]["reason"]) == (True, None)
    assert (recs[4]["kept"], recs[4]["reason"]) == (False, "too few pixels")
    bus = recs[5]
    assert bus["truncated"] and bus["kept"] and bus["truncation"] == 0.5 and bus["visible_fraction"] == 1.0
    json.dumps(list(recs.values()))         # JSON-serialisable as written to meta


def test_visible_fraction_clipped_and_missing_silhouette():
    mask = demo_mask()
    sil = full_silhouettes(mask)
    sil[2] = {"pixels_in_image": 6, "pixels_total": 6}          # rasteriser saw less than the render
    sil[4] = {"pixels_in_image": 0, "pixels_total": 0}          # sub-pixel object
    recs = records_for(mask, sil, min_pixels=1)
    assert recs[2]["visible_fraction"] == 1.0 and recs[4]["visible_fraction"] == 1.0
    del sil[2]
    with pytest.raises(ValueError, match="no silhouette"):
        records_for(mask, sil)


# ----------------------------------------------------------------------------- silhouettes
K = Intrinsics(fx=200.0, fy=200.0, cx=159.5, cy=119.5, width=320, height=240)
IDENTITY = np.eye(4)  # world = OpenCV camera frame


def test_project_points():
    uv, z = project_points(np.array([[0.0, 0.0, 5.0], [1.0, -0.5, 2.0]]), K, IDENTITY)
    np.testing.assert_allclose(uv, [[159.5, 119.5], [259.5, 69.5]])
    np.testing.assert_allclose(z, [5.0, 2.0])
    w2c = np.eye(4)
    w2c[:3, 3] = [0.0, 0.0, 3.0]            # camera 3 m behind the world origin
    _, z = project_points(np.zeros((1, 3)), K, w2c)
    assert z[0] == 3.0


def centre_count(lo, hi):
    """Integer pixel centres in [lo, hi]."""
    return max(0, math.floor(hi) - math.ceil(lo) + 1)


def test_silhouette_of_box_matches_projected_rectangle():
    box = trimesh.creation.box(extents=(6.0, 4.0, 2.0))
    box.apply_translation((0.1, -0.05, 10.0))        # front face at z = 9, centred near the axis
    u0, u1 = (np.array([-2.9, 3.1]) * K.fx / 9.0) + K.cx
    v0, v1 = (np.array([-2.05, 1.95]) * K.fy / 9.0) + K.cy
    area = silhouette_areas({7: [box]}, K, IDENTITY)[7]
    assert area["pixels_in_image"] == area["pixels_total"]
    assert area["pixels_total"] == centre_count(u0, u1) * centre_count(v0, v1)
    assert area["pixels_total"] == pytest.approx((u1 - u0) * (v1 - v0), rel=0.02)
    # (vertices, faces) tuples work the same, and several parts make one silhouette
    halves = [(box.vertices, box.faces[:6]), (box.vertices, box.faces[6:])]
    assert silhouette_areas({7: halves}, K, IDENTITY)[7] == area


def test_silhouette_half_outside_image():
    z = 10.0
    box = trimesh.creation.box(extents=(6.0, 4.0, 0.01))
    box.apply_translation(((-0.5 - K.cx) * z / K.fx, 0.0, z))   # centred on the left image edge
    area = silhouette_areas({1: [box]}, K, IDENTITY)[1]
    assert area["pixels_total"] == pytest.approx(2 * area["pixels_in_image"], rel=0.02)
    behind = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    behind.apply_translation((0.0, 0.0, -5.0))
    assert silhouette_areas({2: [behind]}, K, IDENTITY)[2] == {"pixels_in_image": 0, "pixels_total": 0}


def test_occluded_object_has_lower_visible_fraction():
    box = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    box.apply_translation((0.0, 0.0, 10.0))
    sil = silhouette_areas({1: [box]}, K, IDENTITY)
    uv, _ = project_points(box.vertices, K, IDENTITY)
    mask = np.zeros((K.height, K.width), np.uint16)
    x0, y0 = np.ceil(uv.min(axis=0)).astype(int)
    x1, y1 = np.floor(uv.max(axis=0)).astype(int) + 1
    mask[y0:y1, x0:x1] = 1
    full = object_records(mask, np.ones(mask.shape, np.float32), [{"id": 1, "class": "car"}], sil)[0]
    assert full["visible_fraction"] == 1.0
    mask[y0:y1, x0:(x0 + x1) // 2] = 0                  # left half hidden by something in front
    half = object_records(mask, np.ones(mask.shape, np.float32), [{"id": 1, "class": "car"}], sil)[0]
    assert half["visible_fraction"] == pytest.approx(0.5, abs=0.03)


def tri_area(t):
    return 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).sum()


def test_near_plane_clipping():
    one_behind = np.array([[[0.0, 0.0, -1.0], [1.0, 0.0, 1.0], [-1.0, 0.0, 1.0]]])
    two_behind = np.array([[[0.0, 0.0, 1.0], [1.0, 0.0, -1.0], [-1.0, 0.0, -1.0]]])
    for tris, expected in ((one_behind, (4 - (1 + NEAR) ** 2) / 2), (two_behind, (1 - NEAR) ** 2 / 2)):
        clipped = clip_near(tris)
        assert (clipped[:, :, 2] >= NEAR - 1e-12).all()
        assert tri_area(clipped) == pytest.approx(expected)
    assert clip_near(-one_behind - 2).shape == (0, 3, 3)  # wholly behind


def test_rasteriser_matches_pixel_centre_brute_force():
    rng = np.random.default_rng(11)
    ys, xs = np.mgrid[-20:40, -25:50]
    for k in range(10):
        tris = rng.uniform(-40, 60, (int(rng.integers(1, 20)), 3, 2))
        tris = np.round(tris) if k % 2 else tris       # integer vertices put centres on edges
        inside = np.zeros(xs.shape, bool)
        for a, b, c in tris:
            s = [(q[0] - p[0]) * (ys - p[1]) - (q[1] - p[1]) * (xs - p[0]) for p, q in ((a, b), (b, c), (c, a))]
            inside |= ((s[0] >= 0) & (s[1] >= 0) & (s[2] >= 0)) | ((s[0] <= 0) & (s[1] <= 0) & (s[2] <= 0))
        assert covered_pixels(tris, (-25, -20, 50, 40)) == inside.sum()


# ----------------------------------------------------------------------------- dataset files
LEVELS = [FogLevel("clear", "clear", 0.0), FogLevel("beta0.06", "β=0.06/m", 0.06)]


@pytest.fixture
def tiny_dataset(tmp_path):
    """Two committed frames (96×64) at two levels, written the way commit_frame writes them."""
    layout = DatasetLayout(tmp_path / "out")
    rng = np.random.default_rng(0)
    mask = demo_mask()
    objects = [{"id": i, "class": c} for i, c in ((1, "car"), (2, "pedestrian"), (3, "cyclist"),
                                                  (4, "traffic_sign"), (5, "bus"))]
    for frame, drop in (("000000", ()), ("000001", (1, 5))):
        m = mask.copy()
        m[np.isin(m, drop)] = 0
        recs = object_records(m, np.full(m.shape, 30.0, np.float32), objects, full_silhouettes(mask),
                              min_pixels=10)
        for lv in LEVELS:
            write_image(layout.image(lv.key, frame), rng.integers(0, 256, (64, 96, 3), dtype=np.uint8))
        write_frame_labels(layout, frame, LEVELS, recs, 96, 64)
        write_json(layout.meta(frame), {"frame": frame, "width": 96, "height": 64, "objects": recs})
    return layout


def read_yaml(path):
    """The subset of YAML the writer emits: ``key: "json string"`` and an indented ``names`` map."""
    out, names = {}, {}
    for line in path.read_text().splitlines():
        if line.startswith("#") or line == "names:":
            continue
        key, value = line.split(": ", 1)
        (names if line.startswith("  ") else out)[key.strip()] = json.loads(value)
    return out | {"names": names}


def test_layout_paths_and_labels(tiny_dataset):
    layout = tiny_dataset
    assert layout.done_frames() == ["000000", "000001"] and layout.frame_done("000001")
    (layout.root / "meta" / ".000002.json.abc.part").write_text("{")
    assert layout.done_frames() == ["000000", "000001"] and not layout.frame_done("000002")
    lines = layout.label("clear", "000000").read_text().splitlines()
    assert lines == layout.label("beta0.06", "000000").read_text().splitlines()
    assert sorted(parse_yolo_line(x, 96, 64) for x in lines) == sorted(
        [(CLASS_ID["car"], [10, 5, 30, 15]), (CLASS_ID["pedestrian"], [40, 20, 43, 24]),
         (CLASS_ID["cyclist"], [5, 30, 20, 50]), (CLASS_ID["bus"], [80, 50, 96, 64])])
    write_frame_labels(layout, "empty", LEVELS, [], 96, 64)
    assert layout.label("clear", "empty").read_text() == ""


def test_finalize_writes_coco_yaml_splits_manifest(tiny_dataset):
    layout, root = tiny_dataset, tiny_dataset.root
    summary = finalize(layout, LEVELS, {"preset": "test"})
    metas = {f: json.loads(layout.meta(f).read_text()) for f in layout.done_frames()}
    kept = [(f, r) for f, m in metas.items() for r in m["objects"] if r["kept"]]
    assert len(kept) == 6                                   # 4 in frame 0, 2 in frame 1
    for lv in LEVELS:
        coco = json.loads((root / "coco" / f"{lv.key}.json").read_text())
        assert coco["categories"] == coco_categories() and len(coco["categories"]) == len(LABELLED)
        assert [im["file_name"] for im in coco["images"]] == [f"images/{lv.key}/000000.png",
                                                              f"images/{lv.key}/000001.png"]
        assert all((root / im["file_name"]).is_file() for im in coco["images"])
        anns = coco["annotations"]
        records = [(f, r) for f, m in metas.items() for r in m["objects"]]
        assert len(anns) == len(records) > len(kept) and len({a["id"] for a in anns}) == len(anns)
        by_image = {im["id"]: im["frame"] for im in coco["images"]}
        for ann, (frame, rec) in zip(anns, records):
            x0, y0, x1, y1 = rec["bbox"]
            assert by_image[ann["image_id"]] == frame
            assert ann["bbox"] == [x0, y0, x1 - x0, y1 - y0] and all(isinstance(v, float) for v in ann["bbox"])
            assert ann["area"] == rec["pixels"] and ann["iscrowd"] == (0 if rec["kept"] else 1)
            assert ann.get("ignore_reason") == rec["reason"]  # filtered objects: ignore regions
            assert ann["category_id"] == rec["class_id"] + 1 == [c["id"] for c in coco["categories"]
                                                                 if c["name"] == rec["class"]][0]
            assert ann == coco_annotation(rec, ann["id"], ann["image_id"], ann.get("segmentation"))
            # no mask here: ignore regions get their box's RLE, kept objects their box as a polygon
            size = [metas[frame]["height"], metas[frame]["width"]]
            assert ann["segmentation"] == ([[x0, y0, x1, y0, x1, y1, x0, y1]] if rec["kept"] else
                                           box_rle(rec["bbox"], *size))
            assert ann.get("segmentation_is_box", False) == rec["kept"]
    for name in ["clear", "beta0.06", "all"]:
        data = read_yaml(root / "data" / f"{name}.yaml")
        assert data["path"] == str(root.resolve())
        assert data["names"] == {str(i): n for i, n in enumerate(LABELLED)}
        listed = [p for part in ("train", "val")
                  for p in (root / data[part]).read_text().splitlines()]
        assert listed and all(p.startswith("/") for p in listed)
        assert len(listed) == 2 * (2 if name == "all" else 1)
        for p in listed:
            assert (root / p).is_file()
            assert (root / p.replace("/images/", "/labels/").replace(".png", ".txt")).is_file()
    manifest = json.loads((root / "dataset.json").read_text())
    assert manifest == summary and manifest["preset"] == "test" and manifest["frames"] == 2
    assert manifest["levels"] == [lv.to_dict() for lv in LEVELS] and manifest["classes"] == list(LABELLED)
    assert manifest["counts"]["car"] == 1 and manifest["counts"]["bus"] == 1 and manifest["counts"]["van"] == 0
    assert manifest["filtered"] == {"too few pixels": 2}
    # 640×426 tiles at 384 px, and the legend line (22 px) below a 4 px gap
    assert read_image(root / "contact_sheet.png").shape == (2 * (28 + 256) + 4 + 4 + 22, 2 * 384 + 4, 3)


def test_split_deterministic_and_stable():
    frames = [f"{i:06d}" for i in range(300)]
    train, val = split_frames(frames)
    assert (train, val) == split_frames(list(reversed(frames)))
    assert sorted(train + val) == frames and 0.7 < len(train) / 300 < 0.9
    more_train, more_val = split_frames(frames + [f"{i:06d}" for i in range(300, 400)])
    assert set(train) <= set(more_train) and set(val) <= set(more_val)
    assert split_frames(frames, seed=1) != (train, val)
    for n in (2, 3):
        t, v = split_frames(frames[:n])
        assert t and v and sorted(t + v) == frames[:n]
    assert split_frames(["a"]) == (["a"], ["a"])


def test_contact_sheet_shape(tiny_dataset):
    sheet = contact_sheet(tiny_dataset, LEVELS, tiny_dataset.done_frames(), tile_width=160)
    legend = 4 + 22  # a gap, then the line that says how to read the boxes
    assert sheet.dtype == np.uint8 and sheet.shape == (2 * (28 + 107) + 4 + legend, 2 * 160 + 4, 3)
    one = contact_sheet(tiny_dataset, LEVELS[:1], ["000000"], tile_width=96)
    assert one.shape == (28 + 64 + legend, 96, 3)
    assert (one[28:28 + 64] != read_image(tiny_dataset.image("clear", "000000"))).any()   # boxes drawn


def test_finalize_refuses_empty_and_reserved(tmp_path):
    with pytest.raises(ValueError, match="no finished frames"):
        finalize(DatasetLayout(tmp_path), LEVELS, {})
    with pytest.raises(ValueError, match="reserved"):
        finalize(DatasetLayout(tmp_path), [FogLevel("all", "all", 0.0)], {})


def test_a_one_frame_dataset_says_its_frame_is_in_both_splits(tiny_dataset):
    from fogsim.dataset.writer import split_note

    layout = tiny_dataset
    layout.meta("000001").unlink()
    summary = finalize(layout, LEVELS, {})
    assert summary["split"]["train"] == summary["split"]["val"] == 1 and summary["split"]["in_both"] == ["000000"]
    assert "both train and val" in summary["split"]["note"]
    assert json.loads(layout.manifest().read_text())["split"] == summary["split"]
    for part in ("train", "val"):
        assert layout.split_file("clear", part).read_text().split() == [str(layout.image("clear", "000000").resolve())]
    note = split_note(summary)
    assert "\n" not in note and note.startswith("a one-frame dataset: frame 000000 is in both train and val")
    layout.meta("000001").write_text(json.dumps({"frame": "000001", "width": 96, "height": 64, "objects": []}))
    two = finalize(layout, LEVELS, {})
    assert "in_both" not in two["split"] and "note" not in two["split"] and split_note(two) is None
