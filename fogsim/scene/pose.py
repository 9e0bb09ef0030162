"""Camera poses: the one place where world, OpenCV-camera and Blender-camera frames meet.

World: right-handed, z up, metres. OpenCV camera: x right, y down, z forward (the
``world_to_camera`` stored in every frame's metadata). Blender camera: x right, y up, looking
down its −z; its object matrix is camera→world. The two camera frames differ by a flip of
y and z: R_blender = R_opencv · diag(1, −1, −1).
"""
from __future__ import annotations

import math

import numpy as np

CV_TO_BLENDER = np.diag([1.0, -1.0, -1.0, 1.0])


def camera_to_world(position, yaw_deg: float = 0.0, pitch_deg: float = 0.0,
                    roll_deg: float = 0.0) -> np.ndarray:
    """4×4 OpenCV camera→world for a camera at ``position`` looking along +y when all angles are 0.

    yaw turns left (about world z), pitch tilts up (about the camera's x), roll about the
    viewing axis; degrees.
    """
    # OpenCV axes of a level camera looking along world +y: x → +x, y (down) → −z, z → +y
    base = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])
    y, p, r = (math.radians(a) for a in (yaw_deg, pitch_deg, roll_deg))
    Rz = np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
    Rx = np.array([[1, 0, 0], [0, math.cos(p), -math.sin(p)], [0, math.sin(p), math.cos(p)]])  # tilt up
    Rc = np.array([[math.cos(r), -math.sin(r), 0], [math.sin(r), math.cos(r), 0], [0, 0, 1]])
    M = np.eye(4)
    M[:3, :3] = Rz @ base @ Rx @ Rc
    M[:3, 3] = position
    return M


def world_to_camera(cam_to_world: np.ndarray) -> np.ndarray:
    """Invert a rigid 4×4 transform."""
    R, t = cam_to_world[:3, :3], cam_to_world[:3, 3]
    out = np.eye(4)
    out[:3, :3] = R.T
    out[:3, 3] = -R.T @ t
    return out


def blender_camera_matrix(world_to_camera_cv: np.ndarray) -> np.ndarray:
    """Blender camera object's matrix_world (camera→world) for an OpenCV world→camera."""
    return world_to_camera(np.asarray(world_to_camera_cv, float)) @ CV_TO_BLENDER


def transform(position, yaw_deg: float = 0.0, scale: float = 1.0) -> np.ndarray:
    """4×4 local→world for an object standing at ``position`` turned by ``yaw_deg`` about z."""
    y = math.radians(yaw_deg)
    M = np.eye(4)
    M[:3, :3] = scale * np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
    M[:3, 3] = position
    return M


def blender_lens(K_fx: float, K_fy: float, K_cx: float, K_cy: float, width: int, height: int,
                 sensor_width_mm: float = 36.0) -> dict:
    """Blender camera data settings (sensor fit horizontal) that reproduce the intrinsics.

    Blender centres the optical axis on the image centre, which is pixel-centre coordinate
    (W − 1)/2; shifts are fractions of the image width. Pixels must be square (fx = fy).
    """
    if not math.isclose(K_fx, K_fy, rel_tol=1e-6):
        raise ValueError(f"Blender cameras need square pixels; got fx={K_fx}, fy={K_fy}")
    return {"sensor_fit": "HORIZONTAL", "sensor_width": sensor_width_mm,
            "lens": K_fx * sensor_width_mm / width,
            "shift_x": ((width - 1) / 2.0 - K_cx) / width,
            "shift_y": (K_cy - (height - 1) / 2.0) / width}


def blender_intrinsics(lens_mm: float, sensor_width_mm: float, sensor_height_mm: float, sensor_fit: str,
                       shift_x: float, shift_y: float, width: int, height: int,
                       pixel_aspect_x: float = 1.0, pixel_aspect_y: float = 1.0) -> dict:
    """OpenCV intrinsics ``{fx, fy, cx, cy, width, height}`` of a Blender perspective camera, as
    Blender defines it (``BKE_camera_params_compute_viewplane``; Cycles agrees).

    ``sensor_fit`` "AUTO" fits the sensor *width* to the larger side (pixel aspect included),
    "HORIZONTAL" the width to the image width, "VERTICAL" the sensor *height* to the image height.
    Shifts are fractions of that fitted side (in pixels, ``viewfac``); a pixel is
    ``pixel_aspect_y / pixel_aspect_x`` times as tall as wide, so fy = fx · aspect_x / aspect_y.
    The inverse, for square pixels and horizontal fit, is :func:`blender_lens`.
    """
    ycor = pixel_aspect_y / pixel_aspect_x
    horizontal = (sensor_fit == "HORIZONTAL"
                  or (sensor_fit == "AUTO" and pixel_aspect_x * width >= pixel_aspect_y * height))
    sensor = sensor_height_mm if sensor_fit == "VERTICAL" else sensor_width_mm
    viewfac = width if horizontal else ycor * height  # the fitted side, in pixel widths
    fx = lens_mm * viewfac / sensor
    return {"fx": fx, "fy": fx / ycor, "cx": (width - 1) / 2.0 - shift_x * viewfac,
            "cy": (height - 1) / 2.0 + shift_y * viewfac / ycor, "width": int(width), "height": int(height)}


def opencv_world_to_camera(blender_matrix_world) -> np.ndarray:
    """OpenCV world→camera (4×4) of a Blender camera object's ``matrix_world`` (scale removed):
    the inverse of :func:`blender_camera_matrix`."""
    M = np.asarray(blender_matrix_world, dtype=np.float64)
    R = M[:3, :3] / np.linalg.norm(M[:3, :3], axis=0)
    cam_to_world = np.eye(4)
    cam_to_world[:3, :3], cam_to_world[:3, 3] = R, M[:3, 3]
    return world_to_camera(cam_to_world @ CV_TO_BLENDER)
