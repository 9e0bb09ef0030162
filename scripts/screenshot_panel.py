#!/usr/bin/env python3
"""Screenshot of the fogsim panel in a real Blender window (Debian's Blender under Xvfb).

    python scripts/screenshot_panel.py [--out docs/addon_panel.png]

Starts Xvfb, runs ``blender`` with the add-on registered from this checkout, builds frame 0
of the default preset in the viewport, runs *Preview fog* (sky: the *sunset* HDRI) into an Image
Editor beside it, opens the fogsim sidebar tab (xdotool clicks it: Blender 3.x has no API for
that) and saves a screenshot.
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
TAB_XY = (1308, 201)  # the "fogsim" sidebar tab in a 1600×1000 factory-startup Blender 3.4 window
SIDEBAR_EDGE_XY = (1102, 450)  # the sidebar's left edge there

DRIVER = r'''
import os, sys, bpy
sys.path.insert(0, {root!r})
for site in {sites!r}:
    sys.path.insert(1, site)
import blender_addon
blender_addon.register()
OUT, READY, CLICKED = {out!r}, {ready!r}, {clicked!r}

def override(area, kind="WINDOW"):
    region = next(r for r in area.regions if r.type == kind)
    return bpy.context.temp_override(window=bpy.context.window, area=area, region=region)

def setup():
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj, do_unlink=True)
    s = bpy.context.scene.fogsim
    s.preset, s.resolution, s.samples, s.frames, s.frame = "default", "640x426", 16, 8, 0
    s.levels_kind, s.levels, s.preview_beta = "visibility", "300,150,75,40", 0.04
    s.sky, s.hdri = "hdri", "sunset"  # the preview under Blender's sunset HDRI
    s.output = "/tmp/fogsim_dataset"
    screen = bpy.context.window.screen
    view = next(a for a in screen.areas if a.type == "VIEW_3D")
    before = set(screen.areas[:])
    with override(view):  # the left part of the viewport becomes the Image Editor of the preview
        bpy.ops.screen.area_split(direction="VERTICAL", factor=0.5)
    new = [a for a in screen.areas if a not in before][0]
    left = min((new, view), key=lambda a: a.x)
    left.type = "IMAGE_EDITOR"
    view = next(a for a in screen.areas if a.type == "VIEW_3D")
    space = view.spaces.active
    space.show_region_ui = True
    space.shading.type = "SOLID"
    space.shading.color_type = "MATERIAL"
    for region in view.regions:
        if region.type == "UI" and hasattr(region, "active_panel_category"):  # Blender 4.1+
            region.active_panel_category = "fogsim"
    with override(view):
        bpy.ops.fogsim.build_scene()
        bpy.ops.view3d.view_camera()
        bpy.ops.view3d.view_center_camera()
        bpy.ops.fogsim.preview_fog()
    for obj in bpy.context.view_layer.objects:  # no outline, and no "Item" tab before "fogsim"
        obj.select_set(False)
    bpy.context.view_layer.objects.active = None
    with override(left):
        bpy.ops.image.view_all(fit_view=True)
    open(READY, "w").close()
    return None

def shoot():
    if not os.path.exists(CLICKED):
        return 0.5
    for obj in bpy.context.view_layer.objects:  # a click that missed its tab selects nothing here
        obj.select_set(False)
    bpy.context.view_layer.objects.active = None
    for area in bpy.context.window.screen.areas:
        area.tag_redraw()
    bpy.ops.wm.redraw_timer(type="DRAW_WIN_SWAP", iterations=1)  # what the screenshot reads is drawn now
    bpy.ops.screen.screenshot(filepath=OUT)
    bpy.ops.wm.quit_blender()
    return None

bpy.app.timers.register(setup, first_interval=1.0)
bpy.app.timers.register(shoot, first_interval=2.0)
'''


def _wait_for(path: Path, proc: subprocess.Popen, timeout_s: float) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end and proc.poll() is None:
        if path.exists():
            return True
        time.sleep(0.5)
    return False


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=str(ROOT / "docs" / "addon_panel.png"))
    ap.add_argument("--size", default="1600x1000")
    args = ap.parse_args()
    for tool in ("blender", "Xvfb"):
        if shutil.which(tool) is None:
            sys.exit(f"screenshot_panel: {tool} not found (apt-get install blender xvfb)")
    sites = [str(p) for p in sorted((ROOT / ".venv" / "lib").glob("python3*/site-packages"))]
    with tempfile.TemporaryDirectory() as tmp:
        driver = Path(tmp) / "driver.py"
        out = Path(tmp) / "shot.png"
        ready, clicked = Path(tmp) / "ready", Path(tmp) / "clicked"
        driver.write_text(DRIVER.format(root=str(ROOT), sites=sites, out=str(out), ready=str(ready),
                                        clicked=str(clicked)))
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
            if _wait_for(ready, proc, 240) and shutil.which("xdotool"):
                time.sleep(3.0)  # Blender 3.x has no API to pick a sidebar tab: click it, once it is drawn
                x, y = TAB_XY
                ex, ey = SIDEBAR_EDGE_XY  # then drag the sidebar's edge left, so that its labels fit
                steps = [["mousemove", str(x - 40), str(y)], ["mousemove", str(x), str(y)], ["click", "1"],
                         ["mousemove", str(x), str(y + 2)], ["click", "1"],  # a busy Blender may miss one
                         ["mousemove", str(ex + 20), str(ey)], ["mousemove", str(ex), str(ey)], ["mousedown", "1"],
                         *(["mousemove", str(ex - d), str(ey)] for d in range(20, 161, 20)), ["mouseup", "1"],
                         ["mousemove", str(ex - 500), str(ey + 300)]]
                for step in steps:  # slowly: Blender wants to see the pointer move between the clicks
                    subprocess.run(["xdotool", *step], env=env, check=False)
                    time.sleep(1.0)
            clicked.touch()
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
