"""The BEV study's parts without a detector (``fogsim.detection.bev``): the grid and its rasters against
hand-built scans, the rotated-box labels against the 3D boxes the fixture placed, the rotated IoU, the
scores against hand-computed cases, the LiDAR fog model passed through to the fog spec, resuming, and the
command line's usage errors. Fast tier: no Ultralytics (tests/test_bev_study.py trains)."""
import json
import math

import cv2
import numpy as np
import pytest

import kitti_tree as kt
from fogsim.cli import main
from fogsim.detection.bev.boxes import obb_line, rotated_iou, yaw_box
from fogsim.detection.bev.build import BevLayout, Variant, build_variant, decode_raster
from fogsim.detection.bev.evaluate import ap_r40, distance_bins, evaluate_level
from fogsim.detection.bev.grid import BevGrid, lidar_raster, radar_raster
from fogsim.detection.bev.source import LidarLevels
from fogsim.errors import InputError
from fogsim.fog.engine import FogSettings
from fogsim.lidar.fog import lidar_fog_spec
from fogsim.lidar.rays import empty_rays
from fogsim.runs import level_seed

GRID = BevGrid.for_image(200)  # 0–50 m × ±25 m in 0.25 m cells


# ----------------------------------------------------------------------------- the grid
def test_the_grid_is_the_scene_from_above_forward_up_left_left():
    assert (GRID.width, GRID.height, GRID.cell) == (200, 200, 0.25)
    row, col = GRID.cells(np.array([[49.9, 24.9], [0.1, -24.9], [10.1, 0.1]]))
    assert row.tolist() == [0, 199, 159] and col.tolist() == [0, 199, 99]  # far-left top-left, near-right bottom-right
    xy = np.array([[12.3, -4.56], [0.0, 24.0]])
    assert np.allclose(GRID.to_metres(GRID.to_pixels(xy)), xy)
    assert GRID.inside(np.array([[0.0, -25.0], [50.0, 0.0], [10.0, 25.0], [-0.01, 0.0]])).tolist() == \
        [True, False, False, False]
    with pytest.raises(ValueError, match="low < high"):
        BevGrid((10.0, 0.0))


def test_a_box_of_points_lands_in_the_cells_under_it():
    """An 8 × 4-cell block of points, three heights and intensities per cell, at x 10–12 m, y 2–3 m."""
    i, j = np.meshgrid(np.arange(8), np.arange(4), indexing="ij")
    x, y = 10.125 + 0.25 * i.ravel(), 2.125 + 0.25 * j.ravel()
    z = np.array([-1.5, -1.0, -0.6])
    xyz = np.concatenate([np.stack([x, y, np.full_like(x, zk)], 1) for zk in z])
    intensity = np.concatenate([np.full(len(x), v) for v in (0.2, 0.7, 0.4)])
    far = np.array([[60.0, 0, -1], [20.0, 30, -1], [-1.0, 0, -1], [20.0, 0, 1.5], [20.0, 0, -3.0]])  # off the grid
    raster = lidar_raster(GRID, np.vstack([xyz, far]), np.concatenate([intensity, [1.0] * 5]))
    rows, cols = np.nonzero(raster[..., 2])
    assert set(zip(rows.tolist(), cols.tolist())) == {(r, c) for r in range(152, 160) for c in range(88, 92)}
    block = raster[152:160, 88:92]
    assert (block[..., 0] == round(1 + 254 * (-0.6 + 2.73) / 4.0)).all()  # the highest point, over −2.73…1.27 m
    assert (block[..., 1] == round(255 * 0.7)).all()                        # the brightest
    assert (block[..., 2] == round(255 * math.log(4) / math.log(64))).all()  # three points of 64
    assert (raster[..., 0] > 0).sum() == 32 and (raster[..., 1] > 0).sum() == 32


