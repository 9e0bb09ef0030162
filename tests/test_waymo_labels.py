"""Waymo 2D camera labels with a distance per box, on real-format v1 Frames and v2 parquet tables."""
from __future__ import annotations

import json
import math
import pickle

import numpy as np
import pytest

from fogsim.errors import InputError
from fogsim.readers.base import Labels
from fogsim.readers.waymo import protobuf_wire as pw
from fogsim.readers.waymo import waymo_samples, waymo_v1_samples, waymo_v2_samples
from fogsim.readers.waymo.address import V1Record, V2Frame
from fogsim.readers.waymo.label_distance import distance_from_points, match_projected, pixel_box
from fogsim.readers.waymo.labels import (
    SOURCE_ASSOCIATION,
    SOURCE_MATCH,
    SOURCE_POINTS,
    SOURCE_UNKNOWN,
    WAYMO_CLASSES,
    camera_label_id,
)
from fogsim.readers.waymo.labels import Box2D as ReaderBox
from fogsim.readers.waymo.labels_v1 import WaymoV1Labels
from fogsim.readers.waymo.labels_v2 import WaymoV2Labels, camera_enum
from fogsim.readers.waymo.tfrecord import index_tfrecord, write_tfrecord
from waymo_fixtures import (
    TYPE_CYCLIST,
    TYPE_PEDESTRIAN,
    TYPE_SIGN,
    TYPE_VEHICLE,
    Box2D,
    Box3D,
    Camera,
    LabelFrame,
    StaticPoints,
    camera_labels_message,
    extrinsic,
    frame_message,
    label_message,
    write_v1,
    write_v2,
)

CONTEXT = "10023947602400723454_1120_000_1140_000"
T0, T1 = 1557855896237535, 1557855896337535
FRONT, FRONT_LEFT = 1, 2
E_FRONT = extrinsic((1.5, 0.0, 2.0))  # looking along vehicle +x
E_LEFT = extrinsic((1.4, 0.1, 2.1), yaw=math.radians(45))
P_PED2 = np.array([10.0, 2.0, -0.5])  # the FRONT_LEFT pedestrian, in that camera's frame


def lid(name: str) -> str:
    """A 22-character laser label id, as Waymo's."""
    return (name + "-" * 22)[:22]


