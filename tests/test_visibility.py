"""Per-object visibility in fog: transmission, Weber contrast against the surround, the 5 % flag —
numbers computed here by hand (sRGB decoding and Rec. 709 weights written out again)."""
import json
import math

import numpy as np
import pytest

from fogsim.dataset.coco import coco_dataset, visibility_fields
from fogsim.dataset.layout import DatasetLayout
from fogsim.fog.model import Fogger
from fogsim.fog.visibility import (
    LUMINANCE_FLOOR,
    VISIBLE_CONTRAST,
    attach_visibility,
    frame_visibility,
    object_visibility,
)


def lin(v8):
    """8-bit sRGB value(s) → linear light, float64, by the IEC 61966-2-1 formula."""
    x = np.asarray(v8, np.float64) / 255.0
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def lum(rgb8):
    r, g, b = lin(rgb8[..., 0]), lin(rgb8[..., 1]), lin(rgb8[..., 2])
    return 0.2126 * r + 0.7152 * g + 0.0722 * b


def grey(h, w, v):
    return np.full((h, w, 3), v, np.uint8)


def target():
    """20×20: a 4×4 object at [8, 12)² whose edge pixels are 100 and interior 2×2 is 200; the
    1-px gap around it 10; the ring (Chebyshev 2–4 from the object) 150; beyond it 50."""
    img = grey(20, 20, 50)
    img[4:16, 4:16] = 150
    img[7:13, 7:13] = 10
    img[8:12, 8:12] = 100
    img[9:11, 9:11] = 200
    mask = np.zeros((20, 20), np.uint16)
    mask[8:12, 8:12] = 7
    return img, mask, {"id": 7, "bbox": [8, 8, 12, 12], "distance_m": 20.0}


def test_weber_contrast_of_interior_against_ring_by_hand():
    img, mask, rec = target()
    expected = abs(lin(200) - lin(150)) / lin(150)  # grey: luminance = the channel's linear value
    for m, method in ((mask, "mask"), (None, "box")):  # a rectangle: both methods see the same pixels
        (v,) = object_visibility(img, [rec], 0.06, mask=m, clear=img)
        assert v["method"] == method
        assert v["contrast"] == pytest.approx(expected, abs=1e-4)
        assert v["contrast_clear"] == v["contrast"]
        assert v["transmission"] == pytest.approx(math.exp(-0.06 * 20.0), abs=1e-5)
        assert v["visible"] is True


def test_colour_uses_rec709_luminance_in_linear_light():
    img, mask, rec = target()
    img[9:11, 9:11] = (255, 0, 0)  # a red interior
    (v,) = object_visibility(img, [rec], 0.0, mask=mask)
    l_obj, l_bg = 0.2126, lin(150)
    assert v["contrast"] == pytest.approx(abs(l_obj - l_bg) / l_bg, abs=1e-4)
    assert v["transmission"] == 1.0 and v["contrast_clear"] is None  # β = 0: clear air; no clear image given


def test_mask_ring_excludes_the_object_and_follows_its_shape():
    """An L-shaped object: the ring hugs the L, not its box, and only the mask method knows it."""
    img = grey(30, 30, 200)
    mask = np.zeros((30, 30), np.uint16)
    mask[10:20, 10:13] = 3
    mask[17:20, 10:20] = 3
    img[mask == 3] = 20
    rec = {"id": 3, "bbox": [10, 10, 20, 20], "distance_m": None}
    (vm,) = object_visibility(img, [rec], 0.1, mask=mask)
    (vb,) = object_visibility(img, [rec], 0.1)
    assert vm["contrast"] == pytest.approx((lin(200) - lin(20)) / lin(200), abs=1e-4)
    assert vm["transmission"] is None  # unknown distance
    # the box interior holds background too, so its contrast is lower
    inner = img[11:19, 11:19]
    l_obj = lum(inner).mean()
    assert vb["contrast"] == pytest.approx((lin(200) - l_obj) / lin(200), abs=1e-4)
    assert vb["contrast"] < vm["contrast"]


def test_box_ring_is_clipped_at_the_border_and_empty_regions_give_none():
    img = grey(10, 10, 80)
    img[:, :3] = 255
    rec = {"bbox": [0, 0, 3, 10], "distance_m": 5.0}  # object on the left edge, ring only on its right
    (v,) = object_visibility(img, [rec], 0.03)
    assert v["method"] == "box"
    assert v["contrast"] == pytest.approx((1.0 - lin(80)) / lin(80), abs=1e-4)
    (full,) = object_visibility(img, [{"bbox": [0, 0, 10, 10], "distance_m": 5.0}], 0.03)
    assert full["contrast"] is None and full["visible"] is None