def test_radar_detections_are_discs_and_the_strongest_wins():
    xyz = np.array([[20.0, 0.0, 0.3], [20.5, 0.0, 0.3], [40.0, -10.0, 0.0]])
    raster = radar_raster(GRID, xyz, np.array([10.0, -5.0, 40.0]), np.array([-5.0, 3.0, 0.0]))
    rows, cols = np.mgrid[0:GRID.height, 0:GRID.width]
    centres = GRID.to_metres(np.stack([cols.ravel() + 0.5, rows.ravel() + 0.5], 1)).reshape(GRID.height, GRID.width, 2)
    near = [np.hypot(*(centres - p[:2]).transpose(2, 0, 1)) <= 1.0 for p in xyz]
    assert ((raster[..., 0] > 0) == (near[0] | near[1] | near[2])).all()
    only_weak = near[1] & ~near[0]
    assert (raster[..., 0][near[0]] == round(1 + 254 * 30 / 60)).all()   # 10 dBsm over −20…40, drawn last
    assert (raster[..., 1][near[0]] == round(1 + 254 * 15 / 40)).all()   # −5 m/s over −20…20
    assert (raster[..., 0][only_weak] == round(1 + 254 * 15 / 60)).all()
    assert (raster[..., 0][near[2]] == 255).all() and (raster[..., 1][near[2]] == 128).all()


# ----------------------------------------------------------------------------- boxes
def test_rotated_iou_of_hand_built_boxes():
    a = yaw_box(10, 0, 4, 2, 0.3)
    assert rotated_iou(a, a) == pytest.approx(1, abs=1e-6)
    assert rotated_iou(yaw_box(12, 0, 4, 2, 0), yaw_box(10, 0, 4, 2, 0)) == pytest.approx(1 / 3, abs=1e-6)
    assert rotated_iou(yaw_box(0, 0, 2, 2, 0), yaw_box(0, 0, 2, 2, math.pi / 2)) == pytest.approx(1, abs=1e-6)
    inter = 4 - 2 * (2 - math.sqrt(2)) ** 2  # a square and the same square turned 45°: an octagon
    assert rotated_iou(yaw_box(0, 0, 2, 2, 0), yaw_box(0, 0, 2, 2, math.pi / 4)) == \
        pytest.approx(inter / (8 - inter), abs=1e-6)
    assert rotated_iou(yaw_box(0, 0, 1, 1, 0), yaw_box(5, 5, 1, 1, 0.2)) == 0.0
    # a car turned 25° against its label: IoU below KITTI's 0.7 for cars
    assert 0.5 < rotated_iou(yaw_box(20, 0, 4, 1.8, 0), yaw_box(20, 0, 4, 1.8, math.radians(25))) < 0.7


def test_rotated_iou_of_coinciding_and_slid_boxes():
    """Boxes that (nearly) coincide score 1 — OpenCV's float32 intersectConvexConvex gave 0 or a fraction for
    about 1 such pair in 20 — and boxes slid along and across each other score the overlap computed by hand."""
    rng = np.random.default_rng(7)
    for k in range(400):
        x, y = rng.uniform(5, 48), rng.uniform(-20, 20)
        yaw = rng.uniform(-math.pi, math.pi) if k % 2 else rng.choice([0.0, math.pi / 2, -math.pi / 2, math.pi])
        a = yaw_box(x, y, 4.0, 1.8, yaw)
        b = yaw_box(x + rng.normal(0, 1e-7), y, 4.0, 1.8, yaw + rng.normal(0, 1e-4))
        assert rotated_iou(a, b) > 0.999 and rotated_iou(b, a) > 0.999
        d, e = rng.uniform(-4.5, 4.5), rng.uniform(-2.0, 2.0)   # slid along its length, across its width
        along, across = np.array([math.cos(yaw), math.sin(yaw)]), np.array([-math.sin(yaw), math.cos(yaw)])
        c = np.array([x, y]) + d * along + e * across
        inter = max(0.0, 4.0 - abs(d)) * max(0.0, 1.8 - abs(e))
        assert rotated_iou(a, yaw_box(*c, 4.0, 1.8, yaw)) == pytest.approx(inter / (2 * 7.2 - inter), abs=1e-9)


def test_an_obb_line_is_the_footprint_in_normalised_image_coordinates():
    corners = yaw_box(20, 5, 4, 2, 0.0)
    fields = obb_line(2, corners, GRID).split()
    assert fields[0] == "2"
    uv = np.array(fields[1:], float).reshape(4, 2) * [GRID.width, GRID.height]
    assert np.allclose(GRID.to_metres(uv), corners, atol=1e-5)
    edge = np.array(obb_line(0, yaw_box(49.5, 0, 4, 2, 0), GRID).split()[1:], float)
    assert edge.min() >= 0 and edge.max() <= 1  # over the grid's far edge: clipped for Ultralytics



