"""COCO ``segmentation`` (issue 40 item 3): fogsim's RLE against pycocotools bit for bit, every COCO file
read back with pycocotools (``annToMask`` equal to the instance mask the dataset holds, ``COCOeval`` in
``segm`` mode giving AP 1.0 for the ground truth fed back), every ``iscrowd`` annotation with a valid RLE,
and a KITTI DontCare region as one ignore annotation."""
from __future__ import annotations

import contextlib
import copy
import io
import json
from pathlib import Path

import numpy as np
import pytest

from fogsim.dataset.coco import EVERY_CLASS, expand_every_class
from fogsim.dataset.layout import DatasetLayout
from fogsim.dataset.writer import finalize, write_frame_labels
from fogsim.io.depth_files import read_uint16_map
from fogsim.io.documents import write_json
from fogsim.io.images import write_image
from fogsim.render.labels import object_records
from fogsim.rle import box_mask, box_rle, rle_counts, rle_encode, rle_encode_box
from fogsim.scene.classes import LABELLED
from test_labels import LEVELS, demo_mask, full_silhouettes


# ----------------------------------------------------------------------------- the encoding
def test_run_lengths_from_the_definition():
    m = np.array([[0, 1], [1, 1], [0, 0]], np.uint8)  # column-major: 0 1 0 | 1 1 0
    assert rle_counts(m) == [1, 1, 1, 2, 1]
    assert rle_counts(np.ones((2, 2))) == [0, 4]  # a set first pixel: an empty 0-run first
    assert rle_counts(np.zeros((3, 4))) == [12] and rle_counts(np.zeros((0, 5))) == [0]
    # the string: 1 → '1', 2 → '2'; from the 4th run on, the difference to the run two before
    assert rle_encode(m) == {"size": [3, 2], "counts": "11112"[:3] + chr(48 + (2 - 1)) + chr(48 + (1 - 1))}
    assert rle_encode(np.zeros((1, 40)))["counts"] == chr(48 + (40 & 0x1F) + 0x20) + chr(48 + (40 >> 5))


def test_a_crop_placed_in_its_mask_encodes_as_the_whole_mask():
    rng = np.random.default_rng(2)
    for _ in range(300):
        h, w = (int(v) for v in rng.integers(1, 30, 2))
        ch, cw = int(rng.integers(0, h + 1)), int(rng.integers(0, w + 1))
        top, left = int(rng.integers(0, h - ch + 1)), int(rng.integers(0, w - cw + 1))
        crop = rng.random((ch, cw)) < rng.choice([0.1, 0.5, 0.95, 1.0])
        whole = np.zeros((h, w), bool)
        whole[top:top + ch, left:left + cw] = crop
        assert rle_encode_box(crop, top, left, h, w) == rle_encode(whole)
    with pytest.raises(ValueError, match="not inside"):
        rle_encode_box(np.ones((3, 3)), 2, 0, 4, 4)


def test_box_mask_is_the_pixels_whose_centres_are_inside():
    m = box_mask([2, 1, 5, 3], 4, 6)
    want = np.zeros((4, 6), bool)
    want[1:3, 2:5] = True
    np.testing.assert_array_equal(m, want)
    np.testing.assert_array_equal(box_mask([1.6, 0.4, 5.4, 3.5], 4, 6), box_mask([2, 0, 5, 3], 4, 6))
    assert box_mask([-3, -3, 100, 100], 4, 6).all() and not box_mask([3, 1, 3, 4], 4, 6).any()


