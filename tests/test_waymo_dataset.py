"""``fogsim fog --waymo`` with labels, end to end through the CLI into ``fogsim study``'s report:
a v1 segment whose frames carry camera labels and LiDAR (the wall fixture, a plane at x = 20 m),
depth from the LiDAR (or a depth folder), the render's dataset layout in Waymo's own classes."""
import json

import numpy as np
import pytest

import waymo_lidar_fixtures as lfx
from fogsim.cli import main
from fogsim.dataset.layout import DatasetLayout, frame_from_key
from fogsim.io.depth_files import write_depth
from fogsim.io.images import encode_image
from fogsim.readers.waymo import protobuf_wire as pw
from fogsim.readers.waymo.labels import WAYMO_CLASSES
from fogsim.readers.waymo.tfrecord import write_tfrecord
from waymo_fixtures import Box2D, camera_label, camera_labels_message

STAMPS = (1_000_000, 2_000_000)
LEVELS = ("clear", "beta0.06")


@pytest.fixture
def segment(tmp_path):
    scene = lfx.wall_scene()
    image = encode_image(np.full((lfx.IMAGE_H, lfx.IMAGE_W, 3), 90, np.uint8), ".png")
    car = Box2D("cam-car", 1, cx=lfx.IMAGE_W / 2, cy=lfx.IMAGE_H / 2 + 20, length=120, width=80, difficulty=2)
    ped = Box2D("cam-ped", 2, cx=40, cy=30, length=20, width=50)  # high in the image: no LiDAR point inside
    labels = pw.bytes_field(8, camera_labels_message(1, [camera_label(car), camera_label(ped)]))
    path = tmp_path / "segment.tfrecord"
    write_tfrecord(path, [lfx.frame_msg(scene, t, image=image) + labels for t in STAMPS])
    return path


def _keys():
    return [f"{lfx.CONTEXT}/{t}_FRONT" for t in STAMPS]


def _check_dataset(out):
    layout = DatasetLayout(out)
    frames = [frame_from_key(k) for k in _keys()]
    assert layout.done_frames() == sorted(frames)
    manifest = json.loads(layout.manifest().read_text())
    assert manifest["classes"] == list(WAYMO_CLASSES) and manifest["frames"] == 2
    for lv in LEVELS:
        coco = json.loads(layout.coco(lv).read_text())
        assert [c["name"] for c in coco["categories"]] == list(WAYMO_CLASSES)
        assert len(coco["annotations"]) == 4 and all("distance_m" in a for a in coco["annotations"])
        assert layout.data_yaml(lv).is_file() and layout.split_file(lv, "val").is_file()
        lines = layout.label(lv, frames[0]).read_text().splitlines()
        assert [ln.split()[0] for ln in lines] == ["0", "1"]  # vehicle, pedestrian: Waymo's ids
    assert layout.data_yaml("all").is_file() and layout.contact_sheet().is_file()
    return layout, frames


def test_waymo_fog_with_lidar_depth_writes_a_labelled_dataset(segment, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["fog", "--waymo", str(segment), "--cameras", "FRONT", "--depth-from", "lidar",
                 "--levels", "0,0.06", "--out", str(out), "--quiet"]) == 0, capsys.readouterr().err
    layout, frames = _check_dataset(out)
    meta = json.loads(layout.meta(frames[0]).read_text())
    car, ped = meta["objects"]
    assert car["distance_source"] == "lidar points in box (near cluster)" and 15 < car["distance_m"] < 30
    assert car["difficulty"] == 2 and car["visibility"]["beta0.06"]["transmission"] is not None
    assert ped["distance_m"] is None and ped["distance_source"] == "unknown"
    assert meta["encoding"] == "lidar:ipbasic" and meta["depth_record"]["points_in_image"] > 0


@pytest.mark.detect
def test_waymo_fog_with_a_depth_folder_then_the_study_report(segment, tmp_path, capsys):
    pytest.importorskip("pycocotools")
    depth = tmp_path / "depth"
    for key in _keys():
        write_depth(depth / f"{key}.exr", np.full((lfx.IMAGE_H, lfx.IMAGE_W), 20.0, np.float32))
    out = tmp_path / "out"
    assert main(["fog", "--waymo", str(segment), "--cameras", "FRONT", "--depth-dir", str(depth),
                 "--depth-kind", "ray", "--levels", "0,0.06", "--out", str(out), "--quiet"]) == 0
    _check_dataset(out)
    from fogsim.detection.study import Study
    from fogsim.detection.yolo import TrainConfig

    study = Study(out, tmp_path / "study", TrainConfig())
    gts = study.ground_truth()
    study.check_parameters(gts)
    for m in study.models:
        for lv in study.levels:
            dets = [{"image_id": a["image_id"], "category_id": a["category_id"], "bbox": a["bbox"], "score": 0.9}
                    for a in gts[lv]["annotations"]] if m in (lv, "mixed") else []
            study.prediction(m, lv).parent.mkdir(parents=True, exist_ok=True)
            study.prediction(m, lv).write_text(json.dumps(dets))
    table = study.report()
    # the label distances come from the frame's own LiDAR whatever the fog's depth: the vehicle's
    # is known (≤ 100 m, evaluated), the pedestrian's unknown (an ignore region by default)
    assert table["oracle"]["clear"]["ap50"] == pytest.approx(1.0)
    md = (tmp_path / "study" / "report" / "report.md").read_text()
    assert "vehicle, pedestrian, cyclist" in md and "`--unknown-distance ignore` evaluates 1 objects" in md
