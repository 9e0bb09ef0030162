"""Classes of a user's own Blender scene (scene mode): the ``fogsim_class`` custom property and
the ``--class-map`` of name globs. Pure Python; :mod:`fogsim.render.blender.scene_mode` walks the
scene and asks :meth:`ClassMap.direct` at each object, parent and collection.

A class map is a JSON object mapping a glob over object or collection names (``fnmatch``,
case-sensitive) to a class, e.g. ``{"Car*": "car", "People": "pedestrian", "Tree*": "tree"}``;
the first pattern in file order that matches wins. A ``fogsim_class`` property wins over the map.
Classes are fogsim's (:mod:`fogsim.scene.classes`): a labelled class gets boxes, a stuff class
(or ``"background"``) makes the object background.
"""
from __future__ import annotations

from dataclasses import dataclass
from fnmatch import fnmatchcase

from fogsim.errors import InputError
from fogsim.io.documents import MAX_DOCUMENT_BYTES, parse_json, read_text_bounded
from fogsim.scene.classes import LABELLED, STUFF

PROPERTY = "fogsim_class"
BACKGROUND = "background"
KNOWN = (*LABELLED, *STUFF, BACKGROUND)


def check_class(value, where: str) -> str:
    """``value`` as a class name, or an InputError naming ``where`` (the object, or the map file)."""
    if not isinstance(value, str) or value not in KNOWN:
        raise InputError(where, f"unknown class {value!r} (known: {', '.join(KNOWN)})")
    return value


@dataclass(frozen=True)
class ClassMap:
    """Ordered (glob, class) rules; empty = classes come from ``fogsim_class`` properties only."""

    rules: tuple[tuple[str, str], ...] = ()
    source: str = ""

    def match(self, name: str) -> str | None:
        """The class of the first rule whose glob matches ``name``, or None."""
        return next((cls for pattern, cls in self.rules if fnmatchcase(name, pattern)), None)

    def direct(self, name: str, prop, where: str) -> str | None:
        """The class an object or collection carries itself: its ``fogsim_class`` property
        (``prop``, None when unset; checked, naming ``where``), else the map's match of ``name``."""
        if prop is not None:
            return check_class(str(prop) if not isinstance(prop, str) else prop, where)
        return self.match(name)

    def to_dict(self) -> dict:
        return dict(self.rules)


def load_class_map(arg: str | None) -> ClassMap:
    """``--class-map``: a JSON file, or the JSON object itself (text starting with ``{``).

    Refused (InputError naming the file or the argument): an unreadable file, text that is not
    valid JSON, anything but an object of string → known class."""
    if not arg:
        return ClassMap()
    inline = arg.lstrip().startswith("{")
    source = "--class-map" if inline else arg
    text = arg if inline else read_text_bounded(arg, MAX_DOCUMENT_BYTES, "class map")
    data = parse_json(text, source)
    if not isinstance(data, dict) or not data:
        raise InputError(source, 'the class map must be a non-empty JSON object of name glob → class, '
                                 'e.g. {"Car*": "car"}')
    rules = []
    for pattern, cls in data.items():
        rules.append((pattern, check_class(cls, f"{source} [{pattern!r}]")))
    return ClassMap(tuple(rules), source)