def test_bit_for_bit_against_pycocotools():
    mask_api = pytest.importorskip("pycocotools.mask")
    rng = np.random.default_rng(1)
    cases = [np.zeros((5, 7), np.uint8), np.ones((5, 7), np.uint8), np.zeros((1, 1), np.uint8),
             np.ones((1, 1), np.uint8), np.ones((1000, 3), np.uint8)]
    for _ in range(300):
        h, w = (int(v) for v in rng.integers(1, 60, 2))
        cases.append((rng.random((h, w)) < rng.random()).astype(np.uint8))  # long and short runs, both signs
        big = np.zeros((h * 20, w * 20), np.uint8)
        big[rng.integers(0, h * 20):, rng.integers(0, w * 20):] = 1  # runs of thousands (many 5-bit groups)
        cases.append(big)
    for m in cases:
        ref = mask_api.encode(np.asfortranarray(m))
        got = rle_encode(m)
        assert got["counts"] == ref["counts"].decode("ascii") and got["size"] == list(ref["size"])
        np.testing.assert_array_equal(mask_api.decode({"size": got["size"], "counts": got["counts"]}), m)


# ----------------------------------------------------------------------------- reading COCO files back
def coco_api(path: Path):
    coco_mod = pytest.importorskip("pycocotools.coco")
    with contextlib.redirect_stdout(io.StringIO()):
        return coco_mod.COCO(str(path))


def segm_ap_of_ground_truth(coco) -> float:
    """COCOeval in ``segm`` mode on the ground truth's own masks fed back as detections (score 1)."""
    from pycocotools.cocoeval import COCOeval

    dets = [{"image_id": a["image_id"], "category_id": a["category_id"], "segmentation": a["segmentation"],
             "score": 1.0} for a in coco.dataset["annotations"] if not a["iscrowd"]]
    with contextlib.redirect_stdout(io.StringIO()):
        ev = COCOeval(coco, coco.loadRes(copy.deepcopy(dets)), "segm")
        ev.evaluate()
        ev.accumulate()
        ev.summarize()
    return float(ev.stats[0])


def check_coco_masks(root: Path, masks: dict[str, np.ndarray]) -> int:
    """Every COCO file under ``root``: ``annToMask`` of every annotation with an instance mask equals
    ``masks[frame] == id`` (annotations follow the frame record's objects), every crowd annotation has an
    RLE, and COCOeval ``segm`` gives AP 1.0 for the ground truth. Returns the annotations checked."""
    n = 0
    for path in sorted((root / "coco").glob("*.json")):
        coco = coco_api(path)
        for image in coco.dataset["images"]:
            meta = json.loads((root / "meta" / f"{image['frame']}.json").read_text())
            anns = coco.loadAnns(coco.getAnnIds(imgIds=[image["id"]]))
            assert len(anns) == len(meta["objects"])
            for ann, rec in zip(anns, meta["objects"]):
                assert ann["segmentation"]["size"] == [image["height"], image["width"]]
                got = coco.annToMask(ann)
                np.testing.assert_array_equal(got, masks[image["frame"]] == rec["id"])
                assert ann["iscrowd"] == (not rec["kept"]) and got.sum() == rec["pixels"] == ann["area"]
                n += 1
        assert segm_ap_of_ground_truth(coco) == pytest.approx(1.0)
    return n


@pytest.mark.detect
def test_a_rendered_datasets_coco_masks_are_its_instance_masks(tmp_path):
    """Frames written as the renderer writes them (records from the instance mask, masks/<frame>.png)."""
    layout = DatasetLayout(tmp_path / "out")
    objects = [{"id": i, "class": c} for i, c in ((1, "car"), (2, "pedestrian"), (3, "cyclist"),
                                                  (4, "traffic_sign"), (5, "bus"))]
    masks, rng = {}, np.random.default_rng(0)
    for frame, drop in (("000000", ()), ("000001", (1, 5))):
        m = demo_mask()
        m[np.isin(m, drop)] = 0
        recs = object_records(m, np.full(m.shape, 30.0, np.float32), objects, full_silhouettes(demo_mask()),
                              min_pixels=10)
        for lv in LEVELS:
            write_image(layout.image(lv.key, frame), rng.integers(0, 256, (64, 96, 3), dtype=np.uint8))
        write_frame_labels(layout, frame, LEVELS, recs, 96, 64)
        write_image(layout.mask(frame), m)
        write_json(layout.meta(frame), {"frame": frame, "width": 96, "height": 64, "objects": recs})
        masks[frame] = read_uint16_map(layout.mask(frame))
    finalize(layout, LEVELS, {"preset": "test"})
    assert check_coco_masks(layout.root, masks) == 2 * (5 + 3)  # levels × the two frames' objects
    crowd = [a for a in json.loads(layout.coco("clear").read_text())["annotations"] if a["iscrowd"]]
    assert len(crowd) == 2 and all(a["ignore_reason"] == "too few pixels" for a in crowd)  # the L's too small
    assert json.loads(layout.coco("clear").read_text())["categories"][-1]["name"] == LABELLED[-1]  # no DontCare


