"""The render-pass EXR reader against files written by the OpenEXR library."""
import numpy as np
import OpenEXR
import pytest

from fogsim.errors import InputError
from fogsim.render.exr_reader import read_exr


def channels(rng, h=37, w=23):
    return {"ViewLayer.Combined.R": rng.random((h, w), dtype=np.float32),
            "ViewLayer.Depth.Z": rng.uniform(0, 1e10, (h, w)).astype(np.float32),
            "ViewLayer.IndexOB.X": rng.integers(0, 300, (h, w)).astype(np.float32),
            "half": rng.random((h, w)).astype(np.float16)}


@pytest.mark.parametrize("compression", [OpenEXR.NO_COMPRESSION, OpenEXR.ZIPS_COMPRESSION,
                                         OpenEXR.ZIP_COMPRESSION])
def test_single_part_matches_openexr(tmp_path, compression):
    data = channels(np.random.default_rng(1))
    data["smooth"] = np.zeros((37, 23), np.float32)  # compresses well: exercises zlib path
    path = tmp_path / "a.exr"
    # File() swaps arrays for Channels in the dict it is given: pass a copy
    OpenEXR.File({"compression": compression, "type": OpenEXR.scanlineimage}, dict(data)).write(str(path))
    got = read_exr(path)
    assert set(got) == set(data)
    for k, v in data.items():
        assert got[k].dtype == v.dtype and np.array_equal(got[k], v), k


def test_multi_part_as_blender_5_writes(tmp_path):
    rng = np.random.default_rng(2)
    parts = [OpenEXR.Part({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                          {name: arr}, name=name.rsplit(".", 1)[0])
             for name, arr in channels(rng).items()]
    path = tmp_path / "m.exr"
    OpenEXR.File(parts).write(str(path))
    got = read_exr(path)
    for name, arr in channels(np.random.default_rng(2)).items():
        assert np.array_equal(got[name], arr), name


def test_bad_files(tmp_path):
    bad = tmp_path / "bad.exr"
    bad.write_bytes(b"P6 not an exr")
    with pytest.raises(InputError, match="bad.exr.*magic"):
        read_exr(bad)
    with pytest.raises(InputError, match="nope.exr"):
        read_exr(tmp_path / "nope.exr")
