"""Hostile paths and documents before any schema sees them (issue 31, class 1: U1, U6).

One guard where every path enters (:func:`fogsim.io.paths.check_path_arguments`, run by the front
doors before any command) and one where every JSON text enters (:func:`fogsim.io.documents.parse_json`,
behind ``read_json``, the schema's ``load_json`` and both ``--class-map`` readers): a symlink loop
given to any flag, a document nested 100,000 deep or one larger than the bound is one line naming
the path, exit 2, no traceback, nothing written, the inputs untouched (:func:`conftest.run_hostile_case`).
"""
from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from conftest import run_hostile_case
from fogsim.errors import InputError
from test_hostile import Case, fog, good_folder

DEEP = '{"a": ' + "[" * 100_000 + "]" * 100_000 + "}"


def _loop(tmp: Path, name: str = "loop") -> Path:
    """tmp/in/<name> → tmp/in/<name>.b → tmp/in/<name>: two links that point at each other."""
    a, b = tmp / "in" / name, tmp / "in" / f"{name}.b"
    a.parent.mkdir(parents=True, exist_ok=True)
    os.symlink(b.name, a)
    os.symlink(a.name, b)
    return a


def _looped(make_argv):
    """A good folder dataset in tmp/in, a loop beside it; ``make_argv(tmp, base, loop)``."""
    def build(tmp: Path) -> list[str]:
        base = good_folder(tmp)
        return [str(a) for a in make_argv(tmp, base, _loop(tmp))]
    return build


def _deep(make_argv, name: str = "deep.json", text: str = DEEP):
    """A good folder dataset in tmp/in and tmp/in/<name> holding ``text``; ``make_argv(tmp, base, doc)``."""
    def build(tmp: Path) -> list[str]:
        base = good_folder(tmp)
        doc = tmp / "in" / name
        doc.write_text(text)
        return [str(a) for a in make_argv(tmp, base, doc)]
    return build


def _huge(make_argv):
    """tmp/in/huge.json: 65 MiB (sparse: a hole reads as zeros), above the bound on a document users write."""
    def build(tmp: Path) -> list[str]:
        base = good_folder(tmp)
        doc = tmp / "in" / "huge.json"
        with open(doc, "wb") as f:
            f.truncate(65 << 20)
        return [str(a) for a in make_argv(tmp, base, doc)]
    return build


def _fog_run_deep(tmp: Path, base: Path, doc: Path) -> list:
    """A finished labelled-less run whose fogsim_run.json is then nested 100,000 deep (a damaged run file)."""
    from fogsim.cli import main

    out = tmp / "in" / "run"
    assert main(fog(base, out)) == 0
    (out / "fogsim_run.json").write_text(DEEP)
    return fog(base, tmp / "out")[:-3] + ["--out", out, "--quiet"]


