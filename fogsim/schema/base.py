"""The schema mechanism: declared pydantic v2 models, checked where a document is read, and
every failure one line ``SOURCE: FIELD.PATH: problem (got VALUE)``.

* :func:`check` validates a Python object (decoded JSON, an NPZ's arrays, a decoded record)
  against a model; :func:`load_json` reads a JSON file and checks it; :func:`load_npz` opens an
  ``.npz`` without unpickling (``allow_pickle=False``) and checks its arrays. Each raises
  :class:`~fogsim.errors.InputError` naming the source (exit 2 at the command line), or a plain
  ``ValueError`` when ``source`` is None (a command-line flag: the field's alias is the flag).
* :func:`one_line` turns a :class:`pydantic.ValidationError` into that one line: the first
  error only, its location as a dotted path (list indices in brackets), a short problem in
  words and the value that was given. A union whose branch the input's *type* selects is
  declared with :func:`by_type` (a callable :class:`pydantic.Discriminator`), so the message is
  the selected branch's complaint, not every branch's.

The value types (:data:`Int`, :data:`Number`, :func:`pair` …) hold the project's conventions:

* **Integers** are JSON integers; a float with no fractional part (``3.0``) is accepted as the
  integer 3 — JSON writers (and people) write 3.0 for 3 — but 2.9 is refused, never truncated.
  A bool is never a number; a string is never a number (``"3"`` is refused).
* **Numbers** are finite (no NaN, no ±inf); ints are accepted for floats.
* :class:`Closed` models (what users write: presets, class maps) refuse unknown keys, naming
  them and the allowed ones; :class:`Open` models (fogsim's own outputs read back) ignore keys
  they do not know, so a dataset written by a newer fogsim still resumes.
"""
from __future__ import annotations

import math
import os
import re
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, TypeVar

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Discriminator,
    Field,
    Strict,
    ValidationError,
    model_validator,
)

from fogsim.errors import InputError

__all__ = ["Bool", "Closed", "Open", "Int", "Number", "NonNegInt", "Text", "by_type", "check", "check_flag", "int_in",
           "load_json",
           "items", "word", "load_npz", "number_in", "one_line", "pair", "shape_of", "M"]

M = TypeVar("M", bound=BaseModel)


# ----------------------------------------------------------------------------- value types
class WithJsonSchema_update:  # noqa: N801  (reads as the annotation it is)
    """Adds keywords to a type's generated JSON Schema (e.g. the bounds a validator checks)."""

    def __init__(self, extra: dict):
        self.extra = extra

    def __get_pydantic_json_schema__(self, core_schema, handler):
        js = handler(core_schema)
        js.update(self.extra)
        return js


def _whole(v: Any) -> Any:
    """3.0 → 3 (a float with no fraction is an integer); anything else is left to ``int``'s check."""
    if isinstance(v, float) and math.isfinite(v) and v == int(v):
        return int(v)
    return v


#: A JSON integer (3.0 accepted as 3; 2.9, "3", true refused).
Int = Annotated[int, Strict(), BeforeValidator(_whole)]
#: A finite JSON number (int or float; not a bool, not a string).
Number = Annotated[float, Strict(), Field(allow_inf_nan=False)]
NonNegInt = Annotated[int, Strict(), BeforeValidator(_whole), Field(ge=0)]
Text = Annotated[str, Strict()]
#: JSON true or false (not 0 / 1, not "yes").
Bool = Annotated[bool, Strict()]


def _range_text(lo, hi, lo_open: bool = False, hi_open: bool = False) -> str:
    fmt = lambda x: str(x) if isinstance(x, int) else f"{x:g}"  # noqa: E731
    if lo is not None and hi is not None:
        return f"in {'(' if lo_open else '['}{fmt(lo)}, {fmt(hi)}{')' if hi_open else ']'}"
    if lo is not None:
        return f"{'>' if lo_open else '≥'} {fmt(lo)}"
    return f"{'<' if hi_open else '≤'} {fmt(hi)}"


def _bounded(what: str, lo, hi, lo_open: bool = False, hi_open: bool = False) -> list:
    """A range check whose message gives the whole range, and the JSON Schema keywords for it."""
    def inside(v):
        low = lo is not None and (v <= lo if lo_open else v < lo)
        if low or (hi is not None and (v >= hi if hi_open else v > hi)):
            raise ValueError(f"must be {what} {_range_text(lo, hi, lo_open, hi_open)}")
        return v

    js = {}
    if lo is not None:
        js["exclusiveMinimum" if lo_open else "minimum"] = lo
    if hi is not None:
        js["exclusiveMaximum" if hi_open else "maximum"] = hi
    return [AfterValidator(inside), WithJsonSchema_update(js)] if js else []