def scene(t: int = T0) -> LabelFrame:
    """FRONT: an associated pedestrian, a vehicle with its projected box (plus a weaker decoy and a
    sign box on it), a cyclist at the right edge whose projected box fails IoA, a far vehicle with
    no 3D label, a sign, a box outside the image, a vehicle whose projected box fails IoU and a
    pedestrian associated with a laser label that is not there, and one more pedestrian inside the
    first one's projected box (which the association has already claimed). FRONT_LEFT (turned 45° left): an
    associated pedestrian and the same vehicle, matched through an ``_FRONT_LEFT`` projected id."""
    ped2 = (E_LEFT @ np.append(P_PED2, 1.0))[:3]
    laser = [Box3D(lid("ped"), TYPE_PEDESTRIAN, (20.0, 3.0, 1.0), 0.8, 0.8, 1.8),
             Box3D(lid("car"), TYPE_VEHICLE, (30.0, -5.0, 0.8)),
             Box3D(lid("decoy"), TYPE_VEHICLE, (40.0, -6.0, 0.8)),
             Box3D(lid("cyc"), TYPE_CYCLIST, (12.0, -4.0, 1.0), 1.8, 0.6, 1.7),
             Box3D(lid("sign"), TYPE_SIGN, (15.0, 5.0, 3.0), 0.1, 0.8, 0.8),
             Box3D(lid("low"), TYPE_VEHICLE, (8.0, 2.0, 0.5)),
             Box3D(lid("ped2"), TYPE_PEDESTRIAN, tuple(ped2), 0.8, 0.8, 1.8)]
    front = [Box2D("cam-ped", TYPE_PEDESTRIAN, 100, 120, 21, 60, difficulty=2, laser_id=lid("ped")),
             Box2D("cam-car", TYPE_VEHICLE, 200, 130, 60, 40, difficulty=1),
             Box2D("cam-cyc", TYPE_CYCLIST, 315, 100, 20, 30),
             Box2D("cam-far", TYPE_VEHICLE, 260, 65, 20, 10, difficulty=2),
             Box2D("cam-sign", TYPE_SIGN, 50, 50, 10, 10),
             Box2D("cam-off", TYPE_VEHICLE, -50, 100, 20, 20),
             Box2D("cam-low", TYPE_VEHICLE, 60, 200, 40, 40),
             Box2D("cam-ped-x", TYPE_PEDESTRIAN, 140, 180, 10, 30, laser_id=lid("gone")),
             Box2D("cam-ped-near", TYPE_PEDESTRIAN, 104, 125, 16, 50)]  # inside the pedestrian's projected box
    projected_front = [Box2D(lid("ped"), TYPE_PEDESTRIAN, 100, 120, 24, 64),
                       Box2D(lid("sign"), TYPE_SIGN, 200, 130, 60, 40),   # exactly on cam-car: other type
                       Box2D(lid("decoy"), TYPE_VEHICLE, 215, 130, 60, 40),  # IoU 0.6 with cam-car
                       Box2D(lid("car"), TYPE_VEHICLE, 202, 128, 70, 46),    # IoU 0.745, IoA 1
                       Box2D(lid("cyc"), TYPE_CYCLIST, 318, 100, 14, 30),    # IoU 0.6 but IoA 0.6
                       Box2D(lid("low"), TYPE_VEHICLE, 90, 200, 40, 40)]     # IoU 0.14
    left = [Box2D("cam-ped2", TYPE_PEDESTRIAN, 100, 100, 10, 20, difficulty=1, laser_id=lid("ped2")),
            Box2D("cam-car2", TYPE_VEHICLE, 250, 150, 40, 30)]
    projected_left = [Box2D(lid("car"), TYPE_VEHICLE, 251, 151, 44, 34)]
    cameras = {FRONT: Camera(extrinsic=E_FRONT), FRONT_LEFT: Camera(extrinsic=E_LEFT)}
    return LabelFrame(CONTEXT, t, cameras, {FRONT: front, FRONT_LEFT: left},
                      {FRONT: projected_front, FRONT_LEFT: projected_left}, laser)


#: LiDAR points: 8 on the far vehicle (52.0 … 52.7 m), 6 on the background behind it (90 m),
#: 2 stray ones in front (5 m, fewer than min_points) and 3 outside every box.
FAR_UV = [(251 + 2 * i, 61 + i) for i in range(8)] + [(252 + 3 * i, 68) for i in range(6)] + [(269, 60), (250, 69)]
FAR_RAY = [52.0 + 0.1 * i for i in range(8)] + [90.0] * 6 + [5.0, 5.2]
POINTS = StaticPoints((("FRONT", tuple(FAR_UV) + ((5, 5), (6, 6), (300, 230)), tuple(FAR_RAY) + (1.0, 1.0, 3.0)),))


@pytest.fixture
def v1_file(tmp_path):
    return write_v1(tmp_path / "segment-labels.tfrecord", [scene(T0), scene(T1)])


def _pyarrow():
    pytest.importorskip("pyarrow", exc_type=ImportError)
    pytest.importorskip("pyarrow.parquet", exc_type=ImportError)


def _by_id(labels: Labels) -> dict[str, dict]:
    return {o["object_id"]: o for o in labels.objects}


def _range(center, e) -> tuple[float, float]:
    """Range and planar depth by hand: p_cam = Rᵀ·(c − t)."""
    p = e[:3, :3].T @ (np.asarray(center) - e[:3, 3])
    return float(np.linalg.norm(p)), float(p[0])


