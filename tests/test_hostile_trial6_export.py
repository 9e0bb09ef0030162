"""The sixth hostile-input trial's defects of ``fogsim export nuscenes`` (``shared/notes/reliability-defects-6.md``,
D09–D12, D16, D21, D22, D24: level keys and files read back from a dataset, partial exports, an --out inside the
dataset, empty values, messages, a killed run's leftovers, empty sweeps), each as the trial reproduced it: the
exit code, one line naming the file or flag and the problem, no traceback, the inputs unchanged — and a refused
export writes nothing at all. The readers' defects: :mod:`test_hostile_trial6`; the runs':
:mod:`test_hostile_trial6_runs`.
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from conftest import HANG_S, run_sensor_case
from fogsim.cli import main
from test_hostile import Case
from test_hostile_sensors import (
    _kitti_dataset,
    radar_bytes,
)
from test_hostile_trial6 import LIDAR_SENSOR, _write_json

BAD = "n008__RADAR_FRONT__2.pcd"
#: the trial's sparse bodies: 4 GiB (under the ASCII bound of 48 characters a number for 10⁷ points)
FOUR_GB = 4 << 30


# ------------------------------------------------------------ D09–D12, D16, D21, D22, D24: export nuscenes
def _dataset(tmp: Path, radar: bool = False) -> Path:
    """tmp/in/ds: a fogged KITTI set (levels clear and beta0.06, LiDAR); ``radar``: each frame also gets a
    radar block with a nuScenes sweep per level (as a render with --radar writes them)."""
    ds = _kitti_dataset(tmp)
    if radar:
        for path in sorted((ds / "meta").glob("*.json")):
            meta = json.loads(path.read_text())
            levels = {}
            for key in ("clear", "beta0.06"):
                sweep = ds / "radar" / key / f"{meta['frame']}.pcd"
                sweep.parent.mkdir(parents=True, exist_ok=True)
                sweep.write_bytes(radar_bytes(6 if key == "clear" else 3))
                levels[key] = {"file": f"radar/{key}/{meta['frame']}.pcd"}
            meta["radar"] = {"format": "nuscenes-radar", "sensor": "ars408-lr", "levels": levels}
            path.write_text(json.dumps(meta))
    return ds


def _first_meta(ds: Path) -> tuple[Path, dict]:
    path = sorted((ds / "meta").glob("*.json"))[0]
    return path, json.loads(path.read_text())


def _edit_meta(ds: Path, edit) -> None:
    path, meta = _first_meta(ds)
    edit(meta)
    path.write_text(json.dumps(meta))


def _export_case(change=None, *flags: str, radar: bool = False, out: str = "{tmp}/out"):
    def build(tmp: Path) -> list[str]:
        ds = _dataset(tmp, radar)
        if change is not None:
            change(tmp, ds)
        return ["export", "nuscenes", str(ds), "--out", out.replace("{tmp}", str(tmp)), "--quiet", *flags]
    return build


def _meta_edit(edit):
    def change(tmp: Path, ds: Path) -> None:
        _edit_meta(ds, lambda m: edit(tmp, m))
    return change


def _key(block: str, key: str):
    return _meta_edit(lambda tmp, m: m[block]["levels"].__setitem__(key.replace("{tmp}", str(tmp)),
                                                                    m[block]["levels"].pop("beta0.06")))


def _file(block: str, level: str, file: str | None = None, make=None):
    def edit(tmp: Path, meta: dict) -> None:
        target = tmp / "in" / "outside" / ("x.pcd" if block == "radar" else "x.bin")
        if make is not None:
            make(tmp, target, meta)
        meta[block]["levels"][level]["file"] = (file or str(target)).replace("{tmp}", str(tmp))
    return _meta_edit(edit)


def _outside_copy(tmp: Path, target: Path, meta: dict) -> None:
    """A real scan / sweep outside the dataset (a copy of the frame's own)."""
    ds = tmp / "in" / "ds"
    block = "radar" if target.suffix == ".pcd" else "lidar"
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_bytes((ds / meta[block]["levels"]["clear"]["file"]).read_bytes())


def _link_out_of_the_dataset(tmp: Path, ds: Path) -> None:
    """The frame's clear scan replaced by a link to a copy outside the dataset."""
    _, meta = _first_meta(ds)
    scan = ds / meta["lidar"]["levels"]["clear"]["file"]
    outside = tmp / "in" / "outside" / "x.bin"
    outside.parent.mkdir(parents=True)
    outside.write_bytes(scan.read_bytes())
    scan.unlink()
    scan.symlink_to(outside)


def _last_meta(edit):
    def change(tmp: Path, ds: Path) -> None:
        path = sorted((ds / "meta").glob("*.json"))[-1]
        meta = json.loads(path.read_text())
        edit(meta)
        path.write_text(json.dumps(meta))
    return change


def _damage(block: str, level: str, how):
    def change(tmp: Path, ds: Path) -> None:
        _, meta = sorted(((p, json.loads(p.read_text())) for p in (ds / "meta").glob("*.json")))[-1]
        how(ds / meta[block]["levels"][level]["file"])
    return change


EXPORT = [
    # D09: level keys read back from a frame record are folder names, never paths
    Case("d09-lidar-key-traversal", _export_case(_key("lidar", "../escaped")), 2,
         ("meta/", "lidar.levels: fog level key '../escaped' may hold only")),
    Case("d09-lidar-key-absolute", _export_case(_key("lidar", "{tmp}/abs_escape")), 2,
         ("meta/", "lidar.levels: fog level key", "it names a folder")),
    Case("d09-radar-key-traversal", _export_case(_key("radar", "../escaped_radar"), radar=True), 2,
         ("meta/", "radar.levels: fog level key '../escaped_radar'")),
    Case("d09-key-dot-dot", _export_case(_key("lidar", "..")), 2, ("meta/", "fog level key '..'")),
    Case("d09-key-overwrites-another-root", _export_case(lambda t, ds: (
        (t / "in" / "nusc_real" / "samples" / "LIDAR_TOP").mkdir(parents=True),
        (t / "in" / "nusc_real" / "samples" / "LIDAR_TOP" / "000000.pcd.bin").write_bytes(b"precious"),
        _key("lidar", "{tmp}/in/nusc_real")(t, ds))), 2, ("meta/", "fog level key")),
    Case("d09-export-levels-a-path", _export_case(None, "--levels", "../x"), 2, ("fog level key '../x'",)),
    # D10: level files inside the dataset, links resolved
    Case("d10-lidar-file-absolute", _export_case(_file("lidar", "clear", make=_outside_copy)), 2,
         ("meta/", "lidar.levels.clear.file: must be a path inside the dataset")),
    Case("d10-radar-file-absolute", _export_case(_file("radar", "clear", make=_outside_copy), radar=True), 2,
         ("meta/", "radar.levels.clear.file: must be a path inside the dataset")),
    Case("d10-lidar-file-traversal", _export_case(_file("lidar", "clear", "../outside/x.bin", _outside_copy)), 2,
         ("meta/", "lidar.levels.clear.file: must be a path inside the dataset")),
    Case("d10-lidar-file-links-out", _export_case(_link_out_of_the_dataset), 2,
         ("meta/", "lidar.levels.clear.file", "outside the dataset")),
    # D11: nothing partial when a frame fails (the last frame's files: the others would be written first)
    Case("d11-missing-scan", _export_case(_damage("lidar", "beta0.06", lambda p: p.unlink())), 2,
         ("beta0.06", "not found")),
    Case("d11-truncated-scan", _export_case(_damage("lidar", "clear", lambda p: p.write_bytes(p.read_bytes()[:-3]))),
         2, ("clear", "not a whole number of 16-byte kitti records")),
    Case("d11-missing-radar", _export_case(_damage("radar", "clear", lambda p: p.unlink()), radar=True), 2,
         ("radar/clear", "not found")),
    Case("d11-meta-format-wrong", _export_case(_last_meta(lambda m: m["lidar"].update(format="nuscenes"))), 2,
         ("not a whole number of 20-byte nuscenes records",)),
    # D16: an --out inside the dataset only as a folder of its own
    Case("d16-out-in-meta", _export_case(out="{tmp}/in/ds/meta"), 2,
         ("ds/meta", "holds files that are not an earlier export (one of the dataset's own folders)")),
    Case("d16-out-below-meta", _export_case(out="{tmp}/in/ds/meta/nusc"), 2,
         ("ds/meta/nusc", "lies inside the dataset's meta/")),
    Case("d16-out-around-the-dataset", _export_case(out="{tmp}/in"), 2, ("contains the dataset",)),
    # D21, D22: empty values and the messages
    Case("d21-levels-empty", _export_case(None, "--levels", ""), 2, ("--levels names no level",)),
    Case("d22-levels-commas", _export_case(None, "--levels", ",,"), 2, ("--levels names no level",)),
    Case("d22-dataset-missing", lambda t: ["export", "nuscenes", str(t / "in" / "nope"), "--out", str(t / "out")], 2,
         ("in/nope: not found",)),
    Case("d22-dataset-is-a-file", lambda t: (t / "in").mkdir() or (t / "in" / "afile").write_text("x") and [
        "export", "nuscenes", str(t / "in" / "afile"), "--out", str(t / "out")], 2,
         ("in/afile: is a file, not a folder",)),
    Case("d22-out-is-a-file", _export_case(lambda t, ds: (t / "in" / "afile").write_text("precious"),
                                           out="{tmp}/in/afile"), 2, ("in/afile: is a file, not a folder",)),
    Case("d22-dataset-symlink-loop", lambda t: (t / "in").mkdir() or (t / "in" / "loop").symlink_to(
        t / "in" / "loop") or ["export", "nuscenes", str(t / "in" / "loop"), "--out", str(t / "out")], 2,
         ("in/loop: the dataset argument is, or passes through, a symlink loop",)),
    Case("d22-out-holds-other-files", _export_case(lambda t, ds: (t / "mine").mkdir() or (
        t / "mine" / "notes.txt").write_text("x"), out="{tmp}/mine"), 2,
         ("mine: holds files that are not an earlier",)),
]


def test_d09_nothing_is_written_outside_out(tmp_path, capsys):
    """D09: the trial's escapes (a ``..`` key, an absolute key) leave no file outside ``--out``."""
    for change in (_key("lidar", "../escaped"), _key("lidar", "{tmp}/abs_escape"), _key("radar", "../escaped_r")):
        for p in list(tmp_path.iterdir()):
            shutil.rmtree(p)
        argv = _export_case(change, radar=True)(tmp_path)
        assert main(argv) == 2
        assert sorted(p.name for p in tmp_path.iterdir()) == ["in"], capsys.readouterr().err


def test_d11_a_failed_export_leaves_the_earlier_one_whole(tmp_path, capsys):
    """D11: the first export is complete; a second, failing on its last frame, leaves it as it was (no
    sample of the failed run, its summary intact) and no hidden folder beside it."""
    from conftest import tree_digest

    ds = _dataset(tmp_path, radar=True)
    out = tmp_path / "nusc"
    assert main(["export", "nuscenes", str(ds), "--out", str(out), "--quiet"]) == 0
    before = tree_digest(out)
    _damage("lidar", "beta0.06", lambda p: p.write_bytes(p.read_bytes()[:-3]))(tmp_path, ds)
    assert main(["export", "nuscenes", str(ds), "--out", str(out), "--quiet"]) == 2
    assert tree_digest(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in", "nusc"], capsys.readouterr().err
    assert main(["export", "nuscenes", str(ds), "--out", str(tmp_path / "new"), "--quiet"]) == 2
    assert not (tmp_path / "new").exists()


def test_d11_folders_in_the_way_of_an_earlier_export_are_replaced(tmp_path):
    """D11 (EX_target_is_dir, EX_summary_is_dir): a folder where a sample or the summary goes — the export is
    written beside and replaces the earlier one whole, so the run completes (or, failing, changes nothing)."""
    ds = _dataset(tmp_path)
    out = tmp_path / "nusc"
    frame = sorted(p.stem for p in (ds / "meta").glob("*.json"))[1]
    (out / "clear" / "samples" / "LIDAR_TOP" / f"{frame}.pcd.bin").mkdir(parents=True)
    (out / "fogsim_nuscenes.json").mkdir()
    assert main(["export", "nuscenes", str(ds), "--out", str(out), "--quiet"]) == 0
    assert (out / "clear" / "samples" / "LIDAR_TOP" / f"{frame}.pcd.bin").is_file()
    assert json.loads((out / "fogsim_nuscenes.json").read_text())["samples_per_level"] == {"clear": 3, "beta0.06": 3}


def test_d16_an_out_of_its_own_inside_the_dataset_is_exported(tmp_path):
    """D16: DATASET/nuscenes (a new folder directly in it) is allowed, twice (the second replaces the first),
    and the dataset's own files are untouched."""
    from conftest import tree_digest

    ds = _dataset(tmp_path, radar=True)
    before = tree_digest(ds)
    for _ in range(2):
        assert main(["export", "nuscenes", str(ds), "--out", str(ds / "nuscenes"), "--quiet"]) == 0
    assert (ds / "nuscenes" / "fogsim_nuscenes.json").is_file()
    shutil.rmtree(ds / "nuscenes")
    assert tree_digest(ds) == before


def test_d24_a_killed_exports_leftovers_are_removed(tmp_path):
    """D24: a dead writer's ``.part`` file inside an earlier export and a killed run's hidden folder beside
    it are gone after the next export."""
    import socket

    ds = _dataset(tmp_path)
    out = tmp_path / "nusc"
    assert main(["export", "nuscenes", str(ds), "--out", str(out), "--quiet"]) == 0
    host = socket.gethostname().replace(".", "_").replace("-", "_") or "host"
    part = out / "beta0.06" / "samples" / "LIDAR_TOP" / f".000039.pcd.bin.{host}-999999999.tgvt90s0.part"
    part.write_bytes(b"half")
    staging = tmp_path / f".nusc.{host}-999999999.abc.part"
    (staging / "clear").mkdir(parents=True)
    assert main(["export", "nuscenes", str(ds), "--out", str(out), "--quiet"]) == 0
    assert not list(out.rglob("*.part")) and not staging.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in", "nusc"]


def test_d12_empty_sweeps_finalize_and_export(tmp_path, capsys):
    """D12: a level whose sweeps saw nothing (0 points: a sensor whose range reaches nothing) finalizes (shares
    of 0 points are 0, not a ZeroDivisionError) and exports (an empty sample, as the render wrote it)."""
    ds = _dataset(tmp_path)
    for path in sorted((ds / "meta").glob("*.json")):
        meta = json.loads(path.read_text())
        for entry in meta["lidar"]["levels"].values():
            (ds / entry["file"]).write_bytes(b"")
            entry["outcomes"] = {k: 0 for k in entry.get("outcomes", {"kept": 0})}
        path.write_text(json.dumps(meta))
    assert main(["fog", "--finalize-only", "--out", str(ds), "--quiet"]) == 0, capsys.readouterr().err
    report = json.loads((ds / "dataset.json").read_text())["lidar"]["outcomes"]
    assert report and all(v["points"] == 0 and set(v["shares"].values()) == {0.0} for v in report.values())
    assert main(["export", "nuscenes", str(ds), "--out", str(tmp_path / "nusc"), "--quiet"]) == 0, \
        capsys.readouterr().err
    samples = list((tmp_path / "nusc").rglob("*.pcd.bin"))
    assert samples and all(p.stat().st_size == 0 for p in samples)


@pytest.mark.blender
def test_d12_a_render_whose_sweep_sees_nothing_finalizes_and_exports(tmp_path):
    """D12 as the trial ran it: ``render --lidar near_only.json`` (max range 1.5 m: no return) writes its
    dataset (no ZeroDivisionError at finalize), ``--finalize-only`` again, and the export reads its empty
    scans."""
    import subprocess
    import sys

    from test_blender import _need_bpy

    _need_bpy()
    sensor = _write_json(tmp_path / "near_only.json", LIDAR_SENSOR | {"max_range_m": 1.5, "min_range_m": 0.5,
                                                                      "overlap_full_m": 0.0})
    out = tmp_path / "out"
    base = [sys.executable, "-m", "fogsim", "render", "--frames", "1", "--resolution", "32x24", "--samples", "1",
            "--levels", "clear,0.06", "--lidar", str(sensor), "--out", str(out), "--quiet"]
    for argv in (base, base + ["--finalize-only"]):
        res = subprocess.run(argv, capture_output=True, text=True, timeout=HANG_S)
        assert "Traceback" not in res.stderr and (out / "dataset.json").is_file(), res.stderr[-3000:]
    outcomes = json.loads((out / "dataset.json").read_text())["lidar"]["outcomes"]
    assert outcomes and all(level["points"] == 0 for level in outcomes.values())
    assert main(["export", "nuscenes", str(out), "--out", str(tmp_path / "nusc"), "--quiet"]) == 0
    assert all(p.stat().st_size == 0 for p in (tmp_path / "nusc").rglob("*.pcd.bin"))


CASES = EXPORT


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_trial6_export_case(case: Case, tmp_path, capsys, monkeypatch):
    run_sensor_case(case, tmp_path, capsys, monkeypatch)
    if case.code:
        assert not (tmp_path / "out").exists(), "a refused export wrote into --out"  # nothing partial (D11)