def int_in(lo: int | None = None, hi: int | None = None) -> Any:
    """An :data:`Int` in [lo, hi]."""
    return Annotated[int, Strict(), BeforeValidator(_whole), *_bounded("an integer", lo, hi)]


def number_in(lo: float | None = None, hi: float | None = None, *, lo_open: bool = False,
              hi_open: bool = False) -> Any:
    """A :data:`Number` in [lo, hi] (open at an end with ``lo_open`` / ``hi_open``)."""
    return Annotated[float, Strict(), Field(allow_inf_nan=False), *_bounded("a number", lo, hi, lo_open, hi_open)]


def word(value: str, what: str) -> Any:
    """The string ``value`` alone (a union's word branch, e.g. ``"sky"``); another string → "must be ``what``"."""
    def same(v: str) -> str:
        if v != value:
            raise ValueError(f"must be {what}")
        return v

    return Annotated[str, Strict(), AfterValidator(same), WithJsonSchema_update({"const": value})]


def _ordered(v: list) -> list:
    if v[0] > v[1]:
        raise ValueError("must be [low, high] with low ≤ high")
    return v


def items(item: Any, n: int, what: str = "") -> Any:
    """A JSON list of exactly ``n`` ``item`` values (``what`` names the form, e.g. "[width, height]")."""
    def length(v: list) -> list:
        if len(v) != n:
            raise ValueError(f"must be a {what or f'list of {n} items'}, got {len(v)} item(s)")
        return v

    return Annotated[list[item], BeforeValidator(lambda v: length(v) if isinstance(v, list) else v),
                     Field(json_schema_extra={"minItems": n, "maxItems": n})]


def pair(item: Any = Number) -> Any:
    """A ``[low, high]`` JSON list of two ``item`` values with low ≤ high (kept as a list)."""
    return Annotated[items(item, 2, "[low, high] pair"), AfterValidator(_ordered)]


def by_type(branches: dict[str, Callable[[Any], bool]], what: str) -> Discriminator:
    """A discriminator for an ``Annotated[Union[Annotated[A, Tag("<a>")], …], by_type(…)]``: the
    branch is the first whose test accepts the input's type (``{"<name>": lambda v: isinstance(v, str)}``);
    none → one error "must be ``what``". Tags are written ``<name>`` so :func:`one_line` drops them
    from the field path."""
    def pick(v: Any) -> str | None:
        for tag, test in branches.items():
            if test(v):
                return tag
        return None

    return Discriminator(pick, custom_error_type="wrong_kind", custom_error_message=f"must be {what}")


def is_object(v: Any) -> bool:
    return isinstance(v, dict) or isinstance(v, BaseModel)


def is_list(v: Any) -> bool:
    return isinstance(v, (list, tuple))


__all__ += ["is_object", "is_list"]


# ----------------------------------------------------------------------------- models
class Closed(BaseModel):
    """A document users write: unknown keys are refused (named, with the allowed ones)."""

    model_config = ConfigDict(extra="forbid", frozen=True, populate_by_name=True)

    @model_validator(mode="before")
    @classmethod
    def _known_keys(cls, data: Any) -> Any:
        if isinstance(data, dict):
            known = set()
            for name, f in cls.model_fields.items():
                known |= {name, f.alias} if f.alias else {name}
            unknown = sorted(str(k) for k in data if k not in known)
            if unknown:
                allowed = sorted(f.alias or n for n, f in cls.model_fields.items())
                raise ValueError(f"unknown key{'s' if len(unknown) > 1 else ''} {unknown} (allowed: {allowed})")
        return data

    def given(self) -> dict:
        """The keys the document gave (not the defaults), as checked (3.0 → 3), by their JSON names."""
        return self.model_dump(exclude_unset=True, by_alias=True)


class Open(BaseModel):
    """A document fogsim wrote and reads back: keys it does not know are ignored (a newer
    fogsim's additions), the keys it needs are checked."""

    model_config = ConfigDict(extra="ignore", frozen=True, populate_by_name=True)