LOOP = ("symlink loop",)
LOOP_CASES = [
    Case("loop-input", _looped(lambda t, b, lp: fog(b, t / "out")[:2] + [lp] + fog(b, t / "out")[3:]), 2,
         ("{tmp}/in/loop", "--input", *LOOP)),
    Case("loop-depth", _looped(lambda t, b, lp: ["fog", "--input", b / "images", "--depth", lp, "--hfov", "50",
                                                 "--out", t / "out"]), 2, ("{tmp}/in/loop", "--depth", *LOOP)),
    Case("loop-intrinsics", _looped(lambda t, b, lp: ["fog", "--input", b / "images", "--depth", b / "depth",
                                                      "--intrinsics", lp, "--out", t / "out"]), 2,
         ("--intrinsics", *LOOP)),
    Case("loop-out", _looped(lambda t, b, lp: fog(b, lp)), 2, ("{tmp}/in/loop", "--out", *LOOP)),
    Case("loop-out-parent", _looped(lambda t, b, lp: fog(b, lp / "sub")), 2, ("{tmp}/in/loop/sub", *LOOP)),
    Case("loop-waymo", _looped(lambda t, b, lp: ["fog", "--waymo", lp, "--depth-dir", b / "depth", "--out",
                                                 t / "out"]), 2, ("--waymo", *LOOP)),
    Case("loop-waymo-depth-dir", _looped(lambda t, b, lp: ["fog", "--waymo", b, "--depth-dir", lp, "--out",
                                                           t / "out"]), 2, ("--depth-dir", *LOOP)),
    Case("loop-cityscapes", _looped(lambda t, b, lp: ["fog", "--cityscapes", lp, "--out", t / "out"]), 2,
         ("--cityscapes", *LOOP)),
    Case("loop-render-scene", _looped(lambda t, b, lp: ["render", "--scene", lp, "--out", t / "out"]), 2,
         ("--scene", *LOOP)),
    Case("loop-render-assets", _looped(lambda t, b, lp: ["render", "--assets", lp, "--out", t / "out"]), 2,
         ("--assets", *LOOP)),
    Case("loop-render-preset", _looped(lambda t, b, lp: ["render", "--preset", lp, "--out", t / "out"]), 2,
         ("--preset", *LOOP)),
    Case("loop-render-class-map", _looped(lambda t, b, lp: ["render", "--scene", b / "s.blend", "--class-map", lp,
                                                            "--out", t / "out"]), 2, ("--class-map", *LOOP)),
    Case("loop-study-dataset", _looped(lambda t, b, lp: ["study", "--dataset", lp, "--out", t / "out"]), 2,
         ("--dataset", *LOOP)),
    Case("loop-study-out", _looped(lambda t, b, lp: ["study", "--dataset", b, "--out", lp]), 2, ("--out", *LOOP)),
    Case("loop-depth-score-pred", _looped(lambda t, b, lp: ["depth", "score", "--pred", lp, "--dataset", b,
                                                            "--out", t / "out"]), 2, ("--pred", *LOOP)),
    Case("loop-fit-fog-run", _looped(lambda t, b, lp: ["fit-fog", lp, "--out", t / "out" / "p.json"]), 2,
         ("{tmp}/in/loop", *LOOP)),
    Case("loop-fit-fog-start", _looped(lambda t, b, lp: ["fit-fog", b, "--start", lp, "--out", t / "p.json"]), 2,
         ("--start", *LOOP)),
    Case("loop-ila-predict-input", _looped(lambda t, b, lp: ["ila", "predict", "--checkpoint", b / "K.json",
                                                             "--input", lp, "--out", t / "out"]), 2,
         ("--input", *LOOP)),
]

NEST = ("nest 100001 levels deep",)
DEEP_CASES = [
    Case("deep-scene-class-map", _deep(lambda t, b, d: ["render", "--scene", b / "s.blend", "--class-map", d,
                                                        "--out", t / "out"]), 2, ("deep.json", *NEST)),
    Case("deep-scene-class-map-inline", _deep(lambda t, b, d: ["render", "--scene", b / "s.blend", "--class-map",
                                                               DEEP, "--out", t / "out"]), 2,
         ("--class-map", *NEST)),
    Case("deep-preset", _deep(lambda t, b, d: ["render", "--preset", d, "--out", t / "out"]), 2,
         ("deep.json", *NEST)),
    Case("deep-intrinsics", _deep(lambda t, b, d: ["fog", "--input", b / "images", "--depth", b / "depth",
                                                   "--intrinsics", d, "--out", t / "out"]), 2,
         ("deep.json", *NEST)),
    Case("deep-scatter-params", _deep(lambda t, b, d: fog(b, t / "out", "--model", "scatter", "--scatter-params",
                                                          d)), 2, ("deep.json", *NEST)),
    Case("deep-fit-fog-start", _deep(lambda t, b, d: ["fit-fog", b, "--start", d, "--out", t / "p.json"]), 2,
         ("deep.json", *NEST)),
    Case("deep-study-class-map", _deep(lambda t, b, d: ["study", "--dataset", b, "--class-map", d, "--out",
                                                        t / "out"]), 2, ("deep.json", *NEST)),
    Case("deep-cityscapes-camera", _deep(lambda t, b, d: ["fog", "--cityscapes", t / "in" / "cs", "--out", t / "out"],
                                         name="cs/camera/val/aachen/aachen_000000_000019_camera.json"), 1,
         ("_camera.json", *NEST)),
    Case("deep-run-file", _deep(_fog_run_deep), 2, ("fogsim_run.json", *NEST)),
    Case("deep-objects", _deep(lambda t, b, d: ["render", "--preset", d, "--out", t / "out"],
                               text='{"a": ' * 5000 + "1" + "}" * 5000), 2, ("deep.json", "nest 5000 levels deep")),
    Case("preset-huge", _huge(lambda t, b, d: ["render", "--preset", d, "--out", t / "out"]), 2,
         ("huge.json", "larger than 64 MiB")),
    Case("class-map-huge", _huge(lambda t, b, d: ["study", "--dataset", b, "--class-map", d, "--out", t / "out"]), 2,
         ("huge.json", "larger than 64 MiB")),
    Case("scene-class-map-huge", _huge(lambda t, b, d: ["render", "--scene", b / "s.blend", "--class-map", d, "--out",
                                                        t / "out"]), 2, ("huge.json", "larger than 64 MiB")),
]