@pytest.mark.detect
def test_fogged_cityscapes_carries_gtfine_instance_masks(tmp_path):
    import cityscapes_tree as ct
    from fogsim.cli import main

    root = ct.make_tree(tmp_path / "cs")
    out = tmp_path / "out"
    assert main(["fog", "--quiet", "--cityscapes", str(root), "--levels", "clear,0.06", "--out", str(out)]) == 0
    ids, _, _ = ct.scene()
    masks = {}
    for k, base in enumerate(ct.BASES):
        frame = f"leftImg8bit__val__aachen__{base}_leftImg8bit"
        flipped = ids[:, ::-1] if k else ids
        # a group's record id is its class id and its mask the component: the scene has one per group
        masks[frame] = np.where(flipped >= 1000, flipped, np.where(np.isin(flipped, (26, 29)), flipped, 0))
    assert check_coco_masks(out, masks) == 2 * 2 * 6  # levels × frames × (4 instances + 2 ignore regions)


# ----------------------------------------------------------------------------- KITTI: DontCare once
@pytest.mark.detect
def test_a_kitti_frame_with_4_dontcare_boxes_gives_4_ignore_annotations(tmp_path):
    import kitti_tree as kt
    from fogsim.cli import main
    from fogsim.dataset.reader import val_ground_truth
    from fogsim.detection.coco_eval import evaluate
    from fogsim.readers.kitti.labels import KITTI_CLASSES

    root = kt.write_kitti(tmp_path / "in" / "kitti")
    label = root / "training" / "label_2" / "000000.txt"
    boxes = [(100.0, 10.0, 120.0, 30.0), (2.0, 3.0, 40.0, 20.0), (130.5, 20.25, 150.0, 40.0), (0.0, 0.0, 10.0, 5.0)]
    lines = [ln for ln in label.read_text().splitlines() if not ln.startswith("DontCare")]
    lines += [f"DontCare -1 -1 -10 {a:.2f} {b:.2f} {c:.2f} {d:.2f} -1 -1 -1 -1000 -1000 -1000 -10"
              for a, b, c, d in boxes]
    label.write_text("\n".join(lines) + "\n")
    out = tmp_path / "out"
    assert main(["fog", "--quiet", "--kitti", str(root), "--levels", "clear,0.06", "--out", str(out)]) == 0
    frame = "training__image_2__000000"
    dataset = json.loads((out / "dataset.json").read_text())
    assert dataset["filtered"] == {"DontCare region": 4 + 2}  # this frame's 4, the two other frames' one each
    for level in ("clear", "beta0.06"):
        gt = json.loads((out / "coco" / f"{level}.json").read_text())
        every = gt["categories"][-1]
        assert every == {"id": len(KITTI_CLASSES) + 1, "name": EVERY_CLASS, "supercategory": "ignore"}
        assert [c["name"] for c in gt["categories"][:-1]] == list(KITTI_CLASSES)
        image = next(im for im in gt["images"] if im["frame"] == frame)
        anns = [a for a in gt["annotations"] if a["image_id"] == image["id"]]
        crowd = [a for a in anns if a["iscrowd"]]
        assert len(anns) == 5 and len(crowd) == 4  # the car and one ignore annotation per DontCare box
        coco = coco_api(out / "coco" / f"{level}.json")
        for a, (x0, y0, x1, y1) in zip(crowd, boxes):
            assert a["category_id"] == every["id"] and a["every_class"] and a["ignore_reason"] == "DontCare region"
            want = box_mask([x0, y0, x1 + 1, y1 + 1], kt.HEIGHT, kt.WIDTH)  # KITTI's inclusive pixel corners
            np.testing.assert_array_equal(coco.annToMask(a), want)
            assert a["segmentation"] == box_rle(a["bbox"][:2] + [a["bbox"][0] + a["bbox"][2],
                                                                 a["bbox"][1] + a["bbox"][3]], kt.HEIGHT, kt.WIDTH)
        car = next(a for a in anns if not a["iscrowd"])
        x, y, w, h = car["bbox"]  # a box-only label: its box as a polygon, marked so
        assert car["segmentation"] == [[x, y, x + w, y, x + w, y + h, x, y + h]] and car["segmentation_is_box"]
        assert all("segmentation" in a for a in gt["annotations"] if a["iscrowd"])
        # per-category evaluation: the region ignores a detection of every class there
        per_class = expand_every_class(gt)
        assert len([a for a in per_class["annotations"] if a["image_id"] == image["id"] and a["iscrowd"]]) == \
            4 * len(KITTI_CLASSES)
        assert EVERY_CLASS not in [c["name"] for c in per_class["categories"]]
        det = [{"image_id": image["id"], "category_id": a["category_id"], "bbox": a["bbox"], "score": 0.9}
               for a in anns if not a["iscrowd"]]
        car_there = {"image_id": image["id"], "category_id": 1, "bbox": crowd[2]["bbox"], "score": 0.95}
        one = {**gt, "images": [image], "annotations": anns}
        assert evaluate(expand_every_class(one), det + [car_there])["ap50"] == pytest.approx(1.0)
        assert evaluate(one, det + [car_there])["ap50"] < 1.0  # unexpanded, it would be a false alarm
    val = val_ground_truth(out, "clear")  # the study's ground truth: expanded
    assert all(a["category_id"] <= len(KITTI_CLASSES) for a in val["annotations"])