# ----------------------------------------------------------------------------- boxes and classes
def test_pixel_box_rounds_half_up_and_clamps():
    assert pixel_box(100, 120, 21, 60, 320, 240) == [90, 90, 111, 150]  # 89.5 → 90, 110.5 → 111
    assert pixel_box(315, 100, 20, 30, 320, 240) == [305, 85, 320, 115]  # clamped at W
    assert pixel_box(5, 3, 20, 10, 320, 240) == [0, 0, 15, 8]
    assert pixel_box(-50, 100, 20, 20, 320, 240) == [0, 90, 0, 110]  # empty: left of the image
    assert pixel_box(315, 100, 20, 30, None, None) == [305, 85, 325, 115]  # size unknown: no upper clamp


def test_v1_boxes_classes_difficulty(v1_file):
    samples = waymo_v1_samples(v1_file, cameras=("FRONT", "FRONT_LEFT"))
    assert [s.labels is not None for s in samples] == [True] * 4
    read = samples[0].labels.read()
    labels = read.labels
    assert isinstance(labels, Labels) and labels.classes == WAYMO_CLASSES == ("vehicle", "pedestrian", "cyclist")
    ids = ["cam-ped", "cam-car", "cam-cyc", "cam-far", "cam-low", "cam-ped-x", "cam-ped-near"]
    assert [o["object_id"] for o in labels.objects] == ids
    assert read.dropped == {"not a 2D class": 1, "empty after clamping": 1}
    got = _by_id(labels)
    assert [(o["class"], o["class_id"]) for o in labels.objects] == [
        ("pedestrian", 1), ("vehicle", 0), ("cyclist", 2), ("vehicle", 0), ("vehicle", 0), ("pedestrian", 1),
        ("pedestrian", 1)]
    assert got["cam-ped"]["bbox"] == [90, 90, 111, 150] and got["cam-ped"]["pixels"] == 21 * 60
    assert got["cam-cyc"]["bbox"] == [305, 85, 320, 115] and got["cam-cyc"]["pixels"] == 15 * 30
    assert got["cam-cyc"]["truncated"] and not got["cam-car"]["truncated"]
    assert [o["difficulty"] for o in labels.objects] == [2, 1, 0, 2, 0, 0, 0]
    assert all(o["kept"] and o["reason"] is None for o in labels.objects)


# ----------------------------------------------------------------------------- distances
def test_association_distance_is_the_camera_range_of_the_box_centre(v1_file):
    front, left = waymo_v1_samples(v1_file, cameras=("FRONT", "FRONT_LEFT"))[:2]
    ped = _by_id(front.labels())["cam-ped"]
    # box centre (20, 3, 1) in the vehicle frame, camera at (1.5, 0, 2) looking along +x
    assert ped["distance_m"] == round(math.sqrt(18.5 ** 2 + 3 ** 2 + 1 ** 2), 3) == 18.768
    assert ped["planar_depth_m"] == 18.5
    assert ped["distance_source"] == SOURCE_ASSOCIATION and ped["laser_id"] == lid("ped")
    assert ped["laser_points_in_box"] == 100
    ped2 = _by_id(left.labels())["cam-ped2"]  # a camera turned 45° left: the inverse extrinsic counts
    assert ped2["distance_m"] == round(float(np.linalg.norm(P_PED2)), 3) and ped2["planar_depth_m"] == 10.0
    assert ped2["difficulty"] == 1