# ----------------------------------------------------------------------------- the one line
_PROBLEM = {
    "int_type": "must be an integer", "int_from_float": "must be an integer", "int_parsing": "must be an integer",
    "float_type": "must be a finite number", "float_parsing": "must be a finite number",
    "finite_number": "must be a finite number",
    "bool_type": "must be true or false", "bool_parsing": "must be true or false",
    "string_type": "must be a string", "dict_type": "must be a JSON object", "model_type": "must be a JSON object",
    "model_attributes_type": "must be a JSON object",
    "list_type": "must be a list", "tuple_type": "must be a list", "missing": "missing (required)",
    "extra_forbidden": "unknown key", "none_required": "must be null",
}


def _loc(loc: tuple, prefix: str) -> str:
    out = prefix
    for part in loc:
        if isinstance(part, str) and part.startswith("<") and part.endswith(">"):
            continue  # a by_type tag, not a field
        if isinstance(part, int):
            out += f"[{part}]"
        elif part in ("function-after", "function-before", "function-plain", "function-wrap"):
            continue
        else:
            out += f".{part}" if out else str(part)
    return out


def _short(v: Any, limit: int = 60) -> str:
    text = repr(v)
    return text if len(text) <= limit else text[:limit - 1] + "…"


def _problem(err: dict) -> str:
    kind, ctx = err["type"], err.get("ctx") or {}
    if kind in _PROBLEM:
        return _PROBLEM[kind]
    if kind in ("greater_than_equal", "greater_than", "less_than_equal", "less_than"):
        sign = {"greater_than_equal": "≥", "greater_than": ">", "less_than_equal": "≤", "less_than": "<"}[kind]
        bound = next(iter(ctx.values()))
        return f"must be {sign} {bound:g}" if isinstance(bound, (int, float)) else f"must be {sign} {bound}"
    if kind == "literal_error":
        expected = re.findall(r"'([^']*)'", str(ctx.get("expected", "")))
        return f"must be one of {', '.join(expected) or ctx.get('expected', '')}"
    if kind in ("too_short", "too_long"):
        lo, hi = ctx.get("min_length"), ctx.get("max_length")
        if lo is not None and lo == hi:
            return f"must have {lo} items"
        return f"must have at least {ctx['min_length']} item(s)" if kind == "too_short" else \
            f"must have at most {ctx['max_length']} item(s)"
    if kind == "string_pattern_mismatch":
        return f"must match {ctx.get('pattern')}"
    msg = str(err.get("msg", kind))
    for lead in ("Value error, ", "Assertion failed, "):
        if msg.startswith(lead):
            msg = msg[len(lead):]
    return msg


def one_line(exc: ValidationError, prefix: str = "") -> str:
    """``FIELD.PATH: problem (got VALUE)`` for the first error of ``exc`` (``prefix`` is the
    path of the checked object inside its document, e.g. ``"style"``)."""
    errors = exc.errors(include_url=False)
    # what was given is checked before what is missing is reported (a wrong value is the likelier fix)
    err = next((e for e in errors if e["type"] != "missing"), errors[0])
    where, problem = _loc(tuple(err["loc"]), prefix), _problem(err)
    if err["type"] == "missing":  # every missing key of that object, in one line
        parent = tuple(err["loc"])[:-1]
        names = [e["loc"][-1] for e in errors if e["type"] == "missing" and tuple(e["loc"])[:-1] == parent]
        where = _loc(parent, prefix)
        return f"{where + ': ' if where else ''}lacks {', '.join(repr(n) for n in names)}"
    got = ""
    if err["type"] not in ("missing", "extra_forbidden") and "got " not in problem and "input" in err:
        v = err["input"]
        if not isinstance(v, (dict, BaseModel)) or err["type"] in ("model_type", "dict_type", "list_type"):
            got = f" (got {_short(v)})"
    if err["type"] == "extra_forbidden":
        where, problem = _loc(tuple(err["loc"])[:-1], prefix), f"unknown key {err['loc'][-1]!r}"
    return f"{where}: {problem}{got}" if where else f"{problem}{got}"


