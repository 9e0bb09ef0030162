"""``fogsim schema preset [--out FILE]``: the JSON Schema of a dataset preset (pydantic's, from
:mod:`fogsim.schema.presets`), printed or written atomically. The bundled copy is
``fogsim/presets/preset.schema.json``; a preset names it in ``"$schema"`` so an editor completes
and checks the file as it is typed."""
from __future__ import annotations

import json

from fogsim.errors import EXIT_OK

DOCUMENTS = ("preset",)


def add_parsers(sub) -> None:
    p = sub.add_parser("schema", help="print or write the JSON Schema of a fogsim document (a dataset preset)")
    p.add_argument("document", choices=DOCUMENTS, help="which document: preset (a dataset preset for fogsim render)")
    p.add_argument("--out", help="write it to this file (atomically) instead of printing it")
    p.add_argument("--quiet", action="store_true", help="with --out: print nothing (errors only)")
    p.set_defaults(run=cmd_schema)


def schema_text() -> str:
    """The preset JSON Schema as the shipped file holds it (indented, sorted keys, a final newline)."""
    from fogsim.schema.presets import preset_json_schema

    return json.dumps(preset_json_schema(), indent=2, sort_keys=True, ensure_ascii=False) + "\n"


def cmd_schema(args) -> int:
    text = schema_text()
    if args.out:
        from fogsim.io.atomic import atomic_write_bytes

        atomic_write_bytes(args.out, text.encode())
        if not args.quiet:
            print(f"wrote the JSON Schema of a dataset preset → {args.out}")
    else:
        print(text, end="")
    return EXIT_OK
