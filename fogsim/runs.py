"""Run bookkeeping shared by every long job (fog, render, study): claiming an output folder,
shards for array jobs, and the seeds derived from a run seed.

* **Claiming**: the first run writes ``OUT/<run file>`` with its parameters; a later run with
  the same parameters resumes, one with other parameters is refused (two datasets are never
  mixed in one folder). The claim is atomic: the file is created with a hard link that fails
  when it exists, so of two concurrent runs with other settings only one can win.
* **Shards**: ``--shard i/N`` (0 ≤ i < N, as ``$SLURM_ARRAY_TASK_ID`` or Kubernetes'
  ``$JOB_COMPLETION_INDEX`` count) takes items i, i+N, …
* **Seeds**: every derived seed depends only on the run seed and the item's name or index,
  never on shard, worker count or order — so any split of the work gives the same outputs.
"""
from __future__ import annotations

import json
import os
import zlib
from pathlib import Path
from typing import Callable, Sequence, TypeVar

import numpy as np

from fogsim._version import __version__
from fogsim.errors import InputError
from fogsim.io.atomic import create_exclusive
from fogsim.io.documents import read_json
from fogsim.io.paths import resolve_path

T = TypeVar("T")


# ----------------------------------------------------------------------------- claiming
def check_output(out: str | os.PathLike, inputs: dict[str, str | os.PathLike | None] | list[tuple],
                 allow_inside_out: tuple[str, ...] = (), *, file: bool = False) -> Path:
    """Refuse an output folder that would overwrite or mix with an input; returns it resolved.

    ``inputs`` maps a flag (``--input``) to the path it names (None: not given; a list of
    ``(flag, path)`` pairs when a flag names several, e.g. positional run folders). The output
    may not equal an input, lie inside one, or contain one (symlinks resolved) — except the
    flags in ``allow_inside_out``, inputs a command keeps in its own folder by design (the
    study's dataset). ``--out ''`` and an existing file are refused too. An existing output
    folder's subfolders are resolved as well: a link below it to a folder (a level folder of a
    reused or shared ``--out``) may not lead into an input, nor around one. Checked before
    anything is written.

    ``file=True``: ``out`` is one file a command writes (``fit-fog --out``): it may not be an input
    nor lie inside one, an existing folder is refused, and its folder must be writable.
    """
    if not str(out).strip():
        raise ValueError(f"--out must name a {'file' if file else 'folder'}, got ''")
    target = resolve_path(out, "--out")
    if file and target.is_dir():
        raise InputError(out, "--out is a folder: name the file to write (e.g. OUT/params.json)")
    if not file and target.exists() and not target.is_dir():
        raise InputError(out, "--out exists and is not a folder")
    pairs = [(flag, given, resolve_path(given, flag))
             for flag, given in (inputs.items() if isinstance(inputs, dict) else inputs)
             if given is not None and str(given) != ""]
    for flag, given, src in pairs:
        inside_out = not file and (src == target or target in src.parents)
        if src == target or src in target.parents or (inside_out and flag not in allow_inside_out):
            where = ("is" if src == target else "lies inside" if src in target.parents else "contains")
            raise InputError(out, f"--out {where} {flag} {given}: the outputs would overwrite or mix with "
                                  f"the input; choose an output {'file' if file else 'folder'} outside it")
    if file:
        _check_writable(out, target)
    elif target.is_dir():
        _check_linked_folders(target, [(f, g, s) for f, g, s in pairs if f not in allow_inside_out])
    return target


def _check_linked_folders(target: Path, inputs: list[tuple]) -> None:
    """Refuse a link below the output folder ``target`` that leads to a folder in, or around, an input
    (``inputs``: (flag, given, resolved) triples). A link to a file is harmless (every write replaces the
    link itself: :func:`fogsim.io.atomic.atomic_path`), and so is one that leads nowhere (a write through it
    fails: nothing is created at its end)."""
    folders = [target]
    while folders:
        with os.scandir(folders.pop()) as entries:  # d_type: no stat per file
            for entry in entries:
                if entry.is_dir(follow_symlinks=False):
                    folders.append(Path(entry.path))
                    continue
                link = Path(entry.path)
                if not entry.is_symlink() or (link.exists() and not link.is_dir()):
                    continue
                real = resolve_path(link, "--out")
                for flag, given, src in inputs:
                    if real == src or src in real.parents or real in src.parents:
                        where = "is" if real == src else "lies inside" if src in real.parents else "contains"
                        raise InputError(link, f"is a link below --out to {real}, which {where} {flag} {given}: "
                                               "the outputs would be written into the input; remove the link or "
                                               "use another --out")


def _check_writable(out, target: Path) -> None:
    """A file can be created beside ``target`` (in its folder, or the nearest one that exists): a
    probe file created and removed at once, so a long job does not fail at its last write."""
    import tempfile

    folder = target.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise InputError(out, f"--out cannot be created: {folder} is not a folder")
    try:
        fd, probe = tempfile.mkstemp(prefix=".fogsim-probe.", dir=folder)
    except OSError as exc:
        raise InputError(out, f"--out cannot be written ({exc.strerror or exc} in {folder})") from None
    os.close(fd)
    os.unlink(probe)


