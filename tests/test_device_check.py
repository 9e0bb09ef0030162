"""scripts/device_check.sh: on a machine without a GPU it says so and exits 0 at once; its
``--dry-run`` runs every row on the CPU (so the script is tested before a GPU minute is spent
on it); the torch-fog probe finds a batched function in ``fogsim.augment`` and checks it."""
import os
import shutil
import subprocess
import sys
import time
import types
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "scripts" / "device_check.sh"


def run(*args, path=None, timeout=60):
    env = dict(os.environ)
    if path is not None:
        env["PATH"] = path
    return subprocess.run([shutil.which("bash"), str(SCRIPT), *args], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=timeout)


def test_no_gpu_says_why_and_exits_0_at_once(tmp_path):
    # a PATH with the shell tools but no nvidia-smi, whatever this machine has
    tools = tmp_path / "bin"
    tools.mkdir()
    for tool in ("dirname", "timeout"):
        os.symlink(shutil.which(tool), tools / tool)
    t0 = time.monotonic()
    res = run(path=str(tools))
    assert time.monotonic() - t0 < 5
    assert res.returncode == 0, res.stderr
    assert "no NVIDIA GPU on this machine (nvidia-smi not found): nothing to check" in res.stdout


def test_a_failing_nvidia_smi_is_no_gpu(tmp_path):
    tools = tmp_path / "bin"
    tools.mkdir()
    fake = tools / "nvidia-smi"
    fake.write_text("#!/bin/sh\necho 'NVIDIA-SMI has failed because it could not communicate with the driver'\n"
                    "exit 9\n")
    fake.chmod(0o755)
    t0 = time.monotonic()
    res = run(path=f"{tools}:{os.environ['PATH']}")
    assert time.monotonic() - t0 < 5
    assert res.returncode == 0 and "finds no usable GPU" in res.stdout and "could not communicate" in res.stdout


@pytest.mark.torch
def test_torch_fog_probe_times_and_checks_a_batched_function(monkeypatch):
    torch = pytest.importorskip("torch")
    sys.path.insert(0, str(ROOT / "scripts"))
    try:
        import device_check
    finally:
        sys.path.pop(0)
    assert device_check.find_torch_fog()[0] is None or "fogsim.augment" in device_check.find_torch_fog()[1]

    def fog_batch(images, ray, beta):  # Koschmieder in torch, rounded half up like fogsim's uint8 path
        t = torch.exp(-beta.view(-1, 1, 1, 1) * ray)
        return torch.floor(images.float() * t + 255 * (1 - t) + 0.5).clamp(0, 255).to(torch.uint8)

    fake = types.ModuleType("fogsim.augment")
    fake.fog_batch = fog_batch
    fake.__path__ = []
    monkeypatch.setitem(sys.modules, "fogsim.augment", fake)
    row = device_check.row_torch_fog(dry=True, cpu=True)
    assert row["device"] == "cpu" and row["seconds"] > 0
    assert "fogsim.augment.fog_batch" in row["note"]
    delta = int(row["note"].rsplit("max |Δ| vs fogsim.koschmieder ", 1)[1])
    assert delta <= 1


@pytest.mark.slow
def test_dry_run_runs_every_row_on_the_cpu():
    res = run("--dry-run", timeout=1500)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-2000:]
    table = res.stdout.split("device_check --dry-run:", 1)[1]
    for step in ("render koschmieder --gpu", "render hybrid fog --gpu", "ILA train", "YOLO 1 epoch",
                 "torch fog batch"):
        line = next(ln for ln in table.splitlines() if ln.startswith(step))
        assert " ok" in line or "skipped: " in line, line
    assert "FAILED" not in table