def test_black_surround_uses_the_luminance_floor():
    img = grey(12, 12, 0)
    img[4:8, 4:8] = 128
    (v,) = object_visibility(img, [{"bbox": [4, 4, 8, 8], "distance_m": 1.0}], 0.0, gap_px=0)
    assert v["contrast"] == pytest.approx(lin(128) / LUMINANCE_FLOOR, rel=1e-4)


@pytest.mark.parametrize("space", ["linear", "srgb"])
def test_object_beyond_the_visibility_is_invisible_and_a_near_one_visible(space):
    """Black boxes against the white horizon sky at β = 0.12 (V = ln 20 / 0.12 ≈ 25 m): contrast 1 in
    clear air. Linear blending gives C = t exactly; sRGB blending C = 1 − lin(1 − t) (fog weaker)."""
    beta = 0.12
    assert math.log(20) / beta == pytest.approx(24.96, abs=0.01)
    h, w = 40, 80
    clear = grey(h, w, 255)
    ray = np.full((h, w), np.inf, np.float32)
    mask = np.zeros((h, w), np.uint16)
    records = []
    for oid, (x0, d) in enumerate(((10, 10.0), (50, 40.0)), start=1):
        clear[15:25, x0:x0 + 10] = 0
        ray[15:25, x0:x0 + 10] = d
        mask[15:25, x0:x0 + 10] = oid
        records.append({"id": oid, "bbox": [x0, 15, x0 + 10, 25], "distance_m": d})
    foggy = Fogger(clear, ray, 255, space)(beta)
    near, far = object_visibility(foggy, records, beta, mask=mask, clear=clear)
    for v, d in ((near, 10.0), (far, 40.0)):
        t = math.exp(-beta * d)
        assert v["transmission"] == pytest.approx(t, abs=1e-5) and v["contrast_clear"] == pytest.approx(1.0)
        s = (1 - t) ** (1 / 2.4) * 1.055 - 0.055 if space == "linear" else 1 - t  # the stored sRGB value
        stored = np.round(255 * s)
        assert v["contrast"] == pytest.approx(1 - lin(stored), abs=1e-4)  # the 8-bit image, by hand
        if space == "linear":
            assert v["contrast"] == pytest.approx(t, abs=0.004)  # C / C0 = t against the sky
    assert near["visible"] is True and far["visible"] is False
    assert far["contrast"] < VISIBLE_CONTRAST <= near["contrast"]


def test_frame_visibility_every_level_and_coco_fields(tmp_path):
    img, mask, rec = target()
    fog = grey(20, 20, 250)
    fog[9:11, 9:11] = 252  # almost gone
    records = [dict(rec, kept=True)]
    attach_visibility(records, img, {"clear": img, "beta0.12": fog}, {"clear": 0.0, "beta0.12": 0.12}, mask)
    vis = records[0]["visibility"]
    assert set(vis) == {"clear", "beta0.12"}
    assert vis["clear"]["contrast"] == vis["clear"]["contrast_clear"] and vis["clear"]["transmission"] == 1.0
    assert vis["beta0.12"]["contrast"] == pytest.approx((lin(252) - lin(250)) / lin(250), abs=1e-4)
    assert vis["beta0.12"]["visible"] is False and vis["clear"]["visible"] is True
    assert visibility_fields(records[0], "beta0.12") == {k: vis["beta0.12"][k] for k in
                                                         ("transmission", "contrast", "visible")}
    assert visibility_fields(records[0], "beta0.03") == {} and visibility_fields({"bbox": [0, 0, 1, 1]}, "clear") == {}
    with pytest.raises(ValueError, match="mask is"):
        frame_visibility(img, {}, {}, records, mask[:5])