def claim_output(path: str | os.PathLike, parameters: dict, record: dict | None = None, *, what: str = "run",
                 legacy: Callable[[dict], dict | None] | None = None,
                 upgrade: Callable[[dict], dict] | None = None) -> bool:
    """Claim the run file ``path`` for ``parameters``; True when this call created it.

    The file holds ``{"fogsim_version", **record, "parameters"}``. An existing file with
    equal parameters means "resume"; other parameters raise :class:`InputError` naming it.
    ``legacy(old)`` may derive the parameters of a file written by an older fogsim that had no
    ``parameters``; ``upgrade(stored)`` turns stored parameters written in an older fogsim's words
    into today's (the file itself is left as it is).
    """
    path = Path(path)
    payload = json.dumps({"fogsim_version": __version__, **(record or {}), "parameters": parameters},
                         indent=2, sort_keys=True, default=str).encode()
    if create_exclusive(path, payload):  # atomic: of two concurrent first claims, one wins
        return True
    try:
        old = read_json(path)
    except InputError as exc:
        raise InputError(path, f"unreadable run file ({exc.problem}); delete it or use another --out") from None
    if not isinstance(old, dict):  # (the run file's fields are fogsim.schema.documents' to check)
        raise InputError(path, f"malformed run file: must be a JSON object (got {type(old).__name__}); "
                               "delete it or use another --out")
    stored = old.get("parameters")
    if stored is None and legacy is not None:
        stored = legacy(old)
    if isinstance(stored, dict) and upgrade is not None:
        stored = upgrade(stored)
    given = json.loads(json.dumps(parameters, default=str))
    if given != stored:
        raise InputError(path, f"this output folder holds a {what} with other parameters "
                               f"({describe_difference(stored, given, 'there', 'now')}); run with the parameters "
                               f"recorded in {path.name} to resume or add to it, or choose another --out: two "
                               f"{what}s are never mixed in one folder")
    return False


ABSENT = object()  # a key one side lacks (first_difference)


def first_difference(old, new, where: str = ""):
    """The first place two JSON values differ: ``(dotted path, old part, new part)`` (a key one side
    lacks: :data:`ABSENT` on that side), or None when they are equal."""
    if isinstance(old, dict) and isinstance(new, dict):
        for key in sorted(set(old) | set(new), key=str):
            found = first_difference(old.get(key, ABSENT), new.get(key, ABSENT), f"{where}.{key}" if where else key)
            if found is not None:
                return found
        return None
    nested = any(isinstance(v, (dict, list)) for v in (*old, *new)) if isinstance(old, list) and isinstance(
        new, list) else False  # a list of plain values ([320, 213]) is one value
    if nested and len(old) == len(new):
        for i, (a, b) in enumerate(zip(old, new)):
            if (found := first_difference(a, b, f"{where}[{i}]")) is not None:
                return found
        return None
    return None if old == new else (where, old, new)


def describe_difference(old, new, old_side: str = "recorded", new_side: str = "given") -> str:
    """``"resolution: [320, 213] recorded, [640, 426] given"``: the first difference of two JSON values,
    each side's value shortened to 80 characters ("" when they are equal)."""
    found = first_difference(old, new)
    if found is None:
        return ""
    where, a, b = found

    def show(v) -> str:
        if v is ABSENT:
            return "absent"
        text = json.dumps(v, default=str, ensure_ascii=False)
        return text if len(text) <= 80 else text[:79] + "…"
    return f"{where or 'the value'}: {show(a)} {old_side}, {show(b)} {new_side}"


# ----------------------------------------------------------------------------- shards
def parse_shard(text: str | None) -> tuple[int, int]:
    """``"i/N"`` (0 ≤ i < N) → ``(i, N)``; ``None`` → ``(0, 1)``, the whole run."""
    if not text:
        return 0, 1
    try:
        i, n = (int(x) for x in text.split("/"))
    except ValueError:
        raise ValueError(f"--shard must look like i/N, got {text!r}") from None
    if not (n >= 1 and 0 <= i < n):
        raise ValueError(f"--shard {text}: need 0 ≤ i < N")
    return i, n


def select_shard(items: Sequence[T], shard: tuple[int, int]) -> list[T]:
    """Items i, i+N, … of ``items`` for shard ``(i, N)``."""
    i, n = shard
    return list(items[i::n])


def is_sharded(shard: tuple[int, int]) -> bool:
    """True when the run is one of several shards (dataset-wide files wait for all of them)."""
    return shard[1] > 1


# ----------------------------------------------------------------------------- seeds
def frame_seed(seed: int, index: int) -> int:
    """Seed of rendered frame ``index``: ``SeedSequence([seed, index]).generate_state(1)[0]``."""
    return int(np.random.SeedSequence([int(seed), int(index)]).generate_state(1)[0])


FRAME_SEED_RULE = "numpy SeedSequence([seed, frame index]).generate_state(1)[0]"


def sample_seed(seed: int, key: str) -> int:
    """Seed of fogged sample ``key`` (patchy fog): ``(seed·1 000 003 + crc32(key)) mod 2³²``."""
    return (int(seed) * 1_000_003 + zlib.crc32(key.encode())) % 2**32


def level_seed(seed: int, key: str, level_key: str) -> int:
    """Seed of one sample's fog level where the fog draws noise (the LiDAR's range noise):
    ``SeedSequence([seed, crc32(key), crc32(level key)]).generate_state(1)[0]`` — the same for a level
    whatever the other levels, their order, the shard or the worker."""
    parts = [int(seed) % 2**32, zlib.crc32(key.encode()), zlib.crc32(level_key.encode())]
    return int(np.random.SeedSequence(parts).generate_state(1)[0])


LEVEL_SEED_RULE = ("numpy default_rng(SeedSequence([seed mod 2^32, crc32(frame key), crc32(level key)])"
                   ".generate_state(1)[0])")


def split_key(frame: str, seed: int = 0) -> int:
    """A frame's position in [0, 1000) for the train/val split: ``crc32("seed/frame") mod 1000``."""
    return zlib.crc32(f"{seed}/{frame}".encode()) % 1000
