"""Visible-only label sets (issue 47, point 2): per level, ``visible/labels/<level>/`` holds the YOLO lines of
exactly the kept objects the frame record calls visible at that level (``visibility[<level>].visible``,
measured on the fogged images), its images are hard links to the level's, and ``data/<level>.visible.yaml``
trains on them with the dataset's split; the contact sheet draws hidden boxes dashed."""
from __future__ import annotations

import json
import os

import numpy as np
import pytest

from fogsim.boxes import yolo_line
from fogsim.dataset.layout import DatasetLayout
from fogsim.dataset.visible import visible_at
from fogsim.dataset.writer import PALETTE, draw_boxes
from fogsim.fog.levels import FogLevel, parse_levels
from fogsim.io.documents import write_json
from fogsim.io.images import write_image

LEVELS = [lv.key for lv in parse_levels("paper")]
DISTANCES = (8.0, 30.0, 70.0, 140.0)  # m: one box each; V = ln 20 / β = 100, 50, 33, 25 m at the foggy levels
WHITE_M = 20.0  # and a white box at 20 m: no contrast against the sky, in clear air or fog


def make_sky_dataset(root, frames: int = 6, width: int = 160, height: int = 48):
    """Black boxes at known distances against the horizon sky (+inf, white), fogged in linear light, so a
    box's contrast is its transmission exp(−β d) (:mod:`fogsim.fog.visibility`) and it is visible (≥ 5 %)
    exactly when d < V; and a white box, never visible by contrast. Each record's visibility measured on the
    fogged images, as the renderer's."""
    from fogsim.dataset.writer import finalize, write_frame_labels
    from fogsim.fog.model import Fogger
    from fogsim.fog.visibility import attach_visibility

    levels = parse_levels("paper")
    layout = DatasetLayout(root)
    for i in range(frames):
        frame = f"{i:06d}"
        rgb = np.full((height, width, 3), 255, np.uint8)
        distance = np.full((height, width), np.inf, np.float32)
        records = []
        for k, d in enumerate((*DISTANCES, WHITE_M)):
            x0, y0 = 6 + 30 * k + i % 4, 12 + i % 5
            rgb[y0:y0 + 20, x0:x0 + 18] = 0 if d != WHITE_M else 255
            distance[y0:y0 + 20, x0:x0 + 18] = d
            records.append({"class": "car", "class_id": 0, "bbox": [x0, y0, x0 + 18, y0 + 20], "kept": True,
                            "pixels": 360, "distance_m": d})
        fogger = Fogger(rgb, distance, space="linear")
        fogged = {lv.key: fogger(lv.beta) for lv in levels}
        for lv in levels:
            write_image(layout.image(lv.key, frame), fogged[lv.key])
        attach_visibility(records, rgb, fogged, {lv.key: lv.beta for lv in levels})
        write_frame_labels(layout, frame, levels, records, width, height)
        write_json(layout.meta(frame), {"frame": frame, "width": width, "height": height, "objects": records})
    finalize(layout, levels, {"preset": "sky boxes (tests)"})
    return root


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    return make_sky_dataset(tmp_path_factory.mktemp("vis") / "ds")


def _lines(path) -> list[str]:
    return path.read_text().splitlines()


def test_each_level_keeps_exactly_the_objects_the_meta_calls_visible(dataset):
    layout = DatasetLayout(dataset)
    hidden_somewhere = kept_everywhere = 0
    for meta_file in sorted((dataset / "meta").glob("*.json")):
        meta = json.loads(meta_file.read_text())
        frame, w, h = meta["frame"], meta["width"], meta["height"]
        for level in LEVELS:
            # the rule from the record alone, without fogsim's code: kept, and at a foggy level not visible ==
            # False (the clear level keeps every object: the white box, invisible by contrast, stays there)
            want = [yolo_line(r, w, h) for r in meta["objects"]
                    if r["kept"] and (level == "clear" or r["visibility"][level]["visible"] is not False)]
            assert _lines(layout.visible_label(level, frame)) == want
            assert len(_lines(layout.label(level, frame))) == sum(r["kept"] for r in meta["objects"])
            hidden_somewhere += len(want) < len(_lines(layout.label(level, frame)))
            kept_everywhere += len(want) == len(_lines(layout.label(level, frame)))
            image, link = layout.image(level, frame), layout.visible_image(level, frame)
            assert os.path.samefile(image, link)  # a hard link, no bytes copied
            # and the record's visibility is Koschmieder's: a box is visible exactly when it is nearer than V
            beta = {lv.key: lv.beta for lv in parse_levels("paper")}[level]
            assert len(want) == (5 if beta == 0 else sum(beta * d < np.log(20) for d in DISTANCES))
            assert meta["objects"][4]["visibility"][level]["visible"] is False  # the white box, everywhere
    assert hidden_somewhere == 6 * 4 and kept_everywhere == 6  # every foggy level hides some; clear none