# ----------------------------------------------------------------------------- box-only labels: a polygon
def test_box_only_coco_files_work_with_annToMask(tmp_path):
    """A fogged KITTI tree (box labels only): every annotation has a ``segmentation`` pycocotools reads —
    a kept object its box as a polygon, whose mask is the box's pixels (up to a pixel whose centre sits on
    a fractional edge) — as KITTI→COCO converters write it (issue 47)."""
    pytest.importorskip("pycocotools")
    import kitti_tree as kt
    from fogsim.cli import main

    root = kt.write_kitti(tmp_path / "in" / "kitti")
    out = tmp_path / "out"
    assert main(["fog", "--quiet", "--kitti", str(root), "--levels", "clear,0.06", "--out", str(out)]) == 0
    coco = coco_api(out / "coco" / "beta0.06.json")
    kept = [a for a in coco.dataset["annotations"] if not a["iscrowd"]]
    assert kept and all(a["segmentation_is_box"] for a in kept)
    for a in coco.dataset["annotations"]:
        image = coco.imgs[a["image_id"]]
        mask = coco.annToMask(a).astype(bool)  # a KeyError before: no "segmentation"
        x, y, w, h = a["bbox"]
        want = box_mask([x, y, x + w, y + h], image["height"], image["width"])
        assert mask.shape == want.shape
        assert (mask & ~want).sum() == 0 and (want & ~mask).sum() <= 2 * (w + h) + 4  # the box, edges aside
        assert mask.sum() > 0.8 * want.sum()
