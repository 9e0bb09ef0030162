"""fogsim for Blender: build procedural street scenes and render labeled foggy datasets.

Panel: 3D Viewport ▸ Sidebar ▸ fogsim. "Build scene" puts frame N of the chosen preset in the
viewport; "Render dataset" renders the preset's frames with a progress bar (Esc or "Cancel"
stops after the current frame; a later run resumes). The panel and operators live in
:mod:`fogsim.render.blender.addon`; this file is what Blender loads. ``bl_info["version"]``
is stamped from ``fogsim.__version__`` by ``scripts/build_addon.py``.
"""
import sys
from pathlib import Path

bl_info = {
    "name": "fogsim",
    "author": "fogsim developers",
    "version": (0, 0, 0),
    "blender": (3, 4, 0),
    "location": "3D Viewport > Sidebar > fogsim",
    "description": "Procedural street scenes rendered into labeled datasets at several fog densities",
    "category": "Render",
}

_LIB = Path(__file__).resolve().parent / "lib"  # the packaged add-on bundles fogsim + wheels here
if _LIB.is_dir() and str(_LIB) not in sys.path:
    sys.path.insert(0, str(_LIB))

from fogsim.render.blender.addon import register, unregister  # noqa: E402

__all__ = ["bl_info", "register", "unregister"]