def test_the_visible_data_files_train_on_the_visible_sets_with_the_same_split(dataset):
    layout = DatasetLayout(dataset)
    for level in [*LEVELS, "all"]:
        yaml = (dataset / "data" / f"{level}.visible.yaml").read_text()
        assert f'train: "splits/{level}.visible_train.txt"' in yaml
        for part in ("train", "val"):
            plain = _lines(dataset / "splits" / f"{level}_{part}.txt")
            visible = _lines(dataset / "splits" / f"{level}.visible_{part}.txt")
            assert visible == [p.replace(f"{os.sep}images{os.sep}", f"{os.sep}visible{os.sep}images{os.sep}")
                               for p in plain]
            for p in visible:  # Ultralytics' rule: the label of …/images/… is …/labels/….txt
                label = p.rsplit(f"{os.sep}images{os.sep}", 1)
                assert os.path.isfile(f"{os.sep}labels{os.sep}".join(label).rsplit(".", 1)[0] + ".txt")
    manifest = json.loads((dataset / "dataset.json").read_text())["visible_labels"]
    counts = manifest["levels"]
    assert counts["clear"]["labels"] == counts["beta0.12"]["labels"] == 30
    assert [counts[k]["visible"] for k in LEVELS] == [30, 18, 12, 12, 6]
    assert counts["beta0.12"]["data"] == "data/beta0.12.visible.yaml" and "5 %" in manifest["rule"]
    assert not list(layout.root.rglob("*.part"))


def test_finalize_again_keeps_the_links_and_the_lines(dataset, tmp_path):
    import shutil

    from fogsim.dataset.writer import finalize

    copy = tmp_path / "ds"
    shutil.copytree(dataset, copy)  # copies: the links become files of their own
    layout = DatasetLayout(copy)
    before = {p: p.read_bytes() for p in (copy / "visible" / "labels").rglob("*.txt")}
    finalize(layout, parse_levels("paper"), {"preset": "sky boxes (tests)"})
    assert {p: p.read_bytes() for p in (copy / "visible" / "labels").rglob("*.txt")} == before
    assert os.path.samefile(layout.image("beta0.06", "000000"), layout.visible_image("beta0.06", "000000"))


def test_hidden_boxes_are_dashed_and_unnamed():
    records = [{"bbox": [4, 4, 40, 30], "class": "car", "class_id": 0}]
    solid = draw_boxes(np.zeros((48, 64, 3), np.uint8), records)
    dashed = draw_boxes(np.zeros((48, 64, 3), np.uint8), records, hidden=[True])
    colour = np.array(PALETTE[0])
    top_solid, top_dashed = (np.all(img[4, 4:40] == colour, axis=1) for img in (solid, dashed))
    assert top_solid.all() and 0.3 < top_dashed.mean() < 0.7  # on and off along the edge
    assert np.all(dashed[:4] == 0)  # no name above a hidden box
    foggy, clear = FogLevel("a", "a", 0.06), FogLevel("c", "clear", 0.0)
    assert visible_at({"kept": True, "visibility": {"a": {"visible": False}}}, foggy) is False
    assert visible_at({"kept": True, "visibility": {"a": {"visible": None}}}, foggy) is True
    assert visible_at({"kept": False, "visibility": {}}, foggy) is False
    # clear air hides nothing: a low-contrast object (a white van before a white wall) stays labelled there
    assert visible_at({"kept": True, "visibility": {"c": {"visible": False}}}, clear) is True