# ----------------------------------------------------------------------------- checking
def check(obj: Any, model: type[M], source: str | os.PathLike | None = None, prefix: str = "") -> M:
    """``obj`` as a ``model`` instance; a mismatch is an :class:`InputError` naming ``source``
    (the file, ``FILE#record N`` …), or a ``ValueError`` when ``source`` is None."""
    try:
        return model.model_validate(obj)
    except ValidationError as exc:
        line = one_line(exc, prefix)
        document = getattr(model, "document", None)  # a fogsim document's name: "malformed <it>: …"
        if isinstance(document, str):
            line = f"malformed {document}: {line}"
        if source is None:
            raise ValueError(line) from None
        raise InputError(source, line) from None


def check_flag(flag: str, value: Any, kind: Any) -> Any:
    """The command-line value ``value`` of ``flag`` checked against the value type ``kind`` (e.g.
    ``int_in(1, 1024)``): a ValueError ``--flag: must be an integer in [1, 1024] (got 5000)``, the
    schema's words, for the numbers no document holds (a worker count, an image size …)."""
    from pydantic import TypeAdapter

    try:
        return TypeAdapter(kind).validate_python(value)
    except ValidationError as exc:
        raise ValueError(one_line(exc, flag)) from None


def load_json(path: str | os.PathLike, model: type[M]) -> M:
    """Read the JSON file ``path`` and check it against ``model`` (one line naming the file; the size bound
    of :func:`fogsim.io.documents.read_json` is the smaller one for a :class:`Closed` document, which users write)."""
    from fogsim.io.documents import MAX_DOCUMENT_BYTES, MAX_JSON_BYTES, read_json

    return check(read_json(path, MAX_DOCUMENT_BYTES if issubclass(model, Closed) else MAX_JSON_BYTES), model, path)


def shape_of(a: Any) -> tuple:
    return tuple(getattr(a, "shape", ()))


#: the most bytes one member of an ``.npz`` fogsim reads may unpack to (a 10 M-point outcome file ≈ 90 MB)
MAX_NPZ_MEMBER_BYTES = 1 << 29


def _check_npz_members(path: Path) -> None:
    """Refuse an ``.npz`` member that unpacks to more than :data:`MAX_NPZ_MEMBER_BYTES`, or whose ``.npy``
    header declares more bytes than the member holds — before anything is inflated or allocated."""
    from numpy.lib import format as npf

    with zipfile.ZipFile(path) as zf:
        for info in zf.infolist():
            if info.file_size > MAX_NPZ_MEMBER_BYTES:
                raise InputError(path, f"member {info.filename} unpacks to {info.file_size:,} bytes, above the bound "
                                       f"of {MAX_NPZ_MEMBER_BYTES:,}")
            with zf.open(info) as member:
                try:
                    version = npf.read_magic(member)
                    read = npf.read_array_header_1_0 if version == (1, 0) else npf.read_array_header_2_0
                    shape, _, dtype = read(member)
                except (ValueError, EOFError, SyntaxError, TypeError):
                    continue  # np.load names the problem
                need = math.prod(shape) * dtype.itemsize
                if need > info.file_size:
                    raise InputError(path, f"member {info.filename}: its header declares {dtype} {list(shape)} "
                                           f"({need:,} bytes) but it holds only {info.file_size:,} bytes")


def load_npz(path: str | os.PathLike, model: type[M]) -> M:
    """Open an ``.npz`` without unpickling and check its arrays against ``model`` (each field an
    array or a 0-d scalar, see the model). A truncated, non-zip or pickled file, or one whose
    member does not decode, is one line naming the file; a member's size is bounded before it is
    read (:func:`_check_npz_members`)."""
    import numpy as np

    path = Path(path)
    try:
        with open(path, "rb") as f:
            magic = f.read(4)
        if magic != b"PK\x03\x04":  # np.load would take any other file for a pickle (or a .npy)
            raise InputError(path, "not a readable .npz (not a zip file: truncated, or another kind of file)")
        _check_npz_members(path)
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except FileNotFoundError:
        raise InputError(path, "file not found") from None
    except (zipfile.BadZipFile, EOFError) as exc:
        raise InputError(path, f"not a readable .npz (truncated or not a zip file: {exc})") from None
    except ValueError as exc:  # a pickled member (object array), or a member numpy cannot parse
        if "pickle" in str(exc).lower():
            raise InputError(path, "holds pickled (object) data, which fogsim never loads") from None
        raise InputError(path, f"not a readable .npz ({exc})") from None
    except (OSError, KeyError, zipfile.LargeZipFile, RuntimeError) as exc:
        raise InputError(path, f"not a readable .npz ({type(exc).__name__}: {exc})") from None
    return check(arrays, model, path)
