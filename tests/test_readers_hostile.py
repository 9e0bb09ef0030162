"""Hostile inputs to the readers and decoders: every one is refused with one line naming the
file (exit 1 for one bad item, exit 2 for a bad setup), or read correctly; never a grey-filled
or silently wrong output, never a raw library message on the terminal."""
import json
import os

import cv2
import numpy as np
import pytest

from conftest import tree_digest
from fogsim.camera import Intrinsics
from fogsim.cli import main
from fogsim.errors import InputError
from fogsim.io import integrity
from fogsim.io.depth_files import read_depth_file, write_depth
from fogsim.io.images import decode_image, encode_image, read_image, write_image
from fogsim.readers.folder import find_depth, folder_samples


def _smooth(h=96, w=128, seed=0) -> np.ndarray:
    """A smooth colour image with some noise: JPEG of it spans many entropy-coded bytes."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w]
    img = np.stack([x * 2, y * 2, (x + y)], axis=2) % 256 + rng.integers(0, 30, (h, w, 3))
    return np.clip(img, 0, 255).astype(np.uint8)


def fog_args(ds, out, *extra):
    return ["fog", "--input", str(ds / "images"), "--depth", str(ds / "depth"),
            "--intrinsics", str(ds / "K.json"), "--out", str(out), "--quiet", "--levels", "0.03", *extra]


# ----------------------------------------------------------------------------- #3 damaged images
@pytest.mark.parametrize("ext", [".jpg", ".png"])
def test_truncated_image_is_an_error_not_a_grey_fill(ext):
    data = encode_image(_smooth(), ext)
    for cut in (len(data) // 2, len(data) - 2, 20):
        with pytest.raises(InputError, match="truncated") as err:
            decode_image(data[:cut], "cam.img")
        assert err.value.source == "cam.img"
    assert decode_image(data, "cam.img").shape == (96, 128, 3)


def test_png_with_a_damaged_chunk_is_refused():
    data = bytearray(encode_image(_smooth(), ".png"))
    data[len(data) // 2] ^= 0xFF  # inside IDAT
    with pytest.raises(InputError, match="CRC mismatch in its 'IDAT' chunk"):
        decode_image(bytes(data), "x.png")
    data16 = bytearray(encode_image(_smooth().astype(np.uint16) * 257, ".png"))
    with pytest.raises(InputError, match="truncated PNG"):
        decode_image(bytes(data16[:-30]), "x16.png")


def test_jpeg_with_corrupt_entropy_data_is_refused(capfd):
    """2000 zeroed bytes inside the scan: the structure is intact, libjpeg only warns ('Corrupt
    JPEG data …') and fills the rest: that warning is the error, and it is not printed."""
    data = bytearray(encode_image(_smooth(480, 640), ".jpg"))
    start = len(data) // 3
    data[start:start + 2000] = bytes(2000)
    assert integrity.encoded_image_damage(bytes(data)) is None  # structure intact: the decoder must tell
    with pytest.raises(InputError, match="corrupt image data .*Corrupt JPEG data"):
        decode_image(bytes(data), "z.jpg")
    captured = capfd.readouterr()
    assert "Corrupt JPEG" not in captured.err + captured.out


def test_valid_jpeg_variants_and_trailing_bytes_still_read():
    img, grey = _smooth(), _smooth()[:, :, 0]
    variants = [encode_image(img, ".jpg"),
                cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_PROGRESSIVE, 1])[1].tobytes(),
                cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_RST_INTERVAL, 2])[1].tobytes(),
                encode_image(img, ".jpg") + b"\0" * 64]  # padding after the end-of-image marker
    variants.append(encode_image(grey, ".jpg"))
    for data in variants:  # exactly what OpenCV decodes
        plain = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)[:, :, ::-1]
        assert np.array_equal(decode_image(data, "ok.jpg"), plain)
    assert np.array_equal(decode_image(encode_image(img, ".png"), "ok.png"), img)


