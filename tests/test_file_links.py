"""One file under two names (issue 40 item 6): :func:`fogsim.io.links.link_or_copy` makes a hard link where the
file system allows and a copy where it does not (simulated: ``os.link`` raising EXDEV), never a symbolic
link; a later write through one name never changes the other; the KITTI trees of ``fogsim fog --kitti
--lidar`` link their images and scans to the level folders', resumed runs included."""
from __future__ import annotations

import errno
import json
import os
from pathlib import Path

import numpy as np
import pytest

from fogsim.io.atomic import atomic_write_bytes
from fogsim.io.images import read_image, write_image
from fogsim.io.links import link_or_copy
from fogsim.io.parts import PART_SUFFIX


def links_work(folder: Path) -> bool:
    a, b = folder / "probe.a", folder / "probe.b"
    a.write_bytes(b"x")
    try:
        os.link(a, b)
    except OSError:
        return False
    finally:
        b.unlink(missing_ok=True)
        a.unlink()
    return True


def no_link(*args, **kwargs):
    raise OSError(errno.EXDEV, "Invalid cross-device link")


def test_a_hard_link_where_the_file_system_allows(tmp_path):
    if not links_work(tmp_path):
        pytest.skip("this file system has no hard links")
    src = tmp_path / "images" / "a.png"
    atomic_write_bytes(src, b"level image")
    dst = tmp_path / "kitti" / "image_2" / "000000.png"
    assert link_or_copy(src, dst) == "link"
    assert os.stat(src).st_ino == os.stat(dst).st_ino and os.stat(dst).st_nlink >= 2
    assert not dst.is_symlink() and dst.read_bytes() == b"level image"
    assert link_or_copy(src, dst) == "link"  # again (a resumed run): still one file, nothing left beside it
    assert os.stat(dst).st_nlink == 2 and not list(tmp_path.rglob(f"*{PART_SUFFIX}"))
    other = tmp_path / "old.png"
    atomic_write_bytes(other, b"an older frame")
    assert link_or_copy(src, other) == "link" and other.read_bytes() == b"level image"  # replaced, not written into


def test_a_copy_when_linking_fails(tmp_path, monkeypatch):
    src = tmp_path / "lidar" / "a.bin"
    atomic_write_bytes(src, b"scan bytes")
    monkeypatch.setattr(os, "link", no_link)
    dst = tmp_path / "kitti" / "velodyne" / "000000.bin"
    assert link_or_copy(src, dst) == "copy"
    assert dst.read_bytes() == b"scan bytes" and os.stat(dst).st_ino != os.stat(src).st_ino
    assert os.stat(dst).st_nlink == 1 and not list(tmp_path.rglob(f"*{PART_SUFFIX}"))


def test_a_symlinked_source_gives_a_real_file_never_a_symlink(tmp_path):
    outside = tmp_path / "outside.bin"
    outside.write_bytes(b"outside")
    src = tmp_path / "out" / "link.bin"
    src.parent.mkdir()
    src.symlink_to(outside)
    dst = tmp_path / "out" / "kitti.bin"
    link_or_copy(src, dst)
    assert not dst.is_symlink() and dst.read_bytes() == b"outside"
    planted = tmp_path / "out" / "planted.bin"  # a target that is a symlink (to the very source) is replaced
    real = tmp_path / "out" / "real.bin"
    atomic_write_bytes(real, b"real")
    planted.symlink_to(real)
    link_or_copy(real, planted)
    assert not planted.is_symlink() and planted.read_bytes() == b"real" and outside.read_bytes() == b"outside"


@pytest.mark.parametrize("linking", [True, False])
def test_rewriting_one_name_leaves_its_twin(tmp_path, monkeypatch, linking):
    if linking and not links_work(tmp_path):
        pytest.skip("this file system has no hard links")
    if not linking:
        monkeypatch.setattr(os, "link", no_link)
    src, dst = tmp_path / "a.png", tmp_path / "b.png"
    first = np.zeros((4, 5, 3), np.uint8)
    write_image(src, first)
    link_or_copy(src, dst)
    write_image(src, first + 200)  # every writer replaces the file: a new inode under the old name
    np.testing.assert_array_equal(read_image(dst), first)
    atomic_write_bytes(dst, b"rewritten twin")
    np.testing.assert_array_equal(read_image(src), first + 200)