# boxes of every orientation (both signs, either side of ±90°, the 45° ambiguity of Ultralytics' angle range),
# near and far, left and right, each class's size
ROUND_TRIP = [(0, 12.0, 3.0, 4.0, 1.8, 0.0), (0, 20.0, -6.0, 4.2, 1.7, math.pi / 2), (0, 31.0, 8.5, 3.9, 1.6, -2.8),
              (0, 44.0, -12.0, 4.5, 1.9, math.pi / 4), (0, 8.0, -3.0, 4.0, 1.8, 3 * math.pi / 4 + 0.01),
              (1, 15.0, 1.0, 0.9, 0.7, 1.1), (2, 26.0, -2.0, 1.8, 0.6, -0.4), (0, 37.0, 0.5, 4.0, 1.8, -math.pi / 2)]


def read_obb_line(line: str, grid: BevGrid) -> tuple[int, np.ndarray]:
    """An OBB label line back to (class id, corners in metres): Ultralytics' normalised 0–1 corners ×
    the image's width and height are pixels, which the grid turns back into the LiDAR frame."""
    fields = line.split()
    uv = np.array(fields[1:], float).reshape(4, 2) * [grid.width, grid.height]
    return int(fields[0]), grid.to_metres(uv)


@pytest.mark.parametrize("grid", [GRID, BevGrid.for_image(320), BevGrid.for_image(240, (0.0, 48.0), (-16.0, 16.0))])
def test_labels_read_back_as_predictions_score_ap_one_at_kitti_s_iou(grid):
    """GT boxes → OBB label lines → the corners read back as detections: every one a hit at 0.7 / 0.5
    (exact IoU), AP 1 per class — the labels and the scores use one convention of axes, cell edges and angle."""
    objs = [obj(x, y, ("car", "pedestrian", "cyclist")[c], length=ln, width=w, yaw=yaw)
            for c, x, y, ln, w, yaw in ROUND_TRIP]
    truth = [frame(objs)]
    dets = []
    for o, (c, *_rest) in zip(objs, ROUND_TRIP):
        cid, corners = read_obb_line(obb_line(c, np.asarray(o["corners_m"]), grid), grid)
        assert cid == c and rotated_iou(corners, np.asarray(o["corners_m"])) > 0.9999  # 6-decimal label fields
        dets.append({"image_id": "f0", "category_id": cid, "score": 0.9, "corners_m": corners.tolist()})
    cell = evaluate_level(truth, dets, "L")
    assert cell["ap_car"] == cell["ap_pedestrian"] == cell["ap_cyclist"] == cell["ap"] == pytest.approx(1.0)
    assert cell["recall_max"] == 1.0 and cell["detections"] == len(ROUND_TRIP)


def test_a_box_one_cell_off_scores_the_iou_by_hand():
    """A car label moved by one pixel of the 320-px grid (15.6 cm) — down the image (along x, its length),
    across it (along y, its width), both: IoU (l − c)/(l + c), (w − c)/(w + c), and
    (l − c)(w − c) / (2lw − (l − c)(w − c)) — the scale of what one cell costs at KITTI's 0.7."""
    grid = BevGrid.for_image(320)
    c, length, width = grid.cell, 4.0, 1.8
    assert c == pytest.approx(0.15625)
    gt = yaw_box(20.0, 3.0, length, width, 0.0)
    _, corners = read_obb_line(obb_line(0, gt, grid), grid)
    uv = grid.to_pixels(corners)
    hand = {(0, 1): (length - c) / (length + c), (1, 0): (width - c) / (width + c),
            (1, 1): (length - c) * (width - c) / (2 * length * width - (length - c) * (width - c))}
    for (du, dv), want in hand.items():
        moved = grid.to_metres(uv + [du, dv])
        assert np.allclose(moved.mean(0) - gt.mean(0), [-c * dv, -c * du])  # a pixel right is −y, down is −x
        assert rotated_iou(moved, gt) == pytest.approx(want, abs=1e-5)
    assert hand[(0, 1)] == pytest.approx(0.925, abs=1e-3) and hand[(1, 0)] == pytest.approx(0.840, abs=1e-3)
    assert hand[(1, 1)] == pytest.approx(0.781, abs=1e-3)
    # a car turned by 5° about its centre keeps 0.90: KITTI's 0.7 allows about a cell and a few degrees
    assert rotated_iou(yaw_box(20.0, 3.0, length, width, math.radians(5)), gt) == pytest.approx(0.896, abs=1e-3)


