"""``fogsim bench fog-physics`` without the volumetric renderer: the render commands it would run, and
its analysis on three datasets made here — a committed clear frame (commit_frame, fabricated passes:
sky over a ground 40 → 8 m, 3 % a row) and two "volumetric" copies whose linear renders are exact
linear Koschmieder × 0.35 plus noise."""
import argparse
import json
import math
import shutil

import numpy as np
import OpenEXR
import pytest

from fogsim.bench.fog_physics import analyse, linear_path, read_linear_rgb, render_commands
from fogsim.camera import Intrinsics, planar_to_ray
from fogsim.colour import srgb_to_linear
from fogsim.dataset.layout import DatasetLayout
from fogsim.fog.physics import koschmieder_linear, koschmieder_model, noisy_render
from fogsim.io.images import read_image

W, H, EXPOSURE = 96, 64, 0.35


def args(**kw):
    base = dict(frames=1, resolution="160x107", samples=16, seed=3, levels=None, gpu=False, quiet=True,
                preset="default", analyse_only=False)
    return argparse.Namespace(**(base | kw))


def test_render_commands_two_volumetric_seeds_and_one_clear(tmp_path):
    cmds = render_commands(tmp_path, args(levels="0,0.06", medium="ea"))
    assert list(cmds) == ["clear", "volumetric_seed0", "volumetric_seed1"]
    clear = cmds["clear"]
    assert "--fog" not in clear and "--fog-medium" not in clear and clear[clear.index("--preset") + 1] == "default"
    for seed, name in enumerate(("volumetric_seed0", "volumetric_seed1")):
        cmd = cmds[name]
        assert cmd[cmd.index("--fog") + 1] == "volumetric" and cmd[cmd.index("--out") + 1] == str(tmp_path / name)
        preset = json.loads((tmp_path / "presets" / f"{name}.json").read_text())
        assert preset["fog_model"]["volumetric"] == {"keep_linear": True, "noise_seed": seed, "exposure": "none",
                                                     "denoise": False}
        assert cmd[cmd.index("--fog-medium") + 1] == "ea"
        assert preset["fog_model"]["space"] == "srgb" and preset["style"] == "urban-canyon"  # the rest kept
    for cmd in cmds.values():
        i = cmd.index("render")
        assert cmd[i + 1:].count("--levels") == 1 and cmd[cmd.index("--levels") + 1] == "0,0.06"
        assert cmd[cmd.index("--resolution") + 1] == "160x107" and cmd[cmd.index("--samples") + 1] == "16"


def write_rgb_exr(path, rgb):
    path.parent.mkdir(parents=True, exist_ok=True)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    chans = {c: np.ascontiguousarray(rgb[..., i], np.float32) for i, c in enumerate("RGB")}
    with OpenEXR.File(header, chans) as f:
        f.write(str(path))


@pytest.fixture(scope="module")
def bench_dir(tmp_path_factory):
    return make_bench_dir(tmp_path_factory.mktemp("fog_physics"))


