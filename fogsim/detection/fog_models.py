"""Detectors trained on post-process fog, evaluated in path-traced fog (``fogsim study
--eval-dataset``, ``docs/study.md``).

Three renders of the same scenes (same preset, seed and frames; fog alone differs):

* the study's ``--dataset``, Koschmieder fog (``fogsim render``): its ``mixed`` model is the
  row ``trained on Koschmieder fog``;
* ``--scatter-dataset``, fog kind ``scatter`` (``fogsim render --fog scatter``: the same clear
  render fogged by :mod:`fogsim.fog.scatter`, with the same labels, depth and camera): a model
  :data:`SCATTER_MODEL` trained on every level of it, as the mixed model is, is the row
  ``trained on scatter fog``;
* ``--eval-dataset``, fog path-traced by Cycles (``fogsim render --fog volumetric``, any medium
  and ``--fog-scale``): both rows are evaluated on its validation images of every level.

:func:`check_same_scenes` refuses a dataset that is not such a render of the same scenes, naming
the file that differs.
"""
from __future__ import annotations

from fogsim.dataset.layout import MIXED_MODEL, PARTS, DatasetLayout
from fogsim.dataset.reader import dataset_classes, dataset_levels, read_split
from fogsim.detection.yolo import SCATTER_MODEL
from fogsim.errors import InputError
from fogsim.io.documents import read_json

#: report row → the model whose detections on the path-traced levels it shows
ROWS = {"trained on Koschmieder fog": MIXED_MODEL, "trained on scatter fog": SCATTER_MODEL}
#: the preset keys that make the scenes (the fog model and the Cycles quality may differ)
SCENE_KEYS = ("style", "camera", "resolution", "exposure", "seed", "labels", "lighting", "assets")


def fog_kind(layout: DatasetLayout) -> str | None:
    """The fog kind a render was made with (``dataset.json``'s ``preset.fog_model.kind``,
    ``koschmieder`` when unset), None when the dataset is not a render (no preset)."""
    preset = read_json(layout.manifest()).get("preset")
    if not isinstance(preset, dict):
        return None
    fog = preset.get("fog_model") or {}
    return fog.get("kind", "koschmieder") if isinstance(fog, dict) else None


def check_same_scenes(reference: DatasetLayout, other: DatasetLayout, flag: str, kind: str) -> None:
    """Refuse ``other`` (given as ``flag``) unless it is a render with fog kind ``kind`` of the
    scenes of ``reference`` (the study's Koschmieder render): same levels (keys and β), classes,
    scene settings, frame seeds and train/val frames. An :class:`InputError` names the file."""
    levels, manifest = dataset_levels(other), other.manifest()  # the manifest's own checks first
    if fog_kind(reference) != "koschmieder":
        raise InputError(reference.manifest(), f"{flag} compares fog models on renders: --dataset must be a render "
                                               f"with Koschmieder fog, its fog is {fog_kind(reference)!r}")
    if fog_kind(other) != kind:
        raise InputError(manifest, f"{flag} must be a render with fog kind {kind!r} "
                                   f"(fogsim render --fog {kind}), its fog is {fog_kind(other)!r}")
    ref, oth = read_json(reference.manifest()), read_json(manifest)
    pairs = {"levels (key, β)": ([(lv["key"], lv.get("beta")) for lv in ref["levels"]],
                                 [(lv["key"], lv.get("beta")) for lv in oth["levels"]]),
             "classes": (dataset_classes(reference), dataset_classes(other))}
    pairs |= {f"preset {k}": (ref["preset"].get(k), oth["preset"].get(k)) for k in SCENE_KEYS}
    pairs["frame seeds"] = (ref.get("frame_seeds"), oth.get("frame_seeds"))
    for what, (want, got) in pairs.items():
        if want != got:
            raise InputError(manifest, f"{flag} is not a render of --dataset's scenes: its {what} "
                                       f"{_short(got)} differ from {_short(want)}")
    for lv in levels:
        for part in PARTS:
            if read_split(other, lv, part) != read_split(reference, lv, part):
                raise InputError(other.split_file(lv, part), f"{flag} lists other {part} frames than --dataset "
                                                             f"({reference.split_file(lv, part)})")


def _short(value, limit: int = 120) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[:limit] + " …"


def path_traced_lines(table: dict, levels: list[str], eval_root, scatter_root) -> list[str]:
    """The report's section on path-traced fog: every model (``table``: ``{model: {level: cell}}``)
    on the path-traced levels, mAP@50 / recall over every object, best of each level in bold,
    and the scatter − Koschmieder difference per level."""
    names = {model: row for row, model in ROWS.items()}
    models = [*ROWS.values(), *(m for m in table if m not in ROWS.values())]
    lines = [f"**trained on post-process fog, evaluated on path-traced fog** (`{eval_root}`, validation frames; "
             f"the scatter model is trained on every level of `{scatter_root}`, as `mixed` is on the dataset's): "
             "map50 / recall_all, best of each level in bold. The rows `trained on …` of the tables above are "
             "these, on the path-traced images (their columns are other images than the rest of the table's)", "",
             "| model | " + " | ".join(levels) + " |", "|---" * (len(levels) + 1) + "|"]
    best = {lv: max(table[m][lv]["ap50"] for m in models) for lv in levels}
    for m in models:
        cells = [(f"**{c['ap50']:.3f}**" if c["ap50"] == best[lv] else f"{c['ap50']:.3f}") + f" / {c['recall_all']:.3f}"
                 for lv, c in ((lv, table[m][lv]) for lv in levels)]
        label = f"{names[m]} (`{m}`)" if m in names else f"`{m}`"
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    k, s = ROWS["trained on Koschmieder fog"], ROWS["trained on scatter fog"]
    diff = ", ".join(f"{lv} {table[s][lv]['ap50'] - table[k][lv]['ap50']:+.3f}" for lv in levels)
    return lines + ["", f"map50 of scatter − Koschmieder training on path-traced fog: {diff}."]