def test_projected_box_matching(v1_file):
    front, left = waymo_v1_samples(v1_file, cameras=("FRONT", "FRONT_LEFT"))[:2]
    got = _by_id(front.labels())
    car = got["cam-car"]  # the best same-type box (not the sign on it, nor the weaker decoy)
    assert car["distance_source"] == SOURCE_MATCH and car["laser_id"] == lid("car")
    d, z = _range((30.0, -5.0, 0.8), E_FRONT)
    assert (car["distance_m"], car["planar_depth_m"]) == (round(d, 3), round(z, 3))
    assert (d, z) == (pytest.approx(math.hypot(28.5, 5, 1.2)), pytest.approx(28.5))
    # IoA 0.6, IoU 0.14, no projected box, laser label missing, projected box claimed by an association
    for rejected in ("cam-cyc", "cam-low", "cam-far", "cam-ped-x", "cam-ped-near"):
        assert (got[rejected]["distance_m"], got[rejected]["distance_source"], got[rejected]["laser_id"]) == \
            (None, SOURCE_UNKNOWN, None), rejected
    car2 = _by_id(left.labels())["cam-car2"]  # projected id "<laser id>_FRONT_LEFT"
    d, z = _range((30.0, -5.0, 0.8), E_LEFT)
    assert car2["laser_id"] == lid("car") and car2["distance_m"] == round(d, 3)
    assert car2["planar_depth_m"] == round(z, 3) and abs(z - d) > 1  # off-axis: range ≠ planar


def test_matching_is_one_to_one_and_greedy_by_iou():
    cams = [ReaderBox("a", 1, 50, 50, 20, 20), ReaderBox("b", 1, 53, 50, 20, 20), ReaderBox("c", 2, 50, 50, 20, 20)]
    proj = [ReaderBox("p", 1, 52, 50, 22, 22), ReaderBox("q", 1, 47, 50, 20, 20)]
    # IoU(a,p) = 380/504, IoU(b,p) = 400/484 (b inside p), IoU(a,q) = 340/460, IoU(b,q) = 280/520 (IoA
    # 0.7); c has another type. Greedy: b takes p (the best pair), so a gets q although a-p > a-q.
    assert match_projected(cams, proj, 100, 100) == {1: (0, pytest.approx(400 / 484)), 0: (1, pytest.approx(340 / 460))}
    assert match_projected(cams, proj, 100, 100, exclude={"p"}) == {0: (1, pytest.approx(340 / 460))}
    shifted = [ReaderBox("s", 1, 58, 50, 20, 20)]  # IoU(a,s) = 240/560 ≥ 0.3 but IoA(a) 0.6; IoA(b) 0.75
    assert match_projected(cams[:1], shifted, 100, 100) == {}
    assert match_projected(cams[1:2], shifted, 100, 100) == {0: (0, pytest.approx(300 / 500))}
    far = [ReaderBox("z", 1, 90, 90, 10, 10)]
    assert match_projected(cams, far, 100, 100) == {}


def test_fallback_from_lidar_points(v1_file):
    class Counting(StaticPoints):
        calls: list = []

        def __call__(self, camera):
            Counting.calls.append(camera)
            return super().__call__(camera)

    sample = waymo_v1_samples(v1_file)[0]
    reader = WaymoV1Labels(sample.labels.record, FRONT, sample.source, points=Counting(POINTS.by_camera))
    got = _by_id(reader())
    assert got["cam-far"]["distance_m"] == 52.35 and got["cam-far"]["distance_source"] == SOURCE_POINTS
    assert got["cam-far"]["planar_depth_m"] is None and got["cam-far"]["laser_id"] is None
    assert got["cam-cyc"]["distance_source"] == SOURCE_UNKNOWN  # no point in its box
    assert got["cam-ped"]["distance_source"] == SOURCE_ASSOCIATION  # laser boxes come first
    assert Counting.calls == ["FRONT"]  # fetched once per read
    no_points = StaticPoints((("FRONT_LEFT", (), ()),))
    assert _by_id(WaymoV1Labels(reader.record, FRONT, "x", points=no_points)())[
        "cam-far"]["distance_source"] == SOURCE_UNKNOWN
    assert pickle.loads(pickle.dumps(WaymoV1Labels(reader.record, FRONT, "x", points=POINTS)))() == \
        WaymoV1Labels(reader.record, FRONT, "x", points=POINTS)()