# ----------------------------------------------------------------------------- a fogged KITTI tree
@pytest.fixture(scope="module")
def kitti_fog(tmp_path_factory):
    """The KITTI fixture (three frames, one car each at a known LiDAR-frame pose) through fog --kitti --lidar."""
    base = tmp_path_factory.mktemp("bev_kitti")
    root = kt.write_kitti(base / "kitti")
    out = base / "fog"
    assert main(["fog", "--quiet", "--kitti", str(root), "--lidar", "--levels", "paper", "--out", str(out)]) == 0
    return out


def car_corners(car: kt.Car) -> np.ndarray:
    """The car's ground corners from its pose alone (not through the label or Box3D)."""
    c, s = math.cos(car.yaw), math.sin(car.yaw)
    half = [(sl * car.length / 2, sw * car.width / 2) for sl, sw in ((1, 1), (-1, 1), (-1, -1), (1, -1))]
    return np.array([[car.x + a * c - b * s, car.y + a * s + b * c] for a, b in half])


def same_rectangle(a: np.ndarray, b: np.ndarray, tol: float) -> bool:
    """Whether two corner lists are the same four points in some order."""
    return all(np.min(np.linalg.norm(b - p, axis=1)) <= tol for p in a)


def test_the_rotated_box_labels_are_the_3d_boxes_from_above(kitti_fog, tmp_path):
    src = LidarLevels(kitti_fog)
    layout = BevLayout(tmp_path / "lidar", Variant())
    build_variant(src, layout, GRID, progress=False)
    for kid, car in kt.CARS.items():
        want = car_corners(car)
        truth = json.loads(layout.truth(kid).read_text())
        (obj,) = truth["objects"]
        # the label's 2-decimal location and rotation_y: a centimetre or two
        assert obj["class"] == "car" and same_rectangle(np.array(obj["corners_m"]), want, 0.03)
        assert obj["distance_m"] == pytest.approx(math.hypot(car.x, car.y), abs=0.02)
        for lv in src.levels:
            (line,) = layout.label(lv, kid).read_text().splitlines()
            uv = np.array(line.split()[1:], float).reshape(4, 2) * [GRID.width, GRID.height]
            assert line.split()[0] == "0" and same_rectangle(GRID.to_metres(uv), want, 0.03)
        raster = decode_raster(layout.image("clear", kid))
        inside = np.zeros(raster.shape[:2], np.uint8)
        cv2.fillPoly(inside, [np.round(GRID.to_pixels(want)).astype(np.int32)], 1)
        inside = cv2.dilate(inside, np.ones((3, 3), np.uint8))  # the footprint's edge cells
        rows, cols = GRID.cells(car.surface()[:, :2])
        assert inside[rows, cols].all() and (raster[rows, cols, 2] > 0).all()  # the car's points: under its label
        assert (raster[..., 2] > 0)[inside > 0].sum() >= len(set(zip(rows, cols)))
        # the surface lies 1 mm inside the faces, the label's 2-decimal fields move them by up to a centimetre:
        # the faces on one side of each axis fall outside, the rest is counted
        assert 0.3 * len(car.surface()) <= obj["points"]["clear"] <= len(car.surface())
        assert truth["dontcare"] == [[100.0, 10.0, 121.0, 31.0]]  # KITTI's 100…120 inclusive → pixel edges


def test_points_outside_the_camera_s_view_are_cut(kitti_fog):
    src = LidarLevels(kitti_fog)
    labels = src.labels("000000")
    xyz = np.array([[10.0, 0.0, -1.0], [5.0, 20.0, -1.0], [-5.0, 0.0, -1.0], [30.0, 0.0, -1.0]])
    assert src.in_view(xyz, labels).tolist() == [True, False, False, True]


