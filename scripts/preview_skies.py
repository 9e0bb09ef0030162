"""One street under every sky: procedural, Blender's world HDRIs, overcast — clear and foggy.

Renders frame 0 of the ``default`` preset's street (``--seed``) once per sky with ``fogsim render``
(the bpy module), then writes a PNG: one column per sky, one row per fog level.

    python scripts/preview_skies.py --out docs/skies.png [--seed 2] [--resolution 240x160] [--samples 12]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from fogsim.io.images import read_image, write_image
from fogsim.presets import presets_dir
from fogsim.viz import strip

SKIES = {"procedural": {}, **{h: {"sky": "hdri", "hdri": h, "rotation_deg": [200, 200]}
                              for h in ("city", "courtyard", "forest", "sunrise", "sunset")},
         "overcast": {"overcast": True}}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="the PNG to write")
    ap.add_argument("--seed", type=int, default=2)
    ap.add_argument("--resolution", default="240x160")
    ap.add_argument("--samples", type=int, default=12)
    ap.add_argument("--levels", default="0,0.03", help="fog levels (rows)")
    args = ap.parse_args(argv)
    default = json.loads((presets_dir() / "default.json").read_text())
    rows: dict[str, list] = {}
    with tempfile.TemporaryDirectory(prefix="fogsim_skies_") as tmp:
        for name, lighting in SKIES.items():
            preset = Path(tmp) / f"{name}.json"
            preset.write_text(json.dumps(default | ({"lighting": lighting} if lighting else {})))
            out = Path(tmp) / name
            subprocess.run([sys.executable, "-m", "fogsim", "render", "--preset", str(preset), "--out", str(out),
                            "--frames", "1", "--seed", str(args.seed), "--resolution", args.resolution,
                            "--samples", str(args.samples), "--levels", args.levels, "--quiet"], check=True)
            for level in sorted((out / "images").iterdir(), key=lambda p: (p.name != "clear", p.name)):
                rows.setdefault(level.name, []).append((name, read_image(level / "000000.png")))
    sheet = [strip([img for _, img in row], [f"{n} {lv}" for n, _ in row]) for lv, row in rows.items()]
    write_image(args.out, np.vstack(sheet))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