def _cityscapes_deep_camera(case: Case):
    """The Cityscapes case needs the Cityscapes fixture under tmp/in/cs before the deep camera file."""
    def build(tmp: Path) -> list[str]:
        from test_hostile import good_cityscapes

        good_cityscapes(tmp)
        return case.build(tmp)
    return Case(case.id, build, case.code, case.says)


DEEP_CASES = [_cityscapes_deep_camera(c) if c.id == "deep-cityscapes-camera" else c for c in DEEP_CASES]
CASES = LOOP_CASES + DEEP_CASES


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_hostile_path_or_document(case: Case, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    err = run_hostile_case(case, tmp_path, capsys)
    assert "RecursionError" not in err and "RuntimeError" not in err
    assert len(err.strip().splitlines()) == 1 if case.code == 2 else True, err
    if case.code == 2:
        assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir()), "a usage error wrote output"
        assert not (tmp_path / "p.json").exists()


def test_json_depth_counts_brackets_outside_strings_only():
    from fogsim.io.documents import MAX_JSON_DEPTH, json_depth, parse_json

    doc = [["a\\", ['"[', [[]]], {"k": "]]]}}}"}]] * 60  # escaped quotes and backslashes, brackets in strings
    assert json_depth(json.dumps(doc)) == 5
    assert json_depth("[" * 5000) == 5000
    assert json_depth('[' * 3 + ']' * 3) == 3  # few brackets: the count is the answer
    assert parse_json(json.dumps(doc), "x") == doc
    nested = "[" * MAX_JSON_DEPTH + "]" * MAX_JSON_DEPTH
    assert parse_json(nested, "x")  # at the bound: decoded
    with pytest.raises(InputError, match=r"^x: not readable as JSON: arrays/objects nest 101 levels deep"):
        parse_json("[" + nested + "]", "x")
    with pytest.raises(InputError, match=r"^x: not readable as JSON \(not UTF-8"):
        parse_json(b'{"a": "\xff"}', "x")


def test_read_bounds_the_bytes_it_reads(tmp_path):
    from fogsim.io.documents import read_json, read_text_bounded

    (tmp_path / "big.json").write_text("[" + "0," * 600 + "0]")
    assert len(read_json(tmp_path / "big.json")) == 601
    with pytest.raises(InputError, match=r"big\.json: the JSON file is larger than 1000 bytes"):
        read_json(tmp_path / "big.json", max_bytes=1000)
    with pytest.raises(InputError, match="is a folder"):
        read_text_bounded(tmp_path, 10)


def test_resolve_path_names_a_loop(tmp_path):
    from fogsim.io.paths import resolve_path

    os.symlink("b", tmp_path / "a")
    os.symlink("a", tmp_path / "b")
    with pytest.raises(InputError, match=r"/a: --out is, or passes through, a symlink loop"):
        resolve_path(tmp_path / "a", "--out")
    assert resolve_path(tmp_path / "c") == tmp_path.resolve() / "c"