def test_another_lidar_fog_model_is_passed_to_the_fog_spec(kitti_fog, tmp_path):
    """``lidar@attenuation``: the clear scans fogged again through the fog spec with model ``attenuation``."""
    src = LidarLevels(kitti_fog)
    own = BevLayout(tmp_path / "own", Variant())
    att = BevLayout(tmp_path / "att", Variant(fog_model="attenuation"))
    soft = BevLayout(tmp_path / "soft", Variant(fog_model="soft-target"))
    for layout in (own, att, soft):
        build_variant(src, layout, GRID, seed=3, progress=False)
    kid = "000001"
    assert (decode_raster(att.image("clear", kid)) == decode_raster(own.image("clear", kid))).all()  # β = 0
    cloud, sensor = src.scan("clear", kid), src.lidar_sensor(kid)
    labels = src.labels(kid)
    for model, layout in (("attenuation", att), ("soft-target", soft)):
        fogger = FogSettings(lidar=lidar_fog_spec({"model": model})).lidar_fogger(cloud, sensor,
                                                                                  empty_rays(cloud, sensor))
        fogged = fogger(0.06, np.random.default_rng(level_seed(3, kid, "beta0.06"))).cloud
        view = src.in_view(fogged.xyz, labels)
        want = lidar_raster(GRID, fogged.xyz[view], fogged.intensity[view])
        assert (decode_raster(layout.image("beta0.06", kid)) == want).all()
    assert (decode_raster(att.image("beta0.06", kid)) != decode_raster(soft.image("beta0.06", kid))).any()


def test_a_build_resumes_and_refuses_other_parameters(kitti_fog, tmp_path):
    src = LidarLevels(kitti_fog)
    layout = BevLayout(tmp_path / "lidar", Variant())
    build_variant(src, layout, GRID, progress=False)
    stamp = layout.truth("000000").stat().st_mtime_ns
    build_variant(src, layout, GRID, progress=False)
    assert layout.truth("000000").stat().st_mtime_ns == stamp
    with pytest.raises(InputError, match="other parameters"):
        build_variant(src, layout, BevGrid.for_image(100), progress=False)


def test_lidar_radar_needs_radar_detections(kitti_fog, tmp_path):
    with pytest.raises(InputError, match="radar detections"):
        build_variant(LidarLevels(kitti_fog), BevLayout(tmp_path / "f", Variant(radar=True)), GRID, progress=False)


# ----------------------------------------------------------------------------- scores
P = [[100, 0, 0, 0], [0, 100, 0, 0], [0, 0, 1, 0]]  # a camera looking along x (u = 100·x/z… for the DontCare test)


def frame(objects, dontcare=(), fid="f0", projection=None):
    return {"id": fid, "frame": fid, "split": "val", "objects": objects, "dontcare": [list(b) for b in dontcare],
            "ground_z": -1.7, "projection": projection or P, "image_size": [400, 200]}


def obj(x, y, cls="car", scored=True, difficulty=1, points=20, length=4.0, width=1.8, yaw=0.0):
    return {"class": cls, "scored": scored, "difficulty": difficulty, "kitti_type": "Car",
            "corners_m": yaw_box(x, y, length, width, yaw).tolist(), "distance_m": math.hypot(x, y),
            "points": {"L": points}}


def det(x, y, score, cls=0, fid="f0", yaw=0.0, length=4.0, width=1.8):
    return {"image_id": fid, "category_id": cls, "score": score,
            "corners_m": yaw_box(x, y, length, width, yaw).tolist()}


def test_ap_r40_of_a_hand_computed_curve():
    # 2 objects; hit, false alarm, hit: precision 1 to recall 0.5, then 2/3 to recall 1
    assert ap_r40(np.array([0.9, 0.8, 0.7]), np.array([1.0, 1, 2]), np.array([0.0, 1, 1]), 2) == \
        pytest.approx((20 * 1 + 20 * 2 / 3) / 40)
    truth = [frame([obj(10, 0), obj(30, 5)])]
    cell = evaluate_level(truth, [det(10, 0, 0.9), det(20, -5, 0.8), det(30, 5, 0.7)], "L")
    assert cell["ap"] == pytest.approx((20 + 20 * 2 / 3) / 40) and cell["recall_max"] == 1.0
    assert cell["recall_by_distance"] == {"0-10 m": None, "10-20 m": 1.0, "20-30 m": None, "30-40 m": 1.0,
                                          "40-50 m": None}


