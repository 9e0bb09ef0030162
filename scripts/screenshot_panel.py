#!/usr/bin/env python3
"""Screenshot of the fogsim panel in a real Blender window (Debian's Blender under Xvfb).

    python scripts/screenshot_panel.py [--out docs/addon_panel.png]

Starts Xvfb, runs ``blender`` with the add-on registered from this checkout, builds frame 0
of the default preset in the viewport, opens the fogsim sidebar tab and saves a screenshot.
Needs: apt-get install blender xvfb xdotool (and Mesa's software OpenGL, libgl1-mesa-dri).
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TAB_XY = (1308, 201)  # the "fogsim" sidebar tab in a 1600×900 factory-startup Blender 3.4 window

DRIVER = r'''
import sys, bpy
sys.path.insert(0, {root!r})
for site in {sites!r}:
    sys.path.insert(1, site)
import blender_addon
blender_addon.register()
OUT = {out!r}

def setup():
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj, do_unlink=True)
    s = bpy.context.scene.fogsim
    s.preset, s.resolution, s.samples, s.frames = "default", "640x426", 6, 8
    s.output = "/tmp/fogsim_dataset"
    for area in bpy.context.window.screen.areas:
        if area.type == "VIEW_3D":
            space = area.spaces.active
            space.show_region_ui = True
            space.shading.type = "SOLID"
            space.shading.color_type = "MATERIAL"
            for region in area.regions:
                if region.type == "UI" and hasattr(region, "active_panel_category"):  # Blender 4.1+
                    region.active_panel_category = "fogsim"
            main = next(r for r in area.regions if r.type == "WINDOW")
            with bpy.context.temp_override(window=bpy.context.window, area=area, region=main):
                bpy.ops.fogsim.build_scene()
                bpy.ops.view3d.view_camera()
                bpy.ops.view3d.view_center_camera()
    return None

def shoot():
    bpy.ops.screen.screenshot(filepath=OUT)
    bpy.ops.wm.quit_blender()
    return None

bpy.app.timers.register(setup, first_interval=1.0)
bpy.app.timers.register(shoot, first_interval=9.0)
'''


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=str(ROOT / "docs" / "addon_panel.png"))
    ap.add_argument("--size", default="1600x900")
    args = ap.parse_args()
    for tool in ("blender", "Xvfb"):
        if shutil.which(tool) is None:
            sys.exit(f"screenshot_panel: {tool} not found (apt-get install blender xvfb)")
    sites = [str(p) for p in sorted((ROOT / ".venv" / "lib").glob("python3*/site-packages"))]
    with tempfile.TemporaryDirectory() as tmp:
        driver = Path(tmp) / "driver.py"
        out = Path(tmp) / "shot.png"
        driver.write_text(DRIVER.format(root=str(ROOT), sites=sites, out=str(out)))
        display = ":97"
        xvfb = subprocess.Popen(["Xvfb", display, "-screen", "0", f"{args.size}x24", "-nolisten", "tcp"])
        try:
            time.sleep(1.5)
            env = dict(os.environ, DISPLAY=display)
            blend = Path(tmp) / "start.blend"  # opening a file skips the splash screen
            subprocess.run(["blender", "-b", "--factory-startup", "--python-expr",
                            f"import bpy; bpy.ops.wm.save_as_mainfile(filepath={str(blend)!r})"],
                           check=True, capture_output=True, timeout=120)
            proc = subprocess.Popen(["blender", "--factory-startup", "-noaudio", str(blend), "-P", str(driver)],
                                    env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            time.sleep(5.0)
            if shutil.which("xdotool"):  # Blender 3.x has no API to pick a sidebar tab: click it
                x, y = TAB_XY
                subprocess.run(["xdotool", "mousemove", str(x), str(y), "click", "1"], env=env, check=False)
            _, stderr = proc.communicate(timeout=300)
            res = subprocess.CompletedProcess(proc.args, proc.returncode, "", stderr)
        finally:
            xvfb.terminate()
        if not out.is_file() or "Traceback" in res.stderr:
            sys.exit("screenshot_panel: Blender did not write a clean screenshot (is OpenGL available "
                     f"under Xvfb?)\n{res.stderr[-2000:]}")
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(out, args.out)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