def test_distance_from_points_near_cluster():
    box = [250, 60, 270, 70]
    assert distance_from_points(box, FAR_UV, FAR_RAY) == pytest.approx(52.35)
    assert distance_from_points(box, FAR_UV, FAR_RAY, min_points=9) is None  # 8 + 6 + 2: none has 9
    assert distance_from_points(box, FAR_UV, FAR_RAY, min_points=2) == pytest.approx(5.1)  # the stray pair
    assert distance_from_points(box, np.zeros((0, 2)), []) is None
    # pixel-edge: x0 and y0 inside, x1 and y1 outside; non-finite and ≤ 0 distances ignored
    uv = [(250, 60)] * 3 + [(270, 65), (260, 70)] * 5 + [(255, 65)] * 2
    ray = [10.0, 10.2, 10.4] + [3.0] * 10 + [np.nan, -1.0]
    assert distance_from_points(box, uv, ray, min_points=3) == pytest.approx(10.2)
    assert distance_from_points(box, uv, ray, min_points=4) is None
    with pytest.raises(ValueError, match="3 point coordinates but 2"):
        distance_from_points(box, [(1, 1)] * 3, [1.0, 2.0])


# ----------------------------------------------------------------------------- v2 = v1
@pytest.mark.parametrize("camera_name", ["int8", "string"])
def test_v2_gives_the_same_labels_as_v1(tmp_path, camera_name):
    _pyarrow()
    second = scene(T1)
    second.camera_labels[FRONT_LEFT] = []  # labelled, nothing there (v2: no camera_box rows)
    frames = [scene(T0), second]
    root = write_v2(tmp_path / "training", frames, camera_name=camera_name)
    v1 = waymo_v1_samples(write_v1(tmp_path / "seg.tfrecord", frames), cameras=("FRONT", "FRONT_LEFT"))
    v2 = waymo_v2_samples(root, cameras=("FRONT", "FRONT_LEFT"))
    assert [s.key for s in v2] == [s.key for s in v1]
    assert v2[3].labels() == v1[3].labels() == Labels(WAYMO_CLASSES, [])
    assert len(v2[2].labels().objects) == 7
    for a, b in zip(v1, v2):
        assert isinstance(b.labels, WaymoV2Labels)
        assert a.labels.read() == b.labels.read()
        objects = b.labels().objects  # plain Python values (JSON), not numpy scalars
        assert json.loads(json.dumps(objects)) == objects
        assert {type(v) for o in objects for v in (*o["bbox"], o["pixels"], o["class_id"], o["difficulty"])} <= {int}
        assert a.meta["extrinsic"] == b.meta["extrinsic"]
    assert v1[1].meta["extrinsic"] == E_LEFT.tolist()
    assert {type(v) for v in v2[0].labels().objects[0]["bbox"]} == {int}
    points = WaymoV2Labels(**{**vars(v2[0].labels), "points": POINTS})
    assert _by_id(pickle.loads(pickle.dumps(points))())["cam-far"]["distance_m"] == 52.35


def test_v2_missing_optional_tables(tmp_path):
    _pyarrow()
    frames = [scene(T0)]

    def front(tables):
        root = write_v2(tmp_path / "_".join(t[:4] for t in tables), frames, tables=tables)
        return _by_id(waymo_v2_samples(root)[0].labels())

    full = front(("camera_image", "camera_box", "camera_to_lidar_box_association", "lidar_box",
                  "projected_lidar_box", "camera_calibration"))
    assert full["cam-ped"]["distance_source"] == SOURCE_ASSOCIATION
    # no association table: the pedestrian is matched to its projected box instead (same laser label)
    no_assoc = front(("camera_image", "camera_box", "lidar_box", "projected_lidar_box", "camera_calibration"))
    assert no_assoc["cam-ped"]["distance_source"] == SOURCE_MATCH
    assert no_assoc["cam-ped"]["distance_m"] == full["cam-ped"]["distance_m"] == 18.768
    assert no_assoc["cam-ped-near"]["distance_source"] == SOURCE_UNKNOWN  # IoU 0.52 < 0.82: cam-ped wins
    no_proj = front(("camera_image", "camera_box", "camera_to_lidar_box_association", "lidar_box",
                     "camera_calibration"))
    assert (no_proj["cam-ped"]["distance_source"], no_proj["cam-car"]["distance_source"]) == \
        (SOURCE_ASSOCIATION, SOURCE_UNKNOWN)
    for tables in (("camera_image", "camera_box", "camera_to_lidar_box_association", "projected_lidar_box",
                    "camera_calibration"),   # no lidar_box: no 3D centres
                   ("camera_image", "camera_box", "camera_to_lidar_box_association", "lidar_box",
                    "projected_lidar_box")):  # no calibration: no extrinsic; the image gives the size
        got = front(tables)
        assert all(o["distance_m"] is None and o["distance_source"] == SOURCE_UNKNOWN for o in got.values())
        assert got["cam-cyc"]["bbox"] == [305, 85, 320, 115]
        assert [o["bbox"] for o in got.values()] == [o["bbox"] for o in full.values()]