def test_kitti_s_iou_thresholds_and_ignore_rules():
    truth = [frame([obj(10, 0), obj(20, 3, "pedestrian", length=0.8, width=0.8),
                    obj(30, -4, scored=False),                 # a Van: neighbouring class of cars
                    obj(40, 0, difficulty=3)])]                # hard: ignored at moderate
    turned = det(10, 0, 0.9, yaw=math.radians(25))            # car IoU 0.63: a miss for a car (0.7)
    ped = det(20.15, 3, 0.9, cls=1, length=0.8, width=0.8)    # IoU ≈ 0.68: a hit for a pedestrian
    van = det(30, -4, 0.95)
    hard = det(40, 0, 0.6)
    cell = evaluate_level(truth, [turned, ped, van, hard], "L", difficulty="moderate")
    assert cell["objects"] == 2 and cell["ignored_detections"] == 2
    assert cell["ap_car"] == 0.0 and cell["ap_pedestrian"] == pytest.approx(1.0) and cell["ap"] == pytest.approx(0.5)
    assert cell["ap_loose"] == pytest.approx(1.0)  # at KITTI's looser 0.5 the turned car is found
    every = evaluate_level(truth, [turned, ped, van, hard], "L", difficulty="all")
    # the hard car found after a false alarm, the near one missed: precision ½ up to recall ½
    assert every["objects"] == 3 and every["ap_car"] == pytest.approx(20 * 0.5 / 40)


def test_a_detection_in_a_dontcare_region_is_neither_hit_nor_false_alarm():
    # camera P: u = 100·x/z + 0.5 with x = the point's x … here x is depth (third row picks x), u from y
    projection = [[0, -100, 0, 0], [0, 0, -100, 0], [1, 0, 0, 0]]  # u = −100 y / x, v = −100 z / x
    region = (-30.0, -20.0, 30.0, 20.0)   # around the optical axis: u, v in ±20–30 at any depth
    truth = [frame([obj(10, 5)], dontcare=[region], projection=projection)]
    dets = [det(10, 5, 0.5), det(25, 0, 0.9), det(25, 15, 0.8)]  # the car; in the region; elsewhere
    cell = evaluate_level(truth, dets, "L")
    assert cell["ignored_detections"] == 1  # the one straight ahead
    assert cell["ap"] == pytest.approx(0.5)  # one false alarm (25, 15) outscores the hit


def test_recall_seen_counts_only_what_the_lidar_still_sees():
    truth = [frame([obj(10, 0, points=30), obj(30, 0, points=2)])]
    cell = evaluate_level(truth, [det(10, 0, 0.9)], "L")
    assert cell["recall_seen"] == 1.0 and cell["objects_seen"] == 1 and cell["recall_max"] == 0.5
    assert distance_bins(55.9) == ((0, 10), (10, 20), (20, 30), (30, 40), (40, 50), (50, 60))


# ----------------------------------------------------------------------------- the command line
@pytest.mark.parametrize("argv, says", [
    (["--sensor", "lidar", "--augment", "continuous"], "--augment: only for the camera study"),
    (["--fog-models", "soft-target,attenuation"], "--fog-models: only for --sensor lidar"),
    (["--sensor", "lidar", "--fog-models", "soft-target,nope"], "'nope'"),
    (["--sensor", "lidar", "--fog-models", "soft-target"], "at least two"),
    (["--sensor", "lidar", "--bev-grid", "0:50"], "X0:X1,Y0:Y1"),
    (["--sensor", "lidar", "--bev-grid", "50:0,-25:25"], "low < high"),
])
def test_usage_errors_are_one_line(argv, says, kitti_fog, tmp_path, capsys):
    code = main(["study", "--out", str(tmp_path / "s"), "--dataset", str(kitti_fog), *argv])
    err = capsys.readouterr().err
    assert code == 2 and says in err and "Traceback" not in err, err
    assert not (tmp_path / "s").exists()


def test_lidar_radar_on_a_dataset_without_radar_is_refused(kitti_fog, tmp_path, capsys):
    code = main(["study", "--sensor", "lidar+radar", "--dataset", str(kitti_fog), "--out", str(tmp_path / "s"),
                 "--dry-run"])
    err = capsys.readouterr().err
    assert code == 2 and "radar" in err and "Traceback" not in err, err


def test_a_dataset_without_lidar_levels_is_refused(tmp_path):
    from synthetic_dataset import make_dataset

    ds = make_dataset(tmp_path / "ds")
    with pytest.raises(InputError, match="no LiDAR levels"):
        LidarLevels(ds)