def make_bench_dir(out):
    """A fog-physics folder in ``out``: clear/ (one committed frame) and two stand-in volumetric runs."""
    from fogsim.render.frame import DescribedFrame, FramePasses, commit_frame
    from fogsim.render.preset import load_render_preset

    config = load_render_preset("default", frames=1, resolution=f"{W}x{H}", levels="0,0.06,0.12")
    rng = np.random.default_rng(0)
    rgb = np.clip(rng.normal(0.25, 0.05, (H, W, 3)), 0, 1).astype(np.float32)
    depth = np.tile(np.geomspace(40, 8, H - 12)[:, None], (1, W)).astype(np.float32)
    depth = np.vstack([np.full((12, W), np.inf, np.float32), depth])
    mask = np.zeros((H, W), np.uint16)
    commit_frame(DatasetLayout(out / "clear"), config, DescribedFrame.of(config, 0), FramePasses(rgb, depth, mask),
                 timings={"render": 0.5})
    clear = DatasetLayout(out / "clear")
    meta = json.loads(clear.meta("000000").read_text())
    ray = planar_to_ray(depth, Intrinsics.from_dict(meta["camera"]["intrinsics"]))
    lin = srgb_to_linear(read_image(clear.image("clear", "000000")).astype(np.float32) / 255)
    for seed, name in enumerate(("volumetric_seed0", "volumetric_seed1")):
        shutil.copytree(out / "clear", out / name)
        fog = DatasetLayout(out / name)
        m = json.loads(fog.meta("000000").read_text())
        m["timings_s"]["render"], m["timings_s"]["fog_render"] = 0.5, 5.5  # the clear render, then the fog ones
        fog.meta("000000").write_text(json.dumps(m))
        for lv in config.levels:
            if lv.beta > 0:
                k = koschmieder_linear(lin, ray, lv.beta, koschmieder_model("linear"))
                write_rgb_exr(linear_path(fog, lv.key, "000000"),
                              noisy_render(EXPOSURE * k, 0.1, np.random.default_rng(10 * seed + int(100 * lv.beta))))
    return out


def test_analysis_recovers_exposure_and_zero_model_error(bench_dir):
    result = analyse(bench_dir)
    assert result["labels_identical"] is True and result["frames"] == ["000000"]
    assert result["fog_over_clear_render_time"] == pytest.approx(12.0)
    assert set(result["per_beta"]) == {"0.06", "0.12"}
    for key, pb in result["per_beta"].items():
        assert pb["horizon"]["luminance_mean"] == pytest.approx(EXPOSURE, rel=0.02)
        lin = pb["models"]["linear"]
        assert lin["raw"]["all"]["bias"] < -0.2  # A = white: the stand-in fog is 0.35× as bright
        norm = lin["normalised"]
        assert abs(norm["all"]["bias"]) < 0.02 and norm["all"]["rms"] < 0.3 * norm["all"]["rms_with_noise"]
        assert pb["models"]["srgb"]["normalised"]["all"]["rms"] > 3 * norm["all"]["rms"]  # a real model error
    report = bench_dir / "report"
    md = (report / "fog_physics.md").read_text()
    assert "| 0.12 |" in md and "×12.0 the clear render" in md and "identical across the three runs: True" in md
    assert json.loads((report / "fog_physics.json").read_text())["labels_identical"] is True
    assert (report / "panels_000000.png").stat().st_size > 0


def test_front_door_analyse_only_and_a_label_mismatch(bench_dir, tmp_path, capsys):
    from fogsim.cli import main

    out = tmp_path / "b"
    shutil.copytree(bench_dir, out, ignore=shutil.ignore_patterns("report"))
    m = DatasetLayout(out / "volumetric_seed1").mask("000000")
    from fogsim.io.depth_files import read_uint16_map
    from fogsim.io.images import write_image

    mask = read_uint16_map(m)
    mask[0, 0] = 9
    write_image(m, mask)
    assert main(["bench", "fog-physics", "--out", str(out), "--analyse-only"]) == 0
    said = capsys.readouterr().out
    assert "| 0.06 |" in said and "identical across the three runs: False" in said
    assert main(["bench", "fog-physics", "--out", str(tmp_path / "none"), "--analyse-only"]) == 2


def test_read_linear_rgb_names_a_missing_channel(tmp_path):
    p = tmp_path / "x.exr"
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, {"Y": np.zeros((4, 4), np.float32)}) as f:
        f.write(str(p))
    with pytest.raises(Exception, match="no R channel"):
        read_linear_rgb(p)
    rgb = np.random.default_rng(0).uniform(0, 2, (4, 5, 3)).astype(np.float32)
    write_rgb_exr(tmp_path / "y.exr", rgb)
    assert np.array_equal(read_linear_rgb(tmp_path / "y.exr"), rgb)
    assert math.isfinite(float(rgb.sum()))