def test_render_commit_puts_visibility_in_meta_and_coco(tmp_path):
    """commit_frame (no Blender: fabricated passes for a real scene) → per-object visibility at every
    level in meta, recomputed here from the written images and mask; COCO gets the per-level fields."""
    from fogsim.camera import Intrinsics
    from fogsim.io.images import read_image
    from fogsim.render.frame import DescribedFrame, FramePasses, commit_frame, describe_frame, frame_name, scene_meshes
    from fogsim.render.preset import load_render_preset
    from fogsim.render.silhouette import silhouette_areas
    from fogsim.scene.classes import LABELLED

    W, H = 96, 64
    config = load_render_preset("default", frames=1, resolution=f"{W}x{H}")
    desc = describe_frame(config, 0)
    meshes = scene_meshes(desc)
    K = Intrinsics.from_dict(desc["camera"]["intrinsics"])
    labelled = [o for o in desc["objects"] if o["class"] in LABELLED]
    sil = silhouette_areas({o["id"]: [(v, f) for v, f, _ in meshes[o["id"]]] for o in labelled}, K,
                           np.asarray(desc["camera"]["world_to_camera"]))
    big = sorted(labelled, key=lambda o: -sil[o["id"]]["pixels_in_image"])[:2]
    rgb = np.full((H, W, 3), 0.4, np.float32)
    depth = np.full((H, W), 60.0, np.float32)
    depth[:10] = np.inf
    mask = np.zeros((H, W), np.uint16)
    for o, (x0, d) in zip(big, ((10, 8.0), (60, 45.0))):
        mask[20:40, x0:x0 + 20] = o["id"]
        depth[20:40, x0:x0 + 20] = d
        rgb[20:40, x0:x0 + 20] = 0.02
    layout = DatasetLayout(tmp_path / "ds")
    meta = commit_frame(layout, config, DescribedFrame(0, desc, meshes), FramePasses(rgb, depth, mask))
    stored = json.loads(layout.meta(frame_name(0)).read_text())
    assert len(stored["objects"]) == 2
    for rec in stored["objects"]:
        ys, xs = np.nonzero(mask == rec["id"])
        inner = (slice(ys.min() + 1, ys.max()), slice(xs.min() + 1, xs.max()))
        ring = np.zeros((H, W), bool)
        ring[ys.min() - 4:ys.max() + 5, xs.min() - 4:xs.max() + 5] = True
        ring[ys.min() - 1:ys.max() + 2, xs.min() - 1:xs.max() + 2] = False
        c0 = None
        for lv in config.levels:
            v = rec["visibility"][lv.key]
            img = read_image(layout.image(lv.key, frame_name(0)))
            L = lum(img)
            c = abs(L[inner].mean() - L[ring].mean()) / L[ring].mean()
            assert v["method"] == "mask" and v["contrast"] == pytest.approx(c, abs=1e-4), lv.key
            assert v["transmission"] == pytest.approx(math.exp(-lv.beta * rec["distance_m"]), abs=1e-5)
            assert v["visible"] == (c >= 0.05)
            c0 = c if lv.beta == 0 else c0
            assert v["contrast_clear"] == pytest.approx(c0, abs=1e-4)
    near, far = sorted(stored["objects"], key=lambda r: r["distance_m"])
    top = config.levels[-1].key
    assert near["visibility"][top]["visible"] and not far["visibility"][top]["visible"]
    coco = coco_dataset([meta], config.levels[-1], layout)
    ann = {a["distance_m"]: a for a in coco["annotations"]}
    assert ann[far["distance_m"]]["visible"] is False and ann[near["distance_m"]]["visible"] is True
    assert ann[far["distance_m"]]["contrast"] == far["visibility"][top]["contrast"]
    assert ann[near["distance_m"]]["transmission"] == near["visibility"][top]["transmission"]


def test_real_dataset_records_are_box_based_and_16_bit_images_work():
    """Waymo-like records: string ids, float boxes, unknown distance; a 16-bit image."""
    img = np.full((20, 30, 3), 40000, np.uint16)
    img[5:15, 10:20] = 10000
    mask = np.zeros((20, 30), np.uint16)
    recs = [{"id": "waymo-obj-1", "bbox": [9.6, 5.2, 19.8, 14.9], "distance_m": None, "kept": True},
            {"id": 3, "bbox": [0, 0, 4, 4], "distance_m": 12.0, "kept": False}]
    a, b = object_visibility(img, recs, 0.06, mask=mask, clear=img)
    assert a["method"] == b["method"] == "box" and a["transmission"] is None  # id 3 is not in the mask
    x = np.array([10000, 40000]) / 65535
    l_obj, l_bg = np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)
    assert a["contrast"] == pytest.approx((l_bg - l_obj) / l_bg, abs=1e-4) and a["visible"] is True
    assert b["transmission"] == pytest.approx(math.exp(-0.72), abs=1e-5)
