"""Cityscapes gtFine instanceIds → the 8 detection classes, ignore regions and distances over
valid disparity, on a tree built from the format's spec (tests/cityscapes_tree.py)."""
from pathlib import Path

import numpy as np
import pytest

from cityscapes_tree import BASES, hand_distance, make_tree, scene
from fogsim.errors import InputError
from fogsim.io.images import write_image
from fogsim.readers.base import Labels
from fogsim.readers.cityscapes import cityscapes_samples
from fogsim.readers.cityscapes_labels import CITYSCAPES_CLASSES, instance_records, png_size


@pytest.fixture
def tree(tmp_path):
    return make_tree(tmp_path / "cs")


def by_id(labels: Labels) -> dict:
    return {(o["id"], o["bbox"][0]): o for o in labels.objects}


def test_boxes_classes_and_ignore_regions(tree):
    samples = cityscapes_samples(tree, "val")
    assert [s.key.rsplit("/", 1)[1] for s in samples] == [f"{b}_leftImg8bit" for b in BASES]
    labels = samples[0].labels()
    assert labels.classes == CITYSCAPES_CLASSES == ("person", "rider", "car", "truck", "bus", "train",
                                                    "motorcycle", "bicycle")
    got = {o["id"]: o for o in labels.objects}
    assert set(got) == {26000, 26001, 24000, 24001, 26, 29000}  # no road (7), no building (11)
    expect = {26000: ("car", [4, 10, 15, 21], 121, True), 26001: ("car", [20, 12, 30, 20], 80, True),
              24000: ("person", [40, 8, 44, 22], 56, True), 24001: ("person", [60, 2, 62, 4], 4, True),
              26: ("car", [48, 20, 58, 26], 60, False), 29000: ("car", [2, 24, 10, 30], 48, False)}
    for oid, (cls, box, pixels, kept) in expect.items():
        o = got[oid]
        assert (o["class"], o["bbox"], o["pixels"], o["kept"]) == (cls, box, pixels, kept), oid
        assert o["class_id"] == CITYSCAPES_CLASSES.index(cls)
    assert got[26]["reason"] == "group (cargroup)" and got[29000]["reason"] == "ignored class (caravan)"
    assert all(o["reason"] is None for o in got.values() if o["kept"])
    # the mirrored frame: boxes mirror (x → 64 − x)
    mirrored = {o["id"]: o["bbox"] for o in samples[1].labels().objects}
    assert mirrored[26000] == [64 - 15, 10, 64 - 4, 21]


def test_distance_is_the_median_over_valid_disparity_only(tree):
    labels = {o["id"]: o for o in cityscapes_samples(tree, "val")[0].labels().objects}
    for oid in (26000, 26001, 24000):
        hand = hand_distance(tree, BASES[0], oid)
        assert labels[oid]["distance_m"] == pytest.approx(hand, abs=1.5e-3), oid
        assert labels[oid]["distance_source"] == "valid disparity (median ray distance)"
    # car 26001: 32 of its 80 pixels are holes; the valid columns x 24..29 are 22..24.5 m planar
    car = labels[26001]
    assert car["valid_disparity_pixels"] == 48
    assert 22.0 < car["distance_m"] < 25.5  # with holes as 0 m (or filled from the left) it would be lower
    hole_free = np.median([20 + 0.5 * (x - 20) for x in range(20, 30)])
    assert car["distance_m"] > hole_free + 1  # the holes' columns were really left out
    # Z = 10 m at the image's left: ray distance is longer than planar by the off-axis factor
    assert labels[26000]["distance_m"] > 10.0
    # every pixel of person 24001 is a hole: unknown
    assert labels[24001]["distance_m"] is None and labels[24001]["distance_source"] == "unknown"


def test_instance_records_groups_are_split_into_components():
    ids = np.zeros((10, 20), np.uint16)
    ids[1:3, 1:4] = 24          # a persongroup …
    ids[6:9, 12:18] = 24        # … and another, apart from it
    ids[5, 5] = 30              # a trailer without instances (plain id) → ignore, truck
    ids[0, 19] = 33000          # a bicycle
    ids[9, 0] = 26 * 1000 + 999  # class car via the instance scheme
    recs = instance_records(ids, None)
    assert [(r["id"], r["class"], r["bbox"], r["kept"]) for r in recs] == [
        (26999, "car", [0, 9, 1, 10], True), (33000, "bicycle", [19, 0, 20, 1], True),
        (24, "person", [1, 1, 4, 3], False), (24, "person", [12, 6, 18, 9], False),
        (30, "truck", [5, 5, 6, 6], False)]
    assert all(r["distance_m"] is None for r in recs)


def test_missing_gtfine_and_bad_sizes(tree, tmp_path):
    # no gtFine at all: no labels (the images-only layout)
    bare = make_tree(tmp_path / "bare", gt=False)
    assert all(s.labels is None for s in cityscapes_samples(bare, "val"))
    with pytest.raises(InputError, match="gtFine.*pass --no-labels"):
        cityscapes_samples(bare, "val", labels=True)
    # two splits, one without gtFine: refused, naming it and --no-labels
    make_tree(tree, "train", gt=False)
    with pytest.raises(InputError, match=r"gtFine/train: missing.*--no-labels"):
        cityscapes_samples(tree, "val,train")
    assert all(s.labels is None for s in cityscapes_samples(tree, "val,train", labels=False))
    # one image's instanceIds missing: its reader names the file
    gt = tree / "gtFine" / "val" / "aachen" / f"{BASES[1]}_gtFine_instanceIds.png"
    gt.unlink()
    samples = cityscapes_samples(tree, "val")
    with pytest.raises(InputError, match=f"{gt.name}: missing Cityscapes instance labels"):
        samples[1].labels()
    # instanceIds of another size than the image
    ids, _, _ = scene()
    write_image(gt, ids[:, :32].copy())
    with pytest.raises(InputError, match=r"instanceIds is 32×32 but the image .* is 64×32"):
        samples[1].labels()
    # an 8-bit instanceIds (a colour preview passed by mistake)
    write_image(gt, np.zeros((32, 64, 3), np.uint8))
    with pytest.raises(InputError, match="expected a single-channel 16-bit map"):
        samples[1].labels()


def test_png_size_reads_the_header(tree):
    img = next((tree / "leftImg8bit" / "val" / "aachen").glob("*.png"))
    assert png_size(img) == (64, 32)
    assert png_size(Path(tree) / "nothing.png") is None
