#!/usr/bin/env python3
"""The rows of ``scripts/device_check.sh`` (run that, not this): each row in a process of its own
under a time limit, the CPU figure beside the GPU one where it is cheap, one table at the end.

    python scripts/device_check.py [--dry-run]            # every row, then the table
    python scripts/device_check.py --row NAME --json OUT  # one row (what the table runner starts)

``--dry-run`` runs every row on the CPU at toy sizes, so the script itself is tested on a
machine without a GPU before the first GPU minute is spent on it. Exit 0 when every row is ok
or skipped (with the reason), 1 when a row failed.
"""
from __future__ import annotations

import argparse
import importlib
import json
import os
import pkgutil
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from importlib.util import find_spec
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TOTAL_S = 450  # every row together, on the GPU machine: the table must come out within 8 minutes
GPU_BACKENDS = ("OPTIX", "CUDA", "HIP", "ONEAPI", "METAL")


# --- rendering ---------------------------------------------------------------------------------

def render_command() -> tuple[list[str] | None, str]:
    """How to run ``fogsim render`` here: the bpy module, else a blender binary, else why not."""
    if find_spec("bpy") is not None:
        return [sys.executable, "-m", "fogsim", "render"], "bpy module"
    blender = os.environ.get("BLENDER") or shutil.which("blender")
    if blender:
        return [blender, "-b", "--factory-startup", "-noaudio", "-P", str(ROOT / "scripts" / "render_batch.py"),
                "--"], blender
    return None, (f"no bpy module (bpy 5.0 needs Python 3.11; this is {platform.python_version()}) "
                  "and no blender binary (set BLENDER=/path/to/blender)")


def render_frames(out: Path, args: list[str], timing: str) -> tuple[list[float], dict]:
    """Render into ``out``; returns each frame's ``timings_s[timing]`` and the first frame's render record."""
    cmd, _ = render_command()
    res = subprocess.run([*cmd, "--out", str(out), *args, "--quiet"], cwd=ROOT, capture_output=True, text=True)
    if res.returncode != 0:
        raise RuntimeError(f"fogsim render exit {res.returncode}: {(res.stderr or res.stdout).strip()[-300:]}")
    metas = [json.loads(p.read_text()) for p in sorted((out / "meta").glob("*.json"))]
    return [m["timings_s"][timing] for m in metas], metas[0]["render"]


def row_render(kind: str, dry: bool) -> dict:
    cmd, how = render_command()
    if cmd is None:
        return {"status": f"skipped: {how}"}
    if kind == "koschmieder":
        size, frames, timing, extra = (("96x64", 1, "render", ["--samples", "2"]) if dry
                                       else ("640x426", 3, "render", []))
    else:  # one volumetric fog level, hybrid medium: the fog render is what the GPU must speed up
        size, frames, timing, extra = (("96x64", 1, "fog_render", ["--samples", "2"]) if dry
                                       else ("320x213", 2, "fog_render", []))
        extra += ["--fog", "volumetric", "--fog-medium", "hybrid"]
    common = ["--preset", "default", "--resolution", size, "--levels", "clear,0.06", *extra]
    tmp = Path(tempfile.mkdtemp(prefix="fogsim_device_render_"))
    try:
        gpu_s, record = render_frames(tmp / "gpu", [*common, "--frames", str(frames), "--gpu"], timing)
        cpu_s, _ = render_frames(tmp / "cpu", [*common, "--frames", "1"], timing)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    seconds = statistics.median(gpu_s[1:] or gpu_s)  # the first GPU frame loads/compiles the kernels
    device = record["device"]
    names = ", ".join(record.get("gpu_devices") or [])
    row = {"device": f"{device}{f' ({names})' if names else ''}", "seconds": seconds, "cpu_seconds": cpu_s[0],
           "note": f"{how}; per frame, {size}; first GPU frame {gpu_s[0]:.1f} s"}
    if device in GPU_BACKENDS:
        row["status"] = "ok"
    elif dry and record.get("gpu_fallback"):
        row["status"] = "ok (dry run: --gpu fell back to the CPU and said why)"
    else:
        row["status"] = f"FAILED: --gpu rendered on the CPU ({record.get('gpu_fallback')})"
    return row