def test_cli_truncated_jpeg_and_png_fail_per_image(folder_dataset, tmp_path, capfd):
    ds = folder_dataset
    rng = np.random.default_rng(1)
    for name, ext in (("c", ".jpg"), ("d", ".png")):
        write_image(ds / "images" / f"{name}{ext}", rng.integers(0, 256, (24, 32, 3), dtype=np.uint8))
        write_depth(ds / "depth" / f"{name}.exr", np.full((24, 32), 10.0, np.float32))
        full = (ds / "images" / f"{name}{ext}").read_bytes()
        (ds / "images" / f"{name}{ext}").write_bytes(full[:len(full) // 2])
    before = tree_digest(ds / "images") + tree_digest(ds / "depth")
    out = tmp_path / "out"
    assert main(fog_args(ds, out)) == 1
    err = capfd.readouterr().err
    assert "c.jpg: truncated JPEG" in err and "d.png: truncated PNG" in err
    assert "Premature end" not in err and "libpng" not in err  # no raw decoder lines
    assert (out / "beta0.03" / "a.png").is_file()
    assert not (out / "beta0.03" / "c.png").exists() and not (out / "beta0.03" / "d.png").exists()
    assert tree_digest(ds / "images") + tree_digest(ds / "depth") == before


# ----------------------------------------------------------------------------- #13 symlinked folders
def _image_and_depth(root, rel, seed):
    rng = np.random.default_rng(seed)
    write_image(root / "images" / f"{rel}.png", rng.integers(0, 256, (24, 32, 3), dtype=np.uint8))
    write_depth(root / "depth" / f"{rel}.exr", rng.uniform(2, 50, (24, 32)).astype(np.float32))


def test_symlinked_subfolders_are_followed_and_cycles_are_not(tmp_path, capsys):
    good, s = tmp_path / "good", tmp_path / "s"
    for name in ("im0", "im1", "im2"):
        _image_and_depth(good, name, len(name))
    _image_and_depth(s, "own/im0", 7)
    os.symlink(good / "images", s / "images" / "cityA")
    os.symlink(good / "depth", s / "depth" / "cityA")
    os.symlink(s / "images", s / "images" / "own" / "loop")  # a cycle: back to the root
    os.symlink(tmp_path / "nowhere", s / "images" / "dangling.png")
    samples = folder_samples(s / "images", s / "depth", intrinsics=Intrinsics.from_hfov(50, 32, 24))
    assert [x.key for x in samples] == ["cityA/im0", "cityA/im1", "cityA/im2", "own/im0"]
    assert all(os.path.isfile(x.depth.path) for x in samples)
    assert main(["fog", "--input", str(s / "images"), "--depth", str(s / "depth"), "--hfov", "50",
                 "--levels", "0.03", "--out", str(tmp_path / "o"), "--quiet"]) == 0
    assert "fogged 4 of 4" in capsys.readouterr().out
    # a folder that holds nothing but a symlink to the images
    only = tmp_path / "only"
    only.mkdir()
    os.symlink(good / "images", only / "linked")
    assert [x.key for x in folder_samples(only, None)] == ["linked/im0", "linked/im1", "linked/im2"]


# ----------------------------------------------------------------------------- #14 upper-case extensions
def test_upper_case_depth_extensions_are_found(tmp_path, capsys):
    rng = np.random.default_rng(3)
    write_image(tmp_path / "images" / "IM0.PNG", rng.integers(0, 256, (24, 32, 3), dtype=np.uint8))
    write_image(tmp_path / "images" / "sub" / "im1.Jpg", rng.integers(0, 256, (24, 32, 3), dtype=np.uint8))
    write_depth(tmp_path / "depth" / "x.exr", np.full((24, 32), 9.0, np.float32))
    (tmp_path / "depth" / "x.exr").rename(tmp_path / "depth" / "IM0.EXR")
    (tmp_path / "depth" / "sub").mkdir()
    np.save(tmp_path / "depth" / "sub" / "im1.npy", np.full((24, 32), 9.0, np.float32))
    (tmp_path / "depth" / "sub" / "im1.npy").rename(tmp_path / "depth" / "sub" / "im1.NPY")
    samples = folder_samples(tmp_path / "images", tmp_path / "depth")
    assert [os.path.basename(x.depth.path) for x in samples] == ["IM0.EXR", "im1.NPY"]
    assert find_depth(tmp_path / "depth", "IM0") == tmp_path / "depth" / "IM0.EXR"
    assert find_depth(tmp_path / "depth", "im0") is None  # the stem's case still matters
    assert main(["fog", "--input", str(tmp_path / "images"), "--depth", str(tmp_path / "depth"),
                 "--hfov", "50", "--levels", "0.03", "--out", str(tmp_path / "o"), "--quiet"]) == 0
    assert "fogged 2 of 2" in capsys.readouterr().out


# ----------------------------------------------------------------------------- #22 truncated EXR
def test_truncated_exr_gives_only_the_clean_message(folder_dataset, tmp_path, capfd):
    ds = folder_dataset
    rng = np.random.default_rng(8)
    write_depth(ds / "depth" / "a.exr", rng.uniform(2, 50, (24, 32)).astype(np.float32))
    data = (ds / "depth" / "a.exr").read_bytes()
    (ds / "depth" / "a.exr").write_bytes(data[:len(data) // 2])
    with pytest.raises(InputError, match="not a readable EXR file") as err:
        read_depth_file(ds / "depth" / "a.exr")
    assert err.value.source == str(ds / "depth" / "a.exr")
    captured = capfd.readouterr()
    assert captured.out == "" and captured.err == ""  # OpenEXR's own lines were kept off the terminal
    assert main(fog_args(ds, tmp_path / "out")) == 1
    captured = capfd.readouterr()
    lines = [line for line in (captured.out + captured.err).splitlines() if line.strip()]
    assert all(line.lstrip().startswith(("error:", "failed:", "fogged ")) for line in lines), lines
    assert any("a.exr: not a readable EXR file" in line for line in lines)


# ----------------------------------------------------------------------------- #22 #23 camera values
@pytest.mark.parametrize("field, value", [("cx", "NaN"), ("fx", "Infinity"), ("fy", "-Infinity"),
                                          ("cy", "NaN")])
def test_non_finite_intrinsics_json_is_refused_naming_it(folder_dataset, tmp_path, capsys, field, value):
    K = json.loads((folder_dataset / "K.json").read_text())
    K.pop("K")
    text = json.dumps(K).replace(f'"{field}": {K[field]}', f'"{field}": {value}')
    bad = tmp_path / "badK.json"
    bad.write_text(text)
    assert main(fog_args(folder_dataset, tmp_path / "o") + ["--intrinsics", str(bad)]) == 2
    err = capsys.readouterr().err
    assert f"{bad}: unusable intrinsics" in err and "finite" in err
    assert not (tmp_path / "o").exists()


def test_intrinsics_refuse_non_finite_values():
    with pytest.raises(ValueError, match="finite"):
        Intrinsics(float("inf"), 30.0, 15.5, 11.5, 32, 24)
    with pytest.raises(InputError, match="finite") as err:
        Intrinsics.from_dict({"K": [[30, 0, float("nan")], [0, 30, 11.5], [0, 0, 1]], "width": 32,
                              "height": 24}, "K.json")
    assert err.value.source == "K.json"
    with pytest.raises(InputError, match="malformed"):
        Intrinsics.from_dict({"fx": 30, "fy": 30, "cx": 1, "cy": 1, "width": float("inf"), "height": 24})


@pytest.mark.parametrize("where, value", [("baseline", "Infinity"), ("u0", "NaN"), ("fx", "Infinity")])
def test_non_finite_cityscapes_camera_is_refused_naming_it(cityscapes_root, tmp_path, capsys, where, value):
    cam_file = cityscapes_root / "camera" / "val" / "aachen" / "aachen_000000_000019_camera.json"
    cam = json.loads(cam_file.read_text())
    section = "extrinsic" if where == "baseline" else "intrinsic"
    cam_text = json.dumps(cam).replace(f'"{where}": {cam[section][where]}', f'"{where}": {value}')
    cam_file.write_text(cam_text)
    out = tmp_path / "o"
    assert main(["fog", "--cityscapes", str(cityscapes_root), "--levels", "0.03", "--out", str(out),
                 "--quiet"]) == 1
    err = capsys.readouterr().err
    assert f"{cam_file}: not a Cityscapes camera file" in err and "finite" in err
    assert not list(out.rglob("aachen_000000_000019_leftImg8bit.png"))  # no all-white image
    assert len(list(out.rglob("aachen_000001_000019_leftImg8bit.png"))) == 1


# ----------------------------------------------------------------------------- #25 complex depth
@pytest.mark.parametrize("dtype", [np.complex64, np.complex128, np.bool_])
def test_npy_depth_must_be_real_numbers(folder_dataset, tmp_path, capsys, dtype):
    ds = folder_dataset
    (ds / "depth" / "a.exr").unlink()
    np.save(ds / "depth" / "a.npy", np.full((24, 32), 10, dtype=dtype))
    with pytest.raises(InputError, match="real numbers") as err:
        read_depth_file(ds / "depth" / "a.npy")
    assert err.value.source == str(ds / "depth" / "a.npy")
    assert main(fog_args(ds, tmp_path / "o")) == 1
    assert f"{ds / 'depth' / 'a.npy'}: depth must hold real numbers" in capsys.readouterr().err
    assert not (tmp_path / "o" / "beta0.03" / "a.png").exists()


def test_npy_integer_and_float16_depth_still_read(tmp_path):
    for dtype in (np.uint16, np.int32, np.float16, np.float64):
        np.save(tmp_path / "d.npy", np.full((4, 5), 7, dtype=dtype))
        depth = read_depth_file(tmp_path / "d.npy")
        assert depth.dtype == np.float32 and np.all(depth == 7)


def test_read_image_of_an_empty_or_missing_file(tmp_path):
    (tmp_path / "empty.png").write_bytes(b"")
    with pytest.raises(InputError, match=r"empty \(0 bytes\)"):
        read_image(tmp_path / "empty.png")
    with pytest.raises(InputError, match="not found"):
        read_image(tmp_path / "nope.png")