# ----------------------------------------------------------------------------- no labels, bad labels
def test_labels_missing_is_said_clearly(tmp_path):
    plain = scene(T0)
    plain.camera_labels = {}  # an unlabelled frame (e.g. the test split)
    empty = scene(T1)
    empty.camera_labels = {FRONT: []}  # labelled, nothing there
    path = write_v1(tmp_path / "seg.tfrecord", [plain, empty])
    first, second = waymo_v1_samples(path)
    assert first.labels is None and "no camera_labels entry for FRONT" in first.meta["labels_missing"]
    assert second.labels() == Labels(WAYMO_CLASSES, []) and "labels_missing" not in second.meta
    offset, length = index_tfrecord(path)[0]
    with pytest.raises(InputError, match="no camera_labels entry for FRONT") as err:
        WaymoV1Labels(V1Record(str(path), offset, length), FRONT, f"{path}#record 0 FRONT")()
    assert err.value.source == f"{path}#record 0 FRONT"
    unlabelled = waymo_samples(path, labels=False)
    assert all(s.labels is None and "labels_missing" not in s.meta for s in unlabelled)
    assert unlabelled[0].meta["extrinsic"] == E_FRONT.tolist()  # recorded anyway


def test_v2_without_camera_box_has_no_labels(tmp_path):
    _pyarrow()
    root = write_v2(tmp_path / "validation", [scene(T0)], tables=("camera_image", "camera_calibration"))
    sample = waymo_samples(root)[0]
    expected = root / "camera_box" / f"{CONTEXT}.parquet"
    assert sample.labels is None and sample.meta["labels_missing"].startswith(f"{expected}: not found")
    assert sample.meta["extrinsic"] == E_FRONT.tolist()
    with pytest.raises(InputError, match="no 2D camera labels") as err:
        WaymoV2Labels(V2Frame(str(root), CONTEXT, T0), f"{CONTEXT}.parquet", FRONT, sample.source)()
    assert err.value.source == str(expected)


def test_malformed_label_proto_names_file_and_record(tmp_path):
    good = frame_message(scene(T0))
    bad_label = pw.varint_field(1, 7) + pw.varint_field(3, TYPE_VEHICLE)  # box as a varint
    bad = frame_message(scene(T1)) + pw.bytes_field(8, camera_labels_message(FRONT, [bad_label]))
    path = tmp_path / "seg.tfrecord"
    write_tfrecord(path, [good, bad])
    samples = waymo_v1_samples(path)
    assert samples[0].labels().objects
    with pytest.raises(InputError, match="wire type") as err:
        samples[1].labels()
    assert err.value.source.startswith(f"{path}#record 1 FRONT camera label ")
    nan_box = label_message(pw.double_field(1, float("nan")) + pw.double_field(5, 3.0), TYPE_VEHICLE, "n")
    write_tfrecord(path, [frame_message(scene(T0)) + pw.bytes_field(8, camera_labels_message(FRONT, [nan_box]))])
    with pytest.raises(InputError, match="malformed 2D box") as err:
        waymo_v1_samples(path)[0].labels()
    assert err.value.source.startswith(f"{path}#record 0 FRONT camera label ")