# --- ILA ---------------------------------------------------------------------------------------

def row_ila(dry: bool, cpu: bool = False) -> dict:
    if find_spec("torch") is None:
        return {"status": "skipped: torch is not installed"}
    import numpy as np
    import torch

    from fogsim.depth.ila import ILAConfig, StereoSet, device, train_rounds

    n, size, epochs = (4, (64, 32), 1) if dry else (16, (256, 128), 5)
    rng = np.random.default_rng(0)
    w, h = size
    rgb = rng.random((n, 3, h, w), dtype=np.float32)
    target = (0.01 + 0.02 * rgb[:, :1]).astype(np.float32)
    target[:, :, :, : w // 8] = 0  # a hole band, as stereo leaves
    data = StereoSet(rgb, target, target > 0, [f"f{i}" for i in range(n)], {"baseline_m": 0.2, "fx_over_w": 1.1})
    config = ILAConfig(size=size, rounds=1, epochs=epochs, batch=4)
    steps = epochs * -(-n // config.batch)
    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        train_rounds(data, config, out, progress=False)
        if torch.cuda.is_available():
            torch.cuda.synchronize()
        seconds = time.perf_counter() - t0
    dev = device()
    row = {"device": f"{dev.type}{f' ({torch.cuda.get_device_name(0)})' if dev.type == 'cuda' else ''}",
           "seconds": seconds, "note": f"{steps} steps + predict + checkpoint, {w}x{h}, batch {config.batch}"}
    if cpu:
        return row
    row["cpu_seconds"] = cpu_baseline("ila", dry)
    row["status"] = "ok" if dev.type == "cuda" or dry else "FAILED: torch sees no CUDA device"
    return row


# --- YOLO --------------------------------------------------------------------------------------

def synthetic_yolo(root: Path, n_train: int, n_val: int, size: int) -> Path:
    """Images with 1–3 filled rectangles (class 0) and their YOLO labels; returns data.yaml."""
    import cv2
    import numpy as np

    rng = np.random.default_rng(0)
    for part, n in (("train", n_train), ("val", n_val)):
        (root / "images" / part).mkdir(parents=True)
        (root / "labels" / part).mkdir(parents=True)
        for i in range(n):
            img = rng.integers(60, 120, (size, size, 3), dtype=np.uint8)
            lines = []
            for _ in range(int(rng.integers(1, 4))):
                bw, bh = (int(v) for v in rng.integers(size // 8, size // 3, 2))
                x0, y0 = (int(v) for v in rng.integers(0, size - max(bw, bh), 2))
                img[y0:y0 + bh, x0:x0 + bw] = (220, 40, 40)
                lines.append(f"0 {(x0 + bw / 2) / size:.6f} {(y0 + bh / 2) / size:.6f} {bw / size:.6f} {bh / size:.6f}")
            cv2.imwrite(str(root / "images" / part / f"{i:04d}.png"), img)
            (root / "labels" / part / f"{i:04d}.txt").write_text("\n".join(lines) + "\n")
    data = root / "data.yaml"
    data.write_text(f"path: {root}\ntrain: images/train\nval: images/val\nnames:\n  0: box\n")
    return data


def row_yolo(dry: bool, cpu: bool = False) -> dict:
    missing = [m for m in ("torch", "ultralytics", "polars") if find_spec(m) is None]
    if missing:
        return {"status": f"skipped: {', '.join(missing)} not installed (carry them: scripts/device_wheels.sh)"}
    import torch

    from fogsim.detection.yolo import TrainConfig, train

    use_cuda = torch.cuda.is_available() and not cpu
    n_train, n_val, size, batch = (8, 4, 64, 4) if dry else (128, 32, 320, 16)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        data = synthetic_yolo(tmp / "data", n_train, n_val, size)
        cfg = TrainConfig(model="yolov8n.yaml", epochs=1, imgsz=size, batch=batch, device="0" if use_cuda else "cpu",
                          workers=2, plots=False)
        os.environ["YOLO_VERBOSE"] = "False"
        t0 = time.perf_counter()
        best = train("device_check", data, tmp / "runs" / "device_check", cfg, tmp / "config")
        seconds = time.perf_counter() - t0
        if not best.is_file():
            return {"status": "FAILED: no best.pt"}
    row = {"device": f"cuda ({torch.cuda.get_device_name(0)})" if use_cuda else "cpu", "seconds": seconds,
           "note": f"1 epoch, yolov8n from scratch, {n_train} images at {size} px, batch {batch}"}
    if cpu:
        return row
    row["cpu_seconds"] = cpu_baseline("yolo", dry)
    row["status"] = "ok" if use_cuda or dry else "FAILED: torch sees no CUDA device"
    return row


# --- the torch fog batch function (fogsim.augment, written elsewhere) ---------------------------

TORCH_FOG_NAMES = ("fog_batch", "fog_torch", "torch_fog", "batch_fog", "koschmieder_torch", "koschmieder_batch",
                   "fog_batch_torch")


def find_torch_fog():
    """A batched torch fog function in ``fogsim.augment`` (or one of its modules), else why not."""
    try:
        package = importlib.import_module("fogsim.augment")
    except ImportError as exc:
        return None, f"fogsim.augment cannot be imported ({exc})"
    modules = [package]
    for info in pkgutil.iter_modules(getattr(package, "__path__", [])):
        try:
            modules.append(importlib.import_module(f"fogsim.augment.{info.name}"))
        except ImportError:
            continue
    for module in modules:
        for name in TORCH_FOG_NAMES:
            fn = getattr(module, name, None)
            if callable(fn):
                return fn, f"{module.__name__}.{name}"
    return None, f"fogsim.augment has no batched torch fog function (looked for {', '.join(TORCH_FOG_NAMES)})"


def row_torch_fog(dry: bool, cpu: bool = False) -> dict:
    if find_spec("torch") is None:
        return {"status": "skipped: torch is not installed"}
    fn, where = find_torch_fog()
    if fn is None:
        return {"status": f"skipped: {where}"}
    import numpy as np
    import torch

    from fogsim import koschmieder

    dev = torch.device("cuda" if torch.cuda.is_available() and not cpu else "cpu")
    b, h, w = (2, 64, 96) if dry else (16, 1280, 1920)
    gen = torch.Generator().manual_seed(0)
    images = torch.randint(0, 256, (b, 3, h, w), generator=gen, dtype=torch.uint8).to(dev)
    ray = (torch.rand((b, 1, h, w), generator=gen) * 200 + 1).to(dev)
    beta = torch.full((b,), 0.06, device=dev)

    def call():
        out = fn(images, ray, beta)
        out = out[0] if isinstance(out, tuple) else out
        if dev.type == "cuda":
            torch.cuda.synchronize()
        return out

    out = call()  # warm-up (CUDA context, kernels)
    times = []
    for _ in range(5):
        t0 = time.perf_counter()
        call()
        times.append(time.perf_counter() - t0)
    ref = koschmieder(images[0].permute(1, 2, 0).cpu().numpy(), ray[0, 0].cpu().numpy(), 0.06)
    got = out[0].permute(1, 2, 0).cpu().numpy()
    diff = (f"max |Δ| vs fogsim.koschmieder {np.abs(got.astype(np.int32) - ref.astype(np.int32)).max()}"
            if got.shape == ref.shape else f"output shape {tuple(out.shape)}")
    row = {"device": f"{dev.type}", "seconds": statistics.median(times),
           "note": f"{where}, {b}×3×{h}×{w} uint8, median of 5; {diff}"}
    if cpu:
        return row
    row["cpu_seconds"] = cpu_baseline("torch_fog", dry)
    row["status"] = "ok" if dev.type == "cuda" or dry else "FAILED: torch sees no CUDA device"
    return row


# --- the table ---------------------------------------------------------------------------------

ROWS = {  # name: (title, function, seconds on the GPU machine)
    "render_koschmieder": ("render koschmieder --gpu", lambda dry: row_render("koschmieder", dry), 150),
    "render_hybrid": ("render hybrid fog --gpu", lambda dry: row_render("hybrid", dry), 120),
    "ila": ("ILA train", row_ila, 60),
    "yolo": ("YOLO 1 epoch", row_yolo, 150),
    "torch_fog": ("torch fog batch", row_torch_fog, 45),
}


def cpu_baseline(name: str, dry: bool) -> float | None:
    """The same row on the CPU (CUDA hidden), in a process of its own; None if it failed."""
    env = dict(os.environ, CUDA_VISIBLE_DEVICES="")
    with tempfile.NamedTemporaryFile(suffix=".json") as f:
        cmd = [sys.executable, __file__, "--row", name, "--cpu", "--json", f.name] + (["--dry-run"] if dry else [])
        try:
            subprocess.run(cmd, env=env, capture_output=True, timeout=120, cwd=ROOT)
            return json.loads(Path(f.name).read_text() or "{}").get("seconds")
        except (subprocess.TimeoutExpired, json.JSONDecodeError):
            return None


def run_row(name: str, dry: bool, cpu: bool) -> dict:
    fn = ROWS[name][1]
    try:
        return fn(dry, cpu) if cpu else fn(dry)
    except Exception as exc:  # a row's failure is its status line, the others still run
        return {"status": f"FAILED: {type(exc).__name__}: {' '.join(str(exc).split())[:300]}"}


def table(rows: list[tuple[str, dict]]) -> str:
    head = ("step", "device", "seconds", "CPU s", "speed-up", "status")
    lines = []
    for title, r in rows:
        s, c = r.get("seconds"), r.get("cpu_seconds")
        lines.append((title, r.get("device", "-"), f"{s:.2f}" if s is not None else "-",
                      f"{c:.2f}" if c is not None else "-", f"{c / s:.1f}×" if s and c else "-", r["status"]))
    widths = [max(len(x[i]) for x in [head, *lines]) for i in range(len(head) - 1)]
    fmt = "  ".join(f"{{:<{w}}}" for w in widths) + "  {}"
    out = [fmt.format(*head), fmt.format(*("-" * w for w in widths), "-" * 6)]
    out += [fmt.format(*x) for x in lines]
    out += [f"  {title}: {r['note']}" for title, r in rows if r.get("note")]
    return "\n".join(out)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--dry-run", action="store_true", help="every row on the CPU at toy sizes")
    p.add_argument("--row", choices=sorted(ROWS), help="run one row (internal)")
    p.add_argument("--cpu", action="store_true", help="with --row: the CPU baseline of the row (internal)")
    p.add_argument("--json", help="with --row: where to write its result (internal)")
    args = p.parse_args()
    if args.row:
        result = run_row(args.row, args.dry_run, args.cpu)
        Path(args.json).write_text(json.dumps(result))
        return 0
    started = time.monotonic()
    total = 1200 if args.dry_run else TOTAL_S
    rows = []
    for name, (title, _, budget) in ROWS.items():
        left = total - (time.monotonic() - started)
        if left < 10:
            rows.append((title, {"status": "skipped: out of the script's time budget"}))
            continue
        limit = min(budget * (4 if args.dry_run else 1), left)
        print(f"device_check: {title} (≤ {limit:.0f} s) …", flush=True)
        with tempfile.NamedTemporaryFile(suffix=".json") as f:
            cmd = [sys.executable, __file__, "--row", name, "--json", f.name] + (["--dry-run"] if args.dry_run else [])
            try:
                res = subprocess.run(cmd, capture_output=True, text=True, timeout=limit, cwd=ROOT)
                text = Path(f.name).read_text()
                result = json.loads(text) if text else {
                    "status": f"FAILED: exit {res.returncode}: {(res.stderr or res.stdout).strip()[-300:]}"}
            except subprocess.TimeoutExpired:
                result = {"status": f"FAILED: over its {limit:.0f} s"}
        rows.append((title, result))
    print(f"\ndevice_check{' --dry-run' if args.dry_run else ''}: {time.monotonic() - started:.0f} s, "
          f"Python {platform.python_version()}")
    print(table(rows))
    return 1 if any(r["status"].startswith("FAILED") for _, r in rows) else 0


if __name__ == "__main__":
    sys.exit(main())
