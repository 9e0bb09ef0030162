"""fogsim.io.headers: the size each format's header declares, checked against what the decoders make of the
same bytes (OpenCV for images, OpenEXR for EXR, NumPy for .npy), and the bounded .npy reader."""
from __future__ import annotations

import io

import cv2
import numpy as np
import pytest

from fogsim.errors import InputError
from fogsim.io.depth_files import write_depth
from fogsim.io.exr import write_rgb_exr
from fogsim.io.headers import exr_header, image_header, npy_header, read_npy
from fogsim.io.images import encode_image


@pytest.mark.parametrize("suffix, shape", [(suffix, shape) for suffix in (".png", ".jpg", ".bmp", ".tif", ".webp")
                                            for shape in ((24, 32, 3), (7, 5), (31, 17, 4))
                                            if not (suffix == ".jpg" and shape == (31, 17, 4))])  # JPEG: no alpha
def test_image_headers_declare_what_the_decoder_makes(suffix, shape):
    data = encode_image(np.random.default_rng(0).integers(0, 256, shape, dtype=np.uint8), suffix)
    head = image_header(data[:4096])
    decoded = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    assert (head.height, head.width) == decoded.shape[:2]
    assert head.pixels == shape[0] * shape[1]
    if suffix in (".png", ".tif", ".jpg"):  # these store the channel count they decode to
        assert head.channels == (decoded.shape[2] if decoded.ndim == 3 else 1)


def test_a_jpeg_frame_header_after_large_metadata_is_found():
    data = encode_image(np.zeros((9, 13, 3), np.uint8), ".jpg")
    app = b"\xff\xe1" + (60002).to_bytes(2, "big") + b"\0" * 60000  # an Exif-sized APP1 before the frame header
    head = image_header(data[:2] + app * 3 + data[2:])
    assert (head.kind, head.width, head.height) == ("jpeg", 13, 9)


def test_what_is_not_an_image_declares_nothing():
    assert image_header(b"") is None and image_header(b"GIF89a" + b"\0" * 20) is None
    assert image_header(b"\x89PNG\r\n\x1a\n" + b"\0" * 4) is None  # no IHDR within the bytes given
    assert image_header(b"\xff\xd8\xff\xd9") is None  # ends before a frame header


def test_exr_headers_single_and_multi_channel(tmp_path):
    write_depth(tmp_path / "d.exr", np.ones((24, 32), np.float32))
    write_rgb_exr(tmp_path / "c.exr", np.ones((10, 6, 3), np.float32))
    d, c = exr_header((tmp_path / "d.exr").read_bytes()), exr_header((tmp_path / "c.exr").read_bytes())
    assert (d.width, d.height, d.channels) == (32, 24, 1)
    assert (c.width, c.height, c.channels) == (6, 10, 3)
    assert exr_header(b"v/1\x01\x02\0\0\0name\0") is None  # a header cut short


def test_npy_header_and_bounded_read(tmp_path):
    a = np.arange(24, dtype=">f8").reshape(4, 6)
    for order, name in (("C", "c.npy"), ("F", "f.npy")):
        np.save(tmp_path / name, np.asarray(a, order=order))
        dtype, shape, fortran, offset = npy_header(tmp_path / name)
        assert (dtype, shape, fortran) == (a.dtype, (4, 6), order == "F") and offset % 64 == 0
        np.testing.assert_array_equal(read_npy(tmp_path / name), a)
    seen = []
    read_npy(tmp_path / "c.npy", lambda dtype, shape: seen.append((dtype, shape)))
    assert seen == [(a.dtype, (4, 6))]
    buf = io.BytesIO()
    np.save(buf, np.zeros(1000, np.float32))
    (tmp_path / "short.npy").write_bytes(buf.getvalue()[:200])
    with pytest.raises(InputError, match=r"short.npy: .npy header declares float32 \[1000\] \(4,000 bytes\)"):
        read_npy(tmp_path / "short.npy")
    np.save(tmp_path / "obj.npy", np.array([{}], dtype=object), allow_pickle=True)
    with pytest.raises(InputError, match="pickled"):
        npy_header(tmp_path / "obj.npy")


def test_the_render_exr_reader_refuses_a_file_longer_than_its_header_allows(tmp_path):
    from fogsim.render.exr_reader import read_exr

    write_depth(tmp_path / "d.exr", np.full((24, 32), 7.0, np.float32))
    assert float(read_exr(tmp_path / "d.exr")["Y"][3, 4]) == 7.0
    with open(tmp_path / "d.exr", "r+b") as f:  # a sparse tail: 16 GB that reading whole would allocate
        f.truncate(16 << 30)
    if (tmp_path / "d.exr").stat().st_blocks * 512 > 1 << 30:
        pytest.skip("this file system cannot make sparse files")
    with pytest.raises(InputError, match=r"d.exr: 17,179,869,184 bytes is more than its header's 32×24 × 1"):
        read_exr(tmp_path / "d.exr")