def test_v2_null_box_names_file_and_row(tmp_path):
    _pyarrow()
    import pyarrow.parquet as pq

    root = write_v2(tmp_path / "training", [scene(T0)])
    path = root / "camera_box" / f"{CONTEXT}.parquet"
    table = pq.read_table(path)
    column = "[CameraBoxComponent].box.center.x"
    values = table.column(column).to_pylist()
    values[2] = None
    import pyarrow as pa

    pq.write_table(table.set_column(table.schema.get_field_index(column), column, pa.array(values, pa.float64())), path)
    with pytest.raises(InputError, match="malformed 2D box") as err:
        waymo_v2_samples(root)[0].labels()
    assert err.value.source == f"{path}#row 2"


def test_laser_id_of_a_projected_id():
    assert camera_label_id(f"{lid('car')}_FRONT", "FRONT") == lid("car")
    assert camera_label_id("a_b_FRONT_LEFT", "FRONT_LEFT") == "a_b"
    assert camera_label_id("a_b_FRONT_LEFT", "FRONT") == "a_b_FRONT_LEFT"  # another camera's suffix
    assert camera_label_id(lid("car"), "FRONT") == lid("car")  # v2: already the laser id


def test_camera_enum_accepts_int_and_strings():
    assert [camera_enum(v, "s") for v in (1, np.int8(2), "3", "front_left", " SIDE_LEFT ")] == [1, 2, 3, 2, 4]
    for bad in (None, "BACK", 1.5, True):
        with pytest.raises(InputError, match="key.camera_name"):
            camera_enum(bad, "f.parquet#row 0")


def test_v1_box_without_laser_label_gets_its_distance_from_the_frames_lidar(tmp_path):
    """The wiring of the two decoders: a camera box with no laser label takes the near cluster
    of the frame's own LiDAR points (the wall fixture: a plane at x = 20 m)."""
    import waymo_lidar_fixtures as lfx
    from fogsim.io.images import encode_image
    from fogsim.readers.waymo import waymo_samples
    from fogsim.readers.waymo.lidar_geometry import camera_points
    from fogsim.readers.waymo.lidar_v1 import parse_v1_lidar
    from waymo_fixtures import Box2D, camera_label, camera_labels_message

    scene = lfx.wall_scene()
    image = encode_image(np.full((lfx.IMAGE_H, lfx.IMAGE_W, 3), 90, np.uint8), ".png")
    box = Box2D("cam-box-1", 1, cx=lfx.IMAGE_W / 2, cy=lfx.IMAGE_H / 2 + 20, length=120, width=80)
    frame = lfx.frame_msg(scene, image=image) + pw.bytes_field(8, camera_labels_message(1, [camera_label(box)]))
    path = tmp_path / "seg.tfrecord"
    write_tfrecord(path, [frame, lfx.frame_msg(scene, lfx.TIMESTAMP + 1, with_lasers=False, image=image)
                          + pw.bytes_field(8, camera_labels_message(1, [camera_label(box)]))])
    with_lidar, without = waymo_samples(path, ("FRONT",))
    (obj,) = with_lidar.labels().objects
    pts = camera_points(parse_v1_lidar(frame, "fixture"), "FRONT")
    x0, y0, x1, y1 = obj["bbox"]
    inside = (pts.uv[:, 0] >= x0) & (pts.uv[:, 0] < x1) & (pts.uv[:, 1] >= y0) & (pts.uv[:, 1] < y1)
    assert inside.sum() >= 5
    assert obj["distance_source"] == "lidar points in box (near cluster)"
    assert abs(obj["distance_m"] - float(np.median(pts.ray[inside]))) < 0.5
    (far,) = without.labels().objects  # no LiDAR in that frame: unknown, not an error
    assert far["distance_m"] is None and far["distance_source"] == "unknown"
