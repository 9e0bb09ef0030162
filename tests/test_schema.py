"""The schema layer (:mod:`fogsim.schema`): one declared pydantic model per document, one line
per failure — ``SOURCE: FIELD.PATH: problem (got VALUE)`` — and the published preset JSON Schema."""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fogsim.errors import InputError
from fogsim.presets import SCHEMA_FILE, names, presets_dir
from fogsim.schema.base import Closed, Int, Number, Open, check, load_json, load_npz, one_line
from fogsim.schema.presets import DatasetPreset, FogModel, Lighting, Volumetric, preset_json_schema

ROOT = Path(__file__).resolve().parents[1]


class Doc(Closed):
    count: Int
    size: Number = 1.0


class Loose(Open):
    count: Int


# ----------------------------------------------------------------------------- the mechanism
@pytest.mark.parametrize("value, ok", [(3, 3), (3.0, 3), (2.9, None), ("3", None), (True, None), (None, None),
                                       (float("nan"), None), (float("inf"), None)])
def test_integers_are_json_integers_and_3_0_is_3(value, ok):
    if ok is not None:
        got = check({"count": value}, Doc, "d.json").count
        assert got == ok and type(got) is int
    else:
        with pytest.raises(InputError, match=r"^d\.json: count: must be an integer \(got "):
            check({"count": value}, Doc, "d.json")


@pytest.mark.parametrize("value", ["1.5", float("nan"), float("-inf"), False, [1.0]])
def test_numbers_are_finite_numbers(value):
    with pytest.raises(InputError, match=r"^d\.json: size: must be a finite number \(got "):
        check({"count": 1, "size": value}, Doc, "d.json")


def test_closed_refuses_unknown_keys_open_ignores_them():
    with pytest.raises(InputError, match=r"^d\.json: unknown key \['cuont'\] \(allowed: \['count', 'size'\]\)$"):
        check({"count": 1, "cuont": 2}, Doc, "d.json")
    assert check({"count": 1, "added_by_a_newer_fogsim": 2}, Loose, "d.json").count == 1


@pytest.mark.parametrize("doc, line", [
    ([], "d.json: must be a JSON object (got [])"),
    ("text", "d.json: must be a JSON object (got 'text')"),
    ({}, "d.json: lacks 'count'"),
])
def test_the_trials_shapes_give_one_line(doc, line):
    with pytest.raises(InputError) as err:
        check(doc, Doc, "d.json")
    assert str(err.value) == line


def test_no_source_is_a_value_error_naming_the_field():
    with pytest.raises(ValueError, match=r"^count: must be an integer \(got 'x'\)$"):
        check({"count": "x"}, Doc)


def test_one_line_names_the_nested_field_path():
    from pydantic import ValidationError

    try:
        FogModel.model_validate({"volumetric": {"g": 5}})
    except ValidationError as exc:
        assert one_line(exc, "fog_model") == "fog_model.volumetric.g: must be a number in [-0.99, 0.99] (got 5)"
    else:
        pytest.fail("not refused")


def test_a_union_reports_the_branch_the_type_selects():
    """``airlight`` is a number or [R, G, B]: a list is judged as RGB only, a number as a number."""
    for value, line in (([1, 2], "fog_model.airlight: must be a [R, G, B] list, got 2 item(s)"),
                        ([1, 2, 300], "fog_model.airlight[2]: must be a number in [0, 255] (got 300)"),
                        ("white", "fog_model.airlight: must be a finite number (got 'white')")):
        with pytest.raises(ValueError) as err:
            check({"airlight": value}, FogModel, prefix="fog_model")
        assert str(err.value) == line


def test_load_json_names_the_file(tmp_path):
    p = tmp_path / "x.json"
    p.write_text("{not json")
    with pytest.raises(InputError, match="x.json: not readable as JSON"):
        load_json(p, Doc)
    p.write_text('{"count": "two"}')
    with pytest.raises(InputError, match=r"x.json: count: must be an integer \(got 'two'\)"):
        load_json(p, Doc)


class Arrays(Open):
    model_config = {"arbitrary_types_allowed": True}
    width: object


def test_load_npz_never_unpickles_and_names_a_damaged_file(tmp_path):
    good = tmp_path / "good.npz"
    np.savez(good, width=np.int64(320))
    assert int(load_npz(good, Arrays).width) == 320
    half = tmp_path / "half.npz"
    half.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    with pytest.raises(InputError, match=r"half.npz: not a readable .npz \(truncated or not a zip"):
        load_npz(half, Arrays)
    text = tmp_path / "text.npz"
    text.write_text("hello")
    with pytest.raises(InputError, match="text.npz: not a readable .npz"):
        load_npz(text, Arrays)
    pickled = tmp_path / "pickled.npz"
    np.savez(pickled, width=np.array([{"a": 1}], dtype=object))
    with pytest.raises(InputError, match="pickled.npz: holds pickled"):
        load_npz(pickled, Arrays)


# ----------------------------------------------------------------------------- presets
def test_every_bundled_preset_and_component_is_valid():
    for name in names():
        check(json.loads((presets_dir() / f"{name}.json").read_text()), DatasetPreset, name)
    assert "preset.schema" not in names()


def test_defaults_live_in_the_schema():
    from fogsim.render.fog_settings import VOLUMETRIC_DEFAULTS
    from fogsim.scene.lights import NIGHT

    assert VOLUMETRIC_DEFAULTS == Volumetric().model_dump() and VOLUMETRIC_DEFAULTS["g"] == 0.85
    assert NIGHT == Lighting.night_defaults() and NIGHT["sky_strength"] == 0.01
    d = check({"style": "urban-canyon", "camera": "waymo-front", "quality": "draft"}, DatasetPreset)
    assert (d.frames, d.seed, d.fog, d.exposure, d.train_fraction) == (8, 0, "paper", 1.0, 0.8)


def test_the_shipped_json_schema_is_the_generated_one():
    """``fogsim schema preset`` writes fogsim/presets/preset.schema.json; regenerate it after a schema change."""
    shipped = json.loads(SCHEMA_FILE.read_text())
    assert shipped == json.loads(json.dumps(preset_json_schema())), \
        "run: python -m fogsim schema preset --out fogsim/presets/preset.schema.json"
    r = subprocess.run([sys.executable, "-m", "fogsim", "schema", "preset"], capture_output=True, text=True,
                       cwd=ROOT, timeout=120)
    assert r.returncode == 0 and r.stdout == SCHEMA_FILE.read_text(), r.stderr
    assert shipped["properties"]["frames"] == {"default": 8, "minimum": 1, "maximum": 1_000_000, "title": "Frames",
                                               "type": "integer"}
    assert shipped["additionalProperties"] is False and "$schema" in shipped["properties"]


def test_the_bundled_presets_validate_against_the_json_schema():
    jsonschema = pytest.importorskip("jsonschema")
    schema = json.loads(SCHEMA_FILE.read_text())
    for name in names():
        jsonschema.validate(json.loads((presets_dir() / f"{name}.json").read_text()), schema)
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate({"style": "x", "camera": "y", "quality": "z", "frames": 0}, schema)