# ----------------------------------------------------------------------------- the KITTI trees
def kitti_pairs(out: Path, levels=("clear", "beta0.06")):
    """(level file, KITTI tree file) of every image and scan."""
    for level in levels:
        for img in sorted((out / "kitti" / level / "training" / "image_2").glob("*.png")):
            frame = f"training__image_2__{img.stem}"
            yield out / "images" / level / f"{frame}.png", img
            yield out / "lidar" / level / f"{frame}.bin", out / "kitti" / level / "training" / "velodyne" / \
                f"{img.stem}.bin"


def fog(*args) -> int:
    from fogsim.cli import main

    return main(["fog", "--quiet", *map(str, args)])


def test_fog_kitti_trees_link_to_the_level_files_and_resume(tmp_path):
    import kitti_tree as kt

    if not links_work(tmp_path):
        pytest.skip("this file system has no hard links")
    root = kt.write_kitti(tmp_path / "in" / "kitti")
    out = tmp_path / "out"
    assert fog("--kitti", root, "--lidar", "--levels", "0,0.06", "--out", out) == 0
    pairs = list(kitti_pairs(out))
    assert len(pairs) == 2 * 2 * 3
    for level_file, tree_file in pairs:
        # one file: the level's and the tree's names, and an image's third in visible/images/<level>/
        links = 3 if tree_file.parent.name == "image_2" else 2
        assert os.stat(level_file).st_ino == os.stat(tree_file).st_ino and os.stat(tree_file).st_nlink == links
        assert not tree_file.is_symlink()
    before = {p: p.read_bytes() for pair in pairs for p in pair}
    # a redone frame (its meta gone) rewrites its files: still one file per pair, the same bytes
    frame = "training__image_2__000001"
    (out / "meta" / f"{frame}.json").unlink()
    assert fog("--kitti", root, "--lidar", "--levels", "0,0.06", "--out", out) == 0
    for level_file, tree_file in kitti_pairs(out):
        # one file: the level's and the tree's names, and an image's third in visible/images/<level>/
        links = 3 if tree_file.parent.name == "image_2" else 2
        assert os.stat(level_file).st_ino == os.stat(tree_file).st_ino and os.stat(tree_file).st_nlink == links
        assert level_file.read_bytes() == before[level_file] and tree_file.read_bytes() == before[tree_file]
    assert json.loads((out / "dataset.json").read_text())["frames"] == 3
    # a scan rewritten through its level name leaves the KITTI tree's as it was
    scan = out / "lidar" / "beta0.06" / f"{frame}.bin"
    atomic_write_bytes(scan, b"\0" * 16)
    assert (out / "kitti" / "beta0.06" / "training" / "velodyne" / "000001.bin").read_bytes() == before[
        out / "kitti" / "beta0.06" / "training" / "velodyne" / "000001.bin"]


def test_fog_kitti_trees_are_copies_where_links_fail(tmp_path, monkeypatch):
    import kitti_tree as kt

    real_link = os.link

    def no_link_into_the_trees(src, dst, *args, **kwargs):  # the run file's claim (a link) still works
        if "kitti" in Path(dst).relative_to(tmp_path).parts[1:]:
            no_link()
        return real_link(src, dst, *args, **kwargs)

    monkeypatch.setattr(os, "link", no_link_into_the_trees)
    root = kt.write_kitti(tmp_path / "in" / "kitti")
    out = tmp_path / "out"
    assert fog("--kitti", root, "--lidar", "--levels", "0,0.06", "--out", out) == 0
    for level_file, tree_file in kitti_pairs(out):
        assert tree_file.read_bytes() == level_file.read_bytes()
        assert os.stat(level_file).st_ino != os.stat(tree_file).st_ino and os.stat(tree_file).st_nlink == 1