def test_the_camera_study_of_the_same_folder_is_set_beside(tmp_path):
    from fogsim.detection.bev.report import camera_table, sensors_rows

    levels = ["clear", "beta0.06"]
    bev = {row: {lv: {"ap": a, "ap_car": a + 0.05, "ap_loose": a + 0.1, "recall": a / 2} for lv, a in zip(levels, vals)}
           for row, vals in (("oracle", (0.8, 0.4)), ("mixed", (0.7, 0.6)))}
    cam = {row: {lv: {"ap50": a, "recall_all": a, "recall_by_distance": {"0-25 m": a}} for lv, a in zip(levels, vals)}
           for row, vals in (("oracle", (0.3, 0.1)), ("mixed", (0.35, 0.2)), ("clear", (0.3, 0.0)))}
    assert camera_table(tmp_path) is None
    (tmp_path / "report").mkdir()
    (tmp_path / "report" / "cross_density.json").write_text(json.dumps(cam))
    rows = sensors_rows({"lidar": bev}, camera_table(tmp_path), levels)
    assert rows["camera, own level's model: mAP@50 (2D)"] == {"clear": 0.3, "beta0.06": 0.1}
    assert rows["camera, mixed: recall"] == {"clear": 0.35, "beta0.06": 0.2}
    assert rows["lidar, mixed: BEV AP"] == {"clear": 0.7, "beta0.06": 0.6}
    assert rows["lidar, own level's model: BEV AP car"] == pytest.approx({"clear": 0.85, "beta0.06": 0.45})
    assert rows["lidar, mixed: BEV AP (loose)"] == {"clear": pytest.approx(0.8), "beta0.06": pytest.approx(0.7)}
    assert rows["lidar, own level's model: recall"] == {"clear": 0.4, "beta0.06": 0.2}
    (tmp_path / "report" / "cross_density.json").write_text(json.dumps({"oracle": {"clear": {"ap50": "high"}}}))
    with pytest.raises(InputError, match="cross_density.json"):
        camera_table(tmp_path)


def test_the_report_of_perfect_predictions_and_of_a_damaged_file(kitti_fog, tmp_path, capsys):
    """The report path without a detector: every model's predictions are the ground truth itself."""
    from fogsim.detection.bev.study import BevStudy
    from fogsim.detection.yolo import TrainConfig
    from fogsim.runs import claim_output

    out = tmp_path / "s"
    study = BevStudy(kitti_fog, out, "lidar", TrainConfig(model="yolov8n-obb.yaml", imgsz=200))
    assert study.grid == GRID
    study.prepare(progress=False)
    claim_output(study.files.study_file(), study.parameters(), what="BEV study")
    (v,) = study.variants
    truths = study.truths(v)
    perfect = [{"image_id": t["id"], "category_id": 0, "score": 0.9, "corners_m": o["corners_m"]}
               for t in truths for o in t["objects"]]
    for path in study.prediction_files():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(perfect))
    argv = ["study", "--sensor", "lidar", "--dataset", str(kitti_fog), "--out", str(out), "--report-only", "--quiet"]
    assert main(argv) == 0  # auto on real data: KITTI's moderate, which the fixture's 19-px-high car is not
    table = json.loads((out / "bev" / "report" / "cross_density_lidar.json").read_text())
    assert all(c["difficulty"] == "moderate" and c["objects"] == 0 for c in table["oracle"].values())
    argv += ["--difficulty", "all"]
    assert main(argv) == 0
    table = json.loads((out / "bev" / "report" / "cross_density_lidar.json").read_text())
    assert all(c["ap"] == 1.0 and c["ap_loose"] == 1.0 and c["recall"] == 1.0 for row in table.values()
               for c in row.values())
    md = (out / "bev" / "report" / "report.md").read_text()
    assert "| clear | **1.000** |" in md and "No camera study in this folder" in md and "**BEV AP car**" in md
    assert (out / "bev" / "report" / "lidar_ap_car_heatmap.png").is_file()
    bad = study.files.prediction(v, "mixed", "beta0.06")
    bad.write_text(json.dumps([{"image_id": "000000", "category_id": 7, "score": 0.5, "corners_m": []}]))
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "Traceback" not in err
    capsys.readouterr()
    assert main([*argv[:6], str(tmp_path / "none"), "--report-only"]) == 2
    assert "no BEV study here" in capsys.readouterr().err
